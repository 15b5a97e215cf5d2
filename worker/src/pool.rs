//! The worker process's simulation threads: exactly `threads` long-lived OS threads that
//! take one trial at a time, like the batch evaluator's scoped threads.
//!
//! Why not tokio's blocking pool: it starts a new thread whenever no idle one is there at
//! the instant of the call, and a trial's thread frees its core (the semaphore permit)
//! just before going idle, so trials rotated over 5 or 6 threads on 2 cores: more
//! migrations, colder caches and malloc arenas, and about 15 % more CPU per trial than the
//! batch evaluator (BENCHMARKS.md, "`run` against the batch evaluator alone").

use crate::evaluate::evaluate_to_enter;
use crate::help::{self, panic_message, Job, Offer};
use std::collections::VecDeque;
use std::num::NonZeroUsize;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Instant;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::{Genome, Outcome, Scheme};
use tokio::sync::OwnedSemaphorePermit;

/// One trial to run, and where its answer goes.
pub struct Trial<K> {
    /// Whatever the caller needs to recognise the answer (a candidate id).
    pub key: K,
    /// What the run fixes.
    pub ctx: EvalContext,
    pub genome: Genome,
    /// Its run's scheme.
    pub scheme: Scheme,
    pub seed: CandidateSeed,
    /// The fitness of the elite its cell held when it was drawn, if any
    /// ([`evaluate_to_enter`]).
    pub to_beat: Option<f64>,
    /// Drawn ahead of its generation (`CandidateKey::drawn_ahead`): it waits for every
    /// other trial and for jobs of help, which finish the open generation.
    pub later: bool,
    /// The core it holds: released when the trial ends, before its answer is sent.
    pub core: OwnedSemaphorePermit,
    /// Where the answer goes; a closed receiver (a session that ended) drops it.
    pub answer: flume::Sender<Answer<K>>,
}

/// A finished trial: its key, its outcome (or what the simulation panicked with) and its
/// wall time in seconds.
pub type Answer<K> = (K, Result<Outcome, String>, f64);

/// What a simulation thread runs for each trial.
pub type Evaluate = fn(&EvalContext, &Genome, Scheme, CandidateSeed, Option<f64>) -> Outcome;

/// What a simulation thread takes next (held only until it runs: the size does not matter).
#[allow(clippy::large_enum_variant)]
enum Work<K> {
    Trial(Trial<K>),
    Help(Job),
}

/// Runs one trial and answers it. A trial that panics is answered with the panic's
/// message and its thread goes on: a lost thread would hold its candidate (heartbeated,
/// never answered) until the run hung.
fn answer_trial<K>(t: Trial<K>, eval: Evaluate) {
    let start = Instant::now();
    let outcome = catch_unwind(|| eval(&t.ctx, &t.genome, t.scheme, t.seed, t.to_beat))
        .map_err(|p| panic_message(&*p));
    let seconds = start.elapsed().as_secs_f64();
    drop(t.core);
    let _ = t.answer.send((t.key, outcome, seconds));
}

