//! `strider-coordinator`: owns the MAP-Elites library. `run` runs an experiment on this
//! machine, `serve` serves it to workers over gRPC (both resume from their database),
//! `status` asks a running coordinator for progress, `export` and `analyse` read the
//! library, `check` validates an experiment file.

use anyhow::{bail, Context};
use clap::{Parser, Subcommand, ValueEnum};
use std::collections::HashMap;
use std::io::Write;
use std::net::SocketAddr;
use std::num::NonZeroUsize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use strider_common::Experiment;
use strider_common::Genome;
use strider_common::{BodyPlan, CellIndex, Outcome};
use strider_coordinator::analysis::summary::{summarise, RunResult};
use strider_coordinator::db::{build_id, first_difference, Db, EliteFilter, RunRecord};
use strider_coordinator::export::{self, EliteChoice};
use strider_coordinator::report::{png, Inputs, RunData};
use strider_coordinator::service::auth::Secret;
use strider_coordinator::service::local::run_local;
use strider_coordinator::service::server::{serve, Backup, Ended, ServeOptions};
use strider_proto::process::{UsageError, EXIT_FAILURE};
use strider_worker::batch::default_threads;
use strider_worker::cli::closed_pipe;

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
    /// Everything: elites, infeasible elites and per-generation statistics.
    Json,
    /// One row per elite: features, trial figures and genome.
    Csv,
    /// One row per run and generation: the library's statistics.
    GenerationsCsv,
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
        /// Seconds between progress lines.
        #[arg(long, default_value_t = 10.0)]
        progress_every: f64,
    },
    /// Serve an experiment to workers over gRPC; resumes when the database exists. Stops
    /// when every run is finished (or on SIGTERM / Ctrl-C), everything committed.
    Serve {
        /// Database file (created with --experiment when missing).
        #[arg(long)]
        db: PathBuf,
        /// Experiment file: needed to start; when resuming it must match the database.
        #[arg(long)]
        experiment: Option<PathBuf>,
        /// Address to listen on.
        #[arg(long, default_value = "0.0.0.0:50051")]
        listen: SocketAddr,
        /// File holding the shared secret (else the STRIDER_SECRET environment variable).
        #[arg(long)]
        token_file: Option<PathBuf>,
        /// Write the URL workers should connect to here once listening (atomically).
        #[arg(long)]
        address_file: Option<PathBuf>,
        /// Seconds a lease lasts without a heartbeat.
        #[arg(long, default_value_t = 60.0)]
        lease_seconds: f64,
        /// Workers that may die while simulating a candidate before it is marked failed.
        #[arg(long, default_value_t = 3)]
        max_attempts: u32,
        /// Seconds between progress lines.
        #[arg(long, default_value_t = 10.0)]
        progress_every: f64,
        /// Keep serving clients after every run is finished (until SIGTERM).
        #[arg(long)]
        keep_serving: bool,
        /// Serve Prometheus metrics on this address (GET /metrics; no secret, aggregate
        /// numbers only).
        #[arg(long)]
        metrics: Option<SocketAddr>,
        /// Stop handing out candidates after this many seconds and exit once every lease
        /// is back (set it below a batch job's time limit by the longest trial).
        #[arg(long)]
        stop_leasing_after: Option<f64>,
        /// Keep a safe copy of the database here (for example on shared storage while
        /// --db is on local disk): rewritten whole every --backup-every seconds and on exit.
        #[arg(long)]
        backup: Option<PathBuf>,
        /// Seconds between copies to --backup.
        #[arg(long, default_value_t = 600.0, requires = "backup")]
        backup_every: f64,
        /// Seconds a new connection has to make a call with the secret before it is closed
        /// (connections that never do would otherwise hold a file descriptor each, for
        /// ever; a health probe's lasts this long).
        #[arg(long, default_value_t = 10.0)]
        handshake_seconds: f64,
    },
    /// Print the progress of every run of a running coordinator.
    Status {
        /// The coordinator, e.g. http://host:50051.
        #[arg(long)]
        connect: String,
        /// File holding the shared secret (else the STRIDER_SECRET environment variable).
        #[arg(long)]
        token_file: Option<PathBuf>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
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
        /// One elite instead of all: RUN:CELL, or `best` (of --run, or of the experiment).
        /// Alone, its genome file (JSON, as `strider-worker eval` and `inspect` read it) is
        /// written to standard output (or to --genome FILE); with --urdf, its design as URDF.
        #[arg(long)]
        elite: Option<EliteChoice>,
        /// Write the chosen elite's genome file here instead of to standard output.
        #[arg(long, requires = "elite", conflicts_with = "urdf")]
        genome: Option<PathBuf>,
        /// Write the chosen elite's design here as URDF (links with masses and inertias,
        /// revolute joints with axes and the motors' limits).
        #[arg(long, requires = "elite")]
        urdf: Option<PathBuf>,
    },
    /// Write the experiment's report: one self-contained HTML page, its pictures as SVG and
    /// PNG, its tables as CSV.
    Report {
        /// Database file.
        #[arg(long)]
        db: PathBuf,
        /// Directory to write into (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// The run whose library is drawn (its id; the one with the best design by default).
        #[arg(long)]
        run: Option<i64>,
    },
    /// Check a database against itself: replay every run from its stored candidates (each
    /// genome must be the one its run draws, and the libraries and positions must come out
    /// as stored), then simulate a sample of the stored candidates again (outcomes must
    /// match bit for bit). Exit 0 when all agree, 1 naming where they part.
    Verify {
        /// Database file (opened read-only; a copy or a backup will do).
        #[arg(long)]
        db: PathBuf,
        /// Candidates to simulate again, spread evenly over the stored ones (0: none).
        #[arg(long, default_value_t = 20)]
        sample: usize,
        /// Threads for the simulations (default: every core).
        #[arg(long)]
        workers: Option<NonZeroUsize>,
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
        /// Skip the second of full-length trials that measures this machine's speed (the
        /// cost is then estimated from a figure measured on the development machine).
        #[arg(long)]
        no_calibration: bool,
    },
}

