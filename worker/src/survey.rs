//! The brief's pass rate over random genomes: which constraint fails how often.

use crate::batch::{evaluate_batch, Job};
use crate::evaluate::EvalContext;
use serde::Serialize;
use std::fmt;
use std::num::NonZeroUsize;
use strider_common::brief::Constraint;
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::{Genome, InvalidReason, Outcome, Scheme};

/// Counts over a sample of random genomes.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Survey {
    /// Genomes drawn.
    pub total: usize,
    /// Mass without payload over the limit (checked on every genome).
    pub mass_fails: usize,
    /// Start-pose height under the limit (checked on every genome).
    pub height_fails: usize,
    /// Passed both static checks and were simulated.
    pub simulated: usize,
    /// Simulated and stopped for a self-contact.
    pub self_contact: usize,
    /// Simulated and stopped for a blow-up or a non-finite value.
    pub unstable: usize,
    /// Simulated and did not move forward.
    pub no_progress: usize,
    /// Simulated, completed, but slower than the brief.
    pub speed_fails: usize,
    /// Passed everything.
    pub passed: usize,
}

impl Survey {
    /// Draws `count` random genomes for `scheme` from `seed` (candidate numbers 0..count, the
    /// same genomes a run with that seed starts from) and evaluates them.
    pub fn run(
        ctx: &EvalContext,
        scheme: Scheme,
        seed: u64,
        count: usize,
        threads: NonZeroUsize,
    ) -> Self {
        let jobs: Vec<Job> = (0..count as u64)
            .map(|i| {
                let s = CandidateSeed::new(seed, i);
                Job {
                    genome: Genome::random(scheme, &mut s.rng(Purpose::RandomGenome)),
                    scheme,
                    seed: s,
                }
            })
            .collect();
        let mut out = Survey {
            total: count,
            ..Survey::default()
        };
        for o in evaluate_batch(ctx, &jobs, threads) {
            out.count(&o);
        }
        out
    }

    fn count(&mut self, o: &Outcome) {
        match o {
            Outcome::Valid { .. } => {
                self.simulated += 1;
                self.passed += 1;
            }
            Outcome::Rejected {
                violations, stats, ..
            } => {
                for v in violations {
                    match v.constraint {
                        Constraint::Mass => self.mass_fails += 1,
                        Constraint::Height => self.height_fails += 1,
                        Constraint::Speed => self.speed_fails += 1,
                    }
                }
                self.simulated += usize::from(stats.is_some());
            }
            Outcome::Invalid { reason, .. } => {
                self.simulated += 1;
                match reason {
                    InvalidReason::SelfContact { .. } => self.self_contact += 1,
                    InvalidReason::NonFinite { .. } | InvalidReason::BlowUp { .. } => {
                        self.unstable += 1
                    }
                    InvalidReason::NoForwardProgress { .. } => self.no_progress += 1,
                    InvalidReason::EvaluationFailed { .. } => {}
                }
            }
        }
    }
}

impl fmt::Display for Survey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |n: usize, of: usize| {
            if of == 0 {
                0.0
            } else {
                100.0 * n as f64 / of as f64
            }
        };
        let n = self.total;
        let s = self.simulated;
        writeln!(f, "random genomes               {n}")?;
        writeln!(
            f,
            "fail mass                    {:>5}  {:5.1} % of all",
            self.mass_fails,
            pct(self.mass_fails, n)
        )?;
        writeln!(
            f,
            "fail height                  {:>5}  {:5.1} % of all",
            self.height_fails,
            pct(self.height_fails, n)
        )?;
        writeln!(
            f,
            "pass both, simulated         {:>5}  {:5.1} % of all",
            s,
            pct(s, n)
        )?;
        writeln!(
            f,
            "  self-contact               {:>5}  {:5.1} % of simulated",
            self.self_contact,
            pct(self.self_contact, s)
        )?;
        writeln!(
            f,
            "  blow-up / non-finite       {:>5}  {:5.1} % of simulated",
            self.unstable,
            pct(self.unstable, s)
        )?;
        writeln!(
            f,
            "  no forward progress        {:>5}  {:5.1} % of simulated",
            self.no_progress,
            pct(self.no_progress, s)
        )?;
        writeln!(
            f,
            "  fail speed                 {:>5}  {:5.1} % of simulated",
            self.speed_fails,
            pct(self.speed_fails, s)
        )?;
        write!(
            f,
            "pass all                     {:>5}  {:5.1} % of all",
            self.passed,
            pct(self.passed, n)
        )
    }
}
