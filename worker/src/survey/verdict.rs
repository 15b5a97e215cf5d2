//! One surveyed design's verdict and record: what became of it (rejected, self-contact by
//! the parts involved, fell by how, backward, too slow, passed) and the physical cause
//! that figures computed without physics give for it.

use serde::Serialize;
use strider_common::body_plan::BodyPlan;
use strider_common::brief::Constraint;
use strider_common::contact::{Part, Touch};
use strider_common::kinematics::{gait_period, speed_estimate, GaitSweep};
use strider_common::EvalContext;
use strider_common::{Controller, Fall, Genome, InvalidReason, Outcome, Scheme, StartPose};

/// Which two parts met in a self-contact.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PairKind {
    /// Neighbouring legs on one side.
    Neighbours,
    /// Legs on one side with others between them.
    SameSide,
    /// Legs on opposite sides.
    Opposite,
    /// A leg and the body.
    Body,
    /// The hip link and the lower leg of one leg.
    SameLeg,
}

impl PairKind {
    /// The kind of the pair `a`, `b` on `plan`.
    pub fn of(plan: &BodyPlan, a: Part, b: Part) -> Self {
        match (a, b) {
            (Part::Link { leg: i, .. }, Part::Link { leg: j, .. }) => {
                let (li, lj) = (&plan.legs[i], &plan.legs[j]);
                if i == j {
                    PairKind::SameLeg
                } else if li.side != lj.side {
                    PairKind::Opposite
                } else if li.index.abs_diff(lj.index) == 1 {
                    PairKind::Neighbours
                } else {
                    PairKind::SameSide
                }
            }
            _ => PairKind::Body,
        }
    }

    pub(super) fn label(self) -> &'static str {
        match self {
            PairKind::Neighbours => "neighbours",
            PairKind::SameSide => "same side, not neighbours",
            PairKind::Opposite => "opposite sides",
            PairKind::Body => "leg and body",
            PairKind::SameLeg => "hip and lower leg of one leg",
        }
    }
}

/// How a fall happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FallKind {
    /// Tilted past the limit.
    Tilt,
    /// Body centre sank below the limit.
    Height,
    /// A part other than a lower leg touched the ground.
    Dragging,
}

/// What became of one random design.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case", tag = "verdict")]
pub enum Verdict {
    /// Over the mass limit (checked first).
    RejectedMass,
    /// Under the height limit.
    RejectedHeight,
    /// Parts touch in the start pose.
    RejectedStartPoseContact,
    /// Two parts touched during the trial.
    SelfContact {
        /// Which parts.
        pair: PairKind,
        /// Before the first half gait cycle (`pi / sf`).
        early: bool,
    },
    /// The robot fell.
    Fell { how: FallKind },
    /// A blow-up or a non-finite value.
    Unstable,
    /// Upright to the end, but not forward (d <= 0).
    Backward,
    /// Upright and forward to the end, its feet skating instead of stepping.
    Skated,
    /// Upright and forward, below the brief's speed.
    TooSlow,
    /// Met the brief at the run's step, not at the finer confirming step.
    StepSensitive,
    /// Met the brief on the run's floor, not on one with less or more grip.
    FrictionSensitive,
    /// Met the whole brief.
    Passed,
}

impl Verdict {
    /// Every verdict, in table order.
    pub fn all() -> Vec<Verdict> {
        let mut v = vec![
            Verdict::RejectedMass,
            Verdict::RejectedHeight,
            Verdict::RejectedStartPoseContact,
        ];
        for pair in [
            PairKind::Neighbours,
            PairKind::SameSide,
            PairKind::Opposite,
            PairKind::Body,
            PairKind::SameLeg,
        ] {
            for early in [true, false] {
                v.push(Verdict::SelfContact { pair, early });
            }
        }
        for how in [FallKind::Tilt, FallKind::Height, FallKind::Dragging] {
            v.push(Verdict::Fell { how });
        }
        v.extend([
            Verdict::Unstable,
            Verdict::Backward,
            Verdict::Skated,
            Verdict::TooSlow,
            Verdict::StepSensitive,
            Verdict::FrictionSensitive,
            Verdict::Passed,
        ]);
        v
    }

