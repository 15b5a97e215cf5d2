//! The survey: random genomes evaluated, every outcome classified (rejected before
//! simulating, self-contact by the parts involved, fell by how, backward, too slow,
//! passed), per legs per side, beside figures computed without physics
//! (`strider_common::kinematics`) that explain each failure with a physical cause.

use crate::batch::map_batch;
use crate::evaluate::evaluate;
use serde::Serialize;
use std::fmt;
use std::num::NonZeroUsize;
use strider_common::body_plan::BodyPlan;
use strider_common::brief::Constraint;
use strider_common::contact::{Part, Touch};
use strider_common::genome::ParamVector;
use strider_common::kinematics::{gait_period, speed_estimate, GaitSweep};
use strider_common::params::{CONTROLLER_PARAMS, MORPHOLOGY_PARAMS};
use strider_common::rng::{CandidateSeed, Purpose};
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

    fn label(self) -> &'static str {
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
            Verdict::TooSlow | Verdict::StepSensitive | Verdict::Passed
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
    fn holds(self, r: &Record, brief_distance: f64) -> Option<bool> {
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
    fn explains(self, v: Verdict) -> bool {
        match self {
            Cause::GaitSweepsPartsTogether => matches!(v, Verdict::SelfContact { .. }),
            Cause::LiftingMotorsTooWeak | Cause::UnstableSupport => {
                matches!(v, Verdict::Fell { .. })
            }
            Cause::GaitPushesBackward => v == Verdict::Backward,
            Cause::GaitTooSlow => v != Verdict::Passed,
        }
    }

    fn failure_label(self) -> &'static str {
        match self {
            Cause::GaitSweepsPartsTogether => "self-contact",
            Cause::LiftingMotorsTooWeak | Cause::UnstableSupport => "fell",
            Cause::GaitPushesBackward => "backward",
            Cause::GaitTooSlow => "missed the brief",
        }
    }

    fn label(self) -> &'static str {
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
    fn of(
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

/// Counts of one group of designs (all, or one leg count).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Tally {
    /// Designs drawn.
    pub drawn: usize,
    /// Over the mass limit (whatever else failed).
    pub mass_fails: usize,
    /// Under the height limit (whatever else failed).
    pub height_fails: usize,
    /// Count per verdict, in [`Verdict::all`] order.
    pub verdicts: Vec<usize>,
    /// Failed trials per computed cause, in [`Cause::ALL`] order.
    pub causes: Vec<usize>,
    /// Failed trials with no computed cause.
    pub unexplained: usize,
}

impl Tally {
    fn new() -> Self {
        Tally {
            verdicts: vec![0; Verdict::all().len()],
            causes: vec![0; Cause::ALL.len()],
            ..Tally::default()
        }
    }

    fn count(&self, pick: impl Fn(Verdict) -> bool) -> usize {
        Verdict::all()
            .into_iter()
            .zip(&self.verdicts)
            .filter(|(v, _)| pick(*v))
            .map(|(_, n)| n)
            .sum()
    }

    /// Designs that passed mass and height (whatever the start pose).
    pub fn pass_mass_and_height(&self) -> usize {
        self.drawn - self.count(|v| matches!(v, Verdict::RejectedMass | Verdict::RejectedHeight))
    }

    /// Designs simulated.
    pub fn simulated(&self) -> usize {
        self.count(Verdict::simulated)
    }

    /// Designs that walked forward upright to the end.
    pub fn walked(&self) -> usize {
        self.count(Verdict::walked_forward_upright)
    }

    /// Designs that met the whole brief.
    pub fn passed(&self) -> usize {
        self.count(|v| v == Verdict::Passed)
    }
}

/// A survey of random genomes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Survey {
    /// The scheme evaluated.
    pub scheme: Scheme,
    /// The run seed the genomes were drawn from.
    pub seed: u64,
    /// All designs.
    pub all: Tally,
    /// Per legs per side, 2 to 6.
    pub per_leg_count: Vec<(usize, Tally)>,
    /// Pearson's r between the distance walked and the simple kinematic estimate, over the
    /// designs upright to the end (backward ones included), and their number.
    pub estimate_correlation: (Option<f64>, usize),
    /// The same over designs that walked forward.
    pub estimate_correlation_forward: (Option<f64>, usize),
    /// Pearson's r between the distance walked and the gait's no-slip distance, over the
    /// designs upright to the end.
    pub gait_correlation: (Option<f64>, usize),
    /// Per cause, over simulated designs: (designs showing it, share of them with the
    /// failure it explains, designs not showing it, share of those with that failure). A
    /// cause that explains a failure makes it much likelier.
    pub cause_checks: Vec<(Cause, usize, f64, usize, f64)>,
    /// Every design, in candidate order (for `--csv`).
    #[serde(skip)]
    pub records: Vec<Record>,
}

