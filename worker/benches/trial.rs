//! Trial throughput: trials per second on one core by legs per side, one ES candidate, the
//! batch evaluator on one and two threads, and a confirmed candidate's answer with and
//! without an idle thread's help. Figures go to BENCHMARKS.md.

/// The binaries' allocator, so that the figures are theirs.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::num::NonZeroUsize;
use std::sync::Arc;
use strider_common::params::M;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::Outcome;
use strider_common::{BodyPlan, Controller, Genome, Scheme};
use strider_worker::batch::{evaluate_batch, Job};
use strider_worker::evaluate::evaluate;
use strider_worker::pool::{SimPool, Trial};
use strider_worker::sim::trial::{run_trial, TrialEnd};
use tokio::sync::Semaphore;

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

/// One design that passes every confirming trial (both floors and the finer step at the
/// defaults, 100 simulated seconds counted at 240 Hz; 60 without the finer step): its
/// answer alone on the calling thread, and from a pool of two simulation threads whose
/// other thread is idle and helps (strider_worker::help), as at the end of a generation or
/// on a worker with more cores than candidates.
fn confirmed(c: &mut Criterion) {
    let ctx = EvalContext::paper();
    let genome = Genome::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/walks_on_every_floor.json"),
    )
    .unwrap();
    let seed = CandidateSeed::new(0, 0);
    assert!(matches!(
        evaluate(&ctx, &genome, Scheme::Static, seed),
        Outcome::Valid { .. }
    ));
    let mut group = c.benchmark_group("confirmed_candidate");
    group.sample_size(10);
    group.bench_function("alone", |b| {
        b.iter(|| evaluate(&ctx, &genome, Scheme::Static, seed))
    });
    let pool = SimPool::new(NonZeroUsize::new(2).unwrap()).unwrap();
    let cores = Arc::new(Semaphore::new(2));
    group.bench_function("pool_of_2_one_idle", |b| {
        b.iter(|| {
            let (answer, answers) = flume::unbounded();
            pool.run(Trial {
                key: (),
                ctx,
                genome,
                scheme: Scheme::Static,
                seed,
                to_beat: None,
                later: false,
                core: cores.clone().try_acquire_owned().unwrap(),
                answer,
            });
            answers.recv().unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, trials, batch, confirmed);
criterion_main!(benches);
