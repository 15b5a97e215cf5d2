//! The service's running time: time since it started, less the time its process was
//! stopped (SIGSTOP, a Slurm job suspended, a debugger). Rates and the time left are
//! measured on it, so that a stop of a quarter of an hour does not make the next progress
//! lines read hours left (their window would span the stop, with nothing done in it).
//!
//! A stop is seen as a gap between two readings longer than [`RunningClock::STOPPED_AFTER`]:
//! the service reads the clock every second from a thread of its own, so a longer gap means
//! the process did not run. A system suspend needs nothing: the monotonic clock
//! does not advance through it.

use std::time::{Duration, Instant};

/// Time since a start, less stops.
#[derive(Clone, Copy, Debug)]
pub struct RunningClock {
    started: Instant,
    last_read: Instant,
    stopped: Duration,
}

impl RunningClock {
    /// A gap between readings longer than this was a stop (the service reads every second
    /// at most: ten of them missed is no scheduling delay).
    pub const STOPPED_AFTER: Duration = Duration::from_secs(10);

    /// A clock started at `now`.
    pub fn new(now: Instant) -> Self {
        Self {
            started: now,
            last_read: now,
            stopped: Duration::ZERO,
        }
    }

    /// Seconds run by `now`: since the start, less every gap between readings longer than
    /// [`RunningClock::STOPPED_AFTER`] (each counts as a stop, all of it); and the stop
    /// this reading found, if it found one. Readings earlier than the last change nothing.
    pub fn read(&mut self, now: Instant) -> (f64, Option<Duration>) {
        let mut stop = None;
        if let Some(gap) = now.checked_duration_since(self.last_read) {
            if gap > Self::STOPPED_AFTER {
                self.stopped += gap;
                stop = Some(gap);
            }
            self.last_read = now;
        }
        let run = self
            .last_read
            .duration_since(self.started)
            .saturating_sub(self.stopped);
        (run.as_secs_f64(), stop)
    }

    /// Seconds stopped so far.
    pub fn stopped(&self) -> f64 {
        self.stopped.as_secs_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(seconds: f64) -> Duration {
        Duration::from_secs_f64(seconds)
    }

    #[test]
    fn read_often_it_is_the_time_since_the_start() {
        let t0 = Instant::now();
        let mut c = RunningClock::new(t0);
        for i in 1..=100 {
            let (t, stop) = c.read(t0 + s(f64::from(i) * 0.5));
            assert_eq!(stop, None);
            assert!((t - f64::from(i) * 0.5).abs() < 1e-9, "{i}: {t}");
        }
        assert_eq!(c.stopped(), 0.0);
    }

    #[test]
    fn a_stop_is_left_out_whole() {
        let t0 = Instant::now();
        let mut c = RunningClock::new(t0);
        for i in 1..=40 {
            c.read(t0 + s(f64::from(i)));
        }
        // Stopped 15 minutes after 40 s: the next reading, at once after, is 40 s run.
        let (after, stop) = c.read(t0 + s(40.0 + 900.0));
        assert!((after - 40.0).abs() < 1e-9, "{after}");
        assert_eq!(stop, Some(s(900.0)));
        assert!((c.read(t0 + s(941.0)).0 - 41.0).abs() < 1e-9);
        assert!((c.stopped() - 900.0).abs() < 1e-9);
    }

    #[test]
    fn a_gap_within_the_bound_is_run_time_and_an_earlier_reading_changes_nothing() {
        let t0 = Instant::now();
        let mut c = RunningClock::new(t0);
        let within = RunningClock::STOPPED_AFTER.as_secs_f64();
        assert_eq!(c.read(t0 + s(within)), (within, None));
        // Read by two tasks out of order: the later reading stands.
        assert_eq!(c.read(t0 + s(1.0)), (within, None));
        assert_eq!(c.stopped(), 0.0);
    }
}