/// `serve`'s exit status when it stopped for `--stop-leasing-after` before the experiment
/// finished (EX_TEMPFAIL: serve again on the same database to go on).
const EXIT_NOT_FINISHED: u8 = 75;

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(code) => code,
        // `export ... | head`: the reader had enough; not an error.
        Err(e) if closed_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => ExitCode::from(strider_proto::process::report(e.as_ref())),
    }
}

/// One thread for `run` and the offline commands: there the async work is moving a few
/// messages per trial between threads that simulate on every core, and each extra thread
/// woken per message preempts a simulation (BENCHMARKS.md, `run` against the evaluator).
fn local_runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")
}

/// `serve`: the service's own cores, up to four (SQLite's writer has its own thread).
fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    let threads = default_threads().get().clamp(1, 4);
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(threads)
        .enable_all()
        .build()
        .context("starting the async runtime")
}

fn init_logs() -> anyhow::Result<()> {
    strider_proto::process::init_logs().map_err(|e| UsageError(e).into())
}

fn seconds(name: &str, s: f64) -> anyhow::Result<Duration> {
    if !(s.is_finite() && s > 0.0) {
        return Err(
            UsageError(format!("--{name}: {s} is not a positive number of seconds")).into(),
        );
    }
    Ok(Duration::from_secs_f64(s))
}

/// The signal that asked the process to stop (0 before one came).
static STOPPED_BY: std::sync::atomic::AtomicI32 = std::sync::atomic::AtomicI32::new(0);

