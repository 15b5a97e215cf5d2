//! `report`: the experiment's report, one HTML page with its pictures (SVG and PNG) and
//! tables (CSV).

use super::open::open_existing;
use super::Exit;
use crate::db::{Db, EliteFilter};
use crate::results::report::designs::{self, DesignTrial, DesignTrials, Library};
use crate::results::report::{png, Inputs, RunData};
use anyhow::{bail, Context};
use std::path::PathBuf;
use strider_common::Experiment;
use strider_common::RunId;
use strider_process::files::Outputs;

/// Arguments of `report`.
#[derive(clap::Args)]
pub struct ReportArgs {
    /// Database file.
    #[arg(long)]
    db: PathBuf,
    /// Directory to write into (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// The run whose library is drawn (its id; the one with the best design by default).
    /// Its designs are the ones the page's table, scatter and cards hold.
    #[arg(long)]
    run: Option<RunId>,
    /// How many of the drawn run's fittest feasible designs, and of its nearest near
    /// misses, get an animated replay on their design card (every design gets its motor
    /// sizing from a replay of its trial).
    #[arg(long, default_value_t = 10)]
    replays: usize,
    /// Threads to replay trials on (all cores by default).
    #[arg(long, value_parser = strider_process::at_least_one)]
    threads: Option<std::num::NonZeroUsize>,
}

