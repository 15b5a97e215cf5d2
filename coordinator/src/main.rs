//! `strider-coordinator`: owns the MAP-Elites library. `run` runs an experiment on this
//! machine (resuming from its database), `export` writes the library out, `check`
//! validates an experiment file. The gRPC service comes with the service issue.

use anyhow::{bail, Context};
use clap::{Parser, Subcommand, ValueEnum};
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use strider_common::params::{ParamKind, CONTROLLER_PARAMS, MORPHOLOGY_PARAMS};
use strider_common::Experiment;
use strider_coordinator::analysis::summary::{summarise, RunResult};
use strider_coordinator::db::{build_id, first_difference, Db};
use strider_coordinator::runner::run_experiment;
use strider_worker::batch::default_threads;

#[derive(Parser)]
#[command(
    name = "strider-coordinator",
    version,
    about = "Strider coordinator: runs MAP-Elites experiments"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum Format {
    Json,
    Csv,
}

#[derive(Subcommand)]
enum Command {
    /// Run an experiment on this machine, on all cores; resumes when the database exists.
    Run {
        /// Experiment file (TOML); the built-in quick experiment when left out.
        experiment: Option<PathBuf>,
        /// Database file.
        #[arg(long, default_value = "strider.db")]
        db: PathBuf,
        /// Evaluation threads (all cores by default).
        #[arg(long)]
        workers: Option<NonZeroUsize>,
    },
    /// Write every elite (cell, fitness, genome) and every generation's statistics.
    Export {
        /// Database file.
        #[arg(long)]
        db: PathBuf,
        /// Only this run (its id, from 0).
        #[arg(long)]
        run: Option<i64>,
        /// Output format.
        #[arg(long, value_enum, default_value = "json")]
        format: Format,
    },
    /// Summarise an experiment: final figures per scheme, Mann-Whitney tests between
    /// schemes, the top designs' mean features and controllers, and the design rules.
    Analyse {
        /// Database file.
        #[arg(long)]
        db: PathBuf,
    },
    /// Validate an experiment file and list the runs it defines.
    Check {
        /// Experiment file (TOML).
        experiment: PathBuf,
    },
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .context("starting the async runtime")
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Run {
            experiment,
            db,
            workers,
        } => runtime()?.block_on(run_locally(experiment.as_deref(), &db, workers)),
        Command::Export { db, run, format } => runtime()?.block_on(export(&db, run, format)),
        Command::Analyse { db } => runtime()?.block_on(analyse(&db)),
        Command::Check { experiment } => check(&experiment),
    }
}

async fn run_locally(
    file: Option<&Path>,
    path: &Path,
    workers: Option<NonZeroUsize>,
) -> anyhow::Result<()> {
    let given = match file {
        Some(f) => Some(Experiment::load(f)?),
        None => None,
    };
    let db = Db::open(path, true).await?;
    let experiment = match db.experiment().await? {
        Some((stored, build)) => {
            if let Some(given) = &given {
                if let Some(d) = first_difference(&stored, given) {
                    bail!(
                        "{} holds a different experiment ({d}); use another --db or the same file",
                        path.display()
                    );
                }
            }
            if build != build_id() {
                eprintln!("warning: {} was started by {build}; this is {}: trials are bit-identical only within one build", path.display(), build_id());
            }
            eprintln!(
                "resuming experiment `{}` from {}",
                stored.name,
                path.display()
            );
            stored
        }
        None => {
            let e = given.unwrap_or_else(|| {
                Experiment::from_toml(include_str!("../../experiments/quick.toml"))
                    .expect("the built-in quick experiment is valid")
            });
            db.create_experiment(&e).await?;
            eprintln!("starting experiment `{}` in {}", e.name, path.display());
            e
        }
    };
    let threads = workers.unwrap_or_else(default_threads);
    run_experiment(&db, &experiment, threads).await?;
    eprintln!(
        "experiment `{}` finished: `strider-coordinator export --db {}` writes the library",
        experiment.name,
        path.display()
    );
    Ok(())
}

/// Opens an existing database and its experiment, for reading.
async fn open_existing(path: &Path) -> anyhow::Result<(Db, Experiment)> {
    if !path.exists() {
        bail!("no database at {}", path.display());
    }
    let db = Db::open(path, false).await?;
    let (experiment, _) = db
        .experiment()
        .await?
        .context("the database holds no experiment")?;
    Ok((db, experiment))
}

