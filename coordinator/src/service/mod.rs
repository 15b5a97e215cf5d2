//! The distributed coordinator: the scheduler behind a lock, the database writer, and the
//! gRPC services (workers, clients, health, reflection) over them. Thin: every rule lives
//! in [`crate::qd::scheduler`].

pub mod auth;
pub mod client_api;
pub mod clock;
pub mod incoming;
/// `run`: needs the simulator (the `simulator` feature).
#[cfg(feature = "simulator")]
pub mod local;
pub mod metrics;
pub mod pace;
pub mod reference;
pub mod server;
pub mod sessions;
pub mod worker_api;
pub mod writer;

use crate::qd::scheduler::Scheduler;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio::sync::{mpsc, watch, Notify};
use writer::WriterMessage;

/// Results per second over the last minute, counted in one-second buckets.
#[derive(Default)]
pub struct Throughput {
    buckets: VecDeque<(u64, u64)>,
    total: u64,
}

impl Throughput {
    const WINDOW: u64 = 60;

    /// Counts one result at `second` (seconds since start).
    pub fn record(&mut self, second: u64) {
        self.total += 1;
        match self.buckets.back_mut() {
            Some((s, n)) if *s == second => *n += 1,
            _ => self.buckets.push_back((second, 1)),
        }
        while self
            .buckets
            .front()
            .is_some_and(|(s, _)| *s + Self::WINDOW <= second)
        {
            self.buckets.pop_front();
        }
    }

    /// The rate over the last minute (or since `now` seconds ago, if less).
    pub fn rate(&self, now: f64) -> f64 {
        let from = (now - Self::WINDOW as f64).max(0.0);
        let n: u64 = self
            .buckets
            .iter()
            .filter(|(s, _)| *s as f64 >= from.floor())
            .map(|(_, n)| n)
            .sum();
        n as f64 / (now - from).max(1.0)
    }
}

/// Most changes handed to the writer and not yet committed. While more are queued,
/// worker sessions stop reading results (HTTP/2 flow control then holds the workers
/// back), so the writer's queue, the coordinator's memory and what a crash can lose stay
/// bounded whatever the workers' pace: at most this many results are redone after a
/// SIGKILL.
pub const MAX_BACKLOG: usize = 16384;

/// Changes handed to the writer and not yet committed.
#[derive(Default)]
pub struct Backlog {
    writes: AtomicUsize,
    drained: Notify,
}

impl Backlog {
    /// `n` changes were queued.
    fn queued(&self, n: usize) {
        self.writes.fetch_add(n, Ordering::Relaxed);
    }

    /// `n` changes were committed: sessions waiting for room go on.
    pub fn committed(&self, n: usize) {
        self.writes.fetch_sub(n, Ordering::Relaxed);
        self.drained.notify_waiters();
    }

    /// Changes queued and not committed now.
    pub fn len(&self) -> usize {
        self.writes.load(Ordering::Relaxed)
    }

    /// Whether nothing is waiting to be committed.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether sessions should wait before taking more results.
    pub fn full(&self) -> bool {
        self.len() >= MAX_BACKLOG
    }
}

/// What every connection shares.
pub struct Shared {
    scheduler: Mutex<Scheduler>,
    writer: mpsc::UnboundedSender<WriterMessage>,
    /// What the writer holds uncommitted (bounded by sessions waiting on it).
    backlog: Arc<Backlog>,
    /// Woken when candidates may have become available.
    work: Notify,
    /// Steps completed (generations), for progress watchers.
    steps: watch::Sender<u64>,
    /// Whether every run is finished.
    finished: watch::Sender<bool>,
    /// Worker connections now.
    workers: AtomicU32,
    /// Their slots (candidates each keeps in hand), summed: their shares of a scarce step.
    slots: AtomicUsize,
    next_worker: AtomicU64,
    /// Live worker sessions, so a worker that connects again ends its last one.
    sessions: sessions::Sessions,
    /// The reference trial's digest that workers must match (this coordinator's own, or
    /// built without the simulator, the session's first worker's).
    reference: reference::ReferenceTrial,
    throughput: Mutex<Throughput>,
    started: Instant,
    /// The time run, stops left out: rates and the time left are measured on it.
    clock: Mutex<clock::RunningClock>,
    /// The recent pace, for the time left.
    pace: Mutex<pace::Pace>,
    /// The experiment as workers get it (without its initial designs).
    experiment_toml: String,
    db: crate::db::Db,
}

