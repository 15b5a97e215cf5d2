//! `strider.v1.WorkerService`: one bidirectional stream per worker process. The session
//! keeps the worker's slots filled with leases, takes its results, heartbeats and
//! releases, and gives every lease back the moment the stream ends.

use super::Shared;
use crate::qd::changes::Write;
use crate::qd::scheduler::{Accepted, Refusal};
use std::collections::HashSet;
use std::pin::Pin;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Instant;
use strider_common::CandidateKey;
use strider_common::Outcome;
use strider_common::WorkerId;
use strider_proto::convert::{self, scheme_to_wire};
use strider_proto::v1::{
    self, coordinator_message, worker_message, worker_service_server::WorkerService,
    CoordinatorMessage, WorkerMessage,
};
use strider_proto::PROTOCOL_VERSION;
use tokio::sync::mpsc;
use tokio_stream::wrappers::ReceiverStream;
use tonic::{Request, Response, Status, Streaming};

/// Why a session ended when its connection went without the worker closing its stream.
const CONNECTION_LOST: &str =
    "the connection was lost (no answer to keepalive pings, or the worker's process or network went away)";

/// Most candidates one worker may hold.
pub const MAX_SLOTS: u32 = 4096;

/// The worker service.
pub struct WorkerApi {
    pub(crate) shared: Arc<Shared>,
}

type Outbound = mpsc::Sender<Result<CoordinatorMessage, Status>>;

fn message(kind: coordinator_message::Kind) -> Result<CoordinatorMessage, Status> {
    Ok(CoordinatorMessage { kind: Some(kind) })
}

/// A candidate id off the wire.
pub fn key_from_wire(id: Option<&v1::CandidateId>) -> Result<CandidateKey, Status> {
    convert::key_from_wire("id", id).map_err(|e| Status::invalid_argument(e.to_string()))
}

#[tonic::async_trait]
impl WorkerService for WorkerApi {
    type WorkStream =
        Pin<Box<dyn tokio_stream::Stream<Item = Result<CoordinatorMessage, Status>> + Send>>;

    async fn work(
        &self,
        request: Request<Streaming<WorkerMessage>>,
    ) -> Result<Response<Self::WorkStream>, Status> {
        let mut inbound = request.into_inner();
        let hello = match inbound.message().await? {
            Some(WorkerMessage {
                kind: Some(worker_message::Kind::Hello(h)),
            }) => h,
            Some(_) => return Err(Status::invalid_argument("the first message must be Hello")),
            None => return Err(Status::invalid_argument("the stream ended before Hello")),
        };
        if hello.protocol_version != PROTOCOL_VERSION {
            return Err(Status::failed_precondition(format!(
                "protocol version mismatch: the worker speaks version {}, this coordinator version {PROTOCOL_VERSION}",
                hello.protocol_version
            )));
        }
        if hello.build != strider_common::build_id() {
            return Err(Status::failed_precondition(format!(
                "build mismatch: the worker is {:?}, this coordinator {:?}; trials are bit-identical only within one build on one kind of CPU (docs/rapier.md)",
                hello.build,
                strider_common::build_id()
            )));
        }
        if hello.slots == 0 || hello.slots > MAX_SLOTS {
            return Err(Status::invalid_argument(format!(
                "slots: {} is not in 1..={MAX_SLOTS}",
                hello.slots
            )));
        }
        // Last: a worker refused for its build, protocol or slots sets no digest.
        if let Err(why) = self
            .shared
            .reference
            .admit(hello.reference_trial, &hello.worker_name)
        {
            tracing::warn!(name = %hello.worker_name, "worker refused: {why}");
            return Err(Status::failed_precondition(why));
        }
        let shared = self.shared.clone();
        let id = WorkerId(shared.next_worker.fetch_add(1, Ordering::Relaxed));
        let lease_seconds = shared.with(false, |s| s.lease_duration().as_secs_f64());
        let token = shared.sessions.token(id);
        let (tx, rx) = mpsc::channel(hello.slots as usize + 16);
        tx.send(message(coordinator_message::Kind::Welcome(v1::Welcome {
            protocol_version: PROTOCOL_VERSION,
            experiment: shared.with(false, |s| s.experiment().name.clone()),
            settings_toml: shared.experiment_toml.clone(),
            lease_seconds: lease_seconds.ceil() as u32,
            session: token,
        })))
        .await
        .map_err(|_| Status::cancelled("the worker went away"))?;
        shared.write(vec![Write::WorkerJoined {
            id,
            name: hello.worker_name.clone(),
            build: hello.build.clone(),
            slots: hello.slots,
        }]);
        let replaced = shared.sessions.open(token);
        // Its last session, if still alive here, ends now: the worker gave it up.
        if shared.sessions.replace(hello.replaces, id) {
            tracing::info!(worker = id.0, name = %hello.worker_name, "worker connected again: its last session ends");
        }
        shared.workers.fetch_add(1, Ordering::Relaxed);
        shared
            .slots
            .fetch_add(hello.slots as usize, Ordering::Relaxed);
        tracing::info!(worker = id.0, name = %hello.worker_name, slots = hello.slots, "worker connected");
        let session = Session {
            shared,
            id,
            name: hello.worker_name.clone(),
            slots: hello.slots as usize,
            token,
            replaced,
            held: HashSet::new(),
            draining: false,
            results: 0,
            tx,
        };
        tokio::spawn(session.run(inbound));
        Ok(Response::new(Box::pin(ReceiverStream::new(rx))))
    }
}