/// Completes on SIGTERM or Ctrl-C (SIGINT), noting which in [`STOPPED_BY`].
async fn stop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        let mut term = signal(SignalKind::terminate()).expect("SIGTERM handler");
        let sig = tokio::select! {
            _ = term.recv() => 15,
            _ = tokio::signal::ctrl_c() => 2,
        };
        STOPPED_BY.store(sig, std::sync::atomic::Ordering::Relaxed);
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
        STOPPED_BY.store(2, std::sync::atomic::Ordering::Relaxed);
    }
    tracing::info!("asked to stop: committing and shutting down");
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    let done: anyhow::Result<()> = match cli.command {
        Command::Run {
            experiment,
            db,
            workers,
            progress_every,
        } => {
            init_logs()?;
            let every = seconds("progress-every", progress_every)?;
            return local_runtime()?.block_on(run_locally(
                experiment.as_deref(),
                &db,
                workers,
                every,
            ));
        }
        Command::Serve {
            db,
            experiment,
            listen,
            token_file,
            address_file,
            lease_seconds,
            max_attempts,
            progress_every,
            keep_serving,
            metrics,
            stop_leasing_after,
            backup,
            backup_every,
            handshake_seconds,
        } => {
            init_logs()?;
            let secret = Secret::load(token_file.as_deref())?;
            if max_attempts == 0 {
                return Err(UsageError("--max-attempts: must be at least 1".into()).into());
            }
            let opts = ServeOptions {
                lease: seconds("lease-seconds", lease_seconds)?,
                max_attempts,
                progress_every: Some(seconds("progress-every", progress_every)?),
                keep_serving,
                address_file,
                metrics,
                stop_leasing_after: stop_leasing_after
                    .map(|s| seconds("stop-leasing-after", s))
                    .transpose()?,
                backup: match backup {
                    Some(path) => {
                        if same_file(&path, &db) {
                            return Err(UsageError(format!(
                                "--backup {}: that is the database itself",
                                path.display()
                            ))
                            .into());
                        }
                        Some(Backup {
                            path,
                            every: seconds("backup-every", backup_every)?,
                        })
                    }
                    None => None,
                },
                handshake: seconds("handshake-seconds", handshake_seconds)?,
            };
            let ended = runtime()?.block_on(async {
                let (db, experiment) = open_or_create(experiment.as_deref(), &db, false).await?;
                let listener = tokio::net::TcpListener::bind(listen)
                    .await
                    .with_context(|| format!("listening on {listen}"))?;
                serve(db, experiment, listener, secret, opts, stop_signal()).await
            })?;
            return Ok(match ended {
                Ended::OutOfTime => ExitCode::from(EXIT_NOT_FINISHED),
                Ended::Finished | Ended::AskedToStop => ExitCode::SUCCESS,
            });
        }
        Command::Status {
            connect,
            token_file,
            json,
        } => {
            let secret = Secret::load(token_file.as_deref())?;
            runtime()?.block_on(status(&connect, &secret, json))
        }
        Command::Export {
            db,
            run,
            format,
            elite,
            genome,
            urdf,
        } => match (elite, urdf) {
            (Some(elite), Some(urdf)) => runtime()?.block_on(export_urdf(&db, run, elite, &urdf)),
            (Some(elite), None) => {
                runtime()?.block_on(export_genome(&db, run, elite, genome.as_deref()))
            }
            _ => runtime()?.block_on(export(&db, run, format)),
        },
        Command::Analyse { db } => runtime()?.block_on(analyse(&db)),
        Command::Verify {
            db,
            sample,
            workers,
        } => return runtime()?.block_on(verify(&db, sample, workers)),
        Command::Report { db, out, run } => runtime()?.block_on(report(&db, &out, run)),
        Command::Check {
            experiment,
            no_calibration,
        } => check(&experiment, !no_calibration),
    };
    done.map(|()| ExitCode::SUCCESS)
}

