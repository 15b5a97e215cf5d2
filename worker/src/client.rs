//! The worker process's side of `strider.v1.WorkerService`: connect (retrying with backoff
//! while the coordinator is not there yet or restarts), say Hello, evaluate assignments on
//! every core, stream each result back as soon as it is ready, keep leases alive with
//! heartbeats, and on shutdown give back what has not started and finish (or give back)
//! the rest within a bound.

use crate::evaluate::evaluate_to_enter;
use crate::pool::{Answer, Evaluate, SimPool, Trial};
use crate::synthetic::instant_outcome;
use std::collections::{BTreeSet, VecDeque};
use std::num::NonZeroUsize;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use strider_common::rng::CandidateSeed;
use strider_common::CandidateKey;
use strider_common::EvalContext;
use strider_common::{Experiment, Genome, Outcome, Scheme};
use strider_proto::convert::scheme_from_wire;
use strider_proto::secret::Secret;
use strider_proto::v1::{
    self, coordinator_message, worker_message, worker_service_client::WorkerServiceClient,
    WorkerMessage,
};
use strider_proto::PROTOCOL_VERSION;
use tokio::sync::{mpsc, watch, Semaphore};
use tonic::transport::Endpoint;
use tonic::{Code, Request, Status};

/// How results are produced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Evaluator {
    /// Simulate (the only real one).
    Simulation,
    /// **Benchmark only**: instant made-up results (see [`crate::synthetic`]).
    InstantSyntheticResults,
}

impl Evaluator {
    /// What the simulation threads run for each trial: the session itself never asks
    /// which evaluator it has.
    pub fn function(self) -> Evaluate {
        match self {
            Evaluator::Simulation => evaluate_to_enter,
            Evaluator::InstantSyntheticResults => instant_outcome,
        }
    }
}

/// Where the coordinator is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CoordinatorAddress {
    /// A fixed URL, `http://host:port`.
    Url(String),
    /// The file a coordinator writes its URL to (`serve --address-file`), read again
    /// before every connection attempt: a worker waits for it to appear, and follows a
    /// coordinator that restarts on another host (a resubmitted batch job).
    File(PathBuf),
}

impl CoordinatorAddress {
    /// The URL to try now: the fixed one, or the first line of the address file.
    fn resolve(&self) -> Result<String, String> {
        match self {
            CoordinatorAddress::Url(u) => Ok(u.clone()),
            CoordinatorAddress::File(f) => match std::fs::read_to_string(f) {
                Ok(text) => match text.lines().next().map(str::trim) {
                    Some(url) if !url.is_empty() => Ok(url.to_string()),
                    _ => Err(format!("address file {} is empty", f.display())),
                },
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(format!(
                    "waiting for the coordinator to write {}",
                    f.display()
                )),
                Err(e) => Err(format!("address file {}: {e}", f.display())),
            },
        }
    }
}

impl std::fmt::Display for CoordinatorAddress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CoordinatorAddress::Url(u) => write!(f, "{u}"),
            CoordinatorAddress::File(p) => write!(f, "the coordinator named in {}", p.display()),
        }
    }
}

/// The gRPC endpoint of a URL, with the worker's connection settings.
fn endpoint(url: &str) -> Result<Endpoint, WorkerError> {
    Ok(Endpoint::from_shared(url.to_string())
        .map_err(|e| WorkerError::BadUrl {
            url: url.to_string(),
            problem: e.to_string(),
        })?
        .connect_timeout(Duration::from_secs(5))
        .tcp_nodelay(true)
        .http2_keep_alive_interval(Duration::from_secs(10))
        .keep_alive_timeout(Duration::from_secs(20)))
}

/// How to reach the coordinator and what to offer it.
#[derive(Clone, Debug)]
pub struct ConnectOptions {
    /// Where the coordinator is.
    pub coordinator: CoordinatorAddress,
    /// The secret to show, if the coordinator wants one.
    pub authorization: Option<Secret>,
    /// Trials at once.
    pub threads: NonZeroUsize,
    /// Name for the coordinator's logs.
    pub name: String,
    /// The build (the coordinator refuses another one: trials are bit-identical only
    /// within a build).
    pub build: String,
    /// How results are produced.
    pub evaluator: Evaluator,
    /// On shutdown, how long running trials may take to finish before they are given back.
    pub drain: Duration,
    /// Longest wait between connection attempts.
    pub max_backoff: Duration,
    /// Stop with [`WorkerError::GaveUp`] once no coordinator has welcomed this worker for
    /// this long (`None`: wait for one for ever, as a worker of a separate job does).
    pub give_up_after: Option<Duration>,
}

