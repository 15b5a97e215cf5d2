//! What evaluating a candidate yields: valid with fitness and features, rejected by the
//! brief, or invalid, each with its reason.

use crate::brief::Violation;
use crate::features::{CellIndex, Features};
use crate::genome::Controller;
use serde::{Deserialize, Serialize};

/// Figures of one completed trial.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
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
    /// How the gait steps (0 for outcomes stored before it was measured).
    #[serde(default)]
    pub gait: GaitStats,
}

/// How a completed trial's feet and motors did, over the trial (docs/model.md section 6).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GaitStats {
    /// The largest torque any joint received on any physics step, as a multiple of its
    /// motor's limit (1 at most, to rounding, but for a joint within its limit whose speed
    /// changed much within a step).
    pub peak_torque_ratio: f64,
    /// Ground distance a foot slid while on the ground, mean over the feet, m.
    pub foot_slip: f64,
    /// Share of the feet's forward travel made within the ground clearance (a foot that
    /// skates forward instead of stepping).
    pub low_forward_share: f64,
    /// Share of the trial a foot is on the ground, mean over the feet.
    pub duty_factor: f64,
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
    /// The robot fell: it tilted too far, sank too low, or rested on a part other than a
    /// lower leg (limits: the experiment's `[trial]` table).
    Fell {
        /// What happened.
        fall: Fall,
    },
    /// The feet skated instead of stepping (checked over the trial once it ran to the end;
    /// limits: the experiment's `[trial]` table).
    Skating {
        /// How.
        skate: Skate,
    },
    /// Parts touch already in the start pose (a check before simulating, like mass and
    /// height): two parts not joined by a hinge, or a part other than a lower leg and the
    /// ground.
    StartPoseContact {
        /// One part, e.g. "right leg 0 link 1".
        first: String,
        /// The other part, or "ground".
        second: String,
    },
    /// The robot did not move forward (d <= 0), so its cost of transport is undefined.
    NoForwardProgress {
        /// Its distance, m.
        distance: f64,
    },
    /// Feasible at the run's physics step, not at a finer one (`[trial]
    /// confirm_substeps_factor`): its balance or speed is the integrator's, not the robot's.
    /// `at_time` is when the finer trial ended (its whole length if it ran to the end).
    StepSensitive {
        /// Physics steps per control step of the finer trial.
        substeps: u32,
        /// The finer trial's verdict, e.g. "fell: tilted 20.3° (limit 20°) at 12.40 s".
        verdict: String,
    },
    /// Feasible at the run's physics step and friction, not on a floor with less or more
    /// grip (`[trial] friction_margin`): its walk holds on one floor only.
    /// `at_time` is when that trial ended (its whole length if it ran to the end).
    FrictionSensitive {
        /// The friction coefficient of that trial.
        friction: f64,
        /// Its verdict, e.g. "fell: tilted 20.3° (limit 20°) at 12.40 s".
        verdict: String,
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
            InvalidReason::Fell { fall } => write!(f, "fell: {fall}"),
            InvalidReason::Skating { skate } => write!(f, "skated: {skate}"),
            InvalidReason::StartPoseContact { first, second } => {
                write!(f, "{first} and {second} touch in the start pose")
            }
            InvalidReason::NoForwardProgress { distance } => {
                write!(f, "no forward progress (distance {distance:.3} m)")
            }
            InvalidReason::EvaluationFailed { attempts, last } => {
                write!(f, "evaluation failed {attempts} times (last: {last})")
            }
            InvalidReason::StepSensitive { substeps, verdict } => write!(
                f,
                "feasible at the run's step, not at {substeps} physics steps per control step: {verdict}"
            ),
            InvalidReason::FrictionSensitive { friction, verdict } => write!(
                f,
                "feasible on the run's floor, not at friction {friction}: {verdict}"
            ),
        }
    }
}

/// How a robot's feet skated (docs/model.md section 6, "Feet that step").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "how", rename_all = "snake_case")]
pub enum Skate {
    /// The feet slid along the ground while on it.
    Slid {
        /// Distance a foot slid on the ground (mean over the feet) per metre walked.
        ratio: f64,
        /// The limit.
        limit: f64,
    },
    /// The feet travelled forward within the ground clearance instead of stepping over it.
    Shuffled {
        /// Share of the feet's forward travel made within the clearance.
        share: f64,
        /// The limit.
        limit: f64,
    },
}

impl std::fmt::Display for Skate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Skate::Slid { ratio, limit } => write!(
                f,
                "its feet slid {ratio:.2} m on the ground per metre walked (limit {limit:.2})"
            ),
            Skate::Shuffled { share, limit } => write!(
                f,
                "{:.0} % of its feet's forward travel was along the ground (limit {:.0} %)",
                100.0 * share,
                100.0 * limit
            ),
        }
    }
}

