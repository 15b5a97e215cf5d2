//! Runs MAX's STATIC trial N times (default 10), for profilers:
//! `valgrind --tool=callgrind target/release/examples/profile_trial 10 [SUBSTEPS]`.

/// The binaries' allocator, so that the profile is theirs.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

use strider_common::EvalContext;
use strider_common::{BodyPlan, Controller};
use strider_worker::sim::trial::run_trial;

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map_or(10, |a| a.parse().expect("a count"));
    let g = strider_common::reference::max();
    let mut ctx = EvalContext::paper();
    // An optional second argument: physics steps per control step.
    if let Some(s) = std::env::args().nth(2) {
        ctx.settings.physics_substeps = s.parse().expect("a number of substeps");
    }
    let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
    for _ in 0..n {
        std::hint::black_box(run_trial(
            &plan,
            &Controller::static_default(),
            &ctx.settings,
            &ctx.limits,
            &mut (),
        ));
    }
}