/// Why the worker stopped for good.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// The coordinator refused it in a way retrying cannot fix.
    #[error("the coordinator refused this worker: {0}")]
    Refused(String),
    /// No coordinator welcomed it within [`ConnectOptions::give_up_after`].
    #[error("no coordinator has answered for {0:?}: giving up")]
    GaveUp(Duration),
    /// The coordinator's URL is malformed.
    #[error("coordinator URL {url}: {problem}")]
    BadUrl {
        url: String,
        /// What is wrong.
        problem: String,
    },
    /// The reference trial, run before connecting, panicked (a bug, not a condition).
    #[error("the reference trial failed: {0}")]
    ReferenceTrial(String),
}

/// Results this process has handed to its streams, over all its sessions: said when it
/// ends, so that results sent again after a coordinator lost some can be counted
/// (BENCHMARKS.md, the kill-loss window).
static RESULTS_SENT: AtomicU64 = AtomicU64::new(0);

/// How a session ended.
enum End {
    /// The experiment is finished.
    Finished,
    /// Asked to shut down; done.
    ShutDown,
    /// Connection lost (or never made); try again. `true` when the session got as far as
    /// a Welcome (so backoff restarts).
    Lost(String, bool),
}

/// Works for the coordinator until the experiment is finished or `shutdown` turns true.
pub async fn work(
    opts: ConnectOptions,
    mut shutdown: watch::Receiver<bool>,
) -> Result<(), WorkerError> {
    // A fixed URL that cannot work is an error now; one read from a file may be fixed
    // by the coordinator rewriting it, so it is retried.
    if let CoordinatorAddress::Url(url) = &opts.coordinator {
        endpoint(url)?;
    }
    let authorize = strider_proto::secret::client_interceptor(opts.authorization.as_ref());
    // Shared across sessions, so trials of a lost session still running keep their cores.
    let cores = Arc::new(Semaphore::new(opts.threads.get()));
    let pool = SimPool::with(opts.threads, opts.evaluator.function())
        .map_err(|e| WorkerError::Refused(format!("starting simulation threads: {e}")))?;
    // The reference trial (about 480 physics steps), once, off the async threads: each
    // Hello carries its digest.
    tokio::task::spawn_blocking(crate::reference_trial::digest)
        .await
        .map_err(|e| WorkerError::ReferenceTrial(e.to_string()))?;
    let first_backoff = Duration::from_millis(100);
    let mut backoff = first_backoff;
    // When a coordinator last had this worker connected (or it started).
    let mut last_welcome = tokio::time::Instant::now();
    // The last session's token (its Welcome's): named when connecting again, so the
    // coordinator ends that session at once rather than when its connection times out.
    let mut last_session = 0;
    loop {
        if *shutdown.borrow() {
            return Ok(());
        }
        let end = match opts.coordinator.resolve() {
            Ok(url) => match endpoint(&url) {
                Ok(endpoint) => {
                    session(
                        &opts,
                        &url,
                        &endpoint,
                        authorize.clone(),
                        (&cores, &pool),
                        &mut shutdown,
                        &mut last_session,
                    )
                    .await?
                }
                Err(e) => End::Lost(e.to_string(), false),
            },
            Err(why) => End::Lost(why, false),
        };
        match end {
            End::Finished => {
                tracing::info!(
                    results_sent = RESULTS_SENT.load(Ordering::Relaxed),
                    "the experiment is finished"
                );
                return Ok(());
            }
            End::ShutDown => {
                tracing::info!(
                    results_sent = RESULTS_SENT.load(Ordering::Relaxed),
                    "stopped"
                );
                return Ok(());
            }
            End::Lost(why, welcomed) => {
                // Told to stop meanwhile: nothing to retry, and no warning that retrying
                // would follow.
                if *shutdown.borrow() {
                    tracing::info!(
                        %why,
                        results_sent = RESULTS_SENT.load(Ordering::Relaxed),
                        "stopped; the connection was lost meanwhile"
                    );
                    return Ok(());
                }
                if welcomed {
                    backoff = first_backoff;
                    last_welcome = tokio::time::Instant::now();
                }
                if let Some(limit) = opts.give_up_after {
                    if last_welcome.elapsed() >= limit {
                        tracing::error!("not connected to {}: {why}", opts.coordinator);
                        return Err(WorkerError::GaveUp(limit));
                    }
                }
                tracing::warn!(
                    "not connected to {}: {why}; retrying in {backoff:?}",
                    opts.coordinator
                );
            }
        }
        tokio::select! {
            _ = tokio::time::sleep(backoff) => {}
            _ = shutdown.changed() => return Ok(()),
        }
        backoff = (backoff * 2).min(opts.max_backoff);
    }
}

