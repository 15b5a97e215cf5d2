//! Where a run's candidates come from (spec sections 4 and 5): random genomes in candidate
//! order for the initial population, then offspring of parents drawn uniformly from the
//! library. Each candidate's draws come from its own stream, so a candidate is a pure
//! function of (run seed, candidate number, the library it was bred from).

use crate::library::Library;
use rand::Rng;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{Genome, MutationRates, Scheme};

/// The random genome of candidate `seed` (initial population).
pub fn initial_candidate(scheme: Scheme, seed: CandidateSeed) -> Genome {
    Genome::random(scheme, &mut seed.rng(Purpose::RandomGenome))
}

/// The offspring of candidate `seed`: a parent drawn uniformly from the library (in cell
/// order), mutated. `None` when the library is empty.
pub fn offspring(
    library: &Library,
    scheme: Scheme,
    rates: &MutationRates,
    seed: CandidateSeed,
) -> Option<Genome> {
    if library.is_empty() {
        return None;
    }
    let mut rng = seed.rng(Purpose::Reproduction);
    let parent = library.nth(rng.random_range(0..library.len()))?;
    Some(parent.genome.offspring(scheme, rates, &mut rng))
}
