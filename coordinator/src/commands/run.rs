//! `run`: an experiment on this machine, the coordinator and an embedded worker in one
//! process (needs the `simulator` feature).

use super::Exit;
use std::num::NonZeroUsize;
use std::path::PathBuf;

/// Arguments of `run`.
#[derive(clap::Args)]
pub struct RunArgs {
    /// Experiment file (TOML); the built-in quick experiment when left out.
    experiment: Option<PathBuf>,
    /// Database file.
    #[arg(long, default_value = "strider.db")]
    db: PathBuf,
    /// Simulation threads (all cores by default), as a worker's --threads; --workers is
    /// the older name.
    #[arg(long, visible_alias = "workers", value_parser = strider_process::at_least_one)]
    threads: Option<NonZeroUsize>,
    /// Seconds between progress lines.
    #[arg(long, default_value_t = 10.0)]
    progress_every: f64,
}

/// Runs the experiment until it is finished or a signal stops it.
#[cfg(feature = "simulator")]
pub fn execute(args: RunArgs) -> anyhow::Result<Exit> {
    use crate::service::local::run_local;
    use crate::service::server::Ended;
    use anyhow::Context;
    use strider_process::{default_threads, StopSignals};

    // The progress line is this command's account; the embedded service's INFO lines
    // (a worker connected, serving on a port) only interest someone debugging it.
    super::init_quiet_logs()?;
    let every = super::seconds("progress-every", args.progress_every)?;
    // One thread: here the async work is moving a few messages per trial between threads
    // that simulate on every core, and each extra thread woken per message preempts a
    // simulation (BENCHMARKS.md, `run` against the evaluator).
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(async {
        // Caught before the database is opened: a signal meanwhile stops the run once open.
        let mut signals = StopSignals::catch().context("catching SIGTERM and SIGINT")?;
        let path = &args.db;
        let (db, experiment) =
            super::open::open_or_create(args.experiment.as_deref(), path, true).await?;
        let threads = args.threads.unwrap_or_else(default_threads);
        let (signal_tx, signal_rx) = tokio::sync::oneshot::channel();
        let stop = async move {
            let signal = signals.recv().await;
            // Said at once: the trials in flight get a few seconds to finish and be kept.
            strider_process::note!(
                "stopping: the trials in flight get up to 5 s to finish and be committed; any cut short are simulated again when the run goes on"
            );
            let _ = signal_tx.send(signal);
        };
        match run_local(db, experiment.clone(), threads, every, stop).await? {
            Ended::Finished => {
                eprintln!(
                    "experiment `{}` finished: `strider-coordinator export --db {}` writes the library",
                    experiment.name,
                    path.display()
                );
                Ok(Exit::Success)
            }
            Ended::AskedToStop | Ended::OutOfTime => {
                // Told apart from a finished run by word and by status (128 + the signal,
                // as a shell reports a process the signal ended).
                eprintln!(
                    "experiment `{}` stopped before the end; everything done is committed: `strider-coordinator run --db {}` goes on from there",
                    experiment.name,
                    path.display()
                );
                Ok(Exit::Stopped(signal_rx.await.unwrap_or(0)))
            }
        }
    })
}

/// Without the simulator there is nothing to run the trials on this machine.
#[cfg(not(feature = "simulator"))]
pub fn execute(_: RunArgs) -> anyhow::Result<Exit> {
    anyhow::bail!(
        "this strider-coordinator was built without the simulator (cargo feature `simulator`), so it cannot run trials itself: use `serve` with strider-worker processes, or a default build"
    )
}
