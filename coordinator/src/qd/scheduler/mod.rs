//! The service's core, as plain data: which candidates each run needs evaluated now, who
//! holds them, what came back, and when a step (a stretch of the initial population, or a
//! whole generation) is complete and applied to the run's library in candidate order.
//!
//! No clock, no network, no database: callers pass the time in, and take the changes to
//! store ([`Write`]s) out with [`Scheduler::take_writes`]. So every rule about leases,
//! duplicates, failures and reproducibility is tested here directly.
//!
//! Reproducibility: a candidate is a pure function of (run seed, candidate number, the
//! library it was bred from), results are applied in candidate order, and the initial
//! population ends at the candidate that brings its passes to the target. So neither the
//! number of workers, nor their speed, nor restarts change a run. Candidates drawn ahead
//! of their generation (`ahead`) are kept only where the generation draws them anyway.

use crate::qd::changes::{AppliedCandidate, StepCommit, StoredPending, Write};
use crate::qd::evolution::{initial_candidate, offspring, Parents};
use crate::qd::library::{CellChange, GenerationStats, Library, Placement};
use crate::qd::run::RunRecord;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::time::{Duration, Instant};
use strider_common::experiment::{ConstraintHandling, RunSettings};
use strider_common::ids::{CandidateKey, CandidateNumber};
use strider_common::precheck::precheck;
use strider_common::rng::{CandidateSeed, RunSeed};
use strider_common::{
    BodyPlan, CellIndex, Experiment, Features, Genome, InvalidReason, Outcome, Scheme, Standing,
};
use strider_common::{EvalContext, RunId, WorkerId};

mod ahead;
mod leases;
mod progress;
mod shares;
mod steps;

pub use ahead::AheadCounts;
pub use progress::{fraction_done, RunProgress};
pub use shares::fair_share;
pub use steps::cell_of;

/// The most initial-population candidates a run draws ahead of the first one not yet
/// applied. Bounds memory and the draws wasted once the population is complete; does not
/// affect results.
pub const INITIAL_WINDOW: u64 = 4096;

/// Workers a candidate may take down with it before it is marked failed: each died, lost
/// its connection, stalled past its lease or sent a result that was refused, while it was
/// simulating the candidate; each worker session counts once per candidate. Hand-backs and
/// leases never begun do not count: they say nothing about the candidate.
pub const DEFAULT_MAX_ATTEMPTS: u32 = 3;

/// A candidate handed to a worker.
#[derive(Clone, Debug, PartialEq)]
pub struct Assignment {
    /// Which candidate.
    pub key: CandidateKey,
    pub genome: Genome,
    pub scheme: Scheme,
    /// The run's seed.
    pub run_seed: RunSeed,
    /// The fitness of the feasible elite its cell holds (none: an empty cell, the initial
    /// population, ES): a result fast enough at the run's step and no fitter may skip its
    /// stay-up window and confirming trials and come back `outranked`.
    pub to_beat: Option<f64>,
}

/// Why a result was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    /// The run does not exist.
    #[error("the experiment has no run {0}")]
    NoSuchRun(RunId),
    /// The run has no such candidate (never drawn).
    #[error("{0} does not exist")]
    Unknown(CandidateKey),
    /// A valid outcome marked `outranked` that its cell's elite did not outrank when it
    /// was drawn: its stay-up window and confirming trials were owed.
    #[error("outcome.valid.outranked: fitness {fitness} is above the bar it was drawn with ({to_beat:?}), so its stay-up window and confirming trials were owed")]
    NotOutranked {
        /// The outcome's fitness.
        fitness: f64,
        /// The fitness of its cell's elite when it was drawn, if any.
        to_beat: Option<f64>,
    },
    /// A valid outcome whose cell is not the one its features fall in.
    #[error("outcome.valid.cell: {stated} does not match the features (cell {expected:?})")]
    CellMismatch {
        /// The cell the outcome states.
        stated: u32,
        /// The cell its features fall in (none: outside the grid).
        expected: Option<u32>,
    },
}