    /// Whether a trial was run.
    pub fn simulated(self) -> bool {
        !matches!(
            self,
            Verdict::RejectedMass | Verdict::RejectedHeight | Verdict::RejectedStartPoseContact
        )
    }

    /// Whether the robot ran the whole trial upright, moving forward.
    pub fn walked_forward_upright(self) -> bool {
        matches!(
            self,
            Verdict::TooSlow
                | Verdict::StepSensitive
                | Verdict::FrictionSensitive
                | Verdict::Passed
        )
    }

    /// Whether the robot ran the whole trial upright.
    pub fn upright_to_the_end(self) -> bool {
        matches!(
            self,
            Verdict::Backward
                | Verdict::Skated
                | Verdict::TooSlow
                | Verdict::StepSensitive
                | Verdict::FrictionSensitive
                | Verdict::Passed
        )
    }

    /// A label for tables and CSV.
    pub fn label(self) -> String {
        match self {
            Verdict::RejectedMass => "rejected: mass".into(),
            Verdict::RejectedHeight => "rejected: height".into(),
            Verdict::RejectedStartPoseContact => "rejected: start-pose contact".into(),
            Verdict::SelfContact { pair, early } => format!(
                "self-contact: {}, {}",
                pair.label(),
                if early { "first half cycle" } else { "later" }
            ),
            Verdict::Fell { how } => format!(
                "fell: {}",
                match how {
                    FallKind::Tilt => "tilt",
                    FallKind::Height => "height",
                    FallKind::Dragging => "dragging",
                }
            ),
            Verdict::Unstable => "blow-up / non-finite".into(),
            Verdict::Backward => "backward".into(),
            Verdict::Skated => "skated".into(),
            Verdict::TooSlow => "too slow".into(),
            Verdict::StepSensitive => "step-sensitive".into(),
            Verdict::FrictionSensitive => "friction-sensitive".into(),
            Verdict::Passed => "passed".into(),
        }
    }

    /// Classifies an outcome of a design with body plan `plan`.
    pub fn of(o: &Outcome, plan: &BodyPlan) -> Self {
        let half_cycle = 0.5 * gait_period(o.controller());
        match o {
            Outcome::Valid { .. } => Verdict::Passed,
            Outcome::Rejected { violations, .. } => {
                let failed = |c| violations.iter().any(|v| v.constraint == c);
                if failed(Constraint::Mass) {
                    Verdict::RejectedMass
                } else if failed(Constraint::Height) {
                    Verdict::RejectedHeight
                } else {
                    Verdict::TooSlow
                }
            }
            Outcome::Invalid {
                reason, at_time, ..
            } => match reason {
                InvalidReason::StartPoseContact { .. } => Verdict::RejectedStartPoseContact,
                InvalidReason::SelfContact { first, second } => {
                    let part = |n: &str| Part::named(plan, n).unwrap_or(Part::Body);
                    Verdict::SelfContact {
                        pair: PairKind::of(plan, part(first), part(second)),
                        early: *at_time < half_cycle,
                    }
                }
                InvalidReason::Fell { fall } => Verdict::Fell {
                    how: match fall {
                        Fall::Tilted { .. } => FallKind::Tilt,
                        Fall::Sank { .. } => FallKind::Height,
                        Fall::Dragged { .. } => FallKind::Dragging,
                    },
                },
                InvalidReason::NonFinite { .. }
                | InvalidReason::BlowUp { .. }
                | InvalidReason::EvaluationFailed { .. } => Verdict::Unstable,
                InvalidReason::NoForwardProgress { .. } => Verdict::Backward,
                InvalidReason::Skating { .. } => Verdict::Skated,
                InvalidReason::StepSensitive { .. } => Verdict::StepSensitive,
                InvalidReason::FrictionSensitive { .. } => Verdict::FrictionSensitive,
            },
        }
    }
}

/// A computed physical cause of a failed trial (docs/model.md section 15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Cause {
    /// The commanded gait, with the body held still, sweeps two parts into each other
    /// within the trial.
    GaitSweepsPartsTogether,
    /// Holding the commanded stance on one tripod set needs more torque than a lifting
    /// joint has (static calculation).
    LiftingMotorsTooWeak,
    /// The robot's centre of mass leaves the polygon of the stance feet during the stride
    /// (static calculation; always so for two legs per side, whose stance is a line).
    UnstableSupport,
    /// The commanded feet, never slipping, would carry the body backward (or nowhere).
    GaitPushesBackward,
    /// The commanded feet, never slipping, would not reach the brief's speed.
    GaitTooSlow,
}

