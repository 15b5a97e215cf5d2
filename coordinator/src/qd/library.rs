//! The MAP-Elites libraries of one run (docs/model.md sections 10 and 11): the feasible library (one
//! elite per cell, ranked by fitness) and, under feasible-infeasible search, the infeasible
//! library over the same cells (ranked by closeness to the brief, [`Standing`]); a
//! generation's results applied in candidate order once all are in, and the per-generation
//! statistics. Plain data; the database stores what this computes.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use strider_common::ids::CandidateNumber;
use strider_common::{CellIndex, Genome, Outcome, Shortfall, Standing};

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

/// The best infeasible design found for one cell: simulated, short of the brief.
#[derive(Clone, Debug, PartialEq)]
pub struct InfeasibleElite {
    /// The candidate that holds the cell.
    pub candidate: CandidateNumber,
    /// Its genome (with the controller it was evaluated with).
    pub genome: Genome,
    /// How near the brief it came.
    pub standing: Standing,
    /// What keeps it from the brief.
    pub shortfall: Shortfall,
}

/// What offering a design to an archive did to its cell: what an infeasible result did to
/// the infeasible library, and the feasible library's part of a [`Placement`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CellChange {
    /// Filled an empty cell.
    New,
    /// Replaced an elite further from the brief.
    Improved,
    /// Its cell's elite is at least as near the brief.
    Discarded,
}

impl CellChange {
    /// Its name in the database.
    pub fn name(self) -> &'static str {
        match self {
            CellChange::New => "new",
            CellChange::Improved => "improved",
            CellChange::Discarded => "discarded",
        }
    }

    /// The placement called `name`.
    pub fn named(name: &str) -> Option<Self> {
        [CellChange::New, CellChange::Improved, CellChange::Discarded]
            .into_iter()
            .find(|p| p.name() == name)
    }
}

/// What applying one result did to the feasible library.
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

impl Placement {
    /// Every placement.
    pub const ALL: [Placement; 5] = [
        Placement::New,
        Placement::Improved,
        Placement::Discarded,
        Placement::Rejected,
        Placement::Invalid,
    ];

    /// Its name in the database.
    pub fn name(self) -> &'static str {
        match self {
            Placement::New => "new",
            Placement::Improved => "improved",
            Placement::Discarded => "discarded",
            Placement::Rejected => "rejected",
            Placement::Invalid => "invalid",
        }
    }

    /// The placement called `name`; `None` for any other text.
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|p| p.name() == name)
    }
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
    /// Cells holding an infeasible elite (feasible-infeasible search).
    #[serde(default)]
    pub infeasible_elites: usize,
    /// Cells holding an infeasible elite and no feasible one: where the brief binds.
    #[serde(default)]
    pub infeasible_only: usize,
    /// Results that filled an empty cell of the infeasible library.
    #[serde(default)]
    pub infeasible_new: usize,
    /// Results that replaced an infeasible elite.
    #[serde(default)]
    pub infeasible_improved: usize,
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

    /// Counts one result's change to the infeasible library.
    pub fn record_infeasible(&mut self, p: Option<CellChange>) {
        match p {
            Some(CellChange::New) => self.infeasible_new += 1,
            Some(CellChange::Improved) => self.infeasible_improved += 1,
            Some(CellChange::Discarded) | None => {}
        }
    }
}

/// One elite per occupied cell, with the occupied cells in order so that drawing the i-th
/// parent is O(log n), not O(n). Both libraries are archives: [`Library`] of designs that
/// meet the brief, [`InfeasibleLibrary`] of designs nearest it.
#[derive(Clone, Debug, PartialEq)]
pub struct Archive<E> {
    map: BTreeMap<CellIndex, E>,
    order: Vec<CellIndex>,
}

impl<E> Default for Archive<E> {
    fn default() -> Self {
        Self {
            map: BTreeMap::new(),
            order: Vec::new(),
        }
    }
}

impl<E> Archive<E> {
    /// An empty archive.
    pub fn new() -> Self {
        Self::default()
    }

    /// Occupied cells.
    pub fn len(&self) -> usize {
        self.map.len()
    }

