//! The worker process's simulation threads: exactly `threads` long-lived OS threads that
//! take one trial at a time, like the batch evaluator's scoped threads.
//!
//! Why not tokio's blocking pool: it starts a new thread whenever no idle one is there at
//! the instant of the call, and a trial's thread frees its core (the semaphore permit)
//! just before going idle, so trials rotated over 5 or 6 threads on 2 cores: more
//! migrations, colder caches and malloc arenas, and about 15 % more CPU per trial than the
//! batch evaluator (BENCHMARKS.md, "`run` against the batch evaluator alone").

use crate::evaluate::evaluate_to_enter;
use crate::help::{panic_message, Helpers, Job};
use std::num::NonZeroUsize;
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
    let outcome = std::panic::catch_unwind(|| eval(&t.ctx, &t.genome, t.scheme, t.seed, t.to_beat))
        .map_err(|p| panic_message(&*p));
    let seconds = start.elapsed().as_secs_f64();
    drop(t.core);
    let _ = t.answer.send((t.key, outcome, seconds));
}

/// The simulation threads. Dropping the pool lets them finish the trial in hand and end.
pub struct SimPool<K> {
    trials: flume::Sender<Trial<K>>,
}

impl<K: Send + 'static> SimPool<K> {
    /// Starts `threads` threads named `strider-sim-N`.
    pub fn new(threads: NonZeroUsize) -> std::io::Result<Self> {
        Self::with(threads, evaluate_to_enter)
    }

    /// Starts `threads` threads that run `eval` for each trial ([`answer_trial`]); an idle one helps
    /// another with its confirming trials (crate::help).
    pub fn with(threads: NonZeroUsize, eval: Evaluate) -> std::io::Result<Self> {
        let (trials, queue) = flume::unbounded::<Trial<K>>();
        let (helpers, help_queue) = Helpers::new();
        for i in 0..threads.get() {
            let queue = queue.clone();
            let help_queue = help_queue.clone();
            let helpers = helpers.clone();
            std::thread::Builder::new()
                .name(format!("strider-sim-{i}"))
                .spawn(move || {
                    helpers.clone().install();
                    // A trial first (it holds a core); else another thread's confirming
                    // trial (crate::help); else wait, counted idle, for either.
                    loop {
                        let work = match queue.try_recv() {
                            Ok(t) => Work::Trial(t),
                            Err(flume::TryRecvError::Disconnected) => break,
                            Err(flume::TryRecvError::Empty) => match help_queue.try_recv() {
                                Ok(job) => Work::Help(job),
                                Err(_) => match helpers.idle_while(|| {
                                    flume::Selector::new()
                                        .recv(&queue, |t| t.map(Work::Trial))
                                        .recv(&help_queue, |j| j.map(Work::Help))
                                        .wait()
                                }) {
                                    Ok(work) => work,
                                    // The pool was dropped (its helpers' queue never is).
                                    Err(_) => break,
                                },
                            },
                        };
                        match work {
                            Work::Trial(t) => answer_trial(t, eval),
                            Work::Help(job) => job(),
                        }
                    }
                })?;
        }
        Ok(Self { trials })
    }

    /// Hands a trial to the next free thread (callers hold a core permit, so one is free
    /// or about to be).
    pub fn run(&self, trial: Trial<K>) {
        self.trials
            .send(trial)
            .expect("simulation threads live as long as the pool");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::evaluate;
    use std::sync::Arc;
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
        // abandoned), the second, and the finer step (the last: a helper's verdict).
        let ctx = EvalContext::paper();
        let pool = SimPool::new(NonZeroUsize::new(3).unwrap()).unwrap();
        let cores = Arc::new(Semaphore::new(3));
        for name in [
            "walks_on_every_floor.json",
            "tips_on_the_grippy_floor.json",
            "meets_the_brief_at_the_finer_step_then_falls.json",
            "falls_at_the_finer_step_only.json",
        ] {
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
                core,
                answer,
            });
            let (_, helped, _) = answers.recv_async().await.unwrap();
            let alone = evaluate(&ctx, &genome, Scheme::Static, seed);
            println!("{name}: {alone:?}");
            assert!(
                matches!(alone, Outcome::Valid { .. })
                    || matches!(
                        alone,
                        Outcome::Invalid {
                            reason: InvalidReason::FrictionSensitive { .. }
                                | InvalidReason::StepSensitive { .. },
                            ..
                        }
                    ),
                "{name} reaches the confirming trials: {alone:?}"
            );
            assert_eq!(helped, Ok(alone), "{name}");
        }
        assert_eq!(cores.available_permits(), 3);
    }
}
