//! Working for a coordinator (no command): `--connect URL` or `--address-file FILE`.

use crate::client::{work, ConnectOptions, CoordinatorAddress, Evaluator};
use anyhow::Context;
use std::num::NonZeroUsize;
use std::path::PathBuf;
use strider_process::{default_threads, host_name, StopSignals, UsageError};
use strider_proto::secret::{Secret, SecretError};

/// Working for a coordinator.
#[derive(clap::Args)]
pub struct ConnectArgs {
    /// Work for the coordinator at this URL (e.g. http://host:50051) until its experiment
    /// is finished; retries with backoff while it is unreachable.
    #[arg(long, conflicts_with = "address_file")]
    pub connect: Option<String>,
    /// Work for the coordinator whose URL is the first line of this file (written by
    /// `serve --address-file`): waits for the file, and reads it again before every
    /// connection attempt, so it follows a coordinator that restarts elsewhere.
    #[arg(long)]
    pub address_file: Option<PathBuf>,
    /// File holding the shared secret (else the STRIDER_SECRET environment variable).
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// Trials at once (all cores by default).
    #[arg(long, value_parser = strider_process::at_least_one)]
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

/// Works for the coordinator the arguments name until its experiment is finished, a
/// signal stops it, or (`--give-up-after`) none has answered for too long.
pub fn execute(args: ConnectArgs) -> anyhow::Result<()> {
    let coordinator = match (&args.connect, &args.address_file) {
        (Some(url), _) => CoordinatorAddress::Url(url.clone()),
        (None, Some(file)) => CoordinatorAddress::File(file.clone()),
        (None, None) => return Err(UsageError(
            "nothing to do: pass --connect URL or --address-file FILE, or a command (see --help)"
                .into(),
        )
        .into()),
    };
    strider_process::init_logs().map_err(UsageError)?;
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
    let opts = ConnectOptions {
        coordinator,
        // Every coordinator asks for the secret: without one a worker could only be
        // refused, so it is a usage error here, before any connection (it used to retry,
        // or hear about gRPC metadata from the coordinator).
        authorization: match Secret::load(args.token_file.as_deref()) {
            Ok(secret) => Some(secret),
            Err(e @ SecretError::Missing) => return Err(UsageError(e.to_string()).into()),
            Err(e) => return Err(e.into()),
        },
        threads: args.threads.unwrap_or_else(default_threads),
        name: args
            .name
            .unwrap_or_else(|| format!("{} pid {}", host_name(), std::process::id())),
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
    // Caught now, not when the task below first runs (after the simulation threads start).
    let mut signals = {
        let _in = runtime.enter();
        StopSignals::catch().context("catching SIGTERM and SIGINT")?
    };
    runtime.block_on(async {
        let (stop, stopped) = tokio::sync::watch::channel(false);
        tokio::spawn(async move {
            signals.recv().await;
            tracing::info!("asked to stop");
            let _ = stop.send(true);
        });
        work(opts, stopped).await
    })?;
    Ok(())
}
