//! The time left, from the recent pace: the fraction done over the last two minutes, or
//! over the last tenth of the time so far once that is longer. The pace since the start
//! misleads in both directions: the initial population (most designs fall at once, or are
//! settled without a trial) goes fast, and later generations of walkers, and ES
//! generations, cost more; with the whole-run average an ES run said "about 4 min left"
//! for two minutes on end while it slowed. Two minutes alone are too short late in a long
//! run: a full-size run's estimate swung between 4 and 6 hours from one minute to the next
//! with the generations' mix of walkers and falls (and to 23 hours while a build shared its
//! cores), where the last tenth of its time gives a steadier figure that still follows a
//! lasting change within that tenth.

use std::collections::VecDeque;

/// Recent (seconds, fraction done) samples, one a second at most.
#[derive(Debug, Default)]
pub struct Pace {
    samples: VecDeque<(f64, f64)>,
}

impl Pace {
    /// How far back the pace is measured at least, s.
    pub const WINDOW: f64 = 120.0;
    /// How far back the pace is measured as a share of the time so far, when longer.
    pub const WINDOW_SHARE: f64 = 0.1;
    /// The shortest span an estimate is made from, s. The first seconds of a run are no
    /// guide: trials are in flight and few results in, and prechecks refuse some designs
    /// at once (from 5 s, the quick experiment's said "about 45 min left" at 10 s and "about
    /// 4 min" at 20 s of a 5-min run).
    pub const MIN_SPAN: f64 = 30.0;

    /// Notes `fraction` done at `seconds` (since the work began) and returns the seconds
    /// left at the pace of the last [`Pace::WINDOW`], or of the last [`Pace::WINDOW_SHARE`]
    /// of `seconds` when that is longer (`None` until [`Pace::MIN_SPAN`] of progress is
    /// seen).
    pub fn observe(&mut self, seconds: f64, fraction: f64) -> Option<f64> {
        if fraction >= 1.0 {
            return Some(0.0);
        }
        if self.samples.back().is_none_or(|&(t, _)| seconds - t >= 1.0) {
            self.samples.push_back((seconds, fraction));
        }
        // Keep one sample at or beyond the window's start.
        let window = Self::WINDOW.max(Self::WINDOW_SHARE * seconds);
        while self.samples.len() > 2 && seconds - self.samples[1].0 >= window {
            self.samples.pop_front();
        }
        let &(t0, f0) = self.samples.front()?;
        let (span, done) = (seconds - t0, fraction - f0);
        (done > 0.0 && span >= Self::MIN_SPAN).then(|| span * (1.0 - fraction) / done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_pace_gives_the_exact_time_left() {
        let mut p = Pace::default();
        assert_eq!(p.observe(0.0, 0.0), None);
        assert_eq!(p.observe(20.0, 0.2), None, "too short a span yet");
        // 1 % a second: 70 % left at 30 s is 70 s.
        let left = p.observe(30.0, 0.3).unwrap();
        assert!((left - 70.0).abs() < 1e-9, "{left}");
        assert_eq!(p.observe(40.0, 1.0), Some(0.0));
    }

    #[test]
    fn a_run_that_slows_down_is_estimated_at_its_recent_pace() {
        let mut p = Pace::default();
        // 0.2 % a second for 5 minutes, then 0.02 % a second for 5 minutes.
        let mut fraction = 0.0;
        for t in 0..600 {
            fraction += if t < 300 { 0.002 } else { 0.0002 };
            p.observe(f64::from(t + 1), fraction);
        }
        let left = p.observe(601.0, fraction + 0.0002).unwrap();
        // At 0.02 % a second what is left takes (1 - fraction) / 0.0002 s; the average
        // since the start (0.11 % a second) would say a fifth of that.
        let want = (1.0 - fraction - 0.0002) / 0.0002;
        assert!((left - want).abs() / want < 0.02, "{left} vs {want}");
    }

    #[test]
    fn a_long_run_of_uneven_minutes_is_estimated_at_the_pace_of_its_last_tenth() {
        let mut p = Pace::default();
        // Two hours of three-minute spells that alternate 0.01 % and 0.002 % a second
        // (generations of walkers and of falls): 0.006 % a second on average.
        let mut fraction = 0.0;
        let mut estimates = Vec::new();
        for t in 0..7200 {
            fraction += if (t / 180) % 2 == 0 { 1e-4 } else { 2e-5 };
            if let Some(left) = p.observe(f64::from(t + 1), fraction) {
                if t >= 3600 {
                    estimates.push(left);
                }
            }
        }
        // In the second hour (windows of 6 to 12 minutes) every estimate is within 0.8x
        // to 1.3x of the average pace's; two minutes alone swing from 0.6x to 3x.
        assert_eq!(estimates.len(), 3600);
        for (i, left) in estimates.iter().enumerate() {
            let t = 3601.0 + i as f64;
            let ratio = left / ((1.0 - 6e-5 * t) / 6e-5);
            assert!((0.8..1.3).contains(&ratio), "{t} s: {ratio}x");
        }
    }

    #[test]
    fn no_progress_in_the_window_gives_no_estimate() {
        let mut p = Pace::default();
        for t in 0..300 {
            p.observe(f64::from(t), 0.5);
        }
        assert_eq!(p.observe(300.0, 0.5), None);
    }
}
