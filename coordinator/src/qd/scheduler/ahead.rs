//! Drawing the next generation ahead. While a generation's last trials run, a worker with
//! a core free takes candidates of the next generation bred from a guess at the library
//! that generation will be bred from: the run's library with the open generation's
//! results so far applied in candidate order. When the generation opens it draws its
//! candidates as it always has; a candidate drawn ahead is kept, with its lease or its
//! result, only when it is the very same candidate (number, genome bit for bit, and the bar
//! to enter its cell), whose trial is then exactly the one the generation's own draw asks
//! for. So runs stay the same bits whatever the workers; what a wrong guess costs is the
//! trials it dropped, run on cores that would have waited. A late result for a dropped one
//! is ignored: its key says it was drawn ahead. Part of the scheduler (the methods below
//! extend [`Scheduler`]).

use super::steps::place;
use super::*;

/// A run's candidates drawn ahead.
pub(super) struct Ahead {
    /// The first number drawn ahead: the open step's numbers are below it.
    pub(super) first: u64,
    /// Those not leased, lowest number first.
    pub(super) waiting: BTreeSet<u64>,
    /// Those ever leased: never drawn again, as a worker may still answer for what it was
    /// given (a lease that expired goes back to `waiting` as it was).
    handed: BTreeSet<u64>,
    /// How many of the open step's candidates were resolved when those waiting were drawn.
    basis: usize,
}

/// What drawing ahead did, since the scheduler started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AheadCounts {
    /// Candidates drawn ahead that went to a worker.
    pub leased: u64,
    /// Of those, the ones their generation drew as they were: their leases and results
    /// kept.
    pub kept: u64,
    /// The ones their generation drew otherwise: their trials wasted.
    pub dropped: u64,
    /// Of the dropped, those drawn the same bit for bit but leased with another bar (their
    /// cell's elite changed in between), which a trial ends differently against.
    pub dropped_for_bar: u64,
}

impl std::fmt::Display for AheadCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} leased, {} kept with their trials, {} dropped (their generation drew \
             otherwise; {} of them the same design against another bar)",
            self.leased, self.kept, self.dropped, self.dropped_for_bar
        )
    }
}

impl Scheduler {
    /// Whether workers with room left get the next generation's candidates drawn ahead
    /// (off at first: a replay of stored history answers only what is stored).
    pub fn draw_ahead(&mut self, on: bool) {
        self.draw_ahead = on;
    }

    /// What drawing ahead did so far.
    pub fn ahead_counts(&self) -> AheadCounts {
        self.ahead_counts
    }

    /// Whether run `i` may lease a candidate drawn ahead: its open generation has nothing
    /// waiting, a generation follows it, and not every candidate of that one is out.
    pub(super) fn may_draw_ahead(&self, i: usize) -> bool {
        let r = &self.runs[i];
        self.draw_ahead
            && !r.record.finished
            && !self.initial_phase(i)
            && r.waiting.is_empty()
            && r.record.generation + 2 <= self.experiment.run.generations
            && r.ahead.as_ref().is_none_or(|a| !a.waiting.is_empty())
    }

    /// Leases run `i`'s next candidate drawn ahead; those waiting are drawn again first
    /// when the open generation has more results than their draw saw.
    pub(super) fn take_ahead(
        &mut self,
        i: usize,
        worker: WorkerId,
        now: Instant,
    ) -> Option<Assignment> {
        if !self.may_draw_ahead(i) {
            return None;
        }
        let r = &self.runs[i];
        let resolved = r
            .open_step()
            .filter(|(_, p)| matches!(p.state, State::Resolved(_)))
            .count();
        if r.ahead.as_ref().is_none_or(|a| a.basis < resolved) {
            self.redraw_ahead(i, resolved);
        }
        let ahead = self.runs[i].ahead.as_mut()?;
        let number = ahead.waiting.pop_first()?;
        ahead.handed.insert(number);
        self.ahead_counts.leased += 1;
        Some(self.hand_out(i, number, worker, now))
    }

