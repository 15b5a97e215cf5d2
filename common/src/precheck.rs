//! What a run fixes for every evaluation, and the checks decided without a trial: the
//! brief's mass and height limits and parts touching in the start pose. Model rules, so
//! they live here: the coordinator settles such candidates itself (no physics engine), and
//! the worker makes the same checks before it simulates.

use crate::brief::DesignBrief;
use crate::experiment::{Experiment, RunSettings, TrialLimits};
use crate::features::FeatureGrid;
use crate::{BodyPlan, Controller, Genome, InvalidReason, Outcome, Scheme, StartPose};

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

/// The outcome of evaluating `genome` under `scheme` when it is decided without a trial
/// (the design fails the brief's mass or height limit, or its parts touch in the start
/// pose), computed in microseconds; `None` when a trial is needed.
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

/// The checks made before simulating one controller: the brief's mass and height, then
/// contacts in the start pose. `None` when the design may be simulated.
pub fn check_before_trial(
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
