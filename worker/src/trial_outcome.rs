//! One morphology with one controller: the checks made before a trial, the trial, the
//! speed check and the fitness; what every scheme is built from.

use crate::help::{first_refusal, Check};
use crate::sim::trial::{run_trial_to_beat, Bar, Observer, Sample, TrialEnd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use strider_common::precheck::check_before_trial;
use strider_common::{
    BodyPlan, Controller, EvalContext, Features, Genome, InvalidReason, Outcome, Standing,
    StartPose,
};

/// Evaluates one morphology with one controller: static checks, trial, speed check, and,
/// for a design feasible at the run's step, the same trial on floors with more and less
/// grip (`[trial] friction_margin`) and, where `[trial] confirm_substeps_factor` is more
/// than 1 (2 by default), at a finer step. The outcome's figures are the run's trial's:
/// the confirming trials only decide whether they stand.
pub fn evaluate_controller(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    observer: &mut impl Observer,
) -> Outcome {
    let outcome = judge_at_step(ctx, genome, plan, controller, Bar::NONE, observer);
    confirm(ctx, genome, plan, controller, outcome)
}

/// [`evaluate_controller`] for a candidate that enters its run's library only if it is
/// fitter than `to_beat`, the elite its cell held when its generation was drawn (the
/// library changes only at a generation's end, and only to fitter elites, so no result of
/// the same generation can lower that bar). Where its trial at the run's step is fast
/// enough for the brief and no fitter, it is answered `outranked` with that trial's
/// figures at the trial's end: neither its stay-up window nor its confirming trials are
/// run, since they can only keep its standing or lower it, and it is discarded whatever
/// they say. In a 1000-generation STATIC run, 685 of 1,198 feasible candidates were
/// discarded, their confirmations 11.4 % of the search's simulation without the friction
/// margin's floors, their windows about 4 % (BENCHMARKS.md).
pub fn evaluate_controller_to_enter(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    to_beat: Option<f64>,
) -> Outcome {
    let bar = Bar {
        fitness: to_beat,
        standing: None,
    };
    let outcome = judge_at_step(ctx, genome, plan, controller, bar, &mut ());
    confirm(ctx, genome, plan, controller, outcome)
}

/// [`evaluate_controller`] for a trial that matters only if it ranks above `to_beat`
/// (the ES's parent): `None` where the trial at the run's step does not, since the
/// stay-up window and the confirming trials can only keep its standing or lower it. A
/// child that at the trial's end is fast enough for the brief and no fitter than a
/// feasible parent, or slower and standing no higher than its parent (any slower child
/// against a feasible one), ends there, its window not run ([`Bar::above`]); a child that
/// does not beat its parent is never put through the confirming trials (the floors' of
/// `[trial] friction_margin`, and the finer step's where `confirm_substeps_factor` asks it).
/// The strategy's path is that of judging every child in full.
pub fn evaluate_controller_against(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    to_beat: &Standing,
) -> Option<Outcome> {
    let outcome = judge_at_step(ctx, genome, plan, controller, Bar::above(*to_beat), &mut ());
    if !outcome.standing().beats(to_beat) {
        return None;
    }
    Some(confirm(ctx, genome, plan, controller, outcome))
}

/// `outcome` (the run's trial) if it is not feasible or every confirming trial finds it
/// feasible too: on the floor with more grip and the one with less (else invalid,
/// `friction_sensitive`), then, where `confirm_substeps_factor` is more than 1, at the finer
/// step (else `step_sensitive`). The first that fails ends it, so a design that fails pays
/// only the trials up to that one. An idle
/// simulation thread may run the last meanwhile (crate::help): the verdict is the same,
/// the answer comes sooner, and a trial it ran that no longer counts was that thread's
/// idle time.
fn confirm(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    outcome: Outcome,
) -> Outcome {
    if !matches!(
        outcome,
        Outcome::Valid {
            outranked: false,
            ..
        }
    ) {
        return outcome;
    }
    let checks = Confirmation::all(ctx);
    let (run_ctx, genome, plan, held) = (*ctx, *genome, plan.clone(), *controller);
    let run: Arc<Check<Confirmation, Outcome>> = Arc::new(move |check, abandon| {
        try_judge_at_step(
            &check.context(&run_ctx),
            &genome,
            &plan,
            &held,
            Bar::NONE,
            &mut Abandon(abandon),
        )
    });
    match first_refusal(checks.clone(), run, |o| !matches!(o, Outcome::Valid { .. })) {
        Some((i, confirmation)) => Outcome::Invalid {
            at_time: ended_at(&confirmation),
            reason: checks[i].failed(describe(&confirmation)),
            controller: *controller,
        },
        None => outcome,
    }
}

/// Watches a confirming trial for one thing: whether its verdict still counts.
struct Abandon<'a>(&'a AtomicBool);