/// What became of an accepted result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accepted {
    /// It was the candidate's first result: stored.
    Stored,
    /// The candidate already had its result (or was applied or dropped): ignored.
    Duplicate,
}

#[derive(Clone, Debug, PartialEq)]
enum State {
    Waiting,
    Leased {
        worker: WorkerId,
        expires: Instant,
        /// The worker said it began simulating it.
        started: bool,
    },
    Resolved(Outcome),
}

#[derive(Clone, Debug)]
struct Pending {
    generation: u32,
    genome: Genome,
    /// Its cell's elite's fitness when it was drawn ([`Assignment::to_beat`]).
    to_beat: Option<f64>,
    attempts: u32,
    /// Worker sessions already charged an attempt for it (each counts once).
    charged: Vec<WorkerId>,
    state: State,
    /// Drawn ahead of its generation ([`CandidateKey::drawn_ahead`]): its key says so for
    /// its whole life, kept or not.
    drawn_ahead: bool,
    /// Its result's write, held while it is drawn ahead and not yet kept: a candidate its
    /// generation does not draw must leave no trace in the database.
    deferred: Option<Write>,
}

impl Pending {
    /// A candidate just drawn: charged to no worker, no write held.
    fn new(
        generation: u32,
        genome: Genome,
        to_beat: Option<f64>,
        attempts: u32,
        state: State,
        drawn_ahead: bool,
    ) -> Self {
        Self {
            generation,
            genome,
            to_beat,
            attempts,
            charged: Vec::new(),
            state,
            drawn_ahead,
            deferred: None,
        }
    }

    /// Whether `key` names this candidate (its number already matched).
    fn answers_to(&self, key: CandidateKey) -> bool {
        self.generation == key.generation && self.drawn_ahead == key.drawn_ahead
    }

    fn key(&self, run: RunId, number: u64) -> CandidateKey {
        CandidateKey {
            run,
            generation: self.generation,
            number: CandidateNumber(number),
            drawn_ahead: self.drawn_ahead,
        }
    }
}

struct RunState {
    record: RunRecord,
    /// The current step's candidates not yet applied, by number.
    step: BTreeMap<u64, Pending>,
    /// Those waiting for a worker, lowest number first.
    waiting: BTreeSet<u64>,
    /// One past the highest candidate number drawn (the next initial draw's number).
    frontier: u64,
    /// Draw no initial candidate from this number on (a replay of stored history).
    draw_limit: u64,
    /// The next generation's candidates drawn ahead, while the open one finishes.
    ahead: Option<ahead::Ahead>,
}

impl RunState {
    /// Whether candidate `number` in the step is drawn ahead and not yet kept.
    fn is_ahead(&self, number: u64) -> bool {
        self.ahead.as_ref().is_some_and(|a| number >= a.first)
    }

    /// The first number drawn ahead (none: `u64::MAX`): the open step is below it.
    fn ahead_from(&self) -> u64 {
        self.ahead.as_ref().map_or(u64::MAX, |a| a.first)
    }

    /// The open step's candidates, without those drawn ahead.
    fn open_step(&self) -> std::collections::btree_map::Range<'_, u64, Pending> {
        self.step.range(..self.ahead_from())
    }

    /// Where candidate `number` waits for a worker: the open step's queue, or the queue
    /// of those drawn ahead.
    fn queue_of(&mut self, number: u64) -> &mut BTreeSet<u64> {
        match &mut self.ahead {
            Some(a) if number >= a.first => &mut a.waiting,
            _ => &mut self.waiting,
        }
    }
}

/// Every run of an experiment being served.
pub struct Scheduler {
    experiment: Experiment,
    ctx: EvalContext,
    runs: Vec<RunState>,
    /// Results (and lost leases) read back from the database, used when the candidate is
    /// drawn again after a restart.
    stored: HashMap<CandidateKey, StoredPending>,
    lease: Duration,
    max_attempts: u32,
    cursor: usize,
    writes: Vec<Write>,
    steps_applied: u64,
    /// False once told to stop leasing (a batch job's time limit nears).
    leasing: bool,
    /// Whether idle workers get the next generation's candidates drawn ahead.
    draw_ahead: bool,
    ahead_counts: AheadCounts,
}