/// Whether two paths name one file (as far as can be told before either exists).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// Opens the database, creating it with the given experiment (or, for `run`, the built-in
/// quick one) when new; refuses an experiment that differs from the stored one.
async fn open_or_create(
    file: Option<&Path>,
    path: &Path,
    quick_by_default: bool,
) -> anyhow::Result<(Db, Experiment)> {
    let given = match file {
        Some(f) => Some(Experiment::load(f)?),
        None => None,
    };
    if !path.exists() && given.is_none() && !quick_by_default {
        bail!(
            "no database at {}: pass --experiment FILE to start one",
            path.display()
        );
    }
    let db = Db::open_exclusive(path, true).await?;
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
            let problems = db.inconsistencies(&stored).await?;
            if !problems.is_empty() {
                bail!(
                    "{} is inconsistent, so it is not resumed from: {}. `strider-coordinator verify --db {}` says more; resume from a backup, or start again",
                    path.display(),
                    problems.join("; "),
                    path.display()
                );
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
            let e = match given {
                Some(e) => e,
                None if quick_by_default => {
                    Experiment::from_toml(include_str!("../../experiments/quick.toml"))
                        .expect("the built-in quick experiment is valid")
                }
                None => bail!(
                    "{} holds no experiment: pass --experiment FILE to start one",
                    path.display()
                ),
            };
            db.create_experiment(&e).await?;
            eprintln!("starting experiment `{}` in {}", e.name, path.display());
            e
        }
    };
    Ok((db, experiment))
}

async fn run_locally(
    file: Option<&Path>,
    path: &Path,
    workers: Option<NonZeroUsize>,
    progress_every: Duration,
) -> anyhow::Result<ExitCode> {
    let (db, experiment) = open_or_create(file, path, true).await?;
    let threads = workers.unwrap_or_else(default_threads);
    match run_local(
        db,
        experiment.clone(),
        threads,
        progress_every,
        stop_signal(),
    )
    .await?
    {
        Ended::Finished => {
            eprintln!(
                "experiment `{}` finished: `strider-coordinator export --db {}` writes the library",
                experiment.name,
                path.display()
            );
            Ok(ExitCode::SUCCESS)
        }
        Ended::AskedToStop | Ended::OutOfTime => {
            // Told apart from a finished run by word and by status (128 + the signal, as
            // a shell reports a process the signal ended).
            let sig = STOPPED_BY.load(std::sync::atomic::Ordering::Relaxed);
            eprintln!(
                "experiment `{}` stopped before the end; everything done is committed: `strider-coordinator run --db {}` goes on from there",
                experiment.name,
                path.display()
            );
            Ok(ExitCode::from(128 + sig.clamp(0, 127) as u8))
        }
    }
}

async fn status(url: &str, secret: &Secret, json: bool) -> anyhow::Result<()> {
    use strider_proto::v1::client_service_client::ClientServiceClient;
    let channel = tonic::transport::Endpoint::from_shared(url.to_string())
        .with_context(|| format!("coordinator URL {url}"))?
        .connect_timeout(Duration::from_secs(5))
        .connect()
        .await
        .with_context(|| format!("connecting to {url}"))?;
    let header: tonic::metadata::MetadataValue<_> = secret
        .header_value()
        .parse()
        .context("the secret cannot travel as gRPC metadata")?;
    let mut client =
        ClientServiceClient::with_interceptor(channel, move |mut r: tonic::Request<()>| {
            r.metadata_mut().insert("authorization", header.clone());
            Ok(r)
        });
    let p = client
        .get_progress(strider_proto::v1::ProgressRequest {
            protocol_version: strider_proto::PROTOCOL_VERSION,
        })
        .await
        .map_err(|s| anyhow::anyhow!("{url}: {} ({:?})", s.message(), s.code()))?
        .into_inner();
    if json {
        let runs: Vec<_> = p.runs.iter().map(|r| serde_json::json!({
            "run": r.run, "scheme": strider_proto::convert::scheme_from_wire(r.scheme).map(|s| s.name()).unwrap_or("?"),
            "repeat": r.repeat, "seed": r.seed, "generation": r.generation, "generations": r.generations,
            "initial_passed": r.initial_passed, "trials_done": r.trials_done, "trials_pending": r.trials_pending,
            "coverage": r.coverage, "best_fitness": r.best_fitness, "mean_fitness": r.mean_fitness,
            "qd_score": r.qd_score, "finished": r.finished,
            "feasible_elites": r.feasible_elites, "infeasible_elites": r.infeasible_elites,
            "infeasible_only": r.infeasible_only,
        })).collect();
        outln!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "experiment": p.experiment, "workers_connected": p.workers_connected,
                "trials_per_second": p.trials_per_second, "fraction_done": p.fraction_done,
                "eta_seconds": p.eta_seconds, "runs": runs,
            }))?
        );
        return Ok(());
    }
    outln!(
        "experiment `{}`: {} workers connected, {:.1} trials/s over the last minute; {:.1} % done{}",
        p.experiment,
        p.workers_connected,
        p.trials_per_second,
        100.0 * p.fraction_done,
        match p.eta_seconds {
            Some(s) => format!(", about {} left", strider_proto::process::duration_words(s)),
            None => String::new(),
        }
    );
    outln!("run  scheme   repeat  generation        initial  candidates pending  feasible  infeasible only  coverage  best      mean      QD score");
    for r in &p.runs {
        let scheme = strider_proto::convert::scheme_from_wire(r.scheme)
            .map(|s| s.name())
            .unwrap_or("?");
        let generation = if r.finished {
            format!("{}/{} done", r.generation, r.generations)
        } else {
            format!("{}/{}", r.generation, r.generations)
        };
        outln!(
            "{:<4} {:<8} {:<7} {:<17} {:<8} {:<10} {:<8} {:<9} {:<16} {:<9} {:<9.4} {:<9.4} {:.2}",
            r.run,
            scheme,
            r.repeat,
            generation,
            r.initial_passed,
            r.trials_done,
            r.trials_pending,
            r.feasible_elites,
            r.infeasible_only,
            format!("{:.2} %", 100.0 * r.coverage),
            r.best_fitness,
            r.mean_fitness,
            r.qd_score
        );
    }
    Ok(())
}

