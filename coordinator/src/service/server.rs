//! Starting and stopping the distributed coordinator: load the runs from the database,
//! start the writer, serve gRPC (workers, clients, health, reflection) on a listener,
//! expire leases, print progress, and stop when every run is finished (or when asked),
//! with everything committed.

use super::client_api::{progress, ClientApi};
use super::metrics::serve_metrics;
use super::worker_api::WorkerApi;
use super::writer::{run_writer, WriterMessage};
use super::{Shared, Throughput};
use crate::db::{canonical_toml, Db, DbError};
use crate::qd::scheduler::Scheduler;
use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use strider_common::initial_designs::InitialDesigns;
use strider_common::Experiment;
use strider_process::duration_words;
use strider_process::terminal::Bar;
use strider_proto::secret::Secret;
use strider_proto::v1;
use strider_proto::v1::client_service_server::ClientServiceServer;
use strider_proto::v1::worker_service_server::WorkerServiceServer;
use tokio::net::TcpListener;
use tokio::sync::{mpsc, oneshot, watch, Notify};

/// Largest message accepted (a result is a few hundred bytes).
pub const MAX_MESSAGE_BYTES: usize = 1 << 20;

/// How the coordinator serves.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// Lease length without a heartbeat.
    pub lease: Duration,
    /// Leases a candidate may lose before it fails.
    pub max_attempts: u32,
    /// A progress line this often (none when `None`).
    pub progress_every: Option<Duration>,
    /// Keep serving clients after every run is finished (until asked to stop).
    pub keep_serving: bool,
    /// Write the URL workers should use here once listening (atomically).
    pub address_file: Option<PathBuf>,
    /// Serve Prometheus metrics on this address (`GET /metrics`).
    pub metrics: Option<SocketAddr>,
    /// Stop handing out candidates this long after starting, and exit once every lease
    /// out has come back (for batch jobs with a time limit; serve again to go on).
    pub stop_leasing_after: Option<Duration>,
    /// Copy the database here this often, and once more on the way out.
    pub backup: Option<Backup>,
    /// A connection that has made no authenticated call by then is closed
    /// ([`super::incoming`]).
    pub handshake: Duration,
}

/// A periodic safe copy of the database (see [`Db::backup_to`]).
#[derive(Clone, Debug)]
pub struct Backup {
    /// Where the copy goes (replaced whole each time).
    pub path: PathBuf,
    /// Time between copies.
    pub every: Duration,
}

impl Default for ServeOptions {
    fn default() -> Self {
        Self {
            lease: Duration::from_secs(60),
            max_attempts: crate::qd::scheduler::DEFAULT_MAX_ATTEMPTS,
            progress_every: Some(Duration::from_secs(10)),
            keep_serving: false,
            address_file: None,
            metrics: None,
            stop_leasing_after: None,
            backup: None,
            handshake: Duration::from_secs(10),
        }
    }
}

/// The URL a worker on another machine uses to reach `addr`.
pub fn worker_url(addr: SocketAddr) -> String {
    if addr.ip().is_unspecified() {
        format!("http://{}:{}", strider_process::host_name(), addr.port())
    } else {
        format!("http://{addr}")
    }
}

fn write_atomically(path: &std::path::Path, text: &str) -> std::io::Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path)
}

/// Why [`serve`] returned (everything committed in every case).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ended {
    /// Every run is finished.
    Finished,
    /// `stop` completed (SIGTERM, Ctrl-C).
    AskedToStop,
    /// `stop_leasing_after` ran out and every lease came back; serve again to go on.
    OutOfTime,
}