thread_local! {
    /// This thread runs a trial drawn ahead (counted in `running_later`): it cannot take
    /// the job of help its own trial offers.
    static RUNNING_LATER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// The threads' work: trials, and jobs of help (crate::help), under one lock so that a
/// thread waiting for either is woken by both and counted idle exactly.
struct Queue<K> {
    state: Mutex<QueueState<K>>,
    ready: Condvar,
}

struct QueueState<K> {
    trials: VecDeque<Trial<K>>,
    help: VecDeque<Job>,
    /// Trials drawn ahead, taken last.
    later: VecDeque<Trial<K>>,
    /// Threads waiting for work.
    idle: usize,
    /// Threads running a trial drawn ahead: each takes a job of help next.
    running_later: usize,
    /// The pool was dropped: threads end once no trial waits.
    closed: bool,
}

impl<K> Queue<K> {
    fn new() -> Self {
        Self {
            state: Mutex::new(QueueState {
                trials: VecDeque::new(),
                help: VecDeque::new(),
                later: VecDeque::new(),
                idle: 0,
                running_later: 0,
                closed: false,
            }),
            ready: Condvar::new(),
        }
    }

    fn lock(&self) -> MutexGuard<'_, QueueState<K>> {
        // Nothing panics holding it; a poisoned lock still holds consistent queues.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The next work: a trial, then a job of help, then a trial drawn ahead; `None` once
    /// the pool is dropped and nothing waits.
    fn next(&self) -> Option<Work<K>> {
        let mut s = self.lock();
        loop {
            if let Some(t) = s.trials.pop_front() {
                return Some(Work::Trial(t));
            }
            if let Some(job) = s.help.pop_front() {
                return Some(Work::Help(job));
            }
            if let Some(t) = s.later.pop_front() {
                s.running_later += 1;
                return Some(Work::Trial(t));
            }
            if s.closed {
                return None;
            }
            s.idle += 1;
            s = self.ready.wait(s).unwrap_or_else(PoisonError::into_inner);
            s.idle -= 1;
        }
    }
}

impl<K: Send> Offer for Queue<K> {
    fn offer(&self, job: Job) -> bool {
        let mut s = self.lock();
        // Only for a thread that would otherwise wait, or that runs a trial drawn ahead
        // (it takes the job when that ends, if the holder has not started that trial by
        // then), other than the one asking: one per job or trial waiting.
        let asking = usize::from(RUNNING_LATER.get());
        if s.idle + s.running_later - asking <= s.help.len() + s.trials.len() {
            return false;
        }
        s.help.push_back(job);
        drop(s);
        self.ready.notify_one();
        true
    }
}

/// The simulation threads. Dropping the pool lets them finish the trials handed to them
/// and end.
pub struct SimPool<K> {
    queue: Arc<Queue<K>>,
}

impl<K: Send + 'static> SimPool<K> {
    /// Starts `threads` threads named `strider-sim-N`.
    pub fn new(threads: NonZeroUsize) -> std::io::Result<Self> {
        Self::with(threads, evaluate_to_enter)
    }

    /// Starts `threads` threads that run `eval` for each trial (a panic answered, not
    /// lost); one with nothing to do helps another with its confirming trials
    /// (crate::help).
    pub fn with(threads: NonZeroUsize, eval: Evaluate) -> std::io::Result<Self> {
        let queue = Arc::new(Queue::new());
        for i in 0..threads.get() {
            let queue = queue.clone();
            std::thread::Builder::new()
                .name(format!("strider-sim-{i}"))
                .spawn(move || {
                    help::install(Some(queue.clone() as Arc<dyn Offer>));
                    while let Some(work) = queue.next() {
                        match work {
                            Work::Trial(t) if t.later => {
                                RUNNING_LATER.set(true);
                                answer_trial(t, eval);
                                RUNNING_LATER.set(false);
                                queue.lock().running_later -= 1;
                            }
                            Work::Trial(t) => answer_trial(t, eval),
                            // A job catches its trial's panic for its holder; this only
                            // keeps the thread should the job itself fail.
                            Work::Help(job) => {
                                if let Err(p) = catch_unwind(AssertUnwindSafe(job)) {
                                    tracing::error!(
                                        "a confirming trial's helper failed: {}",
                                        panic_message(&*p)
                                    );
                                }
                            }
                        }
                    }
                })?;
        }
        Ok(Self { queue })
    }

    /// Hands a trial to the next free thread (callers hold a core permit, so a thread is
    /// free or about to be; one may first finish a trial it took to help another).
    pub fn run(&self, trial: Trial<K>) {
        let mut s = self.queue.lock();
        if trial.later {
            s.later.push_back(trial);
        } else {
            s.trials.push_back(trial);
        }
        drop(s);
        self.queue.ready.notify_one();
    }
}