struct Session {
    shared: Arc<Shared>,
    id: WorkerId,
    /// The name the worker gave (`--name`, or host and pid), for the logs.
    name: String,
    slots: usize,
    /// Its token ([`super::sessions::Sessions`]), and word of the session that replaced it.
    token: u64,
    replaced: tokio::sync::oneshot::Receiver<WorkerId>,
    /// Candidates leased to this worker and not answered by it. A lease that expired
    /// stays here: the worker may still be simulating it (it stalled, then went on), and
    /// its late result is taken or, if another worker answered first, ignored.
    held: HashSet<CandidateKey>,
    /// The worker gave candidates back: it is shutting down, so it is leased nothing
    /// more (what it returned would come straight back to it).
    draining: bool,
    results: u64,
    tx: Outbound,
}

impl Session {
    async fn run(mut self, mut inbound: Streaming<WorkerMessage>) {
        let shared = self.shared.clone();
        let mut finished = shared.finished.subscribe();
        // Until the session that replaced it says so (never, unless the worker connects
        // again), or its word is lost.
        let mut may_be_replaced = true;
        let reason = loop {
            if *finished.borrow_and_update() {
                let _ = self
                    .tx
                    .send(message(coordinator_message::Kind::Finished(
                        v1::Finished {},
                    )))
                    .await;
                break "the experiment is finished".to_string();
            }
            let work = shared.work.notified();
            tokio::pin!(work);
            work.as_mut().enable();
            // Registered before the check, so a commit in between is not missed.
            let drained = shared.backlog.drained.notified();
            tokio::pin!(drained);
            drained.as_mut().enable();
            let backlogged = shared.backlog.full();
            if let Err(reason) = self.top_up().await {
                break reason;
            }
            tokio::select! {
                // In this order: the results the worker sent before it connected again
                // are taken before the word that it did ends the session.
                biased;
                // The writer is behind: take no more results until it catches up.
                _ = &mut drained, if backlogged => {}
                m = inbound.message(), if !backlogged => match m {
                    Ok(Some(m)) => {
                        let result_of = match &m.kind {
                            Some(worker_message::Kind::Result(r)) => key_from_wire(r.id.as_ref()).ok(),
                            _ => None,
                        };
                        if let Err(status) = self.handle(m) {
                            // A refused result changes nothing: no attempt is counted and
                            // the session goes on; the lease stands, so the candidate's
                            // fate is decided by real failures only (the worker lost, or
                            // stalled past the lease: a worker whose results are always
                            // refused fails its candidates that way, in bounded time).
                            if let Some(key) = result_of {
                                tracing::warn!(
                                    worker = self.id.0,
                                    name = %self.name,
                                    %key,
                                    "result refused, nothing changed: {}",
                                    status.message()
                                );
                                let m = coordinator_message::Kind::ResultRefused(v1::ResultRefused {
                                    id: Some(key.into()),
                                    code: format!("{:?}", status.code()),
                                    reason: status.message().to_string(),
                                });
                                if self.tx.send(message(m)).await.is_err() {
                                    break CONNECTION_LOST.into();
                                }
                                continue;
                            }
                            tracing::warn!(worker = self.id.0, name = %self.name, "refused: {}", status.message());
                            // Any other malformed message cuts the worker off; what it held
                            // waits for others (the session's end below).
                            let reason = format!("refused: {}", status.message());
                            let _ = self.tx.send(Err(status)).await;
                            break reason;
                        }
                    }
                    Ok(None) => break "the worker closed its stream".into(),
                    // tonic reports a message over the size limit as OUT_OF_RANGE on our
                    // side and would end the stream with OK: tell the worker why.
                    Err(e) if e.code() == tonic::Code::OutOfRange => {
                        let why = format!("message too large: {}", e.message());
                        tracing::warn!(worker = self.id.0, name = %self.name, "refused: {why}");
                        let _ = self.tx.send(Err(Status::resource_exhausted(why.clone()))).await;
                        break format!("refused: {why}");
                    }
                    // HTTP/2 reports a reset connection as a protocol error reading the
                    // body: a worker killed, or its network cut, not a broken protocol.
                    Err(e) if e.code() == tonic::Code::Unknown => break format!(
                        "the connection was reset (the worker's process killed, or its network cut): {}",
                        e.message()
                    ),
                    Err(e) => break format!("stream error: {}", e.message()),
                },
                _ = &mut work => {}
                _ = finished.changed() => {}
                // The response stream is gone with the connection: the server's keepalive
                // gave up (no answer to pings for 20 s: a stopped or hung process, a
                // cut network) or the connection was reset (the process killed).
                _ = self.tx.closed() => break CONNECTION_LOST.into(),
                // Last, and not while the writer is behind (its results wait unread).
                by = &mut self.replaced, if may_be_replaced && !backlogged => match by {
                    Ok(by) => break format!(
                        "the worker connected again (worker {by}) and gave this session up"
                    ),
                    Err(_) => may_be_replaced = false,
                },
            }
        };
        let why = reason.clone();
        self.shared.sessions.close(self.token);
        // Before the others are woken to lease what it held: their shares without its slots.
        self.shared.workers.fetch_sub(1, Ordering::Relaxed);
        self.stop_leasing();
        self.shared.with(true, |s| s.disconnect(self.id, &why));
        self.shared.write(vec![Write::WorkerLeft {
            id: self.id,
            results: self.results,
            reason: reason.clone(),
        }]);
        tracing::info!(
            worker = self.id.0,
            name = %self.name,
            results = self.results,
            "worker left: {reason}"
        );
    }