/// How a robot fell (docs/model.md section 6: a robot that falls is not walking).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "how", rename_all = "snake_case")]
pub enum Fall {
    /// The body tilted more than the limit from upright.
    Tilted {
        /// The body's tilt (angle between its up axis and the vertical), degrees.
        degrees: f64,
        /// The limit, degrees.
        limit: f64,
    },
    /// The body's centre dropped below the limit.
    Sank {
        /// The body centre's height, m.
        height: f64,
        /// The limit (a fraction of the start pose's body height), m.
        limit: f64,
    },
    /// A part other than a lower leg touched the ground (a body or knee dragged).
    Dragged {
        /// The part, e.g. "right leg 1 link 1" or "body".
        part: String,
    },
}

impl std::fmt::Display for Fall {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Fall::Tilted { degrees, limit } => {
                write!(f, "body tilted {degrees:.1} degrees (limit {limit:.1})")
            }
            Fall::Sank { height, limit } => {
                write!(f, "body centre sank to {height:.3} m (limit {limit:.3} m)")
            }
            Fall::Dragged { part } => write!(f, "{part} touched the ground"),
        }
    }
}

/// What keeps a simulated design from the brief: the constraint that binds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shortfall {
    /// Met the brief at the run's physics step, not at the finer step that confirms it.
    StepSensitive,
    /// Met the brief on the run's floor, not on one with less or more grip.
    FrictionSensitive,
    /// Ran to the end upright and forward, below the brief's speed.
    Speed,
    /// Ran to the end upright, not forward.
    Backward,
    /// Ran to the end upright, its feet skating instead of stepping.
    Skating,
    /// Fell (tilted, sank, or dragged a part on the ground).
    Fell,
    /// Two of its parts touched.
    SelfContact,
    /// The simulation blew up or went non-finite.
    Unstable,
}

impl Shortfall {
    /// Every shortfall, nearest the brief first.
    pub const ALL: [Shortfall; 8] = [
        Shortfall::StepSensitive,
        Shortfall::FrictionSensitive,
        Shortfall::Speed,
        Shortfall::Backward,
        Shortfall::Skating,
        Shortfall::Fell,
        Shortfall::SelfContact,
        Shortfall::Unstable,
    ];

    /// Its name (database, CSV, reports).
    pub fn name(self) -> &'static str {
        match self {
            Shortfall::StepSensitive => "step_sensitive",
            Shortfall::FrictionSensitive => "friction_sensitive",
            Shortfall::Speed => "speed",
            Shortfall::Backward => "backward",
            Shortfall::Skating => "skating",
            Shortfall::Fell => "fell",
            Shortfall::SelfContact => "self_contact",
            Shortfall::Unstable => "unstable",
        }
    }

    /// Its label in words (report legends).
    pub fn label(self) -> &'static str {
        match self {
            Shortfall::StepSensitive => "step-sensitive",
            Shortfall::FrictionSensitive => "friction-sensitive",
            Shortfall::Speed => "too slow",
            Shortfall::Backward => "backward",
            Shortfall::Skating => "skating",
            Shortfall::Fell => "fell",
            Shortfall::SelfContact => "self-contact",
            Shortfall::Unstable => "unstable",
        }
    }

    /// What it means, in a sentence a designer reads (the report defines each word).
    pub fn meaning(self) -> &'static str {
        match self {
            Shortfall::StepSensitive => "met the brief at the run's physics step but not at a finer one ([trial] confirm_substeps_factor)",
            Shortfall::FrictionSensitive => "met the brief on the run's floor but not on one with less or more grip ([trial] friction_margin)",
            Shortfall::Speed => "walked the whole trial upright and forward, slower than the brief's minimum speed",
            Shortfall::Backward => "stayed upright to the end but did not move forward",
            Shortfall::Skating => "stayed upright to the end, its feet sliding along the ground instead of stepping (slip and low forward travel past the [trial] limits)",
            Shortfall::Fell => "tilted over, sank too low or dragged a part other than a foot on the ground",
            Shortfall::SelfContact => "two of its own parts not joined by a hinge touched",
            Shortfall::Unstable => "the simulation diverged (a speed past the blow-up limit, or a value that is not a number): the design's figures cannot be trusted, whatever it would do",
        }
    }

    /// The shortfall called `name`.
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// Where an outcome stands against the brief, as one total order (higher is closer):
/// what the ES keeps and how the infeasible library ranks (docs/model.md section 6).
/// Equality is that order's (figures compared with `f64::total_cmp`).
#[derive(Clone, Copy, Debug)]
pub enum Standing {
    /// Stopped by a check before simulating (mass, height, start-pose contact) or never
    /// evaluated: nothing to rank it by.
    NotSimulated,
    /// The trial ended early (self-contact, fell, blew up): later is closer.
    EndedEarly {
        /// Simulated time when it stopped, s.
        at_time: f64,
    },
    /// The trial ran to the end upright but missed the speed: faster is closer (backward
    /// is negative).
    TooSlow {
        /// Average forward speed, m/s.
        speed: f64,
    },
    /// Met the whole brief: fitter is better.
    Feasible {
        /// 1 / cost of transport.
        fitness: f64,
    },
}