impl Survey {
    /// Draws `count` random genomes for `scheme` from `seed` (candidate numbers 0..count, the
    /// same genomes a run with that seed starts from) and evaluates them, calling
    /// `progress` with the number done after each one (from the simulation threads).
    pub fn run(
        ctx: &EvalContext,
        scheme: Scheme,
        seed: u64,
        count: usize,
        threads: NonZeroUsize,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Self {
        let candidates: Vec<u64> = (0..count as u64).collect();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let records = map_batch(&candidates, threads, |&i| {
            let s = CandidateSeed::new(seed, i);
            let genome = Genome::random(scheme, &mut s.rng(Purpose::RandomGenome));
            let outcome = evaluate(ctx, &genome, scheme, s);
            let record = Record::of(ctx, scheme, i, &genome, &outcome);
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            record
        });
        let brief_distance =
            ctx.brief.required_speed(ctx.limits.speed_margin) * ctx.settings.trial_seconds;
        Self::of_records(scheme, seed, brief_distance, records)
    }

    fn of_records(scheme: Scheme, seed: u64, brief_distance: f64, records: Vec<Record>) -> Self {
        let verdicts = Verdict::all();
        let mut all = Tally::new();
        let mut per: Vec<(usize, Tally)> = (2..=6).map(|n| (n, Tally::new())).collect();
        for r in &records {
            let slot = verdicts
                .iter()
                .position(|v| *v == r.verdict)
                .expect("every verdict is listed");
            let group = per
                .iter_mut()
                .find(|(n, _)| *n == r.legs_per_side)
                .map(|(_, t)| t)
                .expect("2 to 6 legs per side");
            for t in [&mut all, group] {
                t.drawn += 1;
                t.mass_fails += usize::from(r.fails_mass);
                t.height_fails += usize::from(r.fails_height);
                t.verdicts[slot] += 1;
                if r.verdict.simulated() && r.verdict != Verdict::Passed {
                    match r.cause {
                        Some(c) => {
                            t.causes[Cause::ALL.iter().position(|x| *x == c).expect("listed")] += 1
                        }
                        None => t.unexplained += 1,
                    }
                }
            }
        }
        let pairs = |pick: fn(Verdict) -> bool, other: fn(&Record) -> Option<f64>| {
            let xy: Vec<(f64, f64)> = records
                .iter()
                .filter(|r| pick(r.verdict))
                .filter_map(|r| Some((r.distance?, other(r)?)))
                .collect();
            (pearson(&xy), xy.len())
        };
        let share = |n: usize, of: usize| {
            if of == 0 {
                f64::NAN
            } else {
                n as f64 / of as f64
            }
        };
        let cause_checks = Cause::ALL
            .iter()
            .map(|&c| {
                let (mut with, mut with_fail, mut without, mut without_fail) = (0, 0, 0, 0);
                for r in &records {
                    match c.holds(r, brief_distance) {
                        Some(true) => {
                            with += 1;
                            with_fail += usize::from(c.explains(r.verdict));
                        }
                        Some(false) => {
                            without += 1;
                            without_fail += usize::from(c.explains(r.verdict));
                        }
                        None => {}
                    }
                }
                (
                    c,
                    with,
                    share(with_fail, with),
                    without,
                    share(without_fail, without),
                )
            })
            .collect();
        Survey {
            scheme,
            seed,
            cause_checks,
            all,
            per_leg_count: per,
            estimate_correlation: pairs(Verdict::upright_to_the_end, |r| r.estimate),
            estimate_correlation_forward: pairs(Verdict::walked_forward_upright, |r| r.estimate),
            gait_correlation: pairs(Verdict::upright_to_the_end, |r| r.gait_distance),
            records,
        }
    }

    /// Every record as CSV, one row per design.
    pub fn write_csv(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        let mut header = String::from(
            "candidate,legs_per_side,verdict,stopped_at,distance,estimate,gait_distance,gait_lift,gait_contact_at,stance_load,support_margin,cause",
        );
        for p in MORPHOLOGY_PARAMS.iter().chain(CONTROLLER_PARAMS) {
            header.push_str(",g_");
            header.push_str(p.name);
        }
        writeln!(out, "{header}")?;
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
        for r in &self.records {
            write!(
                out,
                "{},{},{},{},{},{},{},{},{},{},{},{}",
                r.candidate,
                r.legs_per_side,
                r.verdict.label().replace(',', ";"),
                f(r.stopped_at),
                f(r.distance),
                f(r.estimate),
                f(r.gait_distance),
                f(r.gait_lift),
                f(r.gait_contact_at),
                f(r.stance_load),
                f(r.support_margin),
                r.cause.map_or("", |c| c.label())
            )?;
            for v in r
                .genome
                .morphology
                .values()
                .iter()
                .chain(r.genome.controller.values())
            {
                write!(out, ",{v}")?;
            }
            writeln!(out)?;
        }
        Ok(())
    }
}

/// Pearson's correlation coefficient; `None` under 3 points or with no spread.
pub fn pearson(xy: &[(f64, f64)]) -> Option<f64> {
    let n = xy.len() as f64;
    if xy.len() < 3 {
        return None;
    }
    let (mx, my) = (
        xy.iter().map(|p| p.0).sum::<f64>() / n,
        xy.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in xy {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx) * (x - mx);
        syy += (y - my) * (y - my);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

impl fmt::Display for Survey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |n: usize, of: usize| {
            if of == 0 {
                "-".to_string()
            } else {
                format!("{:.1}", 100.0 * n as f64 / of as f64)
            }
        };
        let groups: Vec<(&str, &Tally)> = std::iter::once(("all", &self.all))
            .chain(
                self.per_leg_count
                    .iter()
                    .map(|(n, t)| (["n=2", "n=3", "n=4", "n=5", "n=6"][n - 2], t)),
            )
            .collect();
        let row = |f: &mut fmt::Formatter<'_>, label: &str, cell: &dyn Fn(&Tally) -> String| {
            write!(f, "{label:<52}")?;
            for (_, t) in &groups {
                write!(f, "{:>9}", cell(t))?;
            }
            writeln!(f)
        };
        writeln!(
            f,
            "random genomes, {} scheme, seed {}: counts, and % where marked",
            self.scheme.name(),
            self.seed
        )?;
        write!(f, "{:<52}", "")?;
        for (name, _) in &groups {
            write!(f, "{name:>9}")?;
        }
        writeln!(f)?;
        row(f, "drawn", &|t| t.drawn.to_string())?;
        row(f, "fail mass (any)", &|t| t.mass_fails.to_string())?;
        row(f, "fail height (any)", &|t| t.height_fails.to_string())?;
        row(f, "pass mass and height", &|t| {
            t.pass_mass_and_height().to_string()
        })?;
        for (i, v) in Verdict::all().into_iter().enumerate() {
            if matches!(v, Verdict::RejectedMass | Verdict::RejectedHeight) {
                continue;
            }
            let indent = if v.simulated() { "  " } else { "" };
            row(f, &format!("{indent}{}", v.label()), &|t| {
                t.verdicts[i].to_string()
            })?;
        }
        row(f, "simulated", &|t| t.simulated().to_string())?;
        row(f, "walk forward upright, % of pass mass and height", &|t| {
            pct(t.walked(), t.pass_mass_and_height())
        })?;
        row(f, "meet the whole brief, % of pass mass and height", &|t| {
            pct(t.passed(), t.pass_mass_and_height())
        })?;
        writeln!(f, "failed trials by computed cause (% of failed trials)")?;
        let failed = |t: &Tally| t.simulated() - t.passed();
        for (i, c) in Cause::ALL.iter().enumerate() {
            row(f, &format!("  {}", c.label()), &|t| {
                pct(t.causes[i], failed(t))
            })?;
        }
        row(f, "  no computed cause", &|t| pct(t.unexplained, failed(t)))?;
        writeln!(
            f,
            "does each cause predict its failure? (designs with / without it; falls among designs\n  whose gait sweeps nothing together, backward among those upright to the end)"
        )?;
        for (c, with, p_with, without, p_without) in &self.cause_checks {
            writeln!(
                f,
                "  {:<50}{:>6} designs: {:>5.1} % {}; {:>6} without: {:>5.1} %",
                c.label(),
                with,
                100.0 * p_with,
                c.failure_label(),
                without,
                100.0 * p_without
            )?;
        }
        let r = |(r, n): (Option<f64>, usize)| match r {
            Some(r) => format!("r = {r:.2} over {n} designs"),
            None => format!("- ({n} designs)"),
        };
        writeln!(
            f,
            "distance vs (2/pi) r wmax, upright to the end        {}",
            r(self.estimate_correlation)
        )?;
        writeln!(
            f,
            "distance vs (2/pi) r wmax, walked forward upright    {}",
            r(self.estimate_correlation_forward)
        )?;
        write!(
            f,
            "distance vs the gait's no-slip distance, upright     {}",
            r(self.gait_correlation)
        )
    }
}
