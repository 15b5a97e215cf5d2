//! Where a run's candidates come from (docs/model.md sections 11 and 12): random genomes in candidate
//! order for the initial population, then offspring of parents drawn from the libraries
//! (uniformly from the feasible one, by tournament on closeness to the brief from the
//! infeasible one). Each candidate's draws come from its own stream, so a candidate is a pure
//! function of (run seed, candidate number, the libraries it was bred from).

use crate::qd::library::{InfeasibleLibrary, Library};
use rand::Rng;
use strider_common::initial_designs::InitialDesigns;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{Genome, MutationRates, Scheme};

/// Initial-population candidate `seed`: the experiment's initial design of that number
/// while there is one (docs/model.md section 12), else a random genome.
pub fn initial_candidate(scheme: Scheme, seed: CandidateSeed, designs: &InitialDesigns) -> Genome {
    designs
        .candidate(scheme, seed.candidate.0)
        .unwrap_or_else(|| Genome::random(scheme, &mut seed.rng(Purpose::RandomGenome)))
}

/// What parents are drawn from.
#[derive(Clone, Copy, Debug)]
pub enum Parents<'a> {
    /// The paper's method: the feasible library alone.
    Feasible(&'a Library),
    /// Feasible-infeasible search: the feasible library with probability `share` (1 while
    /// the infeasible library is empty, 0 while the feasible one is), else the infeasible.
    Both {
        /// Designs that meet the brief.
        feasible: &'a Library,
        /// Designs nearest the brief that miss it.
        infeasible: &'a InfeasibleLibrary,
        /// The feasible library's share of parents.
        share: f64,
        /// Infeasible parents are the nearest the brief of this many elites drawn
        /// uniformly (1: uniform).
        tournament: u32,
    },
}

/// Which library a parent came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// The feasible library.
    Feasible,
    /// The infeasible library.
    Infeasible,
}

impl Parents<'_> {
    /// Draws a parent: under feasible-infeasible search one uniform draw picks the library
    /// (none under the paper's method, so its runs are what they always were), then one
    /// picks a feasible elite uniformly in cell order, or a tournament picks an infeasible
    /// one: `tournament` uniform draws, the one nearest the brief kept (the first drawn on a
    /// tie). `None` when there is nothing to draw.
    pub fn draw<R: Rng>(&self, rng: &mut R) -> Option<(Source, Genome)> {
        let source = match *self {
            Parents::Feasible(_) => Source::Feasible,
            Parents::Both {
                feasible,
                infeasible,
                share,
                ..
            } => {
                let share = if infeasible.is_empty() {
                    1.0
                } else if feasible.is_empty() {
                    0.0
                } else {
                    share
                };
                if rng.random::<f64>() < share {
                    Source::Feasible
                } else {
                    Source::Infeasible
                }
            }
        };
        let genome = match (source, *self) {
            (Source::Feasible, Parents::Feasible(lib) | Parents::Both { feasible: lib, .. }) => {
                if lib.is_empty() {
                    return None;
                }
                lib.nth(rng.random_range(0..lib.len()))?.genome
            }
            (
                Source::Infeasible,
                Parents::Both {
                    infeasible,
                    tournament,
                    ..
                },
            ) => {
                if infeasible.is_empty() {
                    return None;
                }
                let mut best = infeasible.nth(rng.random_range(0..infeasible.len()))?;
                for _ in 1..tournament {
                    let other = infeasible.nth(rng.random_range(0..infeasible.len()))?;
                    if other.standing.beats(&best.standing) {
                        best = other;
                    }
                }
                best.genome
            }
            (Source::Infeasible, Parents::Feasible(_)) => return None,
        };
        Some((source, genome))
    }
}

/// The offspring of candidate `seed`: a parent drawn from `parents`, mutated. `None` when
/// the libraries are empty.
pub fn offspring(
    parents: &Parents<'_>,
    scheme: Scheme,
    rates: &MutationRates,
    seed: CandidateSeed,
) -> Option<Genome> {
    let mut rng = seed.rng(Purpose::Reproduction);
    let (_, parent) = parents.draw(&mut rng)?;
    Some(parent.offspring(scheme, rates, &mut rng))
}
