//! Explicitly seeded, portable random streams.
//!
//! Every random draw in Strider comes from a ChaCha8 stream keyed by the run seed and a
//! purpose, with the candidate number as ChaCha's stream id. ChaCha8's output is fixed by
//! its specification (the same on every platform and rand_chacha release line), so any
//! candidate can be regenerated from `(run seed, candidate number)` alone, and no two
//! candidates or purposes share a stream.

use crate::ids::CandidateNumber;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The generator every part of Strider uses.
pub type StriderRng = ChaCha8Rng;

/// A run's seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct RunSeed(pub u64);

/// Everything that decides a candidate's random draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct CandidateSeed {
    /// The run's seed.
    pub run: RunSeed,
    /// The candidate's number in the run.
    pub candidate: CandidateNumber,
}

/// What a stream is used for; separate purposes never share draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Purpose {
    /// Drawing a random genome (the initial population).
    RandomGenome = 1,
    /// Choosing a parent and mutating it (offspring).
    Reproduction = 2,
    /// The 1+1 evolution strategy that tunes a candidate's controller.
    EvolutionStrategy = 3,
}

impl CandidateSeed {
    /// A candidate's seed.
    pub fn new(run: u64, candidate: u64) -> Self {
        Self {
            run: RunSeed(run),
            candidate: CandidateNumber(candidate),
        }
    }

    /// The stream for one purpose of this candidate.
    pub fn rng(self, purpose: Purpose) -> StriderRng {
        let mut key = [0u8; 32];
        key[..8].copy_from_slice(&self.run.0.to_le_bytes());
        key[8..16].copy_from_slice(&(purpose as u64).to_le_bytes());
        key[16..24].copy_from_slice(b"strider1");
        let mut rng = ChaCha8Rng::from_seed(key);
        rng.set_stream(self.candidate.0);
        rng
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngCore;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a = CandidateSeed::new(7, 3)
            .rng(Purpose::RandomGenome)
            .next_u64();
        let b = CandidateSeed::new(7, 3)
            .rng(Purpose::RandomGenome)
            .next_u64();
        assert_eq!(a, b);
        let others = [
            CandidateSeed::new(7, 4)
                .rng(Purpose::RandomGenome)
                .next_u64(),
            CandidateSeed::new(8, 3)
                .rng(Purpose::RandomGenome)
                .next_u64(),
            CandidateSeed::new(7, 3)
                .rng(Purpose::Reproduction)
                .next_u64(),
        ];
        assert!(others.iter().all(|&o| o != a));
    }

    #[test]
    fn stream_is_pinned() {
        // ChaCha8 is specified; this value must never change, or stored runs stop
        // being reproducible. Update only with a migration note.
        let v = CandidateSeed::new(1, 0)
            .rng(Purpose::RandomGenome)
            .next_u64();
        assert_eq!(v, PINNED);
    }
    const PINNED: u64 = 2_936_920_827_774_487_144;
}
