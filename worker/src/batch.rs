//! Runs many candidates on all cores: one trial per thread at a time, results returned in
//! candidate order. Threads take the next candidate from a shared counter, so a long trial
//! (ES, many legs) never holds up the others.

use crate::evaluate::evaluate_to_enter;
use std::num::NonZeroUsize;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::{Genome, Outcome, Scheme};

/// One candidate to evaluate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Job {
    pub genome: Genome,
    pub scheme: Scheme,
    /// Its seed (ES draws from it).
    pub seed: CandidateSeed,
    /// The fitness of the elite its cell held when it was drawn, if any
    /// ([`evaluate_to_enter`]).
    pub to_beat: Option<f64>,
}

/// Evaluates every job on `threads` threads; `outcomes[i]` belongs to `jobs[i]`.
pub fn evaluate_batch(ctx: &EvalContext, jobs: &[Job], threads: NonZeroUsize) -> Vec<Outcome> {
    map_batch(jobs, threads, |job| {
        evaluate_to_enter(ctx, &job.genome, job.scheme, job.seed, job.to_beat)
    })
}

/// `f` of every item on `threads` threads; `out[i] = f(&items[i])`.
pub fn map_batch<T: Sync, R: Send>(
    items: &[T],
    threads: NonZeroUsize,
    f: impl Fn(&T) -> R + Sync,
) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<R>>> = items.iter().map(|_| Mutex::new(None)).collect();
    let threads = threads.get().min(items.len()).max(1);
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                let r = f(item);
                *slots[i].lock().expect("no thread panics holding a slot") = Some(r);
            });
        }
    });
    slots
        .into_iter()
        .map(|m| {
            m.into_inner()
                .expect("slot lock")
                .expect("every item was mapped")
        })
        .collect()
}