impl Cause {
    /// Every cause, in table order.
    pub const ALL: [Cause; 5] = [
        Cause::GaitSweepsPartsTogether,
        Cause::LiftingMotorsTooWeak,
        Cause::UnstableSupport,
        Cause::GaitPushesBackward,
        Cause::GaitTooSlow,
    ];

    /// Whether a design's figures show this cause (whatever became of it); `None` when
    /// the design is outside the population the check compares: falls are compared among
    /// designs whose gait sweeps no parts together (a self-contact would end the trial
    /// first), backward walking among designs upright to the end.
    pub(super) fn holds(self, r: &Record, brief_distance: f64) -> Option<bool> {
        let sweeps = r.gait_contact_at.is_some();
        Some(match self {
            Cause::GaitSweepsPartsTogether => {
                r.gait_distance?;
                r.gait_contact_at.is_some()
            }
            Cause::LiftingMotorsTooWeak if !sweeps => r.stance_load? > 1.0,
            Cause::UnstableSupport if !sweeps => r.support_margin? <= 0.0,
            Cause::LiftingMotorsTooWeak | Cause::UnstableSupport => return None,
            Cause::GaitPushesBackward if r.verdict.upright_to_the_end() => r.gait_distance? <= 0.0,
            Cause::GaitPushesBackward => return None,
            Cause::GaitTooSlow => r.gait_distance? < brief_distance,
        })
    }

    /// Whether `v` is the failure this cause explains.
    pub(super) fn explains(self, v: Verdict) -> bool {
        match self {
            Cause::GaitSweepsPartsTogether => matches!(v, Verdict::SelfContact { .. }),
            Cause::LiftingMotorsTooWeak | Cause::UnstableSupport => {
                matches!(v, Verdict::Fell { .. })
            }
            Cause::GaitPushesBackward => v == Verdict::Backward,
            Cause::GaitTooSlow => v != Verdict::Passed,
        }
    }

    pub(super) fn failure_label(self) -> &'static str {
        match self {
            Cause::GaitSweepsPartsTogether => "self-contact",
            Cause::LiftingMotorsTooWeak | Cause::UnstableSupport => "fell",
            Cause::GaitPushesBackward => "backward",
            Cause::GaitTooSlow => "missed the brief",
        }
    }

    pub(super) fn label(self) -> &'static str {
        match self {
            Cause::GaitSweepsPartsTogether => "the gait sweeps parts into each other",
            Cause::LiftingMotorsTooWeak => "lifting motors too weak for the stance",
            Cause::UnstableSupport => "centre of mass leaves the stance feet",
            Cause::GaitPushesBackward => "the feet push backward (kinematic)",
            Cause::GaitTooSlow => "the feet sweep too slowly for the brief",
        }
    }
}

/// One surveyed design: its outcome and the figures computed without physics.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Record {
    /// Candidate number (the run's random draw).
    pub candidate: u64,
    pub legs_per_side: usize,
    /// What became of it.
    #[serde(flatten)]
    pub verdict: Verdict,
    /// Over the brief's mass limit (whatever else failed).
    pub fails_mass: bool,
    /// Under the brief's height limit with its first controller (whatever else failed).
    pub fails_height: bool,
    /// When the trial stopped (s), for trials that stopped early.
    pub stopped_at: Option<f64>,
    /// Distance walked (m), for trials that ran to the end.
    pub distance: Option<f64>,
    /// The simple kinematic estimate over the trial, `(2/pi) r wmax T`, m.
    pub estimate: Option<f64>,
    /// The commanded gait's no-slip distance over the trial, m.
    pub gait_distance: Option<f64>,
    /// How high the gait lifts swing feet above stance feet, m.
    pub gait_lift: Option<f64>,
    /// When the commanded gait first sweeps two parts together, s.
    pub gait_contact_at: Option<f64>,
    /// The commanded stance's largest lifting-joint torque over its limit.
    pub stance_load: Option<f64>,
    /// The smallest margin of the centre of mass inside the stance feet's polygon, m.
    pub support_margin: Option<f64>,
    /// Why it failed, when a computed cause explains it.
    pub cause: Option<Cause>,
    /// The design (for `--csv`).
    #[serde(skip)]
    pub genome: Genome,
}