/// Serves `experiment` (already stored in `db`) on `listener` until every run is finished
/// (unless `keep_serving`) or `stop` completes; returns once everything is committed.
pub async fn serve(
    db: Db,
    experiment: Experiment,
    listener: TcpListener,
    secret: Secret,
    opts: ServeOptions,
    stop: impl Future<Output = ()> + Send,
) -> anyhow::Result<Ended> {
    let (shared, mut writer) = start_scheduler(db, &experiment, &opts).await?;

    let addr = listener.local_addr()?;
    let url = worker_url(addr);
    if let Some(path) = &opts.address_file {
        write_atomically(path, &format!("{url}\n"))
            .map_err(|e| anyhow::anyhow!("address file {}: {e}", path.display()))?;
    }
    tracing::info!("serving experiment {:?} on {url}", experiment.name);
    let router = grpc_router(&shared, &secret).await?;

    let mut tasks = background(shared.clone(), &opts);
    if let Some(addr) = opts.metrics {
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| anyhow::anyhow!("metrics endpoint on {addr}: {e}"))?;
        tracing::info!("metrics on http://{}/metrics", listener.local_addr()?);
        tasks.push(tokio::spawn(serve_metrics(listener, shared.clone())));
    }
    if let Some(backup) = opts.backup.clone() {
        tasks.push(tokio::spawn(back_up_periodically(
            shared.db.clone(),
            backup,
        )));
    }
    let (out_of_time_tx, mut out_of_time) = oneshot::channel::<()>();
    if let Some(after) = opts.stop_leasing_after {
        tasks.push(tokio::spawn(stop_leasing(
            shared.clone(),
            after,
            out_of_time_tx,
        )));
    }
    let mut finished = shared.finished.subscribe();
    let keep_serving = opts.keep_serving;
    let (server_stop_tx, server_stop_rx) = oneshot::channel::<()>();
    let server = router.serve_with_incoming_shutdown(
        super::incoming::Incoming::new(listener, opts.handshake),
        async {
            let _ = server_stop_rx.await;
        },
    );
    tokio::pin!(server);
    tokio::pin!(stop);
    let outcome: anyhow::Result<Ended> = loop {
        tokio::select! {
            r = &mut server => break r
                .map_err(anyhow::Error::from)
                .and_then(|()| Err(anyhow::anyhow!("the gRPC server stopped by itself"))),
            r = &mut writer => break match r {
                Ok(Ok(())) => Err(anyhow::anyhow!("the database writer stopped")),
                Ok(Err(e)) => Err(e.into()),
                Err(e) => Err(anyhow::anyhow!("the database writer panicked: {e}")),
            },
            _ = &mut stop => break Ok(Ended::AskedToStop),
            r = &mut out_of_time => if r.is_ok() {
                break Ok(Ended::OutOfTime);
            },
            r = finished.wait_for(|f| *f), if !keep_serving => {
                if r.is_ok() {
                    break Ok(Ended::Finished);
                }
            }
        }
    };
    let ahead = shared.with(false, |s| s.ahead_counts());
    if ahead.leased > 0 {
        tracing::info!("candidates drawn ahead while generations finished: {ahead}");
    }
    for t in tasks {
        t.abort();
        // Awaited, so that a progress bar is cleared before the closing lines print.
        let _ = t.await;
    }
    // Sessions tell their workers the experiment is over (or see the stream end); give
    // them a moment, then stop serving whatever is left.
    let _ = server_stop_tx.send(());
    let _ = tokio::time::timeout(Duration::from_secs(5), &mut server).await;
    let mut ended = outcome?;
    if wind_down(&shared, &mut writer, &opts).await? {
        ended = Ended::Finished;
    }
    // The writer is told to end (sessions that outlived the server's grace time may still
    // hold a sender: what they send now is dropped, as a crash here would drop it); then
    // closing every connection lets SQLite remove the emptied -wal and -shm files.
    let _ = shared.writer.send(WriterMessage::Close);
    let db = shared.db.clone();
    drop(shared);
    match tokio::time::timeout(Duration::from_secs(5), writer).await {
        Err(_) => tracing::warn!("the database writer did not end within 5 s of the stop"),
        // Said: the last group (what came between the flush and the close) is not stored.
        Ok(Ok(Err(e))) => tracing::warn!("the database writer's last commit failed: {e}"),
        Ok(Err(e)) => tracing::warn!("the database writer panicked at the stop: {e}"),
        Ok(Ok(Ok(()))) => {}
    }
    // Bounded, and says so when a connection outlives it (a -wal file left beside the
    // database then has its reason in the log).
    db.close().await;
    Ok(ended)
}