impl Standing {
    fn tier(&self) -> (u8, f64) {
        match *self {
            Standing::NotSimulated => (0, 0.0),
            Standing::EndedEarly { at_time } => (1, at_time),
            Standing::TooSlow { speed } => (2, speed),
            Standing::Feasible { fitness } => (3, fitness),
        }
    }

    /// Whether `self` ranks strictly above `other`.
    pub fn beats(&self, other: &Standing) -> bool {
        self.cmp(other) == std::cmp::Ordering::Greater
    }
}

impl Ord for Standing {
    /// The total order: by tier, then by the tier's figure (`f64::total_cmp`).
    fn cmp(&self, other: &Standing) -> std::cmp::Ordering {
        let (ta, a) = self.tier();
        let (tb, b) = other.tier();
        ta.cmp(&tb).then(a.total_cmp(&b))
    }
}

impl PartialOrd for Standing {
    fn partial_cmp(&self, other: &Standing) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Standing {
    fn eq(&self, other: &Standing) -> bool {
        self.cmp(other) == std::cmp::Ordering::Equal
    }
}

impl Eq for Standing {}

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
        /// Fast enough for the brief in the run's own trial and no fitter than the elite
        /// its cell held when its generation was drawn (the assignment's `to_beat`): it
        /// was answered at its trial's end, its stay-up window and confirming trials (the
        /// finer step's, the floors') not run, since they only keep or lower a design's
        /// standing and it could not enter the library whatever they said. It is never
        /// placed; `verify` simulates it again the same way. Absent from stored JSON when
        /// false.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        outranked: bool,
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

    /// Where this outcome stands against the brief.
    pub fn standing(&self) -> Standing {
        match self {
            Outcome::Valid { fitness, .. } => Standing::Feasible { fitness: *fitness },
            Outcome::Rejected {
                stats: Some(stats), ..
            } => Standing::TooSlow { speed: stats.speed },
            Outcome::Rejected { stats: None, .. } => Standing::NotSimulated,
            Outcome::Invalid {
                reason, at_time, ..
            } => match reason {
                InvalidReason::NoForwardProgress { distance } if *at_time > 0.0 => {
                    Standing::TooSlow {
                        speed: distance / at_time,
                    }
                }
                InvalidReason::StartPoseContact { .. }
                | InvalidReason::EvaluationFailed { .. }
                | InvalidReason::NoForwardProgress { .. } => Standing::NotSimulated,
                InvalidReason::SelfContact { .. }
                | InvalidReason::Fell { .. }
                | InvalidReason::Skating { .. }
                | InvalidReason::NonFinite { .. }
                | InvalidReason::BlowUp { .. }
                | InvalidReason::StepSensitive { .. }
                | InvalidReason::FrictionSensitive { .. } => {
                    Standing::EndedEarly { at_time: *at_time }
                }
            },
        }
    }

