//! `verify`: a database checked against itself: every run replayed from its stored
//! candidates, every row against its checksum, a sample simulated again (with the
//! `simulator` feature).

use super::open::open_existing;
use super::Exit;
use crate::qd::changes::StoredCandidate;
use crate::service::reference::{computes_otherwise, this_machine_identity};
use std::collections::HashMap;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use strider_common::experiment::RunSpec;
use strider_common::RunId;
use strider_common::{Experiment, Outcome};
use strider_process::outln;

/// Arguments of `verify`.
#[derive(clap::Args)]
pub struct VerifyArgs {
    /// Database file (opened read-only; a copy or a backup will do).
    #[arg(long)]
    db: PathBuf,
    /// Candidates to simulate again, spread evenly over the stored ones (0: none).
    #[arg(long, default_value_t = 20)]
    sample: usize,
    /// Threads for the simulations (default: every core); --workers is the older name.
    #[arg(long, visible_alias = "workers", value_parser = strider_process::at_least_one)]
    threads: Option<NonZeroUsize>,
}

/// Replays, checks every row, simulates the sample again; says whether all agree.
pub async fn execute(args: VerifyArgs) -> anyhow::Result<Exit> {
    let (path, sample) = (args.db.as_path(), args.sample);
    let (db, experiment) = open_existing(path).await?;
    let made_by = db.experiment().await?.map(|(_, build)| build);
    let here = this_machine_identity();
    let other_build = made_by.as_deref().filter(|b| computes_otherwise(b, &here));
    if let Some(b) = other_build {
        eprintln!(
            "warning: {} was made by {b}; this is {here}: breeding and trials are bit-identical only within one build on one kind of node, so differences below may be the build's or the node's, not damage",
            path.display(),
        );
    }
    let runs = db.runs().await?;
    let candidates = db.candidates().await?;
    let mut verdict = crate::qd::verify::replay(&experiment, &runs, &candidates);
    outln!(
        "replayed {} of {} stored candidates over {}",
        verdict.replayed,
        candidates.len(),
        strider_process::count_words(runs.len(), "run")
    );
    // Every row against its checksum: damage that leaves the replay agreeing (an
    // outcome's figure that no placement depends on) still shows here.
    let damaged = db.checksum_mismatches(false).await?;
    outln!(
        "checked every candidate row against its checksum: {} damaged",
        damaged.len()
    );
    verdict.problems.extend(crate::db::damaged_rows(&damaged));
    // Each run's per-generation figures, which nothing downstream recomputes (curves,
    // the generations export): against their checksums, then against the replay's (a
    // run with a damaged row is named by the first and not read by the second).
    let damaged_generations = db.generation_checksum_mismatches().await?;
    outln!(
        "checked every generations row against its checksum: {} damaged",
        damaged_generations.len()
    );
    verdict
        .problems
        .extend(crate::db::damaged_generations(&damaged_generations));
    for (i, run) in runs.iter().enumerate() {
        if damaged_generations
            .iter()
            .any(|(r, _)| *r == crate::db::run_column(run.id))
        {
            continue;
        }
        let stored = db.generations(run.id).await?;
        let replayed = verdict.generations.get(i).map_or(&[][..], |g| &g[..]);
        verdict
            .problems
            .extend(crate::qd::verify::generation_problems(
                RunId::from_index(i),
                &stored,
                replayed,
            ));
    }
    outln!("checked every run's generations table against the replay");
    // The cheap checks a resume makes (each library cell against its candidate row, the
    // runs against the experiment): damage the replay does not read, such as an
    // infeasible cell's copy of its holder's standing.
    let cheap = db.inconsistencies(&experiment).await?;
    outln!("made the checks a resume makes: {} problems", cheap.len());
    verdict.problems.extend(cheap);
    // The cheap checks repeat the checksum findings above: each problem once.
    let mut seen = std::collections::HashSet::new();
    verdict.problems.retain(|p| seen.insert(p.clone()));
    // The step in flight (what a resume reads first): every row decodes and matches its
    // checksum, or the error names it.
    let pending = db.pending().await?;
    outln!("read the {} rows of the current steps", pending.len());
    // SQLite's own structure: pages, indexes, constraints (a flipped byte in a table's
    // b-tree that every query above happened to read past).
    let integrity = db.integrity_check().await?;
    if integrity != ["ok"] {
        verdict.problems.extend(
            integrity
                .iter()
                .take(5)
                .map(|line| format!("SQLite's integrity check: {line}")),
        );
    }
    outln!(
        "SQLite's integrity check: {}",
        if integrity == ["ok"] { "ok" } else { "failed" }
    );
    // Every k-th stored candidate whose outcome a worker computed (a candidate that
    // failed for want of a worker has nothing to reproduce).
    let eligible: Vec<&StoredCandidate> = candidates
        .iter()
        .filter(|c| {
            !matches!(
                c.outcome,
                Outcome::Invalid {
                    reason: strider_common::InvalidReason::EvaluationFailed { .. },
                    ..
                }
            )
        })
        .collect();
    let chosen: Vec<&StoredCandidate> = if sample == 0 || eligible.is_empty() {
        Vec::new()
    } else {
        let step = (eligible.len() as f64 / sample as f64).max(1.0);
        (0..sample.min(eligible.len()))
            .map(|i| eligible[(i as f64 * step) as usize])
            .collect()
    };
    if !chosen.is_empty() {
        let spec_of: HashMap<RunId, RunSpec> = runs.iter().map(|r| (r.id, r.spec)).collect();
        // Candidates of no run were reported by the replay; the rest, paired with their jobs.
        let chosen: Vec<_> = chosen
            .into_iter()
            .filter_map(|c| spec_of.get(&c.run).map(|spec| (c, *spec)))
            .collect();
        let Some(outcomes) = simulate_again(&experiment, &chosen, args.threads).await? else {
            eprintln!(
                "warning: {} stored candidates not simulated again: this strider-coordinator was built without the simulator (cargo feature `simulator`); run verify where a worker is built, or pass --sample 0",
                chosen.len()
            );
            return conclude(path, &verdict.problems, Some(chosen.len()));
        };
        let mut differ = 0;
        for ((c, _), o) in chosen.iter().zip(&outcomes) {
            let stored = serde_json::to_string(&c.outcome)?;
            let again = serde_json::to_string(o)?;
            if stored != again {
                differ += 1;
                if differ <= 5 {
                    verdict.problems.push(format!(
                        "run id {} candidate {}: simulated again it gives {again}, the database holds {stored}",
                        c.run, c.number.0
                    ));
                }
            }
        }
        outln!(
            "simulated {} stored candidates again: {} identical, {differ} different",
            chosen.len(),
            chosen.len() - differ
        );
    }
    conclude(path, &verdict.problems, None)
}