impl<K> Drop for SimPool<K> {
    fn drop(&mut self) {
        self.queue.lock().closed = true;
        self.queue.ready.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::evaluate;
    use strider_common::rng::CandidateSeed;
    use strider_common::InvalidReason;
    use tokio::sync::Semaphore;

    #[tokio::test]
    async fn answers_every_trial_with_the_batch_outcome_and_frees_its_cores() {
        let ctx = EvalContext::paper();
        let pool = SimPool::new(NonZeroUsize::new(2).unwrap()).unwrap();
        let cores = Arc::new(Semaphore::new(2));
        let (answer, answers) = flume::unbounded();
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
        let genomes: Vec<Genome> = (0..6)
            .map(|_| Genome::random(Scheme::Static, &mut rng))
            .collect();
        for (i, g) in genomes.iter().enumerate() {
            let core = cores.clone().acquire_owned().await.unwrap();
            pool.run(Trial {
                key: i,
                ctx,
                genome: *g,
                scheme: Scheme::Static,
                seed: CandidateSeed::new(1, i as u64),
                to_beat: None,
                later: false,
                core,
                answer: answer.clone(),
            });
        }
        let mut got = Vec::new();
        for _ in 0..genomes.len() {
            got.push(answers.recv_async().await.unwrap());
        }
        got.sort_by_key(|a| a.0);
        for (i, (key, outcome, seconds)) in got.into_iter().enumerate() {
            assert_eq!(key, i);
            assert!(seconds >= 0.0);
            let expected = evaluate(
                &ctx,
                &genomes[i],
                Scheme::Static,
                CandidateSeed::new(1, i as u64),
            );
            assert_eq!(outcome, Ok(expected));
        }
        // Every core was given back.
        assert_eq!(cores.available_permits(), 2);
    }

    #[tokio::test]
    async fn a_trial_that_panics_is_answered_with_the_message_and_its_thread_goes_on() {
        fn panics_on_odd(
            ctx: &EvalContext,
            g: &Genome,
            s: Scheme,
            seed: CandidateSeed,
            _: Option<f64>,
        ) -> Outcome {
            if seed.candidate.0 % 2 == 1 {
                panic!(
                    "contact manifold overflow in candidate {}",
                    seed.candidate.0
                );
            }
            evaluate(ctx, g, s, seed)
        }
        let ctx = EvalContext::paper();
        // One thread: if a panic took it, the trials after it would never be answered.
        let pool = SimPool::with(NonZeroUsize::MIN, panics_on_odd).unwrap();
        let cores = Arc::new(Semaphore::new(1));
        let (answer, answers) = flume::unbounded();
        let genome = Genome::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../designs/max.json"),
        )
        .unwrap();
        for i in 0..4u64 {
            let core = cores.clone().acquire_owned().await.unwrap();
            pool.run(Trial {
                key: i,
                ctx,
                genome,
                scheme: Scheme::Static,
                seed: CandidateSeed::new(1, i),
                to_beat: None,
                later: false,
                core,
                answer: answer.clone(),
            });
        }
        for i in 0..4u64 {
            let (key, outcome, _) = answers.recv_async().await.unwrap();
            assert_eq!(key, i);
            match outcome {
                Err(why) => {
                    assert_eq!(i % 2, 1);
                    assert!(why.contains("contact manifold overflow"), "{why}");
                }
                Ok(_) => assert_eq!(i % 2, 0),
            }
        }
        assert_eq!(cores.available_permits(), 1);
    }

    #[tokio::test]
    async fn idle_threads_helping_with_the_confirming_trials_give_the_outcome_of_one_thread() {
        // One candidate at a time on three threads: two are idle, and take the later
        // confirming trials (crate::help). Designs that pass every one (the holder waits
        // for the helpers' verdicts), fail the first floor (the helpers' trials are
        // abandoned), the second, and the finer step (the last: a helper's verdict; on
        // by default, said here so that a change of default keeps it).
        let mut ctx = EvalContext::paper();
        ctx.limits.confirm_substeps_factor = 2;
        // The finer step's fixture falls between 1 s (the default window there) and 15 s
        // after its trial: the long window keeps a design that the finer step refuses.
        ctx.limits.confirm_substeps_upright_seconds = 15.0;
        let pool = SimPool::new(NonZeroUsize::new(3).unwrap()).unwrap();
        let cores = Arc::new(Semaphore::new(3));
        let verdict = |o: &Outcome| match o {
            Outcome::Valid { .. } => "feasible".to_string(),
            Outcome::Invalid {
                reason: InvalidReason::FrictionSensitive { friction, .. },
                ..
            } => format!("refused at friction {friction}"),
            Outcome::Invalid {
                reason: InvalidReason::StepSensitive { .. },
                ..
            } => "refused at the finer step".into(),
            other => format!("{other:?}"),
        };
        let designs = [
            ("walks_on_every_floor.json", "feasible"),
            ("tips_on_the_grippy_floor.json", "refused at friction 1"),
            (
                "meets_the_brief_at_the_finer_step_then_falls.json",
                "refused at friction 0.6",
            ),
            (
                "falls_at_the_finer_step_only.json",
                "refused at the finer step",
            ),
        ];
        for (name, expected) in designs {
            let genome = Genome::load(
                &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("tests/fixtures")
                    .join(name),
            )
            .unwrap();
            let seed = CandidateSeed::new(1, 0);
            let (answer, answers) = flume::unbounded();
            let core = cores.clone().acquire_owned().await.unwrap();
            pool.run(Trial {
                key: name,
                ctx,
                genome,
                scheme: Scheme::Static,
                seed,
                to_beat: None,
                later: false,
                core,
                answer,
            });
            let (_, helped, _) = answers.recv_async().await.unwrap();
            let alone = evaluate(&ctx, &genome, Scheme::Static, seed);
            assert_eq!(verdict(&alone), expected, "{name}");
            assert_eq!(helped, Ok(alone), "{name}");
        }
        assert_eq!(cores.available_permits(), 3);
    }