impl Observer for Abandon<'_> {
    const WANTS_SAMPLES: bool = false;
    fn control_step(&mut self, _: &Sample<'_>) {}
    fn abandoned(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// A confirming trial: the run's trial with one setting changed.
#[derive(Clone, Copy)]
enum Confirmation {
    /// At this many physics steps per control step.
    FinerStep(u32),
    /// On a floor with this friction coefficient.
    Floor(f64),
}

impl Confirmation {
    /// The run's confirming trials, in the order they are tried: the likeliest to refuse
    /// for its cost first. In the 1000-generation STATIC run (docs/model.md section 6),
    /// tried finer step first, of the 1,958 candidates that reached them 97 failed at
    /// 480 Hz, 248 of the rest at friction 0.6 and 320 of the rest at 1.0; a 480-Hz trial
    /// costs two.
    fn all(ctx: &EvalContext) -> Vec<Self> {
        let mut all = Vec::new();
        if let Some([less, more]) = ctx.limits.confirming_floors(ctx.settings.friction) {
            all.extend([Self::Floor(more), Self::Floor(less)]);
        }
        let factor = ctx.limits.confirm_substeps_factor;
        if factor > 1 {
            all.push(Self::FinerStep(ctx.settings.physics_substeps * factor));
        }
        all
    }

    /// The context of this trial. The finer step's stay-up window is
    /// `[trial] confirm_substeps_upright_seconds` (1 s by default), not the long one. It
    /// judges the brief as written, with no speed margin:
    /// the margin absorbs the run's step's error in the run's own trial, and asked again
    /// here it refused designs for a few mm/s on a slipperier floor, or at a finer step
    /// where speed moves by 0.1-1 % (32 % of the refusals of the gated 1000-generation
    /// STATIC run, designs PyBullet accepts: docs/model.md section 6).
    fn context(self, ctx: &EvalContext) -> EvalContext {
        let mut c = *ctx;
        c.limits.speed_margin = 0.0;
        match self {
            Self::FinerStep(substeps) => {
                c.settings.physics_substeps = substeps;
                // Its own window: the run's trial and the floors' held it the long one.
                c.limits.upright_after_feasible_seconds = c.limits.confirm_substeps_upright_seconds;
            }
            Self::Floor(friction) => c.settings.friction = friction,
        }
        c
    }

    /// Why a design that fails it is invalid, given its verdict there.
    fn failed(self, verdict: String) -> InvalidReason {
        match self {
            Self::FinerStep(substeps) => InvalidReason::StepSensitive { substeps, verdict },
            Self::Floor(friction) => InvalidReason::FrictionSensitive { friction, verdict },
        }
    }
}

/// When a trial that did not meet the brief ended, s: a stopped trial's time, else its
/// whole length.
fn ended_at(outcome: &Outcome) -> f64 {
    match outcome {
        Outcome::Invalid { at_time, .. } => *at_time,
        Outcome::Rejected { stats, .. } => stats.as_ref().map_or(0.0, |s| s.duration),
        Outcome::Valid { stats, .. } => stats.duration,
    }
}

/// A one-line verdict for a trial that did not meet the brief.
fn describe(outcome: &Outcome) -> String {
    match outcome {
        Outcome::Invalid { reason, .. } => reason.to_string(),
        Outcome::Rejected { violations, .. } => violations
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("; "),
        Outcome::Valid { .. } => "feasible".into(),
    }
}

/// [`try_judge_at_step`] for an observer that never abandons a trial.
fn judge_at_step(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    to_beat: Bar,
    observer: &mut impl Observer,
) -> Outcome {
    try_judge_at_step(ctx, genome, plan, controller, to_beat, observer)
        .expect("only a confirming trial's helper abandons a trial")
}

/// [`evaluate_controller`] at the context's physics step only; a trial fast enough and no
/// fitter than `to_beat` is answered `outranked` at the trial's end, and one slower and
/// standing no higher than it is answered with its trial's figures there, its window not
/// run ([`run_trial_to_beat`]: neither counts). `None` only when the observer abandoned the trial
/// ([`Observer::abandoned`]).
fn try_judge_at_step(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    controller: &Controller,
    to_beat: Bar,
    observer: &mut impl Observer,
) -> Option<Outcome> {
    let pose = StartPose::new(plan, controller);
    // A design that cannot meet the brief, or starts with parts touching, is not simulated.
    if let Some(outcome) = check_before_trial(ctx, plan, &pose, controller) {
        return Some(outcome);
    }
    let (stats, outranked) = match run_trial_to_beat(
        plan,
        &pose,
        controller,
        &ctx.settings,
        &ctx.limits,
        ctx.brief.required_speed(ctx.limits.speed_margin),
        to_beat,
        observer,
    ) {
        TrialEnd::Completed(stats) => (stats, false),
        TrialEnd::Outranked(stats) => (stats, true),
        TrialEnd::Stopped { reason, at_time } => {
            return Some(Outcome::Invalid {
                reason,
                at_time,
                controller: *controller,
            })
        }
        TrialEnd::Abandoned { .. } => return None,
    };
    if stats.distance <= 0.0 {
        return Some(Outcome::Invalid {
            reason: InvalidReason::NoForwardProgress {
                distance: stats.distance,
            },
            at_time: stats.duration,
            controller: *controller,
        });
    }
    if let Some(v) = ctx.brief.check_speed(stats.speed, ctx.limits.speed_margin) {
        return Some(Outcome::Rejected {
            violations: vec![v],
            stats: Some(stats),
            controller: *controller,
        });
    }
    let fitness = 1.0 / stats.cost_of_transport;
    if !fitness.is_finite() {
        return Some(Outcome::Invalid {
            reason: InvalidReason::NonFinite {
                what: "fitness".into(),
            },
            at_time: stats.duration,
            controller: *controller,
        });
    }
    let features = Features::of(&genome.morphology, plan);
    let cell = ctx
        .grid
        .cell_of(&features)
        .expect("features of a valid genome are finite");
    Some(Outcome::Valid {
        fitness,
        stats,
        features,
        cell,
        controller: *controller,
        outranked,
    })
}