async fn export(path: &Path, only: Option<i64>, format: Format) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs: Vec<_> = db
        .runs()
        .await?
        .into_iter()
        .filter(|r| only.is_none_or(|id| r.id == id))
        .collect();
    if let Some(id) = only {
        if runs.is_empty() {
            bail!("the database has no run {id}");
        }
    }
    match format {
        Format::Json => {
            let mut out = Vec::new();
            for r in &runs {
                let generations: Vec<_> = db
                    .generations(r.id)
                    .await?
                    .into_iter()
                    .map(|(g, evaluations, s)| serde_json::json!({"generation": g, "evaluations": evaluations, "stats": s}))
                    .collect();
                let elites: Vec<_> = r
                    .library
                    .elites()
                    .map(|(cell, e)| serde_json::json!({"cell": cell.0, "candidate": e.candidate.0, "fitness": e.fitness, "genome": e.genome}))
                    .collect();
                out.push(serde_json::json!({
                    "run": r.id, "scheme": r.spec.scheme.name(), "repeat": r.spec.repeat, "seed": r.spec.seed.0,
                    "generation": r.generation, "finished": r.finished, "generations": generations, "elites": elites,
                }));
            }
            println!(
                "{}",
                serde_json::to_string_pretty(
                    &serde_json::json!({"experiment": experiment.name, "runs": out})
                )?
            );
        }
        Format::Csv => {
            let mut header = String::from("run,scheme,repeat,cell,candidate,fitness");
            for p in MORPHOLOGY_PARAMS.iter().chain(CONTROLLER_PARAMS) {
                header.push(',');
                header.push_str(p.name);
            }
            println!("{header}");
            for r in &runs {
                for (cell, e) in r.library.elites() {
                    let mut line = format!(
                        "{},{},{},{},{},{}",
                        r.id, r.spec.scheme, r.spec.repeat, cell.0, e.candidate.0, e.fitness
                    );
                    let values = strider_common::genome::ParamVector::values(&e.genome.morphology)
                        .iter()
                        .zip(MORPHOLOGY_PARAMS)
                        .chain(
                            strider_common::genome::ParamVector::values(&e.genome.controller)
                                .iter()
                                .zip(CONTROLLER_PARAMS),
                        );
                    for (v, spec) in values {
                        match spec.kind {
                            ParamKind::Integer => line.push_str(&format!(",{}", *v as i64)),
                            ParamKind::Real => line.push_str(&format!(",{v}")),
                        }
                    }
                    println!("{line}");
                }
            }
        }
    }
    Ok(())
}

async fn analyse(path: &Path) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs = db.runs().await?;
    let mut results = Vec::new();
    for r in &runs {
        let Some((_, _, last)) = db.generations(r.id).await?.pop() else {
            continue; // no generation committed yet
        };
        results.push(RunResult {
            scheme: r.spec.scheme,
            library: &r.library,
            last,
        });
    }
    if results.is_empty() {
        bail!("no run has finished its initial population yet");
    }
    let unfinished = runs.iter().filter(|r| !r.finished).count();
    if unfinished > 0 {
        eprintln!("note: {unfinished} runs are not finished; figures are from their last committed generation");
    }
    print!(
        "{}",
        summarise(&results, &experiment.schemes, experiment.brief.payload)
    );
    Ok(())
}

fn check(path: &Path) -> anyhow::Result<()> {
    let e = Experiment::load(path)?;
    let runs = e.runs();
    println!(
        "experiment `{}`: {} runs; each {} initial designs, then {} generations of {} ({} offspring)",
        e.name,
        runs.len(),
        e.run.initial_population,
        e.run.generations,
        e.run.offspring_per_generation,
        e.offspring_per_run()
    );
    println!(
        "trial {} s at {} Hz control, physics step {:.5} s; brief: mass <= {} kg, height >= {} m, speed >= {} m/s, payload {} kg",
        e.run.trial_seconds,
        e.run.control_hz,
        e.run.physics_dt(),
        e.brief.max_mass,
        e.brief.min_height,
        e.brief.min_speed,
        e.brief.payload
    );
    for r in runs {
        println!(
            "  {:<7} repeat {:>3}  seed {}",
            r.scheme, r.repeat, r.seed.0
        );
    }
    Ok(())
}
