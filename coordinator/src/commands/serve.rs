//! `serve`: the experiment served to workers over gRPC until it is finished, the time is up
//! or a signal stops it.

use super::{seconds, Exit};
use crate::service::server::{serve, Backup, Ended, ServeOptions};
use anyhow::Context;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use strider_process::{StopSignals, UsageError};
use strider_proto::secret::Secret;

/// Arguments of `serve`.
#[derive(clap::Args)]
pub struct ServeArgs {
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
}

/// Serves until the experiment is finished ([`Exit::Success`]), SIGTERM or Ctrl-C (also
/// success: everything is committed), or `--stop-leasing-after` ([`Exit::NotFinished`]).
pub fn execute(args: ServeArgs) -> anyhow::Result<Exit> {
    super::init_logs()?;
    let secret = Secret::load(args.token_file.as_deref())?;
    let opts = options(&args)?;
    let ended = super::runtime()?.block_on(async {
        // Caught before the database is opened: a signal meanwhile stops the service once
        // open (everything committed, exit 0), not the signal's default action.
        let mut signals = StopSignals::catch().context("catching SIGTERM and SIGINT")?;
        let (db, experiment) =
            super::open::open_or_create(args.experiment.as_deref(), &args.db, false).await?;
        let listener = tokio::net::TcpListener::bind(args.listen)
            .await
            .with_context(|| format!("listening on {}", args.listen))?;
        let stop = async move {
            signals.recv().await;
            tracing::info!("asked to stop: committing and shutting down");
        };
        serve(db, experiment, listener, secret, opts, stop).await
    })?;
    Ok(match ended {
        Ended::OutOfTime => Exit::NotFinished,
        Ended::Finished | Ended::AskedToStop => Exit::Success,
    })
}

/// The service's options from the command line, every figure checked.
fn options(args: &ServeArgs) -> anyhow::Result<ServeOptions> {
    if args.max_attempts == 0 {
        return Err(UsageError("--max-attempts: must be at least 1".into()).into());
    }
    let lease = seconds("lease-seconds", args.lease_seconds)?;
    let progress_every = Some(seconds("progress-every", args.progress_every)?);
    let stop_leasing_after = args
        .stop_leasing_after
        .map(|s| seconds("stop-leasing-after", s))
        .transpose()?;
    let backup = match &args.backup {
        Some(path) if same_file(path, &args.db) => {
            return Err(UsageError(format!(
                "--backup {}: that is the database itself",
                path.display()
            ))
            .into());
        }
        Some(path) => Some(Backup {
            path: path.clone(),
            every: seconds("backup-every", args.backup_every)?,
        }),
        None => None,
    };
    Ok(ServeOptions {
        lease,
        max_attempts: args.max_attempts,
        progress_every,
        keep_serving: args.keep_serving,
        address_file: args.address_file.clone(),
        metrics: args.metrics,
        stop_leasing_after,
        backup,
        handshake: seconds("handshake-seconds", args.handshake_seconds)?,
    })
}

/// Whether two paths name one file (as far as can be told before either exists).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}
