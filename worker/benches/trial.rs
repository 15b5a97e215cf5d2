//! Trial throughput: trials per second on one core by legs per side, one ES candidate, and
//! the batch evaluator on one and two threads. Figures go to BENCHMARKS.md.

/// The binaries' allocator, so that the figures are theirs.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::num::NonZeroUsize;
use strider_common::params::M;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::{BodyPlan, Controller, Genome, Scheme};
use strider_worker::batch::{evaluate_batch, Job};
use strider_worker::evaluate::evaluate;
use strider_worker::sim::trial::{run_trial, TrialEnd};

fn max() -> Genome {
    strider_common::reference::max()
}

/// MAX with `n` legs per side and a hip slow enough that neighbours never meet, so every
/// trial runs its full 5 s.
fn walker(n: usize) -> Genome {
    let mut g = max();
    g.morphology.set_clamped(M::LegsPerSide, n as f64);
    if n != 3 {
        g.morphology.set_clamped(M::Motor0MaxSpeed, 0.2);
    }
    g
}

fn trials(c: &mut Criterion) {
    let ctx = EvalContext::paper();
    let mut group = c.benchmark_group("trial_static");
    group.throughput(Throughput::Elements(1));
    for n in [2, 3, 4, 6] {
        let g = walker(n);
        let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
        let end = run_trial(
            &plan,
            &Controller::static_default(),
            &ctx.settings,
            &ctx.limits,
            &mut (),
        );
        assert!(
            matches!(end, TrialEnd::Completed(_)),
            "{n} legs per side: {end:?}"
        );
        group.bench_with_input(BenchmarkId::new("legs_per_side", n), &plan, |b, plan| {
            b.iter(|| {
                run_trial(
                    plan,
                    &Controller::static_default(),
                    &ctx.settings,
                    &ctx.limits,
                    &mut (),
                )
            })
        });
    }
    group.finish();

    let mut group = c.benchmark_group("candidate");
    group.sample_size(10);
    let g = max();
    group.bench_function("max_es_20_iterations", |b| {
        b.iter(|| evaluate(&ctx, &g, Scheme::Es, CandidateSeed::new(0, 0)))
    });
    group.finish();
}

fn batch(c: &mut Criterion) {
    let ctx = EvalContext::paper();
    let jobs: Vec<Job> = (0..16)
        .map(|i| Job {
            genome: max(),
            scheme: Scheme::Static,
            seed: CandidateSeed::new(0, i),
            to_beat: None,
        })
        .collect();
    let mut group = c.benchmark_group("batch_16_max_trials");
    group.sample_size(10);
    group.throughput(Throughput::Elements(jobs.len() as u64));
    for threads in [1, 2] {
        group.bench_with_input(BenchmarkId::new("threads", threads), &threads, |b, &t| {
            b.iter(|| evaluate_batch(&ctx, &jobs, NonZeroUsize::new(t).unwrap()))
        });
    }
    group.finish();
}

criterion_group!(benches, trials, batch);
criterion_main!(benches);
