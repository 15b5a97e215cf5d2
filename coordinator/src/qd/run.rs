//! One run's state: its spec, where it stands, and its two libraries. What the scheduler
//! keeps per run and the database stores in the `runs` table.

use crate::qd::library::{GenerationStats, InfeasibleLibrary, Library};
use strider_common::experiment::RunSpec;
use strider_common::RunId;

/// One run's persistent state.
#[derive(Clone, Debug)]
pub struct RunRecord {
    /// Row id (0-based, in experiment order).
    pub id: RunId,
    /// Scheme, repeat and seed.
    pub spec: RunSpec,
    /// Last committed generation (0: the initial population, complete or not).
    pub generation: u32,
    /// Candidates of the initial population that count toward its size so far.
    pub initial_passed: u32,
    /// First candidate number not yet committed.
    pub next_candidate: u64,
    /// Whether the run has done all its generations.
    pub finished: bool,
    pub library: Library,
    /// Its infeasible library (empty under the paper's method).
    pub infeasible: InfeasibleLibrary,
}

/// Where a run stands (the `runs` row).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunPosition {
    /// Last completed generation.
    pub generation: u32,
    /// Valid candidates in the initial population so far.
    pub initial_passed: u32,
    /// First candidate number not yet applied.
    pub next_candidate: u64,
    /// Whether the run has done all its generations.
    pub finished: bool,
}

impl RunRecord {
    /// A run that has not begun: no candidate, empty libraries.
    pub fn new(id: RunId, spec: RunSpec) -> Self {
        Self {
            id,
            spec,
            generation: 0,
            initial_passed: 0,
            next_candidate: 0,
            finished: false,
            library: Library::new(),
            infeasible: InfeasibleLibrary::default(),
        }
    }

    /// `counts` completed with both libraries' figures.
    pub fn summary(&self, counts: GenerationStats, cell_count: u32) -> GenerationStats {
        self.infeasible
            .summary(self.library.summary(counts, cell_count), &self.library)
    }

    /// Its position.
    pub fn position(&self) -> RunPosition {
        RunPosition {
            generation: self.generation,
            initial_passed: self.initial_passed,
            next_candidate: self.next_candidate,
            finished: self.finished,
        }
    }
}
