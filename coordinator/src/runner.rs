//! Runs an experiment on this machine: every unfinished run advances one step per round
//! (a batch of its initial population, or one generation), all runs' candidates evaluated
//! together on all cores, each run's step committed in one transaction.
//!
//! Reproducibility: a candidate is a pure function of (run seed, candidate number, the
//! library it was bred from); results are applied in candidate order; the initial
//! population stops at the candidate that brings the passes to the target, whatever the
//! batch size. So the library does not depend on thread count, timing, or restarts.

use crate::db::{CandidateRow, Db, DbError, RunRecord};
use crate::evolution::{initial_candidate, offspring};
use crate::library::{GenerationStats, Placement};
use std::num::NonZeroUsize;
use std::time::Instant;
use strider_common::rng::{CandidateNumber, CandidateSeed};
use strider_common::{Experiment, Genome, Outcome};
use strider_worker::batch::{evaluate_batch, Job};
use strider_worker::evaluate::EvalContext;

/// Initial-population candidates drawn per run per round (most are rejected without a
/// trial, so batches are large). Does not affect results.
pub const INITIAL_BATCH: u64 = 256;

/// Drives an experiment stored in `db` to completion.
pub async fn run_experiment(
    db: &Db,
    experiment: &Experiment,
    threads: NonZeroUsize,
) -> Result<(), DbError> {
    let ctx = EvalContext::of(experiment);
    let mut runs = db.runs().await?;
    let started = Instant::now();
    let mut evaluated_total = 0usize;
    let mut evaluating = std::time::Duration::ZERO;
    loop {
        let active: Vec<usize> = (0..runs.len()).filter(|&i| !runs[i].finished).collect();
        if active.is_empty() {
            break;
        }
        // Every active run's next step, evaluated together.
        let plans: Vec<(usize, Vec<Job>)> = active
            .iter()
            .map(|&i| (i, next_jobs(&runs[i], experiment)))
            .collect();
        let all: Vec<Job> = plans
            .iter()
            .flat_map(|(_, jobs)| jobs.iter().copied())
            .collect();
        let evaluation = Instant::now();
        let outcomes = tokio::task::spawn_blocking(move || evaluate_batch(&ctx, &all, threads))
            .await
            .expect("the evaluator thread does not panic");
        evaluating += evaluation.elapsed();
        let mut offset = 0;
        for (i, jobs) in plans {
            let outs = &outcomes[offset..offset + jobs.len()];
            offset += jobs.len();
            evaluated_total += apply_step(db, &mut runs[i], experiment, &jobs, outs).await?;
        }
        progress(&runs, experiment, evaluated_total, started);
    }
    let wall = started.elapsed().as_secs_f64();
    eprintln!(
        "{evaluated_total} candidates in {wall:.1} s; evaluating {:.1} % of the time, the rest breeding and committing",
        100.0 * evaluating.as_secs_f64() / wall.max(1e-9)
    );
    Ok(())
}

/// The jobs of a run's next step.
fn next_jobs(run: &RunRecord, e: &Experiment) -> Vec<Job> {
    let scheme = run.spec.scheme;
    let seed = |n: u64| CandidateSeed::new(run.spec.seed.0, n);
    if run.initial_passed < e.run.initial_population {
        (run.next_candidate..run.next_candidate + INITIAL_BATCH)
            .map(|n| Job {
                genome: initial_candidate(scheme, seed(n)),
                scheme,
                seed: seed(n),
            })
            .collect()
    } else {
        let count = u64::from(e.run.offspring_per_generation);
        (run.next_candidate..run.next_candidate + count)
            .map(|n| Job {
                genome: offspring(&run.library, scheme, &e.mutation, seed(n))
                    .expect("the library holds the initial population"),
                scheme,
                seed: seed(n),
            })
            .collect()
    }
}

/// Applies a run's evaluated step in candidate order and commits it; returns how many
/// candidates it kept.
async fn apply_step(
    db: &Db,
    run: &mut RunRecord,
    e: &Experiment,
    jobs: &[Job],
    outcomes: &[Outcome],
) -> Result<usize, DbError> {
    let target = e.run.initial_population;
    let initial = run.initial_passed < target;
    let generation = if initial { 0 } else { run.generation + 1 };
    let mut rows: Vec<(CandidateNumber, &Genome, &Outcome, Placement)> =
        Vec::with_capacity(jobs.len());
    let mut stats = GenerationStats::default();
    for (job, outcome) in jobs.iter().zip(outcomes) {
        let number = job.seed.candidate;
        let placement = run.library.apply(number, &job.genome, outcome);
        rows.push((number, &job.genome, outcome, placement));
        stats.record(placement);
        if initial && outcome.fitness().is_some() {
            run.initial_passed += 1;
            if run.initial_passed == target {
                // The initial population ends here; later draws of this batch are dropped.
                break;
            }
        }
    }
    run.next_candidate = rows.last().map_or(run.next_candidate, |r| r.0 .0 + 1);
    let completed = if initial {
        (run.initial_passed == target).then_some(0)
    } else {
        Some(generation)
    };
    if let Some(g) = completed {
        run.generation = g;
        run.finished = g == e.run.generations;
        stats = run.library.summary(stats, e.features.cell_count());
    }
    let candidates: Vec<CandidateRow<'_>> = rows
        .iter()
        .map(|&(number, genome, outcome, placement)| CandidateRow {
            number,
            generation,
            genome,
            outcome,
            placement,
        })
        .collect();
    db.commit(run, &candidates, completed.map(|g| (g, stats)))
        .await?;
    Ok(candidates.len())
}

/// One progress line per round, on stderr.
fn progress(runs: &[RunRecord], e: &Experiment, evaluated: usize, started: Instant) {
    let secs = started.elapsed().as_secs_f64();
    let mut line = format!(
        "[{secs:7.1} s] {evaluated} evaluated ({:.1}/s)",
        evaluated as f64 / secs.max(1e-9)
    );
    for r in runs {
        let best = r
            .library
            .elites()
            .map(|(_, el)| el.fitness)
            .fold(0.0, f64::max);
        let phase = if r.initial_passed < e.run.initial_population {
            format!("initial {}/{}", r.initial_passed, e.run.initial_population)
        } else {
            format!("generation {}/{}", r.generation, e.run.generations)
        };
        line.push_str(&format!(
            " | run {} {}#{}: {phase}, {} elites, best {best:.4}",
            r.id,
            r.spec.scheme,
            r.spec.repeat,
            r.library.len()
        ));
    }
    eprintln!("{line}");
}