/// Writes the report into `--out`.
pub async fn execute(args: ReportArgs) -> anyhow::Result<Exit> {
    let (path, out, run) = (args.db.as_path(), args.out.as_path(), args.run);
    let (db, experiment) = open_existing(path).await?;
    let mut runs = Vec::new();
    for r in db.runs().await? {
        let stored = db.generations(r.id).await?;
        let evaluations = stored
            .iter()
            .scan(0, |total, (_, n, _)| {
                *total += n;
                Some(*total)
            })
            .collect();
        let generations = stored.into_iter().map(|(g, _, s)| (g, s)).collect();
        runs.push(RunData {
            id: r.id,
            scheme: r.spec.scheme,
            repeat: r.spec.repeat,
            library: r.library,
            infeasible: r.infeasible,
            generations,
            evaluations,
        });
    }
    if let Some(id) = run {
        if !runs.iter().any(|r| r.id == id) {
            bail!("the database has no run {id}");
        }
    }
    let chosen = run.unwrap_or_else(|| {
        runs.iter()
            .flat_map(|r| r.library.elites().map(move |(_, e)| (r.id, e.fitness)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(RunId(0), |(id, _)| id)
    });
    let trials = match runs.iter().find(|r| r.id == chosen) {
        Some(run) => Some(design_trials(&db, &experiment, run, args.replays, args.threads).await?),
        None => None,
    };
    let max = strider_common::reference::max();
    let report = crate::results::report::build(&Inputs {
        experiment: &experiment,
        runs: &runs,
        chosen,
        reference: Some((&max, "MAX")),
        trials: trials.as_ref(),
    });
    // Every file is written, or none (the directories this command made are removed
    // again); everything that can fail before writing (the PNG pictures) is done first.
    let mut files = Outputs::new();
    files.add(out.join("report.html"), report.html.as_bytes());
    let fonts = png::fonts();
    if fonts.is_empty() {
        eprintln!("warning: no system fonts found: the PNG pictures will have no text (the SVG and HTML are complete); install fonts-dejavu-core");
    }
    for p in &report.pictures {
        files.add(out.join(format!("{}.svg", p.name)), p.svg.as_bytes());
        files.add(
            out.join(format!("{}.png", p.name)),
            png::render(&p.svg, &fonts)?,
        );
    }
    for t in &report.tables {
        files.add(out.join(format!("{}.csv", t.name)), t.csv.as_bytes());
    }
    for f in &report.files {
        files.add(out.join(&f.path), f.bytes.as_slice());
    }
    // The experiment beside the designs, so that any card's replay command runs as is.
    let experiment_file = crate::db::canonical_toml(&experiment);
    let folder = out.join(designs::FOLDER);
    if !report.files.is_empty() {
        files.add(folder.join("experiment.toml"), experiment_file.as_bytes());
    }
    let made_out = !out.exists();
    let made_folder = !report.files.is_empty() && !folder.exists();
    let written = std::fs::create_dir_all(out)
        .with_context(|| format!("creating {}", out.display()))
        .and_then(|()| {
            if made_folder {
                std::fs::create_dir_all(&folder)
                    .with_context(|| format!("creating {}", folder.display()))?;
            }
            Ok(files.commit()?)
        });
    if let Err(e) = written {
        // Only directories this command made, and only if empty (remove_dir refuses
        // otherwise).
        if made_folder {
            let _ = std::fs::remove_dir(&folder);
        }
        if made_out {
            let _ = std::fs::remove_dir(out);
        }
        return Err(e);
    }
    eprintln!(
        "wrote {} ({} pictures as SVG and PNG, {} tables as CSV, {} files of {} designs in {}/)",
        out.join("report.html").display(),
        report.pictures.len(),
        report.tables.len(),
        report.files.len(),
        trials.as_ref().map_or(0, |t| t.designs.len()),
        designs::FOLDER
    );
    Ok(Exit::Success)
}

/// The drawn run's stored outcomes, and what replaying each design's trial measures: its
/// motors' loads, and for the `replays` fittest feasible designs and nearest near misses
/// an animated replay.
async fn design_trials(
    db: &Db,
    experiment: &Experiment,
    run: &RunData,
    replays: usize,
    threads: Option<std::num::NonZeroUsize>,
) -> anyhow::Result<DesignTrials> {
    let mut trials = DesignTrials {
        replays,
        ..DesignTrials::default()
    };
    let filter = EliteFilter {
        run: Some(run.id),
        ..EliteFilter::default()
    };
    for e in db.list_elites(&filter, 0, u32::MAX).await? {
        trials.designs.insert(
            (Library::Feasible, e.cell),
            DesignTrial {
                outcome: Some(e.outcome),
                ..DesignTrial::default()
            },
        );
    }
    for e in db.list_infeasible(run.id).await? {
        trials.designs.insert(
            (Library::Infeasible, e.cell),
            DesignTrial {
                outcome: Some(e.outcome),
                ..DesignTrial::default()
            },
        );
    }
    replay(experiment, run, &mut trials, threads).await?;
    Ok(trials)
}

/// Replays every design of the run (motor sizing) and animates the chosen few.
#[cfg(feature = "simulator")]
async fn replay(
    experiment: &Experiment,
    run: &RunData,
    trials: &mut DesignTrials,
    threads: Option<std::num::NonZeroUsize>,
) -> anyhow::Result<()> {
    use strider_common::drawing::replay_svg;
    use strider_common::{BodyPlan, EvalContext};
    let mut fittest: Vec<_> = run.library.elites().collect();
    fittest.sort_by(|a, b| b.1.fitness.total_cmp(&a.1.fitness));
    let mut nearest: Vec<_> = run.infeasible.elites().collect();
    nearest.sort_by_key(|n| std::cmp::Reverse(n.1.standing));
    let animated: std::collections::HashSet<(Library, strider_common::CellIndex)> = fittest
        .iter()
        .take(trials.replays)
        .map(|(c, _)| (Library::Feasible, *c))
        .chain(
            nearest
                .iter()
                .take(trials.replays)
                .map(|(c, _)| (Library::Infeasible, *c)),
        )
        .collect();
    let jobs: Vec<(
        Library,
        strider_common::CellIndex,
        strider_common::Genome,
        bool,
    )> = run
        .library
        .elites()
        .map(|(c, e)| (Library::Feasible, c, e.genome))
        .chain(
            run.infeasible
                .elites()
                .map(|(c, e)| (Library::Infeasible, c, e.genome)),
        )
        .map(|(l, c, g)| (l, c, g, animated.contains(&(l, c))))
        .collect();
    eprintln!(
        "replaying the {} designs of run {} (motor sizing; {} animated)",
        jobs.len(),
        run.id,
        animated.len()
    );
    let ctx = EvalContext::of(experiment);
    let threads = threads.unwrap_or_else(strider_process::default_threads);
    let payload = experiment.brief.payload;
    let trial_seconds = experiment.run.trial_seconds;
    let run_id = run.id;
    let measured = tokio::task::spawn_blocking(move || {
        // About a quarter of a second of CPU a design: minutes for a large run, so it says
        // how far it is (a bar on a terminal, a line each quarter elsewhere).
        let total = jobs.len();
        let bar = strider_process::terminal::Bar::start(total as u64, "designs");
        let done = std::sync::atomic::AtomicUsize::new(0);
        strider_worker::batch::map_batch(&jobs, threads, |(library, cell, genome, animate)| {
            let m = strider_worker::replay::measure(&ctx, genome, animate.then_some(0.1));
            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            match &bar {
                Some(bar) => bar.set_position(n as u64),
                None if total >= 200 && (4 * n / total) > (4 * (n - 1) / total) => {
                    eprintln!("replayed {n} of {total} designs of run {run_id}");
                }
                None => {}
            }
            let replay = m.frames.map(|mut frames| {
                // The trial and a second after it: the 15-s stay-up window after a
                // feasible trial made the picture 4,000 px wide (26 m walked).
                frames.retain(|f| f.time <= trial_seconds + 1.0 + 1e-9);
                let plan = BodyPlan::new(&genome.morphology, payload);
                let near = if *library == Library::Infeasible {
                    " (near miss)"
                } else {
                    ""
                };
                replay_svg(
                    &plan,
                    &frames,
                    &format!(
                        "run {run_id} cell {}{near}: its trial and the second after",
                        cell.0
                    ),
                )
            });
            ((*library, *cell), m.motors, replay)
        })
    })
    .await
    .context("replaying the designs")?;
    for (key, motors, replay) in measured {
        let t = trials.designs.entry(key).or_default();
        t.motors = Some(motors);
        t.replay = replay;
    }
    Ok(())
}

/// Without the simulator: no replays, and the page says why.
#[cfg(not(feature = "simulator"))]
async fn replay(
    _: &Experiment,
    _: &RunData,
    trials: &mut DesignTrials,
    _: Option<std::num::NonZeroUsize>,
) -> anyhow::Result<()> {
    trials.missing = Some("This strider-coordinator was built without the simulator (cargo feature <code>simulator</code>): the design cards have no replay or motor sizing; make the report where a worker is built.".into());
    Ok(())
}