/// Tries of the exit's checkpoint while the log is busy (20 ms apart).
const EXIT_CHECKPOINT_TRIES: u32 = 50;

/// The database writer task.
type Writer = tokio::task::JoinHandle<Result<(), DbError>>;

/// Reads the runs and pending results, starts the scheduler and the database writer,
/// and stores what opening the runs' steps wrote.
async fn start_scheduler(
    db: Db,
    experiment: &Experiment,
    opts: &ServeOptions,
) -> anyhow::Result<(Arc<Shared>, Writer)> {
    let runs = db.runs().await?;
    let stored = db.pending().await?;
    let next_worker = db.next_worker_id().await?;
    let left_open = db
        .close_sessions_left_open("the coordinator stopped first (closed when it started again)")
        .await?;
    if left_open > 0 {
        tracing::info!("{left_open} worker sessions of a coordinator that stopped first closed");
    }
    let mut scheduler = Scheduler::new(
        experiment.clone(),
        runs,
        stored,
        opts.lease,
        opts.max_attempts,
    );
    scheduler.draw_ahead(true);
    let (writer_tx, writer_rx) = mpsc::unbounded_channel();
    let backlog = Arc::new(super::Backlog::default());
    let writer = tokio::spawn(run_writer(db.clone(), writer_rx, backlog.clone()));
    let shared = Arc::new(Shared {
        scheduler: Mutex::new(scheduler),
        writer: writer_tx,
        backlog,
        work: Notify::new(),
        steps: watch::Sender::new(0),
        finished: watch::Sender::new(false),
        workers: AtomicU32::new(0),
        slots: AtomicUsize::new(0),
        next_worker: AtomicU64::new(next_worker.0),
        sessions: Default::default(),
        reference: super::reference::ReferenceTrial::of_this_coordinator(),
        throughput: Mutex::new(Throughput::default()),
        started: Instant::now(),
        clock: Mutex::new(super::clock::RunningClock::new(Instant::now())),
        pace: Mutex::new(Default::default()),
        // What a worker needs to judge a candidate: not the initial designs (genomes
        // arrive with each candidate), which could pass a message's size limit.
        experiment_toml: canonical_toml(&Experiment {
            initial_designs: InitialDesigns::None,
            ..experiment.clone()
        }),
        db,
    });
    // Store what opening the steps wrote (draws settled without a trial, new generations).
    shared.with(true, |_| ());
    Shared::read_the_clock_every_second(&shared);
    // Where this process began, for its estimate of the time left.
    let _ = shared.eta(shared.fraction_done());

    Ok((shared, writer))
}

