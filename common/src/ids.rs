//! The identities the coordinator, the workers and the database share: a run, a
//! candidate of a run, a worker connection. Each is its own type, so a run's id cannot be
//! passed where a candidate number or a worker id is meant; the database's integer types
//! stay in the database.

use serde::{Deserialize, Serialize};

/// A run of an experiment: its index in the experiment's run order, from 0 (the same
/// number is its row id in the database and its `run` on the wire).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct RunId(pub u32);

impl RunId {
    /// Its position in the experiment's list of runs.
    pub fn index(self) -> usize {
        self.0 as usize
    }

    /// The run at `index` of the experiment's list.
    pub fn from_index(index: usize) -> Self {
        Self(u32::try_from(index).expect("fewer than 2^32 runs"))
    }
}

impl std::str::FromStr for RunId {
    type Err = String;

    /// A run as a user writes it: its number, from 0.
    fn from_str(s: &str) -> Result<Self, String> {
        s.trim()
            .parse()
            .map(RunId)
            .map_err(|_| format!("`{s}` is not a run number (0, 1, 2, ...)"))
    }
}

impl std::fmt::Display for RunId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// A candidate's number within its run (0-based, in creation order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct CandidateNumber(pub u64);

/// A candidate of a run: run index, generation and candidate number. The generation is
/// part of the identity because a draw of the initial population that turned out not to
/// be needed shares its number with a candidate of generation 1: a late result for the
/// draw must never be taken for the offspring. For the same reason a candidate drawn ahead
/// of its generation (before the generation before it was complete) is told apart from the
/// one drawn when the generation opens: they share a number and a generation, but not
/// always a parent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CandidateKey {
    /// Its run.
    pub run: RunId,
    /// Generation (0 = initial population).
    pub generation: u32,
    /// Candidate number within the run.
    pub number: CandidateNumber,
    /// Drawn ahead of its generation, from a guess at the library its generation is bred
    /// from; kept only if the generation, once open, draws the very same candidate.
    pub drawn_ahead: bool,
}

impl std::fmt::Display for CandidateKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "run {} generation {} candidate {}{}",
            self.run,
            self.generation,
            self.number.0,
            if self.drawn_ahead {
                " (drawn ahead)"
            } else {
                ""
            }
        )
    }
}

/// One candidate of an experiment: its run and its number there (the database's key of
/// a candidate; [`CandidateKey`] adds the generation, which a lease needs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CandidateId {
    /// Its run.
    pub run: RunId,
    /// Its number in the run.
    pub number: CandidateNumber,
}

impl From<CandidateKey> for CandidateId {
    fn from(k: CandidateKey) -> Self {
        Self {
            run: k.run,
            number: k.number,
        }
    }
}

/// A worker connection (a session of a worker process; ids are never reused).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct WorkerId(pub u64);

impl std::fmt::Display for WorkerId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}
