//! **Benchmark only.** Instant, made-up results, so that a benchmark can measure how many
//! results a coordinator accepts per second without waiting for simulations. Never a
//! default: a worker uses it only when started with `--benchmark-instant-results`.
//!
//! The outcome is a deterministic function of the candidate (its features and cell are the
//! design's real ones; fitness and statistics are invented), so runs stay reproducible. A
//! third of the simulated candidates meet the brief, a third run to the end too slowly,
//! and a third fall, so that both libraries of a feasible-infeasible search fill.

use strider_common::brief::{Constraint, Violation};
use strider_common::precheck::precheck_plan;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::{
    BodyPlan, Fall, Features, Genome, InvalidReason, Outcome, Scheme, TrialStats,
};

/// A made-up outcome for `genome`, in microseconds. `_to_beat` is unused: there is no
/// confirming trial to skip.
pub fn instant_outcome(
    ctx: &EvalContext,
    genome: &Genome,
    scheme: Scheme,
    seed: CandidateSeed,
    _to_beat: Option<f64>,
) -> Outcome {
    let plan = BodyPlan::new(&genome.morphology, ctx.brief.payload);
    if let Some(o) = precheck_plan(ctx, genome, &plan, scheme) {
        return o;
    }
    let features = Features::of(&genome.morphology, &plan);
    let cell = ctx
        .grid
        .cell_of(&features)
        .expect("features of a valid genome are finite");
    // A fitness in [0.5, 1.5) that depends on the candidate and its design.
    let mix = seed
        .candidate
        .0
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(u64::from(cell.0).wrapping_mul(0xBF58_476D_1CE4_E5B9));
    let unit = (mix >> 11) as f64 / (1u64 << 53) as f64;
    let fitness = 0.5 + unit;
    let mass = plan.total_mass();
    match mix % 3 {
        1 => {
            return Outcome::Rejected {
                violations: vec![Violation {
                    constraint: Constraint::Speed,
                    value: 0.5 * unit,
                    limit: ctx.brief.required_speed(ctx.limits.speed_margin),
                }],
                stats: Some(TrialStats {
                    distance: 2.5 * unit,
                    energy: 1000.0,
                    speed: 0.5 * unit,
                    mass,
                    cost_of_transport: 1.0,
                    duration: 5.0,
                    ..Default::default()
                }),
                controller: genome.controller,
            }
        }
        2 => {
            return Outcome::Invalid {
                reason: InvalidReason::Fell {
                    fall: Fall::Tilted {
                        degrees: 46.0,
                        limit: 45.0,
                    },
                },
                at_time: 5.0 * unit,
                controller: genome.controller,
            }
        }
        _ => {}
    }
    Outcome::Valid {
        fitness,
        stats: TrialStats {
            distance: 1.0,
            energy: mass * 9.81 / fitness,
            speed: 1.0,
            mass,
            cost_of_transport: 1.0 / fitness,
            duration: 1.0,
            ..Default::default()
        },
        features,
        cell,
        controller: genome.controller,
        outranked: false,
    }
}
