//! The coordinator's per-candidate check (body plan, start pose, mass and height limits):
//! it runs on every candidate bred, under the scheduler's lock, so it bounds how many
//! results per second one coordinator accepts. Figures go to BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rand::SeedableRng;
use strider_common::precheck::precheck;
use strider_common::EvalContext;
use strider_common::{BodyPlan, Genome, Scheme};

fn genomes(scheme: Scheme) -> Vec<Genome> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    (0..1000)
        .map(|_| Genome::random(scheme, &mut rng))
        .collect()
}

fn prechecks(c: &mut Criterion) {
    let ctx = EvalContext::paper();
    let mut group = c.benchmark_group("precheck");
    for scheme in [Scheme::Static, Scheme::Genome] {
        let gs = genomes(scheme);
        group.throughput(Throughput::Elements(gs.len() as u64));
        group.bench_function(format!("{}_1000_random", scheme.name()), |b| {
            b.iter(|| {
                gs.iter()
                    .filter(|g| precheck(&ctx, g, scheme).is_some())
                    .count()
            })
        });
    }
    let gs = genomes(Scheme::Static);
    group.bench_function("body_plan_1000_random", |b| {
        b.iter(|| {
            gs.iter()
                .map(|g| BodyPlan::new(&g.morphology, ctx.brief.payload).legs.len())
                .sum::<usize>()
        })
    });
    group.finish();
}

criterion_group!(benches, prechecks);
criterion_main!(benches);