impl Record {
    pub(super) fn of(
        ctx: &EvalContext,
        scheme: Scheme,
        candidate: u64,
        genome: &Genome,
        outcome: &Outcome,
    ) -> Self {
        let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
        let verdict = Verdict::of(outcome, &plan);
        let first_controller = match scheme {
            Scheme::Genome => genome.controller,
            Scheme::Static | Scheme::Es => Controller::static_default(),
        };
        let static_fails = ctx
            .brief
            .check_model(&plan, &StartPose::new(&plan, &first_controller));
        let fails = |c| static_fails.iter().any(|v| v.constraint == c);
        let mut r = Record {
            candidate,
            legs_per_side: plan.legs_per_side(),
            verdict,
            fails_mass: fails(Constraint::Mass),
            fails_height: fails(Constraint::Height),
            stopped_at: None,
            distance: outcome.stats().map(|s| s.distance),
            estimate: None,
            gait_distance: None,
            gait_lift: None,
            gait_contact_at: None,
            stance_load: None,
            support_margin: None,
            cause: None,
            genome: *genome,
        };
        if let Outcome::Invalid {
            reason: InvalidReason::NoForwardProgress { distance },
            ..
        } = outcome
        {
            r.distance = Some(*distance);
        } else if let Outcome::Invalid { at_time, .. } = outcome {
            r.stopped_at = Some(*at_time);
        }
        if !verdict.simulated() {
            return r;
        }
        let c: &Controller = outcome.controller();
        let seconds = ctx.settings.trial_seconds;
        let sweep = GaitSweep::of(&plan, c, seconds, ctx.settings.control_hz);
        r.estimate = Some(speed_estimate(&plan, c) * seconds);
        r.gait_distance = Some(sweep.distance);
        r.gait_lift = Some(sweep.lift);
        r.gait_contact_at = sweep.contact.as_ref().map(|(t, _)| *t);
        r.stance_load = Some(sweep.stance_load);
        r.support_margin = Some(sweep.support_margin);
        r.cause = cause(
            verdict,
            &sweep,
            ctx.brief.required_speed(ctx.limits.speed_margin) * seconds,
        );
        r
    }
}

/// The computed cause that explains a failed trial, if one does.
fn cause(verdict: Verdict, sweep: &GaitSweep, brief_distance: f64) -> Option<Cause> {
    let sweeps = matches!(sweep.contact, Some((_, Touch::Parts(..))));
    let weak = sweep.stance_load > 1.0;
    let unstable = sweep.support_margin <= 0.0;
    let backward = sweep.distance <= 0.0;
    let slow = sweep.distance < brief_distance;
    let first =
        |candidates: &[(bool, Cause)]| candidates.iter().find(|(holds, _)| *holds).map(|(_, c)| *c);
    match verdict {
        // No cause is computed for skating: it needs the trial's foot contacts.
        Verdict::Passed
        | Verdict::Skated
        | Verdict::StepSensitive
        | Verdict::FrictionSensitive
        | Verdict::RejectedMass
        | Verdict::RejectedHeight
        | Verdict::RejectedStartPoseContact => None,
        Verdict::SelfContact { .. } => first(&[
            (sweeps, Cause::GaitSweepsPartsTogether),
            (weak, Cause::LiftingMotorsTooWeak),
            (unstable, Cause::UnstableSupport),
        ]),
        Verdict::Fell { .. } | Verdict::Unstable => first(&[
            (weak, Cause::LiftingMotorsTooWeak),
            (unstable, Cause::UnstableSupport),
            (sweeps, Cause::GaitSweepsPartsTogether),
        ]),
        Verdict::Backward => first(&[
            (backward, Cause::GaitPushesBackward),
            (weak, Cause::LiftingMotorsTooWeak),
            (unstable, Cause::UnstableSupport),
        ]),
        Verdict::TooSlow => first(&[
            (slow, Cause::GaitTooSlow),
            (weak, Cause::LiftingMotorsTooWeak),
        ]),
    }
}