/// Statuses retrying will not fix.
fn permanent(s: &Status) -> bool {
    matches!(
        s.code(),
        Code::Unauthenticated | Code::FailedPrecondition | Code::PermissionDenied
    )
}

struct Job {
    id: v1::CandidateId,
    genome: Genome,
    scheme: Scheme,
    seed: CandidateSeed,
    to_beat: Option<f64>,
}

fn job(a: v1::Assignment) -> Result<Job, String> {
    let id = a.id.ok_or("assignment without an id")?;
    let genome = a
        .genome
        .as_ref()
        .ok_or("assignment without a genome")
        .and_then(|g| Genome::try_from(g).map_err(|_| "assignment with a malformed genome"))
        .map_err(String::from)?;
    let scheme = scheme_from_wire(a.scheme).map_err(|e| e.to_string())?;
    let to_beat = match a.to_beat {
        Some(f) if !(f.is_finite() && f > 0.0) => {
            return Err(format!("to_beat {f} is not a positive fitness"))
        }
        other => other,
    };
    Ok(Job {
        to_beat,
        seed: CandidateSeed::new(a.run_seed, id.number),
        id,
        genome,
        scheme,
    })
}

fn msg(kind: worker_message::Kind) -> WorkerMessage {
    WorkerMessage { kind: Some(kind) }
}

/// The message that carries one candidate's result.
fn result_message(id: v1::CandidateId, outcome: &Outcome, seconds: f64) -> WorkerMessage {
    msg(worker_message::Kind::Result(v1::Result {
        id: Some(id),
        outcome: Some(outcome.into()),
        seconds,
    }))
}

type Done = Answer<v1::CandidateId>;