    /// Whether no cell is occupied.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    /// The elite of a cell.
    pub fn get(&self, cell: CellIndex) -> Option<&E> {
        self.map.get(&cell)
    }

    /// Elites in cell order (the order parents are drawn from).
    pub fn elites(&self) -> impl Iterator<Item = (CellIndex, &E)> {
        self.map.iter().map(|(c, e)| (*c, e))
    }

    /// The elite at a position in cell order.
    pub fn nth(&self, i: usize) -> Option<&E> {
        self.order.get(i).and_then(|c| self.map.get(c))
    }

    /// Puts an elite into its cell, replacing its holder (when an archive is reloaded from
    /// the database).
    pub fn restore(&mut self, cell: CellIndex, e: E) {
        if self.map.insert(cell, e).is_none() {
            let at = self.order.partition_point(|c| *c < cell);
            self.order.insert(at, cell);
        }
    }

    /// Offers `e` to `cell`: it fills an empty cell or replaces a holder `beats` says it
    /// beats strictly.
    fn offer(&mut self, cell: CellIndex, e: E, beats: impl Fn(&E, &E) -> bool) -> CellChange {
        match self.map.get_mut(&cell) {
            None => {
                self.restore(cell, e);
                CellChange::New
            }
            Some(old) if beats(&e, old) => {
                *old = e;
                CellChange::Improved
            }
            Some(_) => CellChange::Discarded,
        }
    }
}

/// One run's feasible library: the designs that meet the whole brief, by fitness.
pub type Library = Archive<Elite>;

/// One run's infeasible library: per cell, the simulated design nearest the brief among
/// those that miss it (feasible-infeasible search).
pub type InfeasibleLibrary = Archive<InfeasibleElite>;

impl Library {
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
        match self.offer(cell, elite, |new, old| new.fitness > old.fitness) {
            CellChange::New => Placement::New,
            CellChange::Improved => Placement::Improved,
            CellChange::Discarded => Placement::Discarded,
        }
    }

    /// `counts` completed with the library's coverage and fitness figures.
    pub fn summary(&self, counts: GenerationStats, cell_count: u32) -> GenerationStats {
        let mut stats = counts;
        stats.elites = self.len();
        stats.coverage = self.len() as f64 / f64::from(cell_count);
        if self.is_empty() {
            return stats;
        }
        // Sum in cell order so the figure is reproducible to the bit; one pass, since this
        // runs for every generation of every run while the scheduler is locked.
        let (mut sum, mut max, mut min) = (0.0, f64::NEG_INFINITY, f64::INFINITY);
        for e in self.map.values() {
            sum += e.fitness;
            max = f64::max(max, e.fitness);
            min = f64::min(min, e.fitness);
        }
        stats.qd_score = sum;
        stats.max_fitness = max;
        stats.min_fitness = min;
        stats.mean_fitness = stats.qd_score / self.len() as f64;
        stats
    }
}

impl InfeasibleLibrary {
    /// Offers a simulated design that missed the brief, placed in `cell` (its features'
    /// cell): it fills an empty cell or replaces an elite it ranks strictly above. `None`
    /// for an outcome that is valid or was not simulated (those are not placed here).
    pub fn apply(
        &mut self,
        candidate: CandidateNumber,
        genome: &Genome,
        outcome: &Outcome,
        cell: CellIndex,
    ) -> Option<CellChange> {
        let shortfall = outcome.shortfall()?;
        let elite = InfeasibleElite {
            candidate,
            genome: Genome {
                morphology: genome.morphology,
                controller: *outcome.controller(),
            },
            standing: outcome.standing(),
            shortfall,
        };
        Some(self.offer(cell, elite, |new, old| new.standing.beats(&old.standing)))
    }

    /// `stats` completed with the infeasible library's counts, beside `feasible`.
    pub fn summary(&self, mut stats: GenerationStats, feasible: &Library) -> GenerationStats {
        stats.infeasible_elites = self.len();
        stats.infeasible_only = self
            .map
            .keys()
            .filter(|c| feasible.get(**c).is_none())
            .count();
        stats
    }
}
