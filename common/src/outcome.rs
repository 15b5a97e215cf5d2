//! What evaluating a candidate yields: valid with fitness and features, rejected by the
//! brief, or invalid, each with its reason.

use crate::brief::Violation;
use crate::features::{CellIndex, Features};
use crate::genome::Controller;
use serde::{Deserialize, Serialize};

/// Figures of one completed trial.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrialStats {
    /// Forward (x) displacement of the robot's centre of mass, m.
    pub distance: f64,
    /// Mechanical energy spent: integral of the sum over joints of |omega * tau|, J.
    pub energy: f64,
    /// Average forward speed, m/s.
    pub speed: f64,
    /// Total mass with payload, kg.
    pub mass: f64,
    /// Cost of transport E / (m g d).
    pub cost_of_transport: f64,
    /// Simulated time, s.
    pub duration: f64,
}

/// Why a trial was stopped and its candidate declared invalid.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum InvalidReason {
    /// Two robot parts that are not joined by a hinge touched.
    SelfContact {
        /// Names of the two parts, e.g. "right leg 0 link 2".
        first: String,
        /// The other part.
        second: String,
    },
    /// A position, velocity, torque or the energy became NaN or infinite.
    NonFinite {
        /// What it was.
        what: String,
    },
    /// Something moved impossibly fast: the simulation blew up.
    BlowUp {
        /// The offending speed, m/s or rad/s.
        speed: f64,
    },
    /// The robot did not move forward (d <= 0), so its cost of transport is undefined.
    NoForwardProgress {
        /// Its distance, m.
        distance: f64,
    },
    /// No result came back: the workers evaluating it died or hung `attempts` times, so the
    /// coordinator gave up on it (its generation goes on without it).
    EvaluationFailed {
        /// Leases lost.
        attempts: u32,
        /// How the last one was lost.
        last: String,
    },
}

impl std::fmt::Display for InvalidReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InvalidReason::SelfContact { first, second } => {
                write!(f, "self-contact between {first} and {second}")
            }
            InvalidReason::NonFinite { what } => write!(f, "non-finite {what}"),
            InvalidReason::BlowUp { speed } => write!(f, "simulation blew up (speed {speed:.1})"),
            InvalidReason::NoForwardProgress { distance } => {
                write!(f, "no forward progress (distance {distance:.3} m)")
            }
            InvalidReason::EvaluationFailed { attempts, last } => {
                write!(f, "evaluation failed {attempts} times (last: {last})")
            }
        }
    }
}

/// The result of evaluating one candidate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum Outcome {
    /// Passed the brief: may enter the library.
    Valid {
        /// 1 / cost of transport.
        fitness: f64,
        /// The trial's figures.
        stats: TrialStats,
        /// Features d1..d6.
        features: Features,
        /// The library cell.
        cell: CellIndex,
        /// The controller that achieved it (the ES result under ES).
        controller: Controller,
    },
    /// Failed one or more constraints of the brief.
    Rejected {
        /// Every failed constraint.
        violations: Vec<Violation>,
        /// The trial's figures, when a trial was run (the speed check needs one).
        stats: Option<TrialStats>,
        /// The controller evaluated last.
        controller: Controller,
    },
    /// The trial failed.
    Invalid {
        /// Why.
        reason: InvalidReason,
        /// Simulated time when it was stopped, s.
        at_time: f64,
        /// The controller evaluated.
        controller: Controller,
    },
}

impl Outcome {
    /// The fitness of a valid outcome.
    pub fn fitness(&self) -> Option<f64> {
        match self {
            Outcome::Valid { fitness, .. } => Some(*fitness),
            _ => None,
        }
    }

    /// The controller this outcome was obtained with.
    pub fn controller(&self) -> &Controller {
        match self {
            Outcome::Valid { controller, .. }
            | Outcome::Rejected { controller, .. }
            | Outcome::Invalid { controller, .. } => controller,
        }
    }

    /// The trial figures, if a trial completed.
    pub fn stats(&self) -> Option<&TrialStats> {
        match self {
            Outcome::Valid { stats, .. } => Some(stats),
            Outcome::Rejected { stats, .. } => stats.as_ref(),
            Outcome::Invalid { .. } => None,
        }
    }

    /// A short word for tables and logs.
    pub fn kind(&self) -> &'static str {
        match self {
            Outcome::Valid { .. } => "valid",
            Outcome::Rejected { .. } => "rejected",
            Outcome::Invalid { .. } => "invalid",
        }
    }
}