/// The gRPC services behind the token: health, reflection, the worker and the client
/// services.
async fn grpc_router(
    shared: &Arc<Shared>,
    secret: &Secret,
) -> anyhow::Result<tonic::transport::server::Router> {
    let (health, health_service) = tonic_health::server::health_reporter();
    for name in ["strider.v1.WorkerService", "strider.v1.ClientService", ""] {
        health
            .set_service_status(name, tonic_health::ServingStatus::Serving)
            .await;
    }
    // Reflection in both versions (Python's reflection client and older grpcurl ask for
    // v1alpha), listing health as well as Strider's services.
    let reflected = || {
        tonic_reflection::server::Builder::configure()
            .register_encoded_file_descriptor_set(strider_proto::FILE_DESCRIPTOR_SET)
            .register_encoded_file_descriptor_set(tonic_health::pb::FILE_DESCRIPTOR_SET)
    };
    let reflection = reflected().build_v1()?;
    let reflection_v1alpha = reflected().build_v1alpha()?;
    let interceptor = super::auth::interceptor(secret);
    let workers = WorkerServiceServer::new(WorkerApi {
        shared: shared.clone(),
    })
    .max_decoding_message_size(MAX_MESSAGE_BYTES);
    let clients = ClientServiceServer::new(ClientApi {
        shared: shared.clone(),
    })
    .max_decoding_message_size(MAX_MESSAGE_BYTES);

    // (No-delay is set per connection by `Incoming`: the builder's applies only to the
    // listener tonic binds itself.)
    let router = tonic::transport::Server::builder()
        .http2_keepalive_interval(Some(Duration::from_secs(10)))
        .http2_keepalive_timeout(Some(Duration::from_secs(20)))
        .add_service(health_service)
        .add_service(tonic::service::interceptor::InterceptedService::new(
            reflection,
            interceptor.clone(),
        ))
        .add_service(tonic::service::interceptor::InterceptedService::new(
            reflection_v1alpha,
            interceptor.clone(),
        ))
        .add_service(tonic::service::interceptor::InterceptedService::new(
            workers,
            interceptor.clone(),
        ))
        .add_service(tonic::service::interceptor::InterceptedService::new(
            clients,
            interceptor,
        ));
    Ok(router)
}

