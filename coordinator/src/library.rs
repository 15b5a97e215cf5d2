//! The MAP-Elites library of one run (spec section 5): one elite per cell, a generation's
//! results applied in candidate order once all are in, and the per-generation statistics.
//! Plain data; the database stores what this computes.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use strider_common::rng::CandidateNumber;
use strider_common::{CellIndex, Genome, Outcome};

/// The best design found for one cell.
#[derive(Clone, Debug, PartialEq)]
pub struct Elite {
    /// The candidate that holds the cell.
    pub candidate: CandidateNumber,
    /// Its genome (the controller is the evaluated one under ES).
    pub genome: Genome,
    /// Its fitness, 1 / COT.
    pub fitness: f64,
}

/// What applying one result did to the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Placement {
    /// Filled an empty cell.
    New,
    /// Replaced a less fit elite.
    Improved,
    /// Valid, but its cell's elite is at least as fit.
    Discarded,
    /// Failed the brief.
    Rejected,
    /// The trial failed.
    Invalid,
}

/// Statistics of the library after a generation, and what the generation did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GenerationStats {
    /// Occupied cells / all cells.
    pub coverage: f64,
    /// Occupied cells.
    pub elites: usize,
    /// Best, mean and lowest elite fitness (0 for an empty library).
    pub max_fitness: f64,
    /// Mean elite fitness.
    pub mean_fitness: f64,
    /// Lowest elite fitness.
    pub min_fitness: f64,
    /// Sum of elite fitness.
    pub qd_score: f64,
    /// Results that filled an empty cell.
    pub new: usize,
    /// Results that replaced an elite.
    pub improved: usize,
    /// Valid results that changed nothing.
    pub discarded: usize,
    /// Results that failed the brief.
    pub rejected: usize,
    /// Results whose trial failed.
    pub invalid: usize,
}

impl GenerationStats {
    /// Counts one result's placement.
    pub fn record(&mut self, p: Placement) {
        match p {
            Placement::New => self.new += 1,
            Placement::Improved => self.improved += 1,
            Placement::Discarded => self.discarded += 1,
            Placement::Rejected => self.rejected += 1,
            Placement::Invalid => self.invalid += 1,
        }
    }
}

/// One run's library.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Library {
    cells: BTreeMap<CellIndex, Elite>,
    /// The occupied cells in order, so that drawing the i-th parent is O(log n), not O(n).
    order: Vec<CellIndex>,
}

impl Library {
    /// An empty library.
    pub fn new() -> Self {
        Self::default()
    }

    /// Occupied cells.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether no cell is occupied.
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The elite of a cell.
    pub fn get(&self, cell: CellIndex) -> Option<&Elite> {
        self.cells.get(&cell)
    }

    /// Elites in cell order (the order parents are drawn from).
    pub fn elites(&self) -> impl Iterator<Item = (CellIndex, &Elite)> {
        self.cells.iter().map(|(c, e)| (*c, e))
    }

    /// The elite at a position in cell order.
    pub fn nth(&self, i: usize) -> Option<&Elite> {
        self.order.get(i).and_then(|c| self.cells.get(c))
    }

    /// Puts an elite back into its cell (when a library is reloaded from the database).
    pub fn restore(&mut self, cell: CellIndex, elite: Elite) {
        if self.cells.insert(cell, elite).is_none() {
            self.occupy(cell);
        }
    }

    fn occupy(&mut self, cell: CellIndex) {
        let at = self.order.partition_point(|c| *c < cell);
        self.order.insert(at, cell);
    }

    /// Applies one result: a valid design fills an empty cell or replaces a strictly less
    /// fit elite.
    pub fn apply(
        &mut self,
        candidate: CandidateNumber,
        genome: &Genome,
        outcome: &Outcome,
    ) -> Placement {
        let (fitness, cell, controller) = match outcome {
            Outcome::Valid {
                fitness,
                cell,
                controller,
                ..
            } => (*fitness, *cell, *controller),
            Outcome::Rejected { .. } => return Placement::Rejected,
            Outcome::Invalid { .. } => return Placement::Invalid,
        };
        let elite = Elite {
            candidate,
            genome: Genome {
                morphology: genome.morphology,
                controller,
            },
            fitness,
        };
        match self.cells.get_mut(&cell) {
            None => {
                self.cells.insert(cell, elite);
                self.occupy(cell);
                Placement::New
            }
            Some(old) if fitness > old.fitness => {
                *old = elite;
                Placement::Improved
            }
            Some(_) => Placement::Discarded,
        }
    }

    /// Applies a whole generation in candidate order and returns its statistics. The caller
    /// passes results sorted by candidate number, so the outcome never depends on which
    /// worker finished first.
    pub fn apply_generation<'a>(
        &mut self,
        results: impl IntoIterator<Item = (CandidateNumber, &'a Genome, &'a Outcome)>,
        cell_count: u32,
    ) -> GenerationStats {
        let mut stats = GenerationStats::default();
        let mut last = None;
        for (candidate, genome, outcome) in results {
            assert!(
                last < Some(candidate),
                "results must come in increasing candidate order"
            );
            last = Some(candidate);
            stats.record(self.apply(candidate, genome, outcome));
        }
        self.summary(stats, cell_count)
    }

    /// `counts` completed with the library's coverage and fitness figures.
    pub fn summary(&self, counts: GenerationStats, cell_count: u32) -> GenerationStats {
        let mut stats = counts;
        stats.elites = self.cells.len();
        stats.coverage = self.cells.len() as f64 / f64::from(cell_count);
        if self.cells.is_empty() {
            return stats;
        }
        // Sum in cell order so the figure is reproducible to the bit; one pass, since this
        // runs for every generation of every run while the scheduler is locked.
        let (mut sum, mut max, mut min) = (0.0, f64::NEG_INFINITY, f64::INFINITY);
        for e in self.cells.values() {
            sum += e.fitness;
            max = f64::max(max, e.fitness);
            min = f64::min(min, e.fitness);
        }
        stats.qd_score = sum;
        stats.max_fitness = max;
        stats.min_fitness = min;
        stats.mean_fitness = stats.qd_score / self.cells.len() as f64;
        stats
    }
}
