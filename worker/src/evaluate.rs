//! Evaluating a candidate under its run's controller scheme: STATIC, GENOME, or ES tuning
//! (which evaluates many controllers). Above both `trial_outcome` and `es`.

use crate::es::tune_controller;
use crate::trial_outcome::evaluate_controller;
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
    let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
    match scheme {
        Scheme::Static => {
            evaluate_controller(ctx, genome, &plan, &Controller::static_default(), &mut ())
        }
        Scheme::Genome => evaluate_controller(ctx, genome, &plan, &genome.controller, &mut ()),
        Scheme::Es => tune_controller(ctx, genome, &plan, seed),
    }
}