async fn session(
    opts: &ConnectOptions,
    url: &str,
    endpoint: &Endpoint,
    authorize: impl FnMut(Request<()>) -> Result<Request<()>, Status> + Clone,
    (cores, pool): (&Arc<Semaphore>, &SimPool<v1::CandidateId>),
    shutdown: &mut watch::Receiver<bool>,
    last_session: &mut u64,
) -> Result<End, WorkerError> {
    let channel = match endpoint.connect().await {
        Ok(c) => c,
        Err(e) => return Ok(End::Lost(format!("connecting: {e}"), false)),
    };
    let mut client = WorkerServiceClient::with_interceptor(channel, authorize);
    let slots = opts.threads.get() * 2;
    let (out, out_rx) = mpsc::channel::<WorkerMessage>(slots + 64);
    out.send(msg(worker_message::Kind::Hello(v1::Hello {
        protocol_version: PROTOCOL_VERSION,
        worker_name: opts.name.clone(),
        slots: slots as u32,
        build: opts.build.clone(),
        replaces: *last_session,
        reference_trial: crate::reference_trial::digest(),
    })))
    .await
    .expect("the channel is open");
    let mut inbound = match client
        .work(tokio_stream::wrappers::ReceiverStream::new(out_rx))
        .await
    {
        Ok(r) => r.into_inner(),
        Err(s) if permanent(&s) => return Err(WorkerError::Refused(s.message().to_string())),
        Err(s) => {
            return Ok(End::Lost(
                format!("opening the stream: {}", s.message()),
                false,
            ))
        }
    };
    let ctx = match inbound.message().await {
        Ok(Some(v1::CoordinatorMessage {
            kind: Some(coordinator_message::Kind::Welcome(w)),
        })) => {
            if w.protocol_version != PROTOCOL_VERSION {
                return Err(WorkerError::Refused(format!(
                    "protocol version mismatch: this worker speaks version {PROTOCOL_VERSION}, the coordinator version {}",
                    w.protocol_version
                )));
            }
            let e = Experiment::from_toml(&w.settings_toml).map_err(|e| {
                WorkerError::Refused(format!("the coordinator's experiment does not load: {e}"))
            })?;
            tracing::info!(experiment = %w.experiment, lease_seconds = w.lease_seconds, "connected to {url}");
            *last_session = w.session;
            (EvalContext::of(&e), w.lease_seconds)
        }
        Ok(Some(_)) => {
            return Ok(End::Lost(
                "the coordinator did not send Welcome first".into(),
                false,
            ))
        }
        Ok(None) => return Ok(End::Lost("the coordinator closed the stream".into(), false)),
        Err(s) if permanent(&s) => return Err(WorkerError::Refused(s.message().to_string())),
        Err(s) => return Ok(End::Lost(s.message().to_string(), false)),
    };
    let (ctx, lease_seconds) = ctx;
    let mut heartbeat = tokio::time::interval(Duration::from_secs_f64(
        (f64::from(lease_seconds) / 3.0).max(0.2),
    ));
    let mut queue: VecDeque<Job> = VecDeque::new();
    let mut running: BTreeSet<CandidateKey> = BTreeSet::new();
    // Answers of this session's trials (a later session never sees them).
    let (answer, mut answers) = flume::unbounded::<Done>();
    let lost = |why: String| Ok(End::Lost(why, true));
    loop {
        tokio::select! {
            m = inbound.message() => match m {
                Ok(Some(v1::CoordinatorMessage { kind: Some(coordinator_message::Kind::Assignment(a)) })) => {
                    let j = match job(a) {
                        Ok(j) => j,
                        Err(why) => return lost(format!("bad assignment: {why}")),
                    };
                    queue.push_back(j);
                }
                Ok(Some(v1::CoordinatorMessage { kind: Some(coordinator_message::Kind::Finished(_)) })) => {
                    return Ok(End::Finished);
                }
                // Nothing changed on the coordinator's side; a result refused is a bug of
                // this build or a damaged message, for the log.
                Ok(Some(v1::CoordinatorMessage { kind: Some(coordinator_message::Kind::ResultRefused(r)) })) => {
                    let key = r.id.as_ref().map(|k| CandidateKey::from(k).to_string()).unwrap_or_default();
                    tracing::error!(candidate = %key, code = %r.code, "the coordinator refused a result: {}", r.reason);
                }
                Ok(Some(_)) => {}
                Ok(None) => return lost("the coordinator closed the stream".into()),
                // Past Welcome, a refusal is of one message (a result the coordinator
                // would not take): reconnect and go on rather than leave for good.
                Err(s) => return lost(format!("{:?}: {}", s.code(), s.message())),
            },
            permit = cores.clone().acquire_owned(), if !queue.is_empty() => {
                let permit = permit.expect("the semaphore is never closed");
                // The open generations' candidates first: one drawn ahead of its
                // generation waits for them (and may be dropped meanwhile).
                let next = queue.iter().position(|j| !j.id.drawn_ahead).unwrap_or(0);
                let j = queue.remove(next).expect("checked non-empty");
                running.insert(CandidateKey::from(&j.id));
                // Said before simulating, so that a worker that dies in this trial counts
                // against the candidate (a crash it causes is caught after a few).
                let began = v1::Heartbeat { in_progress: Vec::new(), started: vec![j.id] };
                if out.send(msg(worker_message::Kind::Heartbeat(began))).await.is_err() {
                    return lost("the stream closed".into());
                }
                pool.run(Trial {
                    key: j.id,
                    ctx,
                    genome: j.genome,
                    scheme: j.scheme,
                    seed: j.seed,
                    to_beat: j.to_beat,
                    later: j.id.drawn_ahead,
                    core: permit,
                    answer: answer.clone(),
                });
            },
            Ok((id, outcome, seconds)) = answers.recv_async() => {
                running.remove(&CandidateKey::from(&id));
                // A simulation that panicked has no outcome to send: leave the session, so
                // that the coordinator counts an attempt against the candidate (it fails
                // after a few workers) and leases the rest elsewhere; then reconnect.
                let outcome = match outcome {
                    Ok(o) => o,
                    Err(why) => {
                        tracing::error!(run = id.run, candidate = id.number, "the simulation panicked: {why}");
                        return lost(format!("the simulation of run {} candidate {} panicked: {why}", id.run, id.number));
                    }
                };
                if out.send(result_message(id, &outcome, seconds)).await.is_err() {
                    return lost("the stream closed".into());
                }
                RESULTS_SENT.fetch_add(1, Ordering::Relaxed);
            },
            _ = heartbeat.tick() => {
                // The running trials are said started again: a lease that expired and came
                // back to this worker began again as not started.
                let started: Vec<v1::CandidateId> = running
                    .iter()
                    .map(|&k| v1::CandidateId::from(k))
                    .collect();
                let in_progress: Vec<v1::CandidateId> = started
                    .iter()
                    .copied()
                    .chain(queue.iter().map(|j| j.id))
                    .collect();
                if !in_progress.is_empty()
                    && out.send(msg(worker_message::Kind::Heartbeat(v1::Heartbeat { in_progress, started }))).await.is_err()
                {
                    return lost("the stream closed".into());
                }
            },
            _ = shutdown.changed() => {
                drop(answer);
                drain(opts.drain, &out, queue, running, &mut answers).await;
                // Close this side and wait, briefly, for the coordinator to close its own:
                // a process that exits at once resets the connection, which the coordinator
                // could only log as an HTTP/2 protocol error.
                drop(out);
                let _ = tokio::time::timeout(Duration::from_secs(2), async {
                    while let Ok(Some(_)) = inbound.message().await {}
                })
                .await;
                return Ok(End::ShutDown);
            },
        }
    }
}