/// Prints the verdict; `not_simulated` counts the sample left unchecked for want of a
/// simulator, which the verdict then names.
fn conclude(
    path: &Path,
    problems: &[String],
    not_simulated: Option<usize>,
) -> anyhow::Result<Exit> {
    if problems.is_empty() {
        match not_simulated {
            None => outln!("{} agrees with itself", path.display()),
            Some(n) => outln!(
                "{} agrees with itself in its rows and replay; {n} sampled candidates were not simulated again (no simulator in this build)",
                path.display()
            ),
        }
        Ok(Exit::Success)
    } else {
        for p in problems {
            outln!("problem: {p}");
        }
        eprintln!(
            "error: {} does not agree with itself ({} problems above); resume from a backup, or start the experiment again",
            path.display(),
            problems.len()
        );
        Ok(Exit::Disagrees)
    }
}

/// The outcomes of the chosen candidates simulated again on this machine, in order.
#[cfg(feature = "simulator")]
async fn simulate_again(
    experiment: &Experiment,
    chosen: &[(&StoredCandidate, RunSpec)],
    workers: Option<NonZeroUsize>,
) -> anyhow::Result<Option<Vec<Outcome>>> {
    use anyhow::Context;
    use strider_common::rng::CandidateSeed;
    use strider_common::EvalContext;
    use strider_worker::batch::{evaluate_batch, Job};
    let jobs: Vec<Job> = chosen
        .iter()
        .map(|(c, spec)| Job {
            genome: c.genome,
            scheme: spec.scheme,
            seed: CandidateSeed::new(spec.seed.0, c.number.0),
            // An outranked design was answered at its trial's end, without its stay-up
            // window and confirming trials: simulated
            // again with the bar it was drawn with, or one as high (its own fitness; the
            // replay above checks that its cell's elite then was at least as fit).
            to_beat: match c.outcome {
                Outcome::Valid {
                    fitness,
                    outranked: true,
                    ..
                } => Some(fitness),
                _ => None,
            },
        })
        .collect();
    let ctx = EvalContext::of(experiment);
    let threads = workers.unwrap_or_else(strider_process::default_threads);
    let outcomes = tokio::task::spawn_blocking(move || evaluate_batch(&ctx, &jobs, threads))
        .await
        .context("simulating the sample")?;
    Ok(Some(outcomes))
}

/// Without the simulator: none.
#[cfg(not(feature = "simulator"))]
async fn simulate_again(
    _: &Experiment,
    _: &[(&StoredCandidate, RunSpec)],
    _: Option<NonZeroUsize>,
) -> anyhow::Result<Option<Vec<Outcome>>> {
    Ok(None)
}