    #[test]
    fn trials_come_before_help_and_help_goes_only_to_a_thread_with_nothing_to_do() {
        let queue = Queue::<u32>::new();
        assert!(!queue.offer(Box::new(|| ())), "no thread waits");
        queue.lock().idle = 1;
        assert!(queue.offer(Box::new(|| ())));
        assert!(
            !queue.offer(Box::new(|| ())),
            "the one waiting thread has a job already"
        );
        let cores = Arc::new(Semaphore::new(1));
        let (answer, _answers) = flume::unbounded();
        queue.lock().trials.push_back(Trial {
            key: 7,
            ctx: EvalContext::paper(),
            genome: strider_common::reference::max(),
            scheme: Scheme::Static,
            seed: CandidateSeed::new(0, 0),
            to_beat: None,
            later: false,
            core: cores.try_acquire_owned().unwrap(),
            answer,
        });
        queue.lock().idle = 0;
        assert!(matches!(
            queue.next(),
            Some(Work::Trial(Trial { key: 7, .. }))
        ));
        assert!(matches!(queue.next(), Some(Work::Help(_))));
        queue.lock().closed = true;
        assert!(queue.next().is_none(), "closed and empty: the thread ends");
    }

    #[test]
    fn help_comes_before_trials_drawn_ahead_and_waits_for_a_thread_running_one() {
        let queue = Queue::<u32>::new();
        let cores = Arc::new(Semaphore::new(2));
        let (answer, _answers) = flume::unbounded();
        let trial = |key| Trial {
            key,
            ctx: EvalContext::paper(),
            genome: strider_common::reference::max(),
            scheme: Scheme::Static,
            seed: CandidateSeed::new(0, 0),
            to_beat: None,
            later: true,
            core: cores.clone().try_acquire_owned().unwrap(),
            answer: answer.clone(),
        };
        queue.lock().later.push_back(trial(1));
        queue.lock().later.push_back(trial(2));
        assert!(matches!(
            queue.next(),
            Some(Work::Trial(Trial { key: 1, .. }))
        ));
        // Asked by the thread running trial 1 itself: no one could take it.
        RUNNING_LATER.set(true);
        assert!(
            !queue.offer(Box::new(|| ())),
            "the asking thread is not a helper"
        );
        RUNNING_LATER.set(false);
        // Asked by another: the thread running trial 1 takes it when done, before trial 2.
        assert!(queue.offer(Box::new(|| ())));
        assert!(!queue.offer(Box::new(|| ())), "one thread, one job");
        assert!(matches!(queue.next(), Some(Work::Help(_))));
        assert!(matches!(
            queue.next(),
            Some(Work::Trial(Trial { key: 2, .. }))
        ));
    }

    #[test]
    fn dropping_the_pool_ends_its_threads() {
        let pool = SimPool::<u32>::new(NonZeroUsize::new(2).unwrap()).unwrap();
        let queue = Arc::downgrade(&pool.queue);
        drop(pool);
        // Each thread holds the queue until it ends.
        let deadline = Instant::now() + std::time::Duration::from_secs(60);
        while queue.upgrade().is_some() {
            assert!(Instant::now() < deadline, "the threads did not end");
            std::thread::yield_now();
        }
    }
}