/// Shutdown: gives back what has not started, lets running trials finish for up to
/// `bound` and sends their results, then gives back the rest.
async fn drain(
    bound: Duration,
    out: &mpsc::Sender<WorkerMessage>,
    queue: VecDeque<Job>,
    mut running: BTreeSet<CandidateKey>,
    answers: &mut flume::Receiver<Done>,
) {
    let release = |candidates: Vec<v1::CandidateId>| {
        msg(worker_message::Kind::Release(v1::Release { candidates }))
    };
    let queued: Vec<v1::CandidateId> = queue.iter().map(|j| j.id).collect();
    if !queued.is_empty() {
        let _ = out.send(release(queued)).await;
    }
    tracing::info!(
        running = running.len(),
        "shutting down: finishing running trials for up to {bound:?}"
    );
    let deadline = tokio::time::Instant::now() + bound;
    while !running.is_empty() {
        tokio::select! {
            next = answers.recv_async() => match next {
                Ok((id, outcome, seconds)) => {
                    running.remove(&CandidateKey::from(&id));
                    // A panicked trial is handed back (the session is ending anyway).
                    let Ok(outcome) = outcome else {
                        let _ = out.send(release(vec![id])).await;
                        continue;
                    };
                    if out.send(result_message(id, &outcome, seconds)).await.is_ok() {
                        RESULTS_SENT.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(_) => break,
            },
            _ = tokio::time::sleep_until(deadline) => break,
        }
    }
    if !running.is_empty() {
        let left = running.iter().map(|&k| v1::CandidateId::from(k)).collect();
        let _ = out.send(release(left)).await;
    }
    // Threads still simulating finish in the background; the process does not wait.
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_address_file_is_waited_for_then_read_each_time() {
        let dir = std::env::temp_dir().join(format!("strider-address-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("coordinator.address");
        let _ = std::fs::remove_file(&file);
        let address = CoordinatorAddress::File(file.clone());

        let missing = address.resolve().unwrap_err();
        assert!(missing.contains("waiting for the coordinator"), "{missing}");
        std::fs::write(&file, "").unwrap();
        assert!(address.resolve().unwrap_err().contains("is empty"));
        std::fs::write(&file, "http://node1:50051\n").unwrap();
        assert_eq!(address.resolve().unwrap(), "http://node1:50051");
        // A coordinator resumed on another host rewrites it; the next attempt follows.
        std::fs::write(&file, "http://node7:50051\n").unwrap();
        assert_eq!(address.resolve().unwrap(), "http://node7:50051");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_malformed_fixed_url_is_an_error_not_a_retry() {
        assert!(matches!(
            endpoint("not a url"),
            Err(WorkerError::BadUrl { .. })
        ));
    }
}