    /// What keeps a simulated design from the brief; `None` for a valid design and for one
    /// stopped before simulating.
    pub fn shortfall(&self) -> Option<Shortfall> {
        match self {
            Outcome::Valid { .. } | Outcome::Rejected { stats: None, .. } => None,
            Outcome::Rejected { stats: Some(s), .. } => Some(if s.distance > 0.0 {
                Shortfall::Speed
            } else {
                Shortfall::Backward
            }),
            Outcome::Invalid { reason, .. } => match reason {
                InvalidReason::NoForwardProgress { .. } => Some(Shortfall::Backward),
                InvalidReason::Fell { .. } => Some(Shortfall::Fell),
                InvalidReason::Skating { .. } => Some(Shortfall::Skating),
                InvalidReason::StepSensitive { .. } => Some(Shortfall::StepSensitive),
                InvalidReason::FrictionSensitive { .. } => Some(Shortfall::FrictionSensitive),
                InvalidReason::SelfContact { .. } => Some(Shortfall::SelfContact),
                InvalidReason::NonFinite { .. } | InvalidReason::BlowUp { .. } => {
                    Some(Shortfall::Unstable)
                }
                InvalidReason::StartPoseContact { .. } | InvalidReason::EvaluationFailed { .. } => {
                    None
                }
            },
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::brief::{Constraint, Violation};
    use crate::features::{CellIndex, Features};

    fn stats(distance: f64) -> TrialStats {
        TrialStats {
            distance,
            energy: 1000.0,
            speed: distance / 5.0,
            mass: 60.0,
            cost_of_transport: 1.0,
            duration: 5.0,
            ..Default::default()
        }
    }

    fn valid(fitness: f64) -> Outcome {
        Outcome::Valid {
            fitness,
            stats: stats(6.0),
            features: Features([2.5, 60.0, 3.0, 0.005, 0.0, 0.0]),
            cell: CellIndex(7),
            controller: Controller::static_default(),
            outranked: false,
        }
    }

    fn slow(distance: f64) -> Outcome {
        Outcome::Rejected {
            violations: vec![Violation {
                constraint: Constraint::Speed,
                value: distance / 5.0,
                limit: 1.0,
            }],
            stats: Some(stats(distance)),
            controller: Controller::static_default(),
        }
    }

    fn invalid(reason: InvalidReason, at_time: f64) -> Outcome {
        Outcome::Invalid {
            reason,
            at_time,
            controller: Controller::static_default(),
        }
    }

    fn fell(at_time: f64) -> Outcome {
        invalid(
            InvalidReason::Fell {
                fall: Fall::Tilted {
                    degrees: 50.0,
                    limit: 45.0,
                },
            },
            at_time,
        )
    }

    #[test]
    fn outcomes_rank_in_one_total_order_nearest_the_brief_first() {
        let contact = |t| {
            invalid(
                InvalidReason::SelfContact {
                    first: "a".into(),
                    second: "b".into(),
                },
                t,
            )
        };
        // Best first.
        let ranked = [
            valid(2.0),
            valid(1.0),
            slow(4.5),
            slow(0.5),
            invalid(InvalidReason::NoForwardProgress { distance: -0.2 }, 5.0),
            fell(4.9),
            contact(1.0),
            fell(0.5),
            Outcome::Rejected {
                violations: vec![Violation {
                    constraint: Constraint::Mass,
                    value: 70.0,
                    limit: 60.0,
                }],
                stats: None,
                controller: Controller::static_default(),
            },
        ];
        for (i, a) in ranked.iter().enumerate() {
            for (j, b) in ranked.iter().enumerate() {
                let want = j.cmp(&i); // earlier in the list ranks higher
                assert_eq!(
                    a.standing().cmp(&b.standing()),
                    want,
                    "{i} vs {j}: {:?} vs {:?}",
                    a.standing(),
                    b.standing()
                );
            }
        }
        // Designs stopped before simulating tie: none is nearer the brief than another.
        let start_pose = invalid(
            InvalidReason::StartPoseContact {
                first: "a".into(),
                second: "ground".into(),
            },
            0.0,
        );
        assert_eq!(start_pose.standing(), Standing::NotSimulated);
        // A fall at the very end still ranks below standing still to the end.
        assert!(slow(0.0).standing().beats(&fell(4.99).standing()));
    }

    #[test]
    fn the_shortfall_names_the_constraint_that_binds() {
        assert_eq!(valid(1.0).shortfall(), None);
        assert_eq!(slow(3.0).shortfall(), Some(Shortfall::Speed));
        assert_eq!(
            invalid(InvalidReason::NoForwardProgress { distance: -1.0 }, 5.0).shortfall(),
            Some(Shortfall::Backward)
        );
        assert_eq!(fell(2.0).shortfall(), Some(Shortfall::Fell));
        assert_eq!(
            invalid(InvalidReason::BlowUp { speed: 200.0 }, 1.0).shortfall(),
            Some(Shortfall::Unstable)
        );
        for s in Shortfall::ALL {
            assert_eq!(Shortfall::named(s.name()), Some(s));
        }
    }

    #[test]
    fn an_outranked_mark_is_stored_only_when_set_so_older_rows_read_and_hash_as_before() {
        let plain = valid(1.5);
        let text = serde_json::to_string(&plain).unwrap();
        assert!(!text.contains("outranked"), "{text}");
        assert_eq!(serde_json::from_str::<Outcome>(&text).unwrap(), plain);
        let mut marked = plain;
        if let Outcome::Valid { outranked, .. } = &mut marked {
            *outranked = true;
        }
        let text = serde_json::to_string(&marked).unwrap();
        assert!(text.contains("\"outranked\":true"), "{text}");
        assert_eq!(serde_json::from_str::<Outcome>(&text).unwrap(), marked);
    }
}
