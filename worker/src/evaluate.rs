//! Evaluating a candidate under its run's controller scheme: STATIC, GENOME, or ES tuning
//! (which evaluates many controllers). Above both `trial_outcome` and `es`.

use crate::es::tune_controller;
use crate::trial_outcome::evaluate_controller_to_enter;
use strider_common::rng::CandidateSeed;
use strider_common::{BodyPlan, Controller, EvalContext, Genome, Outcome, Scheme};

/// Evaluates a genome under a scheme. STATIC uses the STATIC controller whatever the
/// genome holds; GENOME the genome's own; ES tunes from STATIC with the candidate's stream.
pub fn evaluate(
    ctx: &EvalContext,
    genome: &Genome,
    scheme: Scheme,
    seed: CandidateSeed,
) -> Outcome {
    evaluate_to_enter(ctx, genome, scheme, seed, None)
}

/// [`evaluate`] for a candidate of a run whose library holds an elite of fitness `to_beat`
/// in its cell: under STATIC and GENOME a design fast enough at the run's step and no
/// fitter is answered `outranked` at its trial's end, its stay-up window and confirming
/// trials not run ([`evaluate_controller_to_enter`]). ES judges a child in full only if it
/// can beat its parent already, and its parent's standing steers the tuning, so it takes
/// no bar from outside.
pub fn evaluate_to_enter(
    ctx: &EvalContext,
    genome: &Genome,
    scheme: Scheme,
    seed: CandidateSeed,
    to_beat: Option<f64>,
) -> Outcome {
    let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
    match scheme {
        Scheme::Static => {
            evaluate_controller_to_enter(ctx, genome, &plan, &Controller::static_default(), to_beat)
        }
        Scheme::Genome => {
            evaluate_controller_to_enter(ctx, genome, &plan, &genome.controller, to_beat)
        }
        Scheme::Es => tune_controller(ctx, genome, &plan, seed),
    }
}