/// After serving: commits everything the scheduler produced, closes the worker sessions
/// left open, checkpoints the database and copies it if asked; returns whether every run
/// is finished.
async fn wind_down(
    shared: &Arc<Shared>,
    writer: &mut Writer,
    opts: &ServeOptions,
) -> anyhow::Result<bool> {
    // Everything the scheduler produced is committed before returning.
    let (done_tx, done_rx) = oneshot::channel();
    let _ = shared.writer.send(WriterMessage::Flush(done_tx));
    tokio::select! {
        r = done_rx => r.map_err(|_| anyhow::anyhow!("the database writer stopped"))?,
        r = writer => match r {
            Ok(Err(e)) => return Err(e.into()),
            _ => anyhow::bail!("the database writer stopped"),
        },
    }
    let finished = shared.with(false, |s| s.finished());
    if finished {
        strider_process::note!("{}", progress_line(shared));
    }
    // Sessions whose workers had not left by now end with the coordinator.
    if let Err(e) = shared
        .db
        .close_sessions_left_open("the coordinator stopped")
        .await
    {
        tracing::warn!("closing the worker sessions at exit: {e}");
    }
    // A clean exit leaves the database file whole by itself: the write-ahead log copied
    // in and emptied, so the .db alone can be copied or moved. The writer's checkpointer
    // (passive, every 100 ms) or a session's last read can hold the log for a moment: a
    // busy answer is tried again, for up to a second, before the exit says -wal stays.
    for attempt in 1..=EXIT_CHECKPOINT_TRIES {
        match shared.db.checkpoint(true).await {
            Ok(Some(_)) => break,
            Ok(None) if attempt < EXIT_CHECKPOINT_TRIES => {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            Ok(None) => tracing::warn!(
                "the write-ahead log is in use by a reader: the database needs its -wal file until the next start"
            ),
            Err(e) => {
                tracing::warn!("checkpointing the database at exit: {e}");
                break;
            }
        }
    }
    if let Some(backup) = &opts.backup {
        // The live database is complete: a failed copy costs the copy, not the run.
        match shared.db.backup_to(&backup.path).await {
            Ok(()) => tracing::info!("copied the database to {}", backup.path.display()),
            Err(e) => tracing::warn!("{e}; the database itself is complete and committed"),
        }
    }
    Ok(finished)
}

/// Copies the database every `backup.every`; a failed copy is logged and tried again
/// next time (the run goes on: the live database is intact).
async fn back_up_periodically(db: Db, backup: Backup) {
    let mut every = tokio::time::interval(backup.every);
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    every.tick().await;
    loop {
        every.tick().await;
        let started = Instant::now();
        match db.backup_to(&backup.path).await {
            Ok(()) => tracing::info!(
                "copied the database to {} in {:.1} s",
                backup.path.display(),
                started.elapsed().as_secs_f64()
            ),
            Err(e) => tracing::warn!("{e}; trying again in {:?}", backup.every),
        }
    }
}

/// Stops leasing after `after`, then says so on `done` once no lease is out.
async fn stop_leasing(shared: Arc<Shared>, after: Duration, done: oneshot::Sender<()>) {
    tokio::time::sleep(after).await;
    let leased = shared.with(false, |s| {
        s.stop_leasing();
        s.leased()
    });
    tracing::warn!(
        "stopped leasing after {:.0} s (--stop-leasing-after); waiting for {leased} leased candidates",
        after.as_secs_f64()
    );
    let mut every = tokio::time::interval(Duration::from_millis(200));
    // Results, releases and expiries bring the count down; a lease ends one way or another.
    while shared.with(false, |s| s.leased()) > 0 {
        every.tick().await;
    }
    tracing::info!("every lease is back; stopping (serve again on this database to go on)");
    let _ = done.send(());
}

/// Lease expiry and the progress line.
fn background(shared: Arc<Shared>, opts: &ServeOptions) -> Vec<tokio::task::JoinHandle<()>> {
    let mut tasks = Vec::new();
    let tick = (opts.lease / 4).clamp(Duration::from_millis(50), Duration::from_secs(1));
    let s = shared.clone();
    tasks.push(tokio::spawn(async move {
        let mut every = tokio::time::interval(tick);
        loop {
            every.tick().await;
            let expired = s.with(true, |sch| sch.expire(Instant::now()));
            if expired > 0 {
                tracing::warn!(
                    "{expired} leases expired; their candidates wait for another worker"
                );
            }
        }
    }));
    let mut finished = shared.finished.subscribe();
    let s = shared.clone();
    tasks.push(tokio::spawn(async move {
        if finished.wait_for(|f| *f).await.is_ok() {
            // Said once the last results are in the database, so that whoever reads it on
            // this line (a script, a test, `--keep-serving` clients) reads everything.
            let (done_tx, done_rx) = oneshot::channel();
            let _ = s.writer.send(WriterMessage::Flush(done_tx));
            let _ = done_rx.await;
            tracing::info!("every run is finished");
        }
    }));
    if let Some(period) = opts.progress_every {
        tasks.push(tokio::spawn(async move {
            // On a terminal, a bar redrawn in place; elsewhere a line every `period`.
            if let Some(bar) = Bar::start(shared.candidates_budget(), "candidates") {
                let mut every = tokio::time::interval(Duration::from_millis(250));
                loop {
                    every.tick().await;
                    let (position, message) = progress_bar_state(&shared);
                    bar.set_position(position);
                    bar.set_message(message);
                }
            }
            let mut every = tokio::time::interval(period);
            // After a stop (SIGSTOP, a suspended laptop) one line, not one per missed period.
            every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            every.tick().await;
            loop {
                every.tick().await;
                strider_process::note!("{}", progress_line(&shared));
            }
        }));
    }
    tasks
}

/// Where the terminal bar stands (candidates, in whole generations, of the budget) and
/// its text: rate, workers, time left, feasible cells and the best fitness.
fn progress_bar_state(shared: &Shared) -> (u64, String) {
    let p = progress(shared);
    let position = (p.fraction_done * shared.candidates_budget() as f64).round() as u64;
    // The time left first: a narrow terminal cuts the end of the line.
    let left = match p.eta_seconds {
        Some(s) => format!("about {} left, ", duration_words(s)),
        None => String::new(),
    };
    let feasible: u32 = p.runs.iter().map(|r| r.feasible_elites).sum();
    let best = p
        .runs
        .iter()
        .map(|r| r.best_fitness)
        .fold(0.0_f64, f64::max);
    let message = format!(
        "{left}{:.1}/s, {feasible} feasible cells, best {best:.3}, {}",
        p.trials_per_second,
        strider_process::count_words(p.workers_connected as usize, "worker"),
    );
    (position, message)
}

/// Above this many runs, the progress line sums them up instead of listing each.
const RUNS_LISTED: usize = 6;

/// One line of progress: throughput, workers, how much is done and the time left, and each
/// run's state (summed up for a large experiment).
pub fn progress_line(shared: &Shared) -> String {
    let p = progress(shared);
    let left = match p.eta_seconds {
        Some(s) => format!(", about {} left", duration_words(s)),
        None => String::new(),
    };
    let mut line = format!(
        "[{:7.1} s] {:.1} results/s, {}, {:.1} % done{left}",
        shared.uptime(),
        p.trials_per_second,
        strider_process::count_words(p.workers_connected as usize, "worker"),
        100.0 * p.fraction_done,
    );
    let initial = shared.with(false, |s| s.experiment().run.initial_population);
    if p.runs.len() > RUNS_LISTED {
        line.push_str(&runs_summary(&p.runs, initial));
        return line;
    }
    for r in &p.runs {
        let phase = if r.finished {
            "finished".to_string()
        } else if r.initial_passed < initial {
            format!("initial {}/{initial}", r.initial_passed)
        } else {
            format!("generation {}/{}", r.generation, r.generations)
        };
        line.push_str(&format!(
            " | run {}: {phase}, {} candidates, feasible cells {} ({:.2} %), infeasible-only {}, best {}",
            r.run,
            r.trials_done,
            r.feasible_elites,
            100.0 * r.coverage,
            r.infeasible_only,
            best_words(r.feasible_elites, r.best_fitness)
        ));
    }
    line
}

/// The best fitness of a library of `elites` designs, or `none` while it is empty.
fn best_words(elites: u32, best: f64) -> String {
    if elites == 0 {
        "none".into()
    } else {
        format!("{best:.4}")
    }
}

/// Many runs in a few figures: how many are finished, the range of their generations,
/// feasible cells (least, mean, most) and the best fitness of any.
fn runs_summary(runs: &[v1::RunProgress], initial: u32) -> String {
    let finished = runs.iter().filter(|r| r.finished).count();
    let drawing = runs
        .iter()
        .filter(|r| !r.finished && r.initial_passed < initial)
        .count();
    let generations = runs.iter().map(|r| r.generation);
    let (low, high) = (
        generations.clone().min().unwrap_or(0),
        generations.max().unwrap_or(0),
    );
    let cells = runs.iter().map(|r| r.feasible_elites);
    let mean = f64::from(cells.clone().sum::<u32>()) / runs.len() as f64;
    let best = runs
        .iter()
        .filter(|r| r.feasible_elites > 0)
        .map(|r| r.best_fitness)
        .fold(0.0_f64, f64::max);
    let best = best_words(cells.clone().max().unwrap_or(0), best);
    format!(
        " | {} runs: {finished} finished, {drawing} drawing initial designs, generations {low}-{high} of {}; feasible cells {}-{} (mean {mean:.0}); best {best}",
        runs.len(),
        runs[0].generations,
        cells.clone().min().unwrap_or(0),
        cells.max().unwrap_or(0),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn many_runs_are_summed_up_in_a_few_figures() {
        let run = |generation, feasible_elites, finished, best_fitness| v1::RunProgress {
            generation,
            generations: 300,
            initial_passed: if generation > 0 { 400 } else { 17 },
            feasible_elites,
            finished,
            best_fitness,
            ..Default::default()
        };
        let runs = [
            run(0, 0, false, 0.0),
            run(120, 40, false, 2.5),
            run(300, 200, true, 3.25),
            run(150, 60, false, 1.0),
        ];
        assert_eq!(
            runs_summary(&runs, 400),
            " | 4 runs: 1 finished, 1 drawing initial designs, generations 0-300 of 300; \
             feasible cells 0-200 (mean 75); best 3.2500"
        );
    }
}