    /// Draws run `i`'s next generation ahead, or again those of its candidates no worker
    /// has (never leased), from the run's record with the open generation's `resolved`
    /// results applied.
    fn redraw_ahead(&mut self, i: usize, resolved: usize) {
        let count = u64::from(self.experiment.run.offspring_per_generation);
        let mode = self.experiment.search.constraints;
        let r = &self.runs[i];
        let (scheme, generation) = (r.record.spec.scheme, r.record.generation + 2);
        let first = r.record.next_candidate + count;
        let mut guess = r.record.clone();
        for (n, p) in r.open_step() {
            if let State::Resolved(outcome) = &p.state {
                place(&self.ctx, mode, &mut guess, *n, &p.genome, outcome);
            }
        }
        let numbers: Vec<u64> = match &r.ahead {
            None => (first..first + count).collect(),
            Some(a) => a.waiting.difference(&a.handed).copied().collect(),
        };
        let genomes = self.breed(i, &guess, numbers.iter().copied());
        let mut drawn = Vec::with_capacity(numbers.len());
        for (number, genome) in numbers.into_iter().zip(genomes) {
            // One settled without a trial needs no worker: its generation settles it.
            let needs_trial = precheck(&self.ctx, &genome, scheme).is_none();
            let to_beat = self.to_beat(&guess.library, scheme, generation, &genome);
            drawn.push((number, needs_trial, genome, to_beat));
        }
        let r = &mut self.runs[i];
        let ahead = r.ahead.get_or_insert_with(|| Ahead {
            first,
            waiting: BTreeSet::new(),
            handed: BTreeSet::new(),
            basis: 0,
        });
        ahead.basis = resolved;
        for (number, needs_trial, genome, to_beat) in drawn {
            ahead.waiting.remove(&number);
            r.step.remove(&number);
            if needs_trial {
                ahead.waiting.insert(number);
                r.step.insert(
                    number,
                    Pending::new(generation, genome, to_beat, 0, State::Waiting, true),
                );
            }
        }
    }

    /// Keeps run `i`'s candidate `number` drawn ahead, when a worker has it or answered it
    /// and it is the candidate `generation` draws (`genome`, bit for bit, with the same
    /// bar); returns whether it did. Either way the drawn-ahead entry is gone from the step.
    pub(super) fn keep_drawn_ahead(
        &mut self,
        i: usize,
        number: u64,
        generation: u32,
        genome: &Genome,
    ) -> bool {
        let r = &self.runs[i];
        let Some(p) = r.step.get(&number) else {
            return false;
        };
        debug_assert!(
            p.drawn_ahead,
            "the step holds only candidates drawn ahead here"
        );
        let worked = matches!(p.state, State::Leased { .. }) || p.deferred.is_some();
        let to_beat = self.to_beat(&r.record.library, r.record.spec.scheme, generation, genome);
        let key = CandidateKey {
            run: r.record.id,
            generation,
            number: CandidateNumber(number),
            drawn_ahead: false,
        };
        let same_design = p.generation == generation
            && same_bits(&p.genome, genome)
            // A result stored for the generation's own draw wins (none is, in practice:
            // nothing drawn ahead is stored until kept).
            && !self.stored.contains_key(&key);
        let same_bar = p.to_beat.map(f64::to_bits) == to_beat.map(f64::to_bits);
        let r = &mut self.runs[i];
        let mut p = r.step.remove(&number).expect("looked up above");
        if !worked {
            return false;
        }
        if !(same_design && same_bar) {
            self.ahead_counts.dropped += 1;
            self.ahead_counts.dropped_for_bar += u64::from(same_design);
            return false;
        }
        self.ahead_counts.kept += 1;
        if let Some(write) = p.deferred.take() {
            self.writes.push(write);
        }
        r.step.insert(number, p);
        true
    }
}

/// Whether two genomes are the same bit for bit (`==` takes 0.0 for -0.0).
fn same_bits(a: &Genome, b: &Genome) -> bool {
    use strider_common::genome::ParamVector;
    let bits = |g: &Genome| {
        g.morphology
            .values()
            .iter()
            .chain(g.controller.values())
            .map(|v| v.to_bits())
            .collect::<Vec<u64>>()
    };
    bits(a) == bits(b)
}
