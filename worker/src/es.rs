//! The ES scheme: a 1+1 evolution strategy that tunes one morphology's controller.
//!
//! The parent starts as the STATIC controller; each iteration mutates every controller
//! parameter (the same Gaussian rule as reproduction) and the child replaces the parent if
//! it ranks strictly higher. The result is the parent at the end: the best found.
//!
//! Ranking (**choice**, documented in docs/model.md section 7): the one total order of
//! [`strider_common::Standing`]: valid outcomes by fitness, above trials that ran to the
//! end upright but too slowly (by speed, so the strategy can climb toward the brief), above
//! trials that ended early (self-contact, a fall; later is better), above children
//! stopped before simulating. A fallen child thus ranks below every child that stayed up.
//! Plain fitness comparison would leave the strategy blind until a child passed the brief.
//!
//! A child that does not beat its parent at its trial's end is not simulated further
//! (`evaluate_controller_against`): one fast enough for the brief and no fitter than a
//! feasible parent, or slower and standing no higher than its parent, skips its stay-up
//! window, and none is put through the confirming trials (the floors, and the finer step
//! where set). The window and those trials could only lower it, so the strategy's path and
//! result are those of judging every child in full (a test holds it, bit for bit).

use crate::trial_outcome::{evaluate_controller, evaluate_controller_against};
use rand::Rng;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::EvalContext;
use strider_common::{BodyPlan, Controller, Genome, Outcome};

/// Tunes the controller of `genome`'s morphology; returns the best outcome found.
pub fn tune_controller(
    ctx: &EvalContext,
    genome: &Genome,
    plan: &BodyPlan,
    seed: CandidateSeed,
) -> Outcome {
    tune_with(ctx, genome, plan, &mut seed.rng(Purpose::EvolutionStrategy))
}

fn tune_with<R: Rng>(ctx: &EvalContext, genome: &Genome, plan: &BodyPlan, rng: &mut R) -> Outcome {
    let mass_fails = plan.mass_without_payload() > ctx.brief.max_mass;
    let mut best = evaluate_controller(ctx, genome, plan, &Controller::static_default(), &mut ());
    if mass_fails {
        // No controller changes the mass: don't spend 20 trials on it.
        return best;
    }
    for _ in 0..ctx.settings.es_iterations {
        let mut child = *best.controller();
        child.mutate_all(rng);
        let Some(outcome) =
            evaluate_controller_against(ctx, genome, plan, &child, &best.standing())
        else {
            continue;
        };
        if outcome.standing().beats(&best.standing()) {
            best = outcome;
        }
    }
    best
}