impl Scheduler {
    /// Serves `runs` (as stored) with the results in `stored`.
    pub fn new(
        experiment: Experiment,
        runs: Vec<RunRecord>,
        stored: Vec<StoredPending>,
        lease: Duration,
        max_attempts: u32,
    ) -> Self {
        let ctx = EvalContext::of(&experiment);
        let mut s = Self {
            experiment,
            ctx,
            runs: runs
                .into_iter()
                .map(|record| RunState {
                    frontier: record.next_candidate,
                    draw_limit: u64::MAX,
                    record,
                    step: BTreeMap::new(),
                    waiting: BTreeSet::new(),
                    ahead: None,
                })
                .collect(),
            stored: stored
                .into_iter()
                .map(|p| {
                    let key = CandidateKey {
                        run: p.run,
                        generation: p.generation,
                        number: p.number,
                        drawn_ahead: false,
                    };
                    (key, p)
                })
                .collect(),
            lease,
            max_attempts,
            cursor: 0,
            writes: Vec::new(),
            steps_applied: 0,
            leasing: true,
            draw_ahead: false,
            ahead_counts: AheadCounts::default(),
        };
        for i in 0..s.runs.len() {
            if !s.runs[i].record.finished && !s.initial_phase(i) {
                s.open_generation(i);
            }
            s.advance(i);
        }
        s
    }

    /// The experiment.
    pub fn experiment(&self) -> &Experiment {
        &self.experiment
    }

    /// How long a lease lasts without a heartbeat.
    pub fn lease_duration(&self) -> Duration {
        self.lease
    }

    /// Whether every run is finished.
    pub fn finished(&self) -> bool {
        self.runs.iter().all(|r| r.record.finished)
    }

    /// Hands out no more candidates from now on: results of leases out still count, and a
    /// restart on the database goes on from there.
    pub fn stop_leasing(&mut self) {
        self.leasing = false;
    }

    /// Candidates leased to workers now.
    pub fn leased(&self) -> usize {
        self.runs
            .iter()
            .flat_map(|r| r.step.values())
            .filter(|p| matches!(p.state, State::Leased { .. }))
            .count()
    }

    /// Whether a lease request could get a candidate now.
    pub fn available(&self) -> bool {
        if !self.leasing {
            return false;
        }
        let window = |r: &RunState| r.frontier - r.record.next_candidate < INITIAL_WINDOW;
        self.runs.iter().enumerate().any(|(i, r)| {
            !r.record.finished
                && (!r.waiting.is_empty()
                    || (r.record.initial_passed < self.experiment.run.initial_population
                        && window(r)
                        && r.frontier < r.draw_limit)
                    || self.may_draw_ahead(i))
        })
    }

    /// Steps applied since this scheduler started (watchers wait for it to change).
    pub fn steps_applied(&self) -> u64 {
        self.steps_applied
    }

    /// The changes to store since the last call, in order.
    pub fn take_writes(&mut self) -> Vec<Write> {
        std::mem::take(&mut self.writes)
    }

    /// Leases up to `max` candidates to `worker`, taking runs in turn so that every run
    /// advances.
    pub fn lease(&mut self, worker: WorkerId, now: Instant, max: usize) -> Vec<Assignment> {
        let mut out = Vec::new();
        if !self.leasing {
            return out;
        }
        // The open steps first; then, for what room is left, the next generations'
        // candidates drawn ahead.
        for ahead in [false, true] {
            let n = self.runs.len();
            let mut idle = 0;
            while out.len() < max && idle < n {
                let i = self.cursor % n;
                self.cursor = self.cursor.wrapping_add(1);
                let taken = if ahead {
                    self.take_ahead(i, worker, now)
                } else {
                    self.take_one(i, worker, now)
                };
                match taken {
                    Some(a) => {
                        out.push(a);
                        idle = 0;
                    }
                    None => idle += 1,
                }
            }
        }
        out
    }

