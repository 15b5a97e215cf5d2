//! What the scheduler hands to storage and takes back on a restart: the changes it emits
//! (results, lost leases, applied steps, worker sessions) and the pending candidates of
//! an open step (a run's own state is `qd::run`). Plain data; the scheduler and the database both
//! depend on it, neither on the other.

use crate::qd::library::{CellChange, Elite, GenerationStats, InfeasibleElite, Placement};
use crate::qd::run::RunPosition;
use strider_common::ids::CandidateNumber;
use strider_common::{CellIndex, Genome, Outcome, RunId, WorkerId};

/// One evaluated candidate applied to its run's library, ready to store.
#[derive(Clone, Debug)]
pub struct AppliedCandidate {
    pub number: CandidateNumber,
    /// Its generation (0 = initial population).
    pub generation: u32,
    pub genome: Genome,
    pub outcome: Outcome,
    /// What it did to the feasible library.
    pub placement: Placement,
    /// What it did to the infeasible library, if it was offered there.
    pub infeasible: Option<CellChange>,
}

/// A step of a run applied to its library: stored in the same transaction as everything
/// written before it, so the database never holds half a generation.
#[derive(Clone, Debug)]
pub struct StepCommit {
    pub run: RunId,
    /// The run's position after the step.
    pub position: RunPosition,
    /// The candidates applied, in order.
    pub candidates: Vec<AppliedCandidate>,
    /// The cells the step changed, with their new elites.
    pub elites: Vec<(CellIndex, Elite)>,
    /// The infeasible library's cells the step changed, with their new elites.
    pub infeasible: Vec<(CellIndex, InfeasibleElite)>,
    /// The generation the step completed, with its statistics (for the initial population
    /// the placement counts are filled in from all its stored candidates).
    pub completed: Option<(u32, GenerationStats)>,
}

impl StepCommit {
    /// Whether the initial population is complete after this step.
    pub fn initial_population_done(&self) -> bool {
        self.position.generation > 0 || matches!(self.completed, Some((0, _)))
    }

    /// Whether this step removes a candidate's row from `pending`: applied candidates
    /// leave the step, and so do the initial population's spare draws once it is complete.
    pub fn clears(&self, number: CandidateNumber, generation: u32) -> bool {
        number.0 < self.position.next_candidate
            || (generation == 0 && self.initial_population_done())
    }
}

/// One change to the database. The writer task commits them in order, in groups.
///
/// Only what a restart needs is written while a step is open: results, and leases lost to
/// dead or silent workers (so attempts survive a restart). Waiting and leased candidates
/// live in memory: they are redrawn or rebred, identically, after a restart.
// Writes live for milliseconds on their way to the writer; boxing genomes would cost an
// allocation each for nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Write {
    /// A candidate's result came in (or it failed for good).
    Resolved {
        run: RunId,
        number: CandidateNumber,
        generation: u32,
        /// Leases it lost before.
        attempts: u32,
        outcome: Outcome,
        /// Worker session that sent it (none when it failed).
        worker: Option<WorkerId>,
        /// Wall time the evaluation took.
        seconds: f64,
    },
    /// A lease was lost (worker died, hung or disconnected); the candidate waits again.
    LeaseLost {
        run: RunId,
        number: CandidateNumber,
        generation: u32,
        /// Leases it has lost so far.
        attempts: u32,
        /// The worker session that lost it.
        worker: WorkerId,
    },
    /// A step was applied to the library.
    Step(Box<StepCommit>),
    /// A worker connected.
    WorkerJoined {
        id: WorkerId,
        name: String,
        build: String,
        /// Candidates it holds at once.
        slots: u32,
    },
    /// A worker disconnected.
    WorkerLeft {
        id: WorkerId,
        /// Results it sent.
        results: u64,
        /// Why it left.
        reason: String,
    },
}

/// A candidate of a run's current step as stored: its result if one came in.
#[derive(Clone, Debug, PartialEq)]
pub struct StoredPending {
    pub run: RunId,
    pub number: CandidateNumber,
    pub generation: u32,
    /// Leases lost so far.
    pub attempts: u32,
    /// Its outcome, once done (or failed).
    pub outcome: Option<Outcome>,
}

/// An applied candidate as stored (the `candidates` table).
#[derive(Clone, Debug, PartialEq)]
pub struct StoredCandidate {
    pub run: RunId,
    pub number: CandidateNumber,
    pub generation: u32,
    pub genome: Genome,
    pub outcome: Outcome,
    /// The columns that repeat the outcome for queries: `kind`, `fitness`, `cell`.
    pub columns: (String, Option<f64>, Option<i64>),
}

impl StoredCandidate {
    /// Whether the columns that repeat the outcome say what the outcome says.
    pub fn columns_agree(&self) -> bool {
        let cell = match &self.outcome {
            Outcome::Valid { cell, .. } => Some(i64::from(cell.0)),
            _ => None,
        };
        self.columns.0 == self.outcome.kind()
            && self.columns.1.map(f64::to_bits) == self.outcome.fitness().map(f64::to_bits)
            && self.columns.2 == cell
    }
}
