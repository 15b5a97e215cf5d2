//! How long an experiment takes on this machine, measured in a moment: full-length trials
//! of the reference design MAX (`designs/max.json`) on every thread at once, under the
//! experiment's own trial length and physics step, give the wall time of one trial to its
//! end with every core busy. That is the cost of a trial that walks and misses the brief:
//! the many that fall or are refused before a trial cost less, a design that meets the
//! brief (its long window, its confirming trials) costs more, so it is an estimate of a
//! run, not a bound.

use crate::batch::map_batch;
use crate::sim::trial::{run_trial_from, TrialEnd};
use std::num::NonZeroUsize;
use std::time::{Duration, Instant};
use strider_common::experiment::{RunSettings, TrialLimits};
use strider_common::{BodyPlan, Controller, DesignBrief, StartPose};

/// What a calibration measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Full-length trials simulated.
    pub trials: usize,
    /// Threads they ran on, at once.
    pub threads: usize,
    /// Wall time they took.
    pub wall_seconds: f64,
    /// Simulated seconds of one trial (the trial and the upright window after it).
    pub simulated_seconds: f64,
    /// The fastest single trial, in CPU seconds of its thread (wall seconds where the
    /// platform has no thread clock): what a trial costs, whatever else the machine runs.
    pub fastest_trial_seconds: f64,
}

impl Calibration {
    /// Seconds one thread spends on one full-length trial: CPU time, the fastest measured,
    /// so that the estimate does not grow with whatever else the machine runs meanwhile
    /// (the wall-clock mean of a loaded minute read 3.5x a quiet one's).
    pub fn thread_seconds_per_trial(&self) -> f64 {
        self.fastest_trial_seconds
    }

    /// Wall seconds for `trials` full-length trials on this machine's `threads`, each at
    /// the fastest measured cost.
    pub fn wall_seconds_for(&self, trials: u64) -> f64 {
        trials as f64 * self.fastest_trial_seconds / self.threads as f64
    }
}

/// Simulates MAX to the end of the trial (falls are not checked: the point is the cost of
/// a whole trial) in rounds of one trial per thread until `at_least` has passed, at most
/// 64 rounds.
pub fn calibrate(
    settings: &RunSettings,
    limits: &TrialLimits,
    brief: &DesignBrief,
    threads: NonZeroUsize,
    at_least: Duration,
) -> Calibration {
    let genome = strider_common::reference::max();
    let plan = BodyPlan::new(&genome.morphology, brief.payload);
    let controller = Controller::static_default();
    let pose = StartPose::new(&plan, &controller);
    let whole = TrialLimits {
        max_tilt_degrees: 180.0,
        min_height_fraction: 0.0,
        only_feet_on_ground: false,
        upright_after_max_tilt_degrees: 180.0,
        ..*limits
    };
    let round: Vec<usize> = (0..threads.get()).collect();
    let started = Instant::now();
    let mut trials = 0;
    let mut fastest = f64::INFINITY;
    for _ in 0..64 {
        let ends = map_batch(&round, threads, |_| {
            let (start, cpu) = (Instant::now(), strider_process::thread_cpu_seconds());
            let end = run_trial_from(
                &plan,
                &pose,
                &controller,
                settings,
                &whole,
                f64::INFINITY,
                &mut (),
            );
            let cost = match (cpu, strider_process::thread_cpu_seconds()) {
                (Some(a), Some(b)) => b - a,
                _ => start.elapsed().as_secs_f64(),
            };
            (end, cost)
        });
        trials += ends.len();
        debug_assert!(ends
            .iter()
            .all(|(e, _)| matches!(e, TrialEnd::Completed(_))));
        fastest = ends.iter().map(|e| e.1).fold(fastest, f64::min);
        if started.elapsed() >= at_least {
            break;
        }
    }
    Calibration {
        trials,
        threads: threads.get(),
        wall_seconds: started.elapsed().as_secs_f64(),
        simulated_seconds: settings.trial_seconds + limits.upright_after_seconds,
        fastest_trial_seconds: fastest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_calibration_runs_whole_trials_and_scales_to_an_experiment() {
        let c = calibrate(
            &RunSettings::default(),
            &TrialLimits::default(),
            &DesignBrief::default(),
            NonZeroUsize::new(2).unwrap(),
            Duration::ZERO,
        );
        // One round of one trial per thread, each the 5 s trial and the 1 s after it.
        assert_eq!((c.trials, c.threads), (2, 2));
        assert_eq!(c.simulated_seconds, 6.0);
        assert!(c.wall_seconds > 0.0);
        // The fastest trial is one of the two, so no more CPU than their wall time.
        assert!(c.fastest_trial_seconds > 0.0 && c.fastest_trial_seconds <= c.wall_seconds);
        assert_eq!(c.thread_seconds_per_trial(), c.fastest_trial_seconds);
        assert!((c.wall_seconds_for(1000) - 1000.0 * c.fastest_trial_seconds / 2.0).abs() < 1e-9);
    }
}