    /// The worker is leaving (it gave candidates back, or its session ended): it is leased
    /// nothing more, and the others' shares of a scarce step no longer count its slots.
    /// Once, whichever comes first.
    fn stop_leasing(&mut self) {
        if !self.draining {
            self.shared.slots.fetch_sub(self.slots, Ordering::Relaxed);
            self.draining = true;
        }
    }

    /// Leases candidates until the worker's slots are full or none is available.
    async fn top_up(&mut self) -> Result<(), String> {
        let room = self.slots.saturating_sub(self.held.len());
        if room == 0 || self.draining {
            return Ok(());
        }
        let (id, slots) = (self.id, self.slots);
        let all_slots = self.shared.slots.load(Ordering::Relaxed);
        let leased = self.shared.with(false, |s| {
            let room = s
                .lease_cap(id, slots, all_slots)
                .map_or(room, |cap| room.min(cap));
            s.lease(id, Instant::now(), room)
        });
        for a in leased {
            if !self.held.insert(a.key) {
                // Its lease expired while this worker still had it, and came back to the
                // same worker: it is still queued or simulating there; sending it again
                // would simulate it twice.
                continue;
            }
            let m = coordinator_message::Kind::Assignment(v1::Assignment {
                id: Some(a.key.into()),
                genome: Some((&a.genome).into()),
                scheme: scheme_to_wire(a.scheme).into(),
                run_seed: a.run_seed.0,
                to_beat: a.to_beat,
            });
            if self.tx.send(message(m)).await.is_err() {
                return Err(CONNECTION_LOST.into());
            }
        }
        Ok(())
    }