/// Opens an existing database and its experiment, for reading.
async fn open_existing(path: &Path) -> anyhow::Result<(Db, Experiment)> {
    if !path.exists() {
        bail!("no database at {}", path.display());
    }
    // A file this process may not write (a read-only mount, a backup kept read-only)
    // fails the usual open (it migrates and sets the log mode): read it as it is.
    let db = match Db::open(path, false).await {
        Ok(db) => db,
        Err(writable) => Db::open_read_only(path)
            .await
            .map_err(|read_only| anyhow::anyhow!("{writable}; read-only, {read_only}"))?,
    };
    let (experiment, _) = db
        .experiment()
        .await?
        .context("the database holds no experiment")?;
    Ok((db, experiment))
}

async fn export(path: &Path, only: Option<i64>, format: Format) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs = selected_runs(&db, only).await?;
    let mut rows = Vec::new();
    for r in &runs {
        let outcomes: HashMap<CellIndex, Outcome> = db
            .list_elites(
                &EliteFilter {
                    run: Some(r.id),
                    ..EliteFilter::default()
                },
                0,
                u32::MAX,
            )
            .await?
            .into_iter()
            .map(|e| (e.cell, e.outcome))
            .collect();
        rows.push(export::rows(r, &outcomes));
    }
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    match format {
        Format::Json => {
            let mut json = Vec::new();
            for (r, rows) in runs.iter().zip(&rows) {
                let generations: Vec<_> = db
                    .generations(r.id)
                    .await?
                    .into_iter()
                    .map(|(g, evaluations, s)| serde_json::json!({"generation": g, "evaluations": evaluations, "stats": s}))
                    .collect();
                let elites: Vec<_> = rows.iter().map(export::json).collect();
                let infeasible: Vec<_> = db
                    .list_infeasible(r.id)
                    .await?
                    .iter()
                    .map(export::infeasible_json)
                    .collect();
                json.push(serde_json::json!({
                    "run": r.id, "scheme": r.spec.scheme.name(), "repeat": r.spec.repeat, "seed": r.spec.seed.0,
                    "generation": r.generation, "finished": r.finished, "generations": generations, "elites": elites,
                    "infeasible": infeasible,
                }));
            }
            serde_json::to_writer_pretty(
                &mut out,
                &serde_json::json!({"experiment": experiment.name, "runs": json}),
            )?;
            writeln!(out)?;
        }
        Format::Csv => {
            writeln!(out, "{}", export::csv_header())?;
            for row in rows.iter().flatten() {
                writeln!(out, "{}", export::csv_line(row))?;
            }
        }
        Format::GenerationsCsv => {
            writeln!(out, "{}", export::GENERATIONS_CSV_HEADER)?;
            for r in &runs {
                let mut cumulative = 0;
                for (g, evaluations, s) in db.generations(r.id).await? {
                    cumulative += evaluations;
                    let line = export::generations_csv_line(r, g, (evaluations, cumulative), &s);
                    writeln!(out, "{line}")?;
                }
            }
        }
    }
    out.flush()?;
    Ok(())
}

