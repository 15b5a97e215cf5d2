//! Does a verdict depend on the physics step? The same designs evaluated at several
//! `physics_substeps` (and, on request, with a longer stay-up window after the trial or
//! another friction coefficient between the robot and the ground), and
//! each setting compared with the next finer one: how often the verdict agrees, and how far
//! distance and energy move (docs/model.md section 6, the convergence table).

use crate::batch::map_batch;
use crate::evaluate::evaluate;
use serde::Serialize;
use std::fmt;
use std::num::NonZeroUsize;
use strider_common::outcome::Fall;
use strider_common::rng::CandidateSeed;
use strider_common::{EvalContext, Genome, InvalidReason, Outcome, Scheme};

/// A verdict's class, what two settings must agree on: feasible, too slow, or the way the
/// trial ended or the design was refused.
pub fn verdict(o: &Outcome) -> String {
    match o {
        Outcome::Valid { .. } => "feasible".into(),
        Outcome::Rejected { stats: Some(_), .. } => "too_slow".into(),
        Outcome::Rejected { stats: None, .. } => "rejected".into(),
        Outcome::Invalid { reason, .. } => match reason {
            InvalidReason::Fell { fall } => match fall {
                Fall::Tilted { .. } => "fell_tilted".into(),
                Fall::Sank { .. } => "fell_sank".into(),
                Fall::Dragged { .. } => "fell_dragged".into(),
            },
            other => serde_json::to_value(other)
                .ok()
                .and_then(|v| v["kind"].as_str().map(str::to_owned))
                .unwrap_or_else(|| "invalid".into()),
        },
    }
}

/// One design at one setting.
#[derive(Clone, Debug, Serialize)]
pub struct Trial {
    pub verdict: String,
    /// Distance and energy of a completed trial.
    pub distance: Option<f64>,
    pub energy: Option<f64>,
    pub fitness: Option<f64>,
    pub peak_torque_ratio: Option<f64>,
    pub foot_slip: Option<f64>,
    pub low_forward_share: Option<f64>,
    pub duty_factor: Option<f64>,
}

impl Trial {
    fn of(o: &Outcome) -> Self {
        let s = o.stats();
        Self {
            verdict: verdict(o),
            distance: s.map(|s| s.distance),
            energy: s.map(|s| s.energy),
            fitness: o.fitness(),
            peak_torque_ratio: s.map(|s| s.gait.peak_torque_ratio),
            foot_slip: s.map(|s| s.gait.foot_slip),
            low_forward_share: s.map(|s| s.gait.low_forward_share),
            duty_factor: s.map(|s| s.gait.duty_factor),
        }
    }
}

/// One setting of the study.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Setting {
    pub physics_substeps: u32,
    /// Seconds the robot must stay up after the trial.
    pub upright_after_seconds: f64,
    /// Seconds a robot fast enough to meet the brief must stay up after the trial (the
    /// longer of this and `upright_after_seconds` applies to it).
    pub upright_after_feasible_seconds: f64,
    /// Friction coefficient between the robot and the ground.
    pub friction: f64,
    /// Sideways shove at the trial's end, m/s (0: none).
    pub push_speed: f64,
}

impl Setting {
    /// Seconds a design fast enough for the brief must stay up: the longer window.
    pub fn long_window(&self) -> f64 {
        self.upright_after_feasible_seconds
            .max(self.upright_after_seconds)
    }
}

impl fmt::Display for Setting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} substeps, up {} s after",
            self.physics_substeps, self.upright_after_seconds
        )?;
        // The window that judges a feasible design, said where it is the longer one.
        if self.long_window() > self.upright_after_seconds {
            write!(f, " ({} s if fast enough)", self.long_window())?;
        }
        write!(f, ", friction {}", self.friction)?;
        if self.push_speed > 0.0 {
            write!(f, ", pushed {} m/s", self.push_speed)?;
        }
        Ok(())
    }
}

/// How one setting compares with another over the same designs.
#[derive(Clone, Debug, Serialize)]
pub struct Agreement {
    pub from: Setting,
    pub to: Setting,
    pub designs: usize,
    /// Designs with the same verdict in both.
    pub same_verdict: usize,
    /// Feasible in `from`, and of those feasible in `to` too.
    pub feasible_from: usize,
    pub feasible_both: usize,
    /// Completed (feasible or too slow) in both.
    pub completed_both: usize,
    /// Median |d_from - d_to| / |d_to| over those, and the same for energy.
    pub median_distance_change: Option<f64>,
    pub median_energy_change: Option<f64>,
}

