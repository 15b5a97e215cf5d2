//! `strider-coordinator run`: the coordinator and a worker in one process, talking gRPC
//! over loopback with a one-time secret, so one machine runs exactly what a cluster runs.

use super::server::{serve, worker_url, Ended, ServeOptions};
use crate::db::Db;
use std::num::NonZeroUsize;
use std::time::Duration;
use strider_common::Experiment;
use strider_proto::secret::Secret;
use strider_worker::client::{work, ConnectOptions, CoordinatorAddress, Evaluator};
use tokio::net::TcpListener;
use tokio::sync::watch;

/// Runs `experiment` (stored in `db`) on `threads` local cores until it is finished or
/// `stop` completes; says which.
pub async fn run_local(
    db: Db,
    experiment: Experiment,
    threads: NonZeroUsize,
    progress_every: Duration,
    stop: impl std::future::Future<Output = ()> + Send + 'static,
) -> anyhow::Result<Ended> {
    let listener = TcpListener::bind("127.0.0.1:0").await?;
    let url = worker_url(listener.local_addr()?);
    let secret = Secret::random();
    let opts = ServeOptions {
        progress_every: Some(progress_every),
        ..ServeOptions::default()
    };
    if db.unfinished_runs().await? == 0 {
        // Finished already: the service ends as it starts, so no worker (it would find
        // the service gone and say so).
        return serve(db, experiment, listener, secret, opts, stop).await;
    }
    let (stop_worker, stopped) = watch::channel(false);
    let worker = tokio::spawn(work(
        ConnectOptions {
            coordinator: CoordinatorAddress::Url(url),
            authorization: Some(secret.clone()),
            threads,
            name: format!("local ({} threads)", threads),
            build: strider_common::build_id(),
            evaluator: Evaluator::Simulation,
            drain: Duration::from_secs(5),
            max_backoff: Duration::from_millis(500),
            give_up_after: None,
        },
        stopped,
    ));
    let served = serve(db, experiment, listener, secret, opts, stop);
    tokio::pin!(served);
    let mut worker = worker;
    tokio::select! {
        r = &mut served => {
            let _ = stop_worker.send(true);
            let _ = worker.await;
            r
        }
        w = &mut worker => {
            // The worker only ends by itself when refused: a bug, not a condition to wait out.
            match w {
                Ok(Err(e)) => Err(anyhow::anyhow!("the local worker stopped: {e}")),
                _ => served.await,
            }
        }
    }
}
