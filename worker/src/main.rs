//! `strider-worker`: evaluates robot designs. `--connect URL` (or `--address-file F`)
//! works for a coordinator on every core; `eval` simulates one genome; `inspect`, `params` and `random` describe
//! genomes without simulating; `survey` measures how often random designs pass the brief.

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::io::Write;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use strider_common::drawing::{design_svg, filmstrip_svg, replay_svg};
use strider_common::inspect::Inspection;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::StartPose;
use strider_common::{BodyPlan, Controller, Experiment, Genome, Outcome, Scheme};
use strider_proto::process::{report, UsageError};
use strider_proto::terminal::Bar;
use strider_worker::batch::default_threads;
use strider_worker::client::{work, ConnectOptions, CoordinatorAddress, Evaluator, WorkerError};
use strider_worker::evaluate::{evaluate, evaluate_controller, EvalContext};
use strider_worker::replay::Replay;
use strider_worker::survey::Survey;
use strider_worker::trace::CsvTrace;

/// Writes a line to standard output and returns from the command on an error: a reader that
/// closed the pipe early (`| head`) ends the command quietly (`closed_pipe` in `main`).
macro_rules! outln {
    ($($t:tt)*) => { writeln!(std::io::stdout().lock(), $($t)*)? };
}

/// [`outln`] without the newline.
macro_rules! out {
    ($($t:tt)*) => { write!(std::io::stdout().lock(), $($t)*)? };
}

#[derive(Parser)]
#[command(
    name = "strider-worker",
    version,
    about = "Strider worker: evaluates robot designs"
)]
#[command(args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    connect: ConnectArgs,
}

/// Working for a coordinator.
#[derive(clap::Args)]
struct ConnectArgs {
    /// Work for the coordinator at this URL (e.g. http://host:50051) until its experiment
    /// is finished; retries with backoff while it is unreachable.
    #[arg(long, conflicts_with = "address_file")]
    connect: Option<String>,
    /// Work for the coordinator whose URL is the first line of this file (written by
    /// `serve --address-file`): waits for the file, and reads it again before every
    /// connection attempt, so it follows a coordinator that restarts elsewhere.
    #[arg(long)]
    address_file: Option<PathBuf>,
    /// File holding the shared secret (else the STRIDER_SECRET environment variable).
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// Trials at once (all cores by default).
    #[arg(long)]
    threads: Option<NonZeroUsize>,
    /// Name in the coordinator's logs (host name and process id by default).
    #[arg(long)]
    name: Option<String>,
    /// On SIGTERM, seconds running trials may take to finish before they are given back.
    #[arg(long, default_value_t = 10.0)]
    drain_seconds: f64,
    /// Longest wait, in seconds, between attempts to reach the coordinator.
    #[arg(long, default_value_t = 5.0)]
    max_backoff_seconds: f64,
    /// Exit with status 69 once no coordinator has had this worker connected for this many
    /// seconds (default: wait for ever). The Slurm script's one-job role uses it to end a
    /// job whose coordinator's node is lost.
    #[arg(long)]
    give_up_after: Option<f64>,
    /// BENCHMARK ONLY: answer every candidate instantly with a made-up result, to measure
    /// the coordinator. Never use for real runs.
    #[arg(long)]
    benchmark_instant_results: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate one genome and print its outcome.
    Eval {
        /// Genome file (.json or .toml).
        genome: PathBuf,
        /// Controller scheme: static (midpoint gait), genome (the file's gait) or es (tuned).
        #[arg(long, default_value = "static")]
        scheme: Scheme,
        /// Run seed (ES draws its mutations from it).
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Take settings, brief and features from this experiment file (paper defaults otherwise).
        #[arg(long)]
        experiment: Option<PathBuf>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Write a CSV trace (body pose, joint angles and torques per control step).
        #[arg(long)]
        trace: Option<PathBuf>,
        /// Write a drawing of the design (side, front and top views of its start pose, to
        /// scale, with a 1 m bar) as SVG.
        #[arg(long)]
        svg: Option<PathBuf>,
        /// Write a replay of the trial: an animated side view (SVG; opens in a browser).
        #[arg(long)]
        replay: Option<PathBuf>,
        /// Write the trial as a still picture (SVG): side, front and top views every half
        /// second and at the end.
        #[arg(long)]
        filmstrip: Option<PathBuf>,
    },
    /// Print a genome's masses, start-pose height, features, cell and static brief checks.
    Inspect {
        /// Genome file (.json or .toml).
        genome: PathBuf,
        /// Take the brief and feature grid from this experiment file (paper defaults otherwise).
        #[arg(long)]
        experiment: Option<PathBuf>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Write a genome's design as URDF (links with masses and inertias, revolute joints with
    /// axes and the motors' limits), for ROS, Gazebo, PyBullet or MuJoCo's importer.
    Urdf {
        /// Genome file (.json or .toml).
        genome: PathBuf,
        /// Where to write it.
        #[arg(long)]
        out: PathBuf,
        /// Take the payload from this experiment file (the paper's otherwise).
        #[arg(long)]
        experiment: Option<PathBuf>,
    },
    /// Print the genome's parameter table (Markdown): names, ranges, units, groups.
    Params,
    /// Print the random genome a run draws as candidate N (JSON).
    Random {
        /// Run seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Candidate number.
        #[arg(long, default_value_t = 0)]
        candidate: u64,
        /// Scheme (GENOME also draws a random controller).
        #[arg(long, default_value = "static")]
        scheme: Scheme,
    },
    /// Evaluate random genomes and report how often each constraint of the brief fails.
    Survey {
        /// Genomes to draw.
        #[arg(long, default_value_t = 1000)]
        count: usize,
        /// Controller scheme.
        #[arg(long, default_value = "static")]
        scheme: Scheme,
        /// Run seed the genomes are drawn from.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Threads (all cores by default).
        #[arg(long)]
        threads: Option<NonZeroUsize>,
        /// Take settings, brief and features from this experiment file (paper defaults otherwise).
        #[arg(long)]
        experiment: Option<PathBuf>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
        /// Also write one CSV row per design: its outcome, the figures computed without
        /// physics, and the cause found for a failure.
        #[arg(long)]
        csv: Option<PathBuf>,
    },
}

/// Exit status of a worker that gave up waiting for a coordinator (`--give-up-after`);
/// sysexits.h's EX_UNAVAILABLE.
const EXIT_GAVE_UP: u8 = 69;

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        // `survey | head`: the reader had enough; not an error.
        Err(e) if strider_worker::cli::closed_pipe(&e) => ExitCode::SUCCESS,
        Err(e) if matches!(e.downcast_ref(), Some(WorkerError::GaveUp(_))) => {
            report(e.as_ref());
            ExitCode::from(EXIT_GAVE_UP)
        }
        Err(e) => ExitCode::from(report(e.as_ref())),
    }
}