    fn handle(&mut self, m: WorkerMessage) -> Result<(), Status> {
        match m.kind {
            Some(worker_message::Kind::Result(r)) => self.result(r),
            Some(worker_message::Kind::Heartbeat(h)) => {
                let keys = h
                    .in_progress
                    .iter()
                    .map(|k| key_from_wire(Some(k)))
                    .collect::<Result<Vec<_>, _>>()?;
                let started = h
                    .started
                    .iter()
                    .map(|k| key_from_wire(Some(k)))
                    .collect::<Result<Vec<_>, _>>()?;
                let id = self.id;
                self.shared.with(false, |s| {
                    s.heartbeat(id, &keys, Instant::now());
                    s.started(id, &started);
                });
                Ok(())
            }
            Some(worker_message::Kind::Release(r)) => {
                let keys = r
                    .candidates
                    .iter()
                    .map(|k| key_from_wire(Some(k)))
                    .collect::<Result<Vec<_>, _>>()?;
                for k in &keys {
                    self.held.remove(k);
                }
                self.stop_leasing();
                let id = self.id;
                self.shared.with(true, |s| s.release(id, &keys));
                Ok(())
            }
            Some(worker_message::Kind::Hello(_)) => {
                Err(Status::invalid_argument("Hello may only open the stream"))
            }
            None => Err(Status::invalid_argument("empty message")),
        }
    }

    fn result(&mut self, r: v1::Result) -> Result<(), Status> {
        let key = key_from_wire(r.id.as_ref())?;
        if !self.held.contains(&key) {
            // A result for a candidate that has one already (this worker's own, sent
            // twice, or another's): acknowledged and ignored, as the protocol says.
            if self.shared.with(false, |s| s.answered(key)) {
                tracing::debug!(worker = self.id.0, name = %self.name, %key, "duplicate result ignored");
                return Ok(());
            }
            return Err(Status::failed_precondition(format!(
                "{key} is not leased to this worker"
            )));
        }
        if !r.seconds.is_finite() || r.seconds < 0.0 {
            return Err(Status::invalid_argument(format!(
                "seconds: {} is not a duration",
                r.seconds
            )));
        }
        let wire = r
            .outcome
            .as_ref()
            .ok_or_else(|| Status::invalid_argument("outcome: missing"))?;
        let outcome =
            Outcome::try_from(wire).map_err(|e| Status::invalid_argument(e.to_string()))?;
        let id = self.id;
        let accepted = self.shared.with(true, |s| {
            s.accept(id, key, outcome, r.seconds).map_err(|e| match e {
                Refusal::NoSuchRun(_) | Refusal::Unknown(_) => Status::not_found(e.to_string()),
                Refusal::CellMismatch { .. } | Refusal::NotOutranked { .. } => {
                    Status::invalid_argument(e.to_string())
                }
            })
        })?;
        self.held.remove(&key);
        self.results += 1;
        // A result the candidate already had, or of one drawn ahead and dropped since, is
        // no work done for the run: not counted in results per second.
        if accepted == Accepted::Stored {
            let second = self.shared.running_seconds() as u64;
            self.shared
                .throughput
                .lock()
                .expect("no panic while counting")
                .record(second);
        }
        tracing::trace!(worker = id.0, %key, ?accepted, "result");
        Ok(())
    }
}