    fn take_one(&mut self, i: usize, worker: WorkerId, now: Instant) -> Option<Assignment> {
        if self.runs[i].record.finished {
            return None;
        }
        if self.runs[i].waiting.is_empty() && self.initial_phase(i) {
            self.draw_initial(i);
            self.advance(i);
        }
        let number = self.runs[i].waiting.pop_first()?;
        Some(self.hand_out(i, number, worker, now))
    }

    /// Leases waiting candidate `number` of run `i` to `worker`.
    fn hand_out(&mut self, i: usize, number: u64, worker: WorkerId, now: Instant) -> Assignment {
        let expires = now + self.lease;
        let r = &mut self.runs[i];
        let p = r
            .step
            .get_mut(&number)
            .expect("waiting candidates are in the step");
        p.state = State::Leased {
            worker,
            expires,
            started: false,
        };
        let key = p.key(RunId::from_index(i), number);
        Assignment {
            key,
            genome: p.genome,
            scheme: r.record.spec.scheme,
            run_seed: r.record.spec.seed,
            to_beat: p.to_beat,
        }
    }

    /// Takes a result. The caller has checked that this worker was leased the candidate
    /// and that the outcome is well formed.
    pub fn accept(
        &mut self,
        worker: WorkerId,
        key: CandidateKey,
        outcome: Outcome,
        seconds: f64,
    ) -> Result<Accepted, Refusal> {
        // A design is placed in the cell its outcome states: that must be the cell its
        // features fall in.
        if let Outcome::Valid { features, cell, .. } = &outcome {
            let expected = self.experiment.features.cell_of(features).ok();
            if expected != Some(*cell) {
                return Err(Refusal::CellMismatch {
                    stated: cell.0,
                    expected: expected.map(|c| c.0),
                });
            }
        }
        if self.answered(key) {
            return Ok(Accepted::Duplicate);
        }
        let i = key.run.index();
        let r = self.runs.get_mut(i).ok_or(Refusal::NoSuchRun(key.run))?;
        let number = key.number.0;
        let ahead = r.is_ahead(number);
        match r.step.get_mut(&number) {
            Some(p) if p.answers_to(key) => {
                if let Outcome::Valid {
                    fitness,
                    outranked: true,
                    ..
                } = outcome
                {
                    if !p.to_beat.is_some_and(|elite| fitness <= elite) {
                        return Err(Refusal::NotOutranked {
                            fitness,
                            to_beat: p.to_beat,
                        });
                    }
                }
                p.state = State::Resolved(outcome.clone());
                let write = Write::Resolved {
                    run: r.record.id,
                    number: key.number,
                    generation: p.generation,
                    attempts: p.attempts,
                    outcome,
                    worker: Some(worker),
                    seconds,
                };
                if ahead {
                    p.deferred = Some(write);
                } else {
                    self.writes.push(write);
                }
                r.queue_of(number).remove(&number);
                self.advance(i);
                Ok(Accepted::Stored)
            }
            // Every other known candidate is answered (above).
            _ => Err(Refusal::Unknown(key)),
        }
    }

    /// Draws no initial candidate of run `i` numbered `limit` or more: a replay of stored
    /// history (`verify`) stops where the history does.
    pub fn limit_draws(&mut self, run: RunId, limit: u64) {
        let i = run.index();
        if let Some(r) = self.runs.get_mut(i) {
            r.draw_limit = limit;
        }
    }

    /// Whether `key` needs no result any more: it has one, or was applied or dropped. A
    /// result for it is a duplicate, acknowledged and ignored.
    pub fn answered(&self, key: CandidateKey) -> bool {
        let Some(r) = self.runs.get(key.run.index()) else {
            return false;
        };
        let number = key.number.0;
        match r.step.get(&number) {
            Some(p) if p.answers_to(key) => matches!(p.state, State::Resolved(_)),
            // A dropped initial draw whose number a later generation reuses, or a
            // candidate drawn ahead that its generation drew otherwise.
            Some(_) => true,
            None => number < r.record.next_candidate || number < r.frontier,
        }
    }

    /// A run's record (position and library), for tests and tools.
    pub fn run(&self, run: RunId) -> Option<&RunRecord> {
        self.runs.get(run.index()).map(|r| &r.record)
    }
}