fn context(experiment: Option<&Path>) -> anyhow::Result<EvalContext> {
    Ok(match experiment {
        Some(path) => EvalContext::of(&Experiment::load(path)?),
        None => EvalContext::paper(),
    })
}

/// The secret from a file, else the environment; none if neither is given.
fn load_secret(file: Option<&Path>) -> anyhow::Result<Option<String>> {
    let text = match file {
        Some(f) => {
            std::fs::read_to_string(f).with_context(|| format!("secret file {}", f.display()))?
        }
        None => match std::env::var("STRIDER_SECRET") {
            Ok(s) => s,
            Err(_) => return Ok(None),
        },
    };
    let secret = text.lines().next().unwrap_or("").trim().to_string();
    anyhow::ensure!(!secret.is_empty(), "the secret is empty");
    Ok(Some(format!("Bearer {secret}")))
}

fn connect(args: ConnectArgs, coordinator: CoordinatorAddress) -> anyhow::Result<()> {
    strider_proto::process::init_logs().map_err(UsageError)?;
    if !(args.drain_seconds.is_finite() && args.drain_seconds >= 0.0) {
        return Err(UsageError(format!(
            "--drain-seconds: {} is not a number of seconds",
            args.drain_seconds
        ))
        .into());
    }
    let give_up_after = match args.give_up_after {
        None => None,
        Some(s) if s.is_finite() && s > 0.0 => Some(std::time::Duration::from_secs_f64(s)),
        Some(s) => {
            return Err(
                UsageError(format!("--give-up-after: {s} is not a number of seconds")).into(),
            )
        }
    };
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .unwrap_or_else(|_| "localhost".into());
    let opts = ConnectOptions {
        coordinator,
        authorization: load_secret(args.token_file.as_deref())?,
        threads: args.threads.unwrap_or_else(default_threads),
        name: args
            .name
            .unwrap_or_else(|| format!("{host} pid {}", std::process::id())),
        build: strider_common::build_id(),
        evaluator: if args.benchmark_instant_results {
            Evaluator::InstantSyntheticResults
        } else {
            Evaluator::Simulation
        },
        drain: std::time::Duration::from_secs_f64(args.drain_seconds),
        max_backoff: std::time::Duration::from_secs_f64(
            args.max_backoff_seconds.clamp(0.05, 600.0),
        ),
        give_up_after,
    };
    // One async thread moves the messages; trials run on the simulation threads.
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(async {
        let (stop, stopped) = tokio::sync::watch::channel(false);
        tokio::spawn(async move {
            use tokio::signal::unix::{signal, SignalKind};
            let mut term = signal(SignalKind::terminate()).expect("SIGTERM handler");
            tokio::select! {
                _ = term.recv() => {}
                _ = tokio::signal::ctrl_c() => {}
            }
            tracing::info!("asked to stop");
            let _ = stop.send(true);
        });
        work(opts, stopped).await
    })?;
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let Some(command) = cli.command else {
        let coordinator = match (&cli.connect.connect, &cli.connect.address_file) {
            (Some(url), _) => CoordinatorAddress::Url(url.clone()),
            (None, Some(file)) => CoordinatorAddress::File(file.clone()),
            (None, None) => {
                return Err(UsageError(
                    "nothing to do: pass --connect URL or --address-file FILE, or a command (see --help)"
                        .into(),
                )
                .into())
            }
        };
        return connect(cli.connect, coordinator);
    };
    match command {
        Command::Eval {
            genome,
            scheme,
            seed,
            experiment,
            json,
            trace,
            svg,
            replay,
            filmstrip,
        } => {
            let g = Genome::load(&genome)?;
            let ctx = context(experiment.as_deref())?;
            let cand = CandidateSeed::new(seed, 0);
            let outcome = evaluate(&ctx, &g, scheme, cand);
            if let Some(path) = trace {
                // Replay the reported controller with a trace attached (the trial is
                // deterministic, so this is the same trial).
                write_trace(&ctx, &g, outcome.controller(), &path)?;
            }
            let title = format!(
                "{} ({} scheme): {}",
                genome.file_name().unwrap_or_default().to_string_lossy(),
                scheme.name(),
                outcome_summary(&outcome)
            );
            if let Some(path) = svg {
                let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
                let pose = StartPose::new(&plan, outcome.controller());
                std::fs::write(&path, design_svg(&plan, &pose, &title))
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            if replay.is_some() || filmstrip.is_some() {
                let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
                let mut frames = Replay::default();
                evaluate_controller(&ctx, &g, &plan, outcome.controller(), &mut frames);
                if let Some(path) = replay {
                    std::fs::write(&path, replay_svg(&plan, &frames.frames, &title))
                        .with_context(|| format!("writing {}", path.display()))?;
                }
                if let Some(path) = filmstrip {
                    let stills = frames.every(0.5);
                    std::fs::write(&path, filmstrip_svg(&plan, &stills, &title))
                        .with_context(|| format!("writing {}", path.display()))?;
                }
            }
            if json {
                outln!(
                    "{}",
                    serde_json::to_string_pretty(&outcome).context("serialising the outcome")?
                );
            } else {
                print_outcome(&outcome)?;
            }
            Ok(())
        }
        Command::Inspect {
            genome,
            experiment,
            json,
        } => {
            let g = Genome::load(&genome)?;
            let ctx = context(experiment.as_deref())?;
            emit(&Inspection::of(&g, &ctx.brief, &ctx.grid), json)
        }
        Command::Urdf {
            genome,
            out,
            experiment,
        } => {
            let g = Genome::load(&genome)?;
            let ctx = context(experiment.as_deref())?;
            let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
            let name = genome
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("design");
            let pose = strider_common::urdf::write_files(name, &plan, &g.controller, &out)?;
            eprintln!(
                "{}: {:.2} kg, {} legs -> {} (start pose: {})",
                genome.display(),
                plan.total_mass(),
                plan.legs.len(),
                out.display(),
                pose.display()
            );
            Ok(())
        }
        Command::Survey {
            count,
            scheme,
            seed,
            threads,
            experiment,
            json,
            csv,
        } => {
            let ctx = context(experiment.as_deref())?;
            let threads = threads.unwrap_or_else(default_threads);
            // A bar on a terminal, else a line on stderr every 5 s (or so), with the rate
            // and what is left: a large survey runs for minutes.
            let started = std::time::Instant::now();
            let last = std::sync::Mutex::new(started);
            let bar = Bar::start(count as u64, "designs");
            let progress = |done: usize| {
                if let Some(bar) = &bar {
                    bar.set_position(done as u64);
                    let rate = done as f64 / started.elapsed().as_secs_f64().max(1e-9);
                    if done > 0 {
                        bar.set_message(format!(
                            "{rate:.0}/s, about {} left",
                            strider_proto::process::duration_words(
                                (count - done) as f64 / rate.max(1e-9)
                            )
                        ));
                    }
                    return;
                }
                let Ok(mut last) = last.try_lock() else {
                    return;
                };
                if last.elapsed() < std::time::Duration::from_secs(5) {
                    return;
                }
                *last = std::time::Instant::now();
                let seconds = started.elapsed().as_secs_f64();
                let rate = done as f64 / seconds;
                eprintln!(
                    "survey: {done} of {count} designs ({:.0} %), {rate:.0}/s, about {} left",
                    100.0 * done as f64 / count as f64,
                    strider_proto::process::duration_words((count - done) as f64 / rate.max(1e-9))
                );
            };
            let survey = Survey::run(&ctx, scheme, seed, count, threads, &progress);
            drop(bar);
            if let Some(path) = csv {
                let file = std::fs::File::create(&path)
                    .with_context(|| format!("creating {}", path.display()))?;
                let mut out = std::io::BufWriter::new(file);
                survey
                    .write_csv(&mut out)
                    .and_then(|()| std::io::Write::flush(&mut out))
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            emit(&survey, json)
        }
        Command::Random {
            seed,
            candidate,
            scheme,
        } => {
            let mut rng = CandidateSeed::new(seed, candidate).rng(Purpose::RandomGenome);
            outln!("{}", Genome::random(scheme, &mut rng).to_json_pretty());
            Ok(())
        }
        Command::Params => {
            out!("{}", strider_common::params::markdown_table());
            Ok(())
        }
    }
}

/// Prints a report as pretty JSON or as its table.
fn emit<T: serde::Serialize + std::fmt::Display>(report: &T, json: bool) -> anyhow::Result<()> {
    if json {
        outln!(
            "{}",
            serde_json::to_string_pretty(report).context("serialising the report")?
        );
    } else {
        outln!("{report}");
    }
    Ok(())
}

fn write_trace(
    ctx: &EvalContext,
    g: &Genome,
    controller: &Controller,
    path: &Path,
) -> anyhow::Result<()> {
    let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
    let file = std::fs::File::create(path)
        .with_context(|| format!("creating trace file {}", path.display()))?;
    let mut trace = CsvTrace::new(std::io::BufWriter::new(file), &plan)?;
    evaluate_controller(ctx, g, &plan, controller, &mut trace);
    trace
        .finish()
        .with_context(|| format!("writing trace file {}", path.display()))
}

/// One line about an outcome, for drawing titles.
fn outcome_summary(o: &Outcome) -> String {
    match (o.fitness(), o.stats()) {
        (Some(f), Some(s)) => format!("fitness {f:.3}, {:.1} kg, {:.2} m/s", s.mass, s.speed),
        (None, Some(s)) => format!("{}, {:.1} kg, {:.2} m/s", o.kind(), s.mass, s.speed),
        _ => o.kind().to_string(),
    }
}

fn print_outcome(o: &Outcome) -> anyhow::Result<()> {
    outln!("outcome          {}", o.kind());
    if let Some(s) = o.stats() {
        outln!("distance         {:.3} m", s.distance);
        outln!("speed            {:.3} m/s", s.speed);
        outln!("energy           {:.1} J", s.energy);
        outln!("cost of transport {:.4}", s.cost_of_transport);
        outln!("mass             {:.2} kg", s.mass);
    }
    match o {
        Outcome::Valid {
            fitness,
            features,
            cell,
            ..
        } => {
            outln!("fitness          {fitness:.4}");
            outln!("features         {:?}", features.0);
            outln!("cell             {}", cell.0);
        }
        Outcome::Rejected { violations, .. } => {
            for v in violations {
                outln!("rejected         {v}");
            }
        }
        Outcome::Invalid {
            reason, at_time, ..
        } => {
            outln!("invalid          {reason} at t = {at_time:.3} s");
        }
    }
    let c = o.controller();
    outln!(
        "controller       {}",
        serde_json::to_string(c).expect("controller serialises")
    );
    Ok(())
}