impl Shared {
    /// Runs `f` on the scheduler, hands its changes to the writer in order, and wakes
    /// watchers and (when `wake` and work is available) waiting workers.
    pub fn with<R>(&self, wake: bool, f: impl FnOnce(&mut Scheduler) -> R) -> R {
        let mut s = self.scheduler.lock().expect("no panic while scheduling");
        let out = f(&mut s);
        self.write(s.take_writes());
        let steps = s.steps_applied();
        self.steps
            .send_if_modified(|v| std::mem::replace(v, steps) != steps);
        let finished = s.finished();
        self.finished
            .send_if_modified(|v| std::mem::replace(v, finished) != finished);
        let available = wake && s.available();
        drop(s);
        if available {
            self.work.notify_waiters();
        }
        out
    }

    /// Hands changes to the writer, in order, counting them in the backlog.
    pub fn write(&self, writes: Vec<crate::qd::changes::Write>) {
        if writes.is_empty() {
            return;
        }
        self.backlog.queued(writes.len());
        // The writer only stops when the service does.
        let _ = self.writer.send(WriterMessage::Writes(writes));
    }

    /// Results accepted since the service started.
    pub fn results_total(&self) -> u64 {
        self.throughput
            .lock()
            .expect("no panic while counting")
            .total
    }

    /// Seconds since the service started.
    pub fn uptime(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// Reads the running clock every second from a thread of its own (not a task: a
    /// runtime busy for 10 s, say with a slow copy to shared storage, would read as a
    /// stop), so that only a stopped process misses readings. Ends with the service.
    pub fn read_the_clock_every_second(shared: &Arc<Self>) {
        let shared = Arc::downgrade(shared);
        let spawned = std::thread::Builder::new()
            .name("running clock".into())
            .spawn(move || loop {
                std::thread::sleep(std::time::Duration::from_secs(1));
                match shared.upgrade() {
                    Some(s) => s.running_seconds(),
                    None => return,
                };
            });
        if let Err(e) = spawned {
            tracing::warn!("no thread to read the running clock ({e}): a stop of the process will count as running time");
        }
    }

    /// Seconds the service has run: [`Shared::uptime`] less the time its process was
    /// stopped ([`clock::RunningClock`]). Read every second by a thread of its own.
    pub fn running_seconds(&self) -> f64 {
        let (seconds, stop) = self
            .clock
            .lock()
            .expect("no panic while reading the clock")
            .read(Instant::now());
        if let Some(stop) = stop {
            tracing::warn!(
                "this process was stopped for {:.1} s (SIGSTOP, a suspended job); rates and the time left leave it out",
                stop.as_secs_f64()
            );
        }
        seconds
    }

    /// Candidates the experiment evaluates, every run's initial population and
    /// generations (ES candidates count once).
    pub fn candidates_budget(&self) -> u64 {
        self.with(false, |s| {
            let e = s.experiment();
            e.run.candidates_per_run() * e.runs().len() as u64
        })
    }

    /// How much of the experiment is done, 0 to 1 ([`crate::qd::scheduler::fraction_done`]).
    pub fn fraction_done(&self) -> f64 {
        self.with(false, |s| {
            crate::qd::scheduler::fraction_done(&s.progress(), &s.experiment().run)
        })
    }

    /// Seconds left at the recent pace ([`pace::Pace`]: the last two minutes, or the last
    /// tenth of this process's time when longer, its stops left out), once this process
    /// has done some of the work: an estimate.
    pub fn eta(&self, fraction: f64) -> Option<f64> {
        let now = self.running_seconds();
        self.pace
            .lock()
            .expect("no panic while estimating")
            .observe(now, fraction)
    }
}
