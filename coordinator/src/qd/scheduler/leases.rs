//! Leases: heartbeats keep them, workers give them back or vanish, and leases past their
//! time end, charging an attempt to a candidate its worker had begun simulating. Part of
//! the scheduler (the methods below extend [`Scheduler`]).

use super::*;

impl Scheduler {
    /// Keeps `worker`'s leases on `keys` alive.
    pub fn heartbeat(&mut self, worker: WorkerId, keys: &[CandidateKey], now: Instant) {
        let until = now + self.lease;
        for key in keys {
            if let Some(p) = self.pending_mut(*key) {
                if let State::Leased {
                    worker: w, expires, ..
                } = &mut p.state
                {
                    if *w == worker {
                        *expires = until;
                    }
                }
            }
        }
    }

    /// `worker` began simulating `keys`: from now on, losing it with them counts as an
    /// attempt.
    pub fn started(&mut self, worker: WorkerId, keys: &[CandidateKey]) {
        for key in keys {
            if let Some(p) = self.pending_mut(*key) {
                if let State::Leased {
                    worker: w, started, ..
                } = &mut p.state
                {
                    if *w == worker {
                        *started = true;
                    }
                }
            }
        }
    }

    /// `worker` gives candidates back unevaluated (it is shutting down): they wait again,
    /// with no attempt counted.
    pub fn release(&mut self, worker: WorkerId, keys: &[CandidateKey]) {
        for key in keys {
            self.end_lease(*key, |w| w == worker, None);
        }
    }

    /// `worker` is gone: what it held waits again, and each candidate it had begun
    /// simulating counts one attempt (a candidate that takes down every worker that
    /// simulates it fails after `max_attempts`; one that was only queued is not suspect).
    pub fn disconnect(&mut self, worker: WorkerId, why: &str) {
        for key in self.leases_where(|w, _, started| w == worker && started) {
            self.end_lease(key, |w| w == worker, Some(why));
        }
        for key in self.leases_where(|w, _, _| w == worker) {
            self.end_lease(key, |w| w == worker, None);
        }
    }

    /// Leases past their time wait again. A lease never begun costs nothing; one its worker
    /// was simulating counts an attempt (once per worker: a worker stopped or cut off
    /// once is not charged again, but a candidate that stalls every worker that takes it
    /// fails instead of going round for ever). Returns how many expired. A result that
    /// comes late is still taken if the candidate has none yet.
    pub fn expire(&mut self, now: Instant) -> usize {
        let started = self.leases_where(|_, expires, started| expires <= now && started);
        for key in &started {
            self.end_lease(*key, |_| true, Some("its worker stalled past the lease"));
        }
        let queued = self.leases_where(|_, expires, _| expires <= now);
        for key in &queued {
            self.end_lease(*key, |_| true, None);
        }
        started.len() + queued.len()
    }

    fn leases_where(&self, f: impl Fn(WorkerId, Instant, bool) -> bool) -> Vec<CandidateKey> {
        let mut out = Vec::new();
        for (i, r) in self.runs.iter().enumerate() {
            for (n, p) in &r.step {
                if let State::Leased {
                    worker,
                    expires,
                    started,
                } = p.state
                {
                    if f(worker, expires, started) {
                        out.push(p.key(RunId::from_index(i), *n));
                    }
                }
            }
        }
        out
    }

    /// Ends a lease held by a worker `holder` accepts: back to waiting, or, when `lost`
    /// says how, one attempt more, and failed after too many.
    fn end_lease(
        &mut self,
        key: CandidateKey,
        holder: impl Fn(WorkerId) -> bool,
        lost: Option<&str>,
    ) {
        let max_attempts = self.max_attempts;
        let i = key.run.index();
        let Some(r) = self.runs.get_mut(i) else {
            return;
        };
        let ahead = r.is_ahead(key.number.0);
        let Some(p) = r.step.get_mut(&key.number.0) else {
            return;
        };
        if !p.answers_to(key) {
            return;
        }
        let State::Leased { worker, .. } = p.state else {
            return;
        };
        if !holder(worker) {
            return;
        }
        let run = r.record.id;
        // Each worker session is charged once per candidate.
        let lost = lost.filter(|_| !p.charged.contains(&worker));
        if let Some(why) = lost {
            p.charged.push(worker);
            p.attempts += 1;
            if p.attempts >= max_attempts {
                let outcome = Outcome::Invalid {
                    reason: InvalidReason::EvaluationFailed {
                        attempts: p.attempts,
                        last: format!("worker {}: {why}", worker.0),
                    },
                    at_time: 0.0,
                    controller: p.genome.controller,
                };
                p.state = State::Resolved(outcome.clone());
                let write = Write::Resolved {
                    run,
                    number: key.number,
                    generation: p.generation,
                    attempts: p.attempts,
                    outcome,
                    worker: None,
                    seconds: 0.0,
                };
                if ahead {
                    p.deferred = Some(write);
                } else {
                    self.writes.push(write);
                }
                self.advance(i);
                return;
            }
        }
        p.state = State::Waiting;
        // A candidate drawn ahead leaves no trace until kept (its attempts go with it).
        if lost.is_some() && !ahead {
            self.writes.push(Write::LeaseLost {
                run,
                number: key.number,
                generation: p.generation,
                attempts: p.attempts,
                worker,
            });
        }
        r.queue_of(key.number.0).insert(key.number.0);
    }

    fn pending_mut(&mut self, key: CandidateKey) -> Option<&mut Pending> {
        self.runs
            .get_mut(key.run.index())?
            .step
            .get_mut(&key.number.0)
            .filter(|p| p.answers_to(key))
    }
}