/// Every run of the database, or only `only` (which must exist).
async fn selected_runs(db: &Db, only: Option<i64>) -> anyhow::Result<Vec<RunRecord>> {
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
    Ok(runs)
}

/// `export --elite E [--genome FILE]`: one elite's genome file, to standard output or FILE.
async fn export_genome(
    path: &Path,
    only: Option<i64>,
    choice: EliteChoice,
    to: Option<&Path>,
) -> anyhow::Result<()> {
    let (db, _) = open_existing(path).await?;
    let runs = selected_runs(&db, only).await?;
    let (run, cell, fitness, genome) = export::find(&runs, choice).map_err(anyhow::Error::msg)?;
    match to {
        Some(file) => std::fs::write(file, genome.to_json_pretty() + "\n")
            .with_context(|| format!("writing {}", file.display()))?,
        None => outln!("{}", genome.to_json_pretty()),
    }
    eprintln!("run {run}, cell {}: fitness {fitness:.4}", cell.0);
    Ok(())
}

async fn export_urdf(
    path: &Path,
    only: Option<i64>,
    choice: EliteChoice,
    urdf: &Path,
) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs = selected_runs(&db, only).await?;
    let (run, cell, fitness, genome) = export::find(&runs, choice).map_err(anyhow::Error::msg)?;
    let plan = BodyPlan::new(&genome.morphology, experiment.brief.payload);
    let name = format!("{} run {run} cell {}", experiment.name, cell.0);
    let pose = strider_common::urdf::write_files(&name, &plan, &genome.controller, urdf)?;
    eprintln!(
        "run {run}, cell {}: fitness {fitness:.4}, {:.2} kg, {} legs -> {} (start pose: {})",
        cell.0,
        plan.total_mass(),
        plan.legs.len(),
        urdf.display(),
        pose.display()
    );
    Ok(())
}

/// The reference design MAX, marked on library maps.
const MAX_DESIGN: &str = include_str!("../../designs/max.json");

async fn report(path: &Path, out: &Path, run: Option<i64>) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let mut runs = Vec::new();
    for r in db.runs().await? {
        let generations = db
            .generations(r.id)
            .await?
            .into_iter()
            .map(|(g, _, s)| (g, s))
            .collect();
        runs.push(RunData {
            id: r.id,
            scheme: r.spec.scheme,
            repeat: r.spec.repeat,
            library: r.library,
            infeasible: r.infeasible,
            generations,
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
            .map_or(0, |(id, _)| id)
    });
    let max: Genome = serde_json::from_str(MAX_DESIGN).context("the built-in MAX design")?;
    let report = strider_coordinator::report::build(&Inputs {
        experiment: &experiment,
        runs: &runs,
        chosen,
        reference: Some((&max, "MAX")),
    });
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let write = |name: &str, bytes: &[u8]| {
        let p = out.join(name);
        std::fs::write(&p, bytes).with_context(|| format!("writing {}", p.display()))
    };
    write("report.html", report.html.as_bytes())?;
    let fonts = png::fonts();
    if fonts.is_empty() {
        eprintln!("warning: no system fonts found: the PNG pictures will have no text (the SVG and HTML are complete); install fonts-dejavu-core");
    }
    for p in &report.pictures {
        write(&format!("{}.svg", p.name), p.svg.as_bytes())?;
        write(&format!("{}.png", p.name), &png::render(&p.svg, &fonts)?)?;
    }
    for t in &report.tables {
        write(&format!("{}.csv", t.name), t.csv.as_bytes())?;
    }
    eprintln!(
        "wrote {} ({} pictures as SVG and PNG, {} tables as CSV)",
        out.join("report.html").display(),
        report.pictures.len(),
        report.tables.len()
    );
    Ok(())
}

