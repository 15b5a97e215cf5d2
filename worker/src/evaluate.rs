//! Evaluating a candidate: the brief's static checks, the trial, the speed check, and the
//! controller scheme (STATIC, GENOME, or ES tuning) around them.

use crate::es::tune_controller;
use crate::sim::trial::{run_trial_from, Observer, TrialEnd};
use strider_common::brief::DesignBrief;
use strider_common::experiment::{Experiment, RunSettings, TrialLimits};
use strider_common::features::FeatureGrid;
use strider_common::rng::CandidateSeed;
use strider_common::{
    BodyPlan, Controller, Features, Genome, InvalidReason, Outcome, Scheme, StartPose,
};

/// What a run fixes for every evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EvalContext {
    /// Trial length, rates, ES iterations.
    pub settings: RunSettings,
    /// When a robot counts as fallen.
    pub limits: TrialLimits,
    /// Constraints.
    pub brief: DesignBrief,
    /// Feature binning.
    pub grid: FeatureGrid,
}

impl EvalContext {
    /// The context of an experiment's runs.
    pub fn of(e: &Experiment) -> Self {
        Self {
            settings: e.run,
            limits: e.trial,
            brief: e.brief,
            grid: e.features,
        }
    }

    /// The paper's settings.
    pub fn paper() -> Self {
        Self {
            settings: RunSettings::default(),
            limits: TrialLimits::default(),
            brief: DesignBrief::default(),
            grid: FeatureGrid::default(),
        }
    }
}

/// Evaluates a genome under a scheme. STATIC uses the STATIC controller whatever the
/// genome holds; GENOME the genome's own; ES tunes from STATIC with the candidate's stream.
pub fn evaluate(
    ctx: &EvalContext,
    genome: &Genome,
    scheme: Scheme,
    seed: CandidateSeed,
) -> Outcome {
    let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
    match scheme {
        Scheme::Static => {
            evaluate_controller(ctx, genome, &plan, &Controller::static_default(), &mut ())
        }
        Scheme::Genome => evaluate_controller(ctx, genome, &plan, &genome.controller, &mut ()),
        Scheme::Es => tune_controller(ctx, genome, &plan, seed),
    }
}

/// The outcome of `evaluate` when it is decided without a trial (the design fails the
/// brief's mass or height limit, or its parts touch in the start pose), computed in
/// microseconds; `None` when a trial is needed.
/// The coordinator settles such candidates itself instead of sending them to a worker.
pub fn precheck(ctx: &EvalContext, genome: &Genome, scheme: Scheme) -> Option<Outcome> {
    let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
    precheck_plan(ctx, genome, &plan, scheme)
}

/// [`precheck`] for a genome whose body plan is already built.
pub fn precheck_plan(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    scheme: Scheme,
) -> Option<Outcome> {
    let controller = match scheme {
        Scheme::Static | Scheme::Es => Controller::static_default(),
        Scheme::Genome => genome.controller,
    };
    // Under ES only the mass is final: another controller may change the start height.
    if scheme == Scheme::Es && plan.mass_without_payload() <= ctx.brief.max_mass {
        return None;
    }
    check_before_trial(ctx, plan, &StartPose::new(plan, &controller), &controller)
}

/// The checks made before simulating: the brief's mass and height, then contacts in the
/// start pose. `None` when the design may be simulated.
fn check_before_trial(
    ctx: &EvalContext,
    plan: &BodyPlan,
    pose: &StartPose,
    controller: &Controller,
) -> Option<Outcome> {
    let violations = ctx.brief.check_model(plan, pose);
    if !violations.is_empty() {
        return Some(Outcome::Rejected {
            violations,
            stats: None,
            controller: *controller,
        });
    }
    let (first, second) = pose.touch(plan)?.describe(plan);
    Some(Outcome::Invalid {
        reason: InvalidReason::StartPoseContact { first, second },
        at_time: 0.0,
        controller: *controller,
    })
}

/// Evaluates one morphology with one controller: static checks, trial, speed check.
pub fn evaluate_controller(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    observer: &mut impl Observer,
) -> Outcome {
    let pose = StartPose::new(plan, controller);
    // A design that cannot meet the brief, or starts with parts touching, is not simulated.
    if let Some(outcome) = check_before_trial(ctx, plan, &pose, controller) {
        return outcome;
    }
    let stats = match run_trial_from(
        plan,
        &pose,
        controller,
        &ctx.settings,
        &ctx.limits,
        observer,
    ) {
        TrialEnd::Completed(stats) => stats,
        TrialEnd::Stopped { reason, at_time } => {
            return Outcome::Invalid {
                reason,
                at_time,
                controller: *controller,
            }
        }
    };
    if stats.distance <= 0.0 {
        return Outcome::Invalid {
            reason: InvalidReason::NoForwardProgress {
                distance: stats.distance,
            },
            at_time: stats.duration,
            controller: *controller,
        };
    }
    if let Some(v) = ctx.brief.check_speed(stats.speed) {
        return Outcome::Rejected {
            violations: vec![v],
            stats: Some(stats),
            controller: *controller,
        };
    }
    let fitness = 1.0 / stats.cost_of_transport;
    if !fitness.is_finite() {
        return Outcome::Invalid {
            reason: InvalidReason::NonFinite {
                what: "fitness".into(),
            },
            at_time: stats.duration,
            controller: *controller,
        };
    }
    let features = Features::of(&genome.morphology, plan);
    let cell = ctx
        .grid
        .cell_of(&features)
        .expect("features of a valid genome are finite");
    Outcome::Valid {
        fitness,
        stats,
        features,
        cell,
        controller: *controller,
    }
}