/// The study: every design's trial at every setting.
#[derive(Clone, Debug, Serialize)]
pub struct Study {
    pub settings: Vec<Setting>,
    /// `trials[d][s]`: design `d` at setting `s`.
    pub trials: Vec<Vec<Trial>>,
    pub agreements: Vec<Agreement>,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

fn agreement(trials: &[Vec<Trial>], settings: &[Setting], a: usize, b: usize) -> Agreement {
    let mut same = 0;
    let (mut feasible_from, mut feasible_both) = (0, 0);
    let (mut dd, mut de) = (Vec::new(), Vec::new());
    for t in trials {
        let (x, y) = (&t[a], &t[b]);
        same += usize::from(x.verdict == y.verdict);
        if x.verdict == "feasible" {
            feasible_from += 1;
            feasible_both += usize::from(y.verdict == "feasible");
        }
        if let (Some(d0), Some(d1), Some(e0), Some(e1)) =
            (x.distance, y.distance, x.energy, y.energy)
        {
            dd.push((d0 - d1).abs() / d1.abs().max(1e-9));
            de.push((e0 - e1).abs() / e1.abs().max(1e-9));
        }
    }
    Agreement {
        from: settings[a],
        to: settings[b],
        designs: trials.len(),
        same_verdict: same,
        feasible_from,
        feasible_both,
        completed_both: dd.len(),
        median_distance_change: median(dd),
        median_energy_change: median(de),
    }
}

/// The setting that setting `s` (> 0) is compared with: the one before it when the two
/// differ only in the physics step (a convergence ladder: 120 -> 240 -> 480 Hz), else the
/// first, the run's own (a window, floor or shove against the run's, not against the
/// finest step before it).
fn compared_with(settings: &[Setting], s: usize) -> usize {
    let (a, b) = (settings[s - 1], settings[s]);
    let same_but_step = Setting {
        physics_substeps: b.physics_substeps,
        ..a
    };
    if same_but_step == b {
        s - 1
    } else {
        0
    }
}

impl Study {
    /// Evaluates `genomes` under `scheme` at every setting (`ctx` gives everything else)
    /// and compares each setting after the first with the one it varies from
    /// (`compared_with`).
    pub fn run(
        ctx: &EvalContext,
        genomes: &[Genome],
        scheme: Scheme,
        settings: &[Setting],
        threads: NonZeroUsize,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Self {
        let jobs: Vec<(usize, usize)> = (0..genomes.len())
            .flat_map(|d| (0..settings.len()).map(move |s| (d, s)))
            .collect();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let flat = map_batch(&jobs, threads, |&(d, s)| {
            let mut c = *ctx;
            c.settings.physics_substeps = settings[s].physics_substeps;
            c.limits.upright_after_seconds = settings[s].upright_after_seconds;
            c.limits.upright_after_feasible_seconds = settings[s].upright_after_feasible_seconds;
            c.settings.friction = settings[s].friction;
            c.limits.push_speed = settings[s].push_speed;
            // Each step judged on its own: the run's confirmation at a finer step is what
            // this study measures, not part of it.
            c.limits.confirm_substeps_factor = 1;
            c.limits.friction_margin = 0.0;
            let o = evaluate(&c, &genomes[d], scheme, CandidateSeed::new(1, d as u64));
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            Trial::of(&o)
        });
        let mut trials: Vec<Vec<Trial>> = Vec::with_capacity(genomes.len());
        let mut it = flat.into_iter();
        for _ in genomes {
            trials.push(it.by_ref().take(settings.len()).collect());
        }
        let agreements = (1..settings.len())
            .map(|s| agreement(&trials, settings, compared_with(settings, s), s))
            .collect();
        Self {
            settings: settings.to_vec(),
            trials,
            agreements,
        }
    }

    /// One CSV row per design and setting.
    pub fn write_csv(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(
            out,
            "design,physics_substeps,upright_after_seconds,upright_after_feasible_seconds,friction,push_speed,verdict,distance,energy,fitness,peak_torque_ratio,foot_slip,low_forward_share,duty_factor"
        )?;
        let f = |v: Option<f64>| v.map(|v| format!("{v}")).unwrap_or_default();
        for (d, row) in self.trials.iter().enumerate() {
            for (s, t) in self.settings.iter().zip(row) {
                writeln!(
                    out,
                    "{d},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    s.physics_substeps,
                    s.upright_after_seconds,
                    s.long_window(),
                    s.friction,
                    s.push_speed,
                    t.verdict,
                    f(t.distance),
                    f(t.energy),
                    f(t.fitness),
                    f(t.peak_torque_ratio),
                    f(t.foot_slip),
                    f(t.low_forward_share),
                    f(t.duty_factor)
                )?;
            }
        }
        Ok(())
    }
}

impl fmt::Display for Study {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.trials.len();
        writeln!(f, "{n} designs")?;
        for (s, setting) in self.settings.iter().enumerate() {
            let feasible = self
                .trials
                .iter()
                .filter(|t| t[s].verdict == "feasible")
                .count();
            writeln!(f, "  {setting}: {feasible} feasible")?;
        }
        let pct = |a: usize, b: usize| {
            if b == 0 {
                "-".to_string()
            } else {
                format!("{:.1} %", 100.0 * a as f64 / b as f64)
            }
        };
        let opt = |v: Option<f64>| {
            v.map(|v| format!("{:.1} %", 100.0 * v))
                .unwrap_or_else(|| "-".into())
        };
        for a in &self.agreements {
            writeln!(
                f,
                "{} -> {}: same verdict {} ({}/{}); feasible kept {} ({}/{}); distance {} and energy {} (median change over {} completed in both)",
                a.from,
                a.to,
                pct(a.same_verdict, a.designs),
                a.same_verdict,
                a.designs,
                pct(a.feasible_both, a.feasible_from),
                a.feasible_both,
                a.feasible_from,
                opt(a.median_distance_change),
                opt(a.median_energy_change),
                a.completed_both
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setting(physics_substeps: u32) -> Setting {
        Setting {
            physics_substeps,
            upright_after_seconds: 1.0,
            upright_after_feasible_seconds: 15.0,
            friction: 0.8,
            push_speed: 0.0,
        }
    }

    #[test]
    fn steps_form_a_ladder_and_other_settings_are_compared_with_the_runs() {
        // fidelity --substeps 4,8,16 --stay-up 3,15 --friction 0.6 --push 0.3
        let run = setting(4);
        let settings = [
            run,
            setting(8),
            setting(16),
            Setting {
                upright_after_seconds: 3.0,
                ..run
            },
            Setting {
                upright_after_seconds: 15.0,
                ..run
            },
            Setting {
                friction: 0.6,
                ..run
            },
            Setting {
                push_speed: 0.3,
                ..run
            },
        ];
        let with: Vec<usize> = (1..settings.len())
            .map(|s| compared_with(&settings, s))
            .collect();
        assert_eq!(with, [0, 1, 0, 0, 0, 0]);
    }
}