async fn verify(
    path: &Path,
    sample: usize,
    workers: Option<NonZeroUsize>,
) -> anyhow::Result<ExitCode> {
    use strider_common::rng::CandidateSeed;
    use strider_worker::batch::{evaluate_batch, Job};
    use strider_worker::evaluate::EvalContext;
    let (db, experiment) = open_existing(path).await?;
    let made_by = db.experiment().await?.map(|(_, build)| build);
    let other_build = made_by.as_deref().filter(|b| *b != build_id());
    if let Some(b) = other_build {
        eprintln!(
            "warning: {} was made by {b}; this is {}: breeding and trials are bit-identical only within one build, so differences below may be the build's, not damage",
            path.display(),
            build_id()
        );
    }
    let runs = db.runs().await?;
    let candidates = db.candidates().await?;
    let mut verdict = strider_coordinator::verify::replay(&experiment, &runs, &candidates);
    outln!(
        "replayed {} of {} stored candidates over {} runs",
        verdict.replayed,
        candidates.len(),
        runs.len()
    );
    // Every row against its checksum: damage that leaves the replay agreeing (an
    // outcome's figure that no placement depends on) still shows here.
    let damaged = db.checksum_mismatches(false).await?;
    outln!(
        "checked every candidate row against its checksum: {} damaged",
        damaged.len()
    );
    verdict
        .problems
        .extend(strider_coordinator::db::damaged_rows(&damaged));
    // Every k-th stored candidate whose outcome a worker computed (a candidate that
    // failed for want of a worker has nothing to reproduce).
    let eligible: Vec<&strider_coordinator::db::StoredCandidate> = candidates
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
    let chosen: Vec<&strider_coordinator::db::StoredCandidate> =
        if sample == 0 || eligible.is_empty() {
            Vec::new()
        } else {
            let step = (eligible.len() as f64 / sample as f64).max(1.0);
            (0..sample.min(eligible.len()))
                .map(|i| eligible[(i as f64 * step) as usize])
                .collect()
        };
    if !chosen.is_empty() {
        let spec_of: HashMap<i64, strider_common::experiment::RunSpec> =
            runs.iter().map(|r| (r.id, r.spec)).collect();
        // Candidates of no run were reported by the replay; the rest, paired with their jobs.
        let chosen: Vec<_> = chosen
            .into_iter()
            .filter_map(|c| spec_of.get(&c.run).map(|spec| (c, *spec)))
            .collect();
        let jobs: Vec<Job> = chosen
            .iter()
            .map(|(c, spec)| Job {
                genome: c.genome,
                scheme: spec.scheme,
                seed: CandidateSeed::new(spec.seed.0, c.number.0),
            })
            .collect();
        let ctx = EvalContext::of(&experiment);
        let threads = workers.unwrap_or_else(default_threads);
        let outcomes = tokio::task::spawn_blocking(move || evaluate_batch(&ctx, &jobs, threads))
            .await
            .context("simulating the sample")?;
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
    if verdict.problems.is_empty() {
        outln!("{} agrees with itself", path.display());
        Ok(ExitCode::SUCCESS)
    } else {
        for p in &verdict.problems {
            outln!("problem: {p}");
        }
        eprintln!(
            "error: {} does not agree with itself ({} problems above); resume from a backup, or start the experiment again",
            path.display(),
            verdict.problems.len()
        );
        Ok(ExitCode::from(EXIT_FAILURE))
    }
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
            infeasible: &r.infeasible,
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
    out!(
        "{}",
        summarise(&results, &experiment.schemes, experiment.brief.payload)
    );
    Ok(())
}

/// A duration in hours, as a person reads it.
fn hours_text(h: f64) -> String {
    if h >= 1.0 {
        format!("{h:.1} h")
    } else {
        format!("{:.0} min", (h * 60.0).ceil())
    }
}

fn check(path: &Path, calibrate: bool) -> anyhow::Result<()> {
    let e = Experiment::load(path)?;
    let runs = e.runs();
    outln!(
        "experiment `{}`: {} runs; each {} initial designs, then {} generations of {} ({} offspring)",
        e.name,
        runs.len(),
        e.run.initial_population,
        e.run.generations,
        e.run.offspring_per_generation,
        e.offspring_per_run()
    );
    outln!(
        "trial {} s at {} Hz control, physics step {:.5} s; brief: mass <= {} kg, height >= {} m, speed >= {} m/s, payload {} kg",
        e.run.trial_seconds,
        e.run.control_hz,
        e.run.physics_dt(),
        e.brief.max_mass,
        e.brief.min_height,
        e.brief.min_speed,
        e.brief.payload
    );
    outln!(
        "search: {}{}; a trial ends when the robot falls: tilt > {} degrees, body centre below {} of its start height{}",
        e.search.constraints.name(),
        match e.search.constraints {
            strider_common::experiment::ConstraintHandling::FeasibleInfeasible => format!(
                " (feasible and infeasible libraries, {} of parents from the feasible one, infeasible parents by tournament of {})",
                e.search.feasible_parent_share, e.search.infeasible_tournament
            ),
            strider_common::experiment::ConstraintHandling::Reject => {
                " (designs that miss the brief are dropped; the initial population is drawn until that many pass)".into()
            }
        },
        e.trial.max_tilt_degrees,
        e.trial.min_height_fraction,
        if e.trial.only_feet_on_ground {
            ", or a part other than a lower leg on the ground"
        } else {
            ""
        }
    );
    if e.trial.upright_after_seconds > 0.0 {
        outln!(
            "after the trial the robot must stay up {} s more, its body within {} degrees of level",
            e.trial.upright_after_seconds,
            e.trial
                .max_tilt_degrees
                .min(e.trial.upright_after_max_tilt_degrees)
        );
    }
    // What it costs: every trial (an ES candidate is many) at the cost of one that walks
    // to its end, measured now on this machine, or else from MAX's measured trial on the
    // development machine (BENCHMARKS.md: 0.124 ms a physics step on one core).
    let per_run = u64::from(e.run.initial_population) + e.offspring_per_run();
    let trials: u64 = runs
        .iter()
        .map(|r| match r.scheme {
            strider_common::Scheme::Es => per_run * (u64::from(e.run.es_iterations) + 1),
            _ => per_run,
        })
        .sum();
    outln!(
        "cost: {} candidates, at most {} trials (an ES candidate is {} trials){}",
        per_run * runs.len() as u64,
        trials,
        e.run.es_iterations + 1,
        match e.search.constraints {
            strider_common::experiment::ConstraintHandling::Reject =>
                ", plus the initial draws until enough meet the whole brief (unbounded)",
            _ => "",
        },
    );
    let cores = default_threads();
    let (thread_seconds, upper, source) = if calibrate {
        let c = strider_worker::calibrate::calibrate(
            &e.run,
            &e.trial,
            &e.brief,
            cores,
            Duration::from_secs(1),
        );
        (
            c.thread_seconds_per_trial(),
            c.upper_bound(trials),
            format!(
                "measured now: {} trials of MAX to their end in {:.1} s",
                c.trials, c.wall_seconds
            ),
        )
    } else {
        let steps = (e.run.trial_seconds + e.trial.upright_after_seconds) / e.run.physics_dt();
        let per_trial = steps * 0.124e-3;
        (
            per_trial,
            trials as f64 * per_trial / cores.get() as f64,
            "from MAX's trial on the development machine; --no-calibration".to_string(),
        )
    };
    outln!(
        "time on this machine's {} cores: at most {} ({:.1} ms of one core a trial that walks to its end, {source}); most trials end sooner in a fall or are settled without one: the whole runs in BENCHMARKS.md took a fifth to a half of this figure",
        cores,
        hours_text(upper / 3600.0),
        thread_seconds * 1e3,
    );
    for r in runs {
        outln!(
            "  {:<7} repeat {:>3}  seed {}",
            r.scheme,
            r.repeat,
            r.seed.0
        );
    }
    Ok(())
}
