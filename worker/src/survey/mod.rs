//! The survey: random genomes evaluated, every outcome classified (rejected before
//! simulating, self-contact by the parts involved, fell by how, backward, too slow,
//! passed), per legs per side, beside figures computed without physics
//! (`strider_common::kinematics`) that explain each failure with a physical cause.

use crate::batch::map_batch;
use crate::evaluate::evaluate;
use serde::Serialize;
use std::fmt;
use std::num::NonZeroUsize;
use strider_common::genome::ParamVector;
use strider_common::params::{CONTROLLER_PARAMS, MORPHOLOGY_PARAMS};
use strider_common::rng::{CandidateSeed, Purpose};
use strider_common::EvalContext;
use strider_common::{Genome, Scheme};

mod verdict;

pub use verdict::{Cause, FallKind, PairKind, Record, Verdict};

/// Counts of one group of designs (all, or one leg count).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Tally {
    /// Designs drawn.
    pub drawn: usize,
    /// Over the mass limit (whatever else failed).
    pub mass_fails: usize,
    /// Under the height limit (whatever else failed).
    pub height_fails: usize,
    /// Count per verdict, in [`Verdict::all`] order.
    pub verdicts: Vec<usize>,
    /// Failed trials per computed cause, in [`Cause::ALL`] order.
    pub causes: Vec<usize>,
    /// Failed trials with no computed cause.
    pub unexplained: usize,
}

impl Tally {
    fn new() -> Self {
        Tally {
            verdicts: vec![0; Verdict::all().len()],
            causes: vec![0; Cause::ALL.len()],
            ..Tally::default()
        }
    }

    fn count(&self, pick: impl Fn(Verdict) -> bool) -> usize {
        Verdict::all()
            .into_iter()
            .zip(&self.verdicts)
            .filter(|(v, _)| pick(*v))
            .map(|(_, n)| n)
            .sum()
    }

    /// Designs that passed mass and height (whatever the start pose).
    pub fn pass_mass_and_height(&self) -> usize {
        self.drawn - self.count(|v| matches!(v, Verdict::RejectedMass | Verdict::RejectedHeight))
    }

    /// Designs simulated.
    pub fn simulated(&self) -> usize {
        self.count(Verdict::simulated)
    }

    /// Designs that walked forward upright to the end.
    pub fn walked(&self) -> usize {
        self.count(Verdict::walked_forward_upright)
    }

    /// Designs that met the whole brief.
    pub fn passed(&self) -> usize {
        self.count(|v| v == Verdict::Passed)
    }
}

/// A survey of random genomes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Survey {
    /// The scheme evaluated.
    pub scheme: Scheme,
    /// The run seed the genomes were drawn from.
    pub seed: u64,
    /// All designs.
    pub all: Tally,
    /// Per legs per side, 2 to 6.
    pub per_leg_count: Vec<(usize, Tally)>,
    /// Pearson's r between the distance walked and the simple kinematic estimate, over the
    /// designs upright to the end (backward ones included), and their number.
    pub estimate_correlation: (Option<f64>, usize),
    /// The same over designs that walked forward.
    pub estimate_correlation_forward: (Option<f64>, usize),
    /// Pearson's r between the distance walked and the gait's no-slip distance, over the
    /// designs upright to the end.
    pub gait_correlation: (Option<f64>, usize),
    /// Per cause, over simulated designs: (designs showing it, share of them with the
    /// failure it explains, designs not showing it, share of those with that failure). A
    /// cause that explains a failure makes it much likelier.
    pub cause_checks: Vec<(Cause, usize, f64, usize, f64)>,
    /// Every design, in candidate order (for `--csv`).
    #[serde(skip)]
    pub records: Vec<Record>,
}

impl Survey {
    /// Draws `count` random genomes for `scheme` from `seed` (candidate numbers 0..count, the
    /// same genomes a run with that seed starts from) and evaluates them, calling
    /// `progress` with the number done after each one (from the simulation threads).
    pub fn run(
        ctx: &EvalContext,
        scheme: Scheme,
        seed: u64,
        count: usize,
        threads: NonZeroUsize,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Self {
        let candidates: Vec<u64> = (0..count as u64).collect();
        let done = std::sync::atomic::AtomicUsize::new(0);
        let records = map_batch(&candidates, threads, |&i| {
            let s = CandidateSeed::new(seed, i);
            let genome = Genome::random(scheme, &mut s.rng(Purpose::RandomGenome));
            let outcome = evaluate(ctx, &genome, scheme, s);
            let record = Record::of(ctx, scheme, i, &genome, &outcome);
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1);
            record
        });
        let brief_distance =
            ctx.brief.required_speed(ctx.limits.speed_margin) * ctx.settings.trial_seconds;
        Self::of_records(scheme, seed, brief_distance, records)
    }

    fn of_records(scheme: Scheme, seed: u64, brief_distance: f64, records: Vec<Record>) -> Self {
        let verdicts = Verdict::all();
        let mut all = Tally::new();
        let mut per: Vec<(usize, Tally)> = (2..=6).map(|n| (n, Tally::new())).collect();
        for r in &records {
            let slot = verdicts
                .iter()
                .position(|v| *v == r.verdict)
                .expect("every verdict is listed");
            let group = per
                .iter_mut()
                .find(|(n, _)| *n == r.legs_per_side)
                .map(|(_, t)| t)
                .expect("2 to 6 legs per side");
            for t in [&mut all, group] {
                t.drawn += 1;
                t.mass_fails += usize::from(r.fails_mass);
                t.height_fails += usize::from(r.fails_height);
                t.verdicts[slot] += 1;
                if r.verdict.simulated() && r.verdict != Verdict::Passed {
                    match r.cause {
                        Some(c) => {
                            t.causes[Cause::ALL.iter().position(|x| *x == c).expect("listed")] += 1
                        }
                        None => t.unexplained += 1,
                    }
                }
            }
        }
        let pairs = |pick: fn(Verdict) -> bool, other: fn(&Record) -> Option<f64>| {
            let xy: Vec<(f64, f64)> = records
                .iter()
                .filter(|r| pick(r.verdict))
                .filter_map(|r| Some((r.distance?, other(r)?)))
                .collect();
            (pearson(&xy), xy.len())
        };
        let share = |n: usize, of: usize| {
            if of == 0 {
                f64::NAN
            } else {
                n as f64 / of as f64
            }
        };
        let cause_checks = Cause::ALL
            .iter()
            .map(|&c| {
                let (mut with, mut with_fail, mut without, mut without_fail) = (0, 0, 0, 0);
                for r in &records {
                    match c.holds(r, brief_distance) {
                        Some(true) => {
                            with += 1;
                            with_fail += usize::from(c.explains(r.verdict));
                        }
                        Some(false) => {
                            without += 1;
                            without_fail += usize::from(c.explains(r.verdict));
                        }
                        None => {}
                    }
                }
                (
                    c,
                    with,
                    share(with_fail, with),
                    without,
                    share(without_fail, without),
                )
            })
            .collect();
        Survey {
            scheme,
            seed,
            cause_checks,
            all,
            per_leg_count: per,
            estimate_correlation: pairs(Verdict::upright_to_the_end, |r| r.estimate),
            estimate_correlation_forward: pairs(Verdict::walked_forward_upright, |r| r.estimate),
            gait_correlation: pairs(Verdict::upright_to_the_end, |r| r.gait_distance),
            records,
        }
    }

    /// Every record as CSV, one row per design.
    pub fn write_csv(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        let mut header = String::from(
            "candidate,legs_per_side,verdict,stopped_at,distance,estimate,gait_distance,gait_lift,gait_contact_at,stance_load,support_margin,cause",
        );
        for p in MORPHOLOGY_PARAMS.iter().chain(CONTROLLER_PARAMS) {
            header.push_str(",g_");
            header.push_str(p.name);
        }
        writeln!(out, "{header}")?;
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6}"));
        for r in &self.records {
            write!(
                out,
                "{},{},{},{},{},{},{},{},{},{},{},{}",
                r.candidate,
                r.legs_per_side,
                r.verdict.label().replace(',', ";"),
                f(r.stopped_at),
                f(r.distance),
                f(r.estimate),
                f(r.gait_distance),
                f(r.gait_lift),
                f(r.gait_contact_at),
                f(r.stance_load),
                f(r.support_margin),
                r.cause.map_or("", |c| c.label())
            )?;
            for v in r
                .genome
                .morphology
                .values()
                .iter()
                .chain(r.genome.controller.values())
            {
                write!(out, ",{v}")?;
            }
            writeln!(out)?;
        }
        Ok(())
    }
}

/// Pearson's correlation coefficient; `None` under 3 points or with no spread.
pub fn pearson(xy: &[(f64, f64)]) -> Option<f64> {
    let n = xy.len() as f64;
    if xy.len() < 3 {
        return None;
    }
    let (mx, my) = (
        xy.iter().map(|p| p.0).sum::<f64>() / n,
        xy.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in xy {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx) * (x - mx);
        syy += (y - my) * (y - my);
    }
    (sxx > 0.0 && syy > 0.0).then(|| sxy / (sxx * syy).sqrt())
}

impl fmt::Display for Survey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let pct = |n: usize, of: usize| {
            if of == 0 {
                "-".to_string()
            } else {
                format!("{:.1}", 100.0 * n as f64 / of as f64)
            }
        };
        let groups: Vec<(&str, &Tally)> = std::iter::once(("all", &self.all))
            .chain(
                self.per_leg_count
                    .iter()
                    .map(|(n, t)| (["n=2", "n=3", "n=4", "n=5", "n=6"][n - 2], t)),
            )
            .collect();
        // The label column holds the longest label (verdicts are indented by two).
        let width = Verdict::all()
            .into_iter()
            .map(|v| v.label().chars().count() + 2)
            .chain(Cause::ALL.iter().map(|c| c.label().chars().count() + 2))
            .fold(52, usize::max)
            + 1;
        let row = |f: &mut fmt::Formatter<'_>, label: &str, cell: &dyn Fn(&Tally) -> String| {
            write!(f, "{label:<width$}")?;
            for (_, t) in &groups {
                write!(f, "{:>9}", cell(t))?;
            }
            writeln!(f)
        };
        writeln!(
            f,
            "random genomes, {} scheme, seed {}: counts, and % where marked",
            self.scheme.name(),
            self.seed
        )?;
        write!(f, "{:<width$}", "")?;
        for (name, _) in &groups {
            write!(f, "{name:>9}")?;
        }
        writeln!(f)?;
        row(f, "drawn", &|t| t.drawn.to_string())?;
        row(f, "fail mass (any)", &|t| t.mass_fails.to_string())?;
        row(f, "fail height (any)", &|t| t.height_fails.to_string())?;
        row(f, "pass mass and height", &|t| {
            t.pass_mass_and_height().to_string()
        })?;
        for (i, v) in Verdict::all().into_iter().enumerate() {
            if matches!(v, Verdict::RejectedMass | Verdict::RejectedHeight) {
                continue;
            }
            let indent = if v.simulated() { "  " } else { "" };
            row(f, &format!("{indent}{}", v.label()), &|t| {
                t.verdicts[i].to_string()
            })?;
        }
        row(f, "simulated", &|t| t.simulated().to_string())?;
        row(f, "walk forward upright, % of pass mass and height", &|t| {
            pct(t.walked(), t.pass_mass_and_height())
        })?;
        row(f, "meet the whole brief, % of pass mass and height", &|t| {
            pct(t.passed(), t.pass_mass_and_height())
        })?;
        writeln!(f, "failed trials by computed cause (% of failed trials)")?;
        let failed = |t: &Tally| t.simulated() - t.passed();
        for (i, c) in Cause::ALL.iter().enumerate() {
            row(f, &format!("  {}", c.label()), &|t| {
                pct(t.causes[i], failed(t))
            })?;
        }
        row(f, "  no computed cause", &|t| pct(t.unexplained, failed(t)))?;
        writeln!(
            f,
            "does each cause predict its failure? (designs with / without it; falls among designs\n  whose gait sweeps nothing together, backward among those upright to the end)"
        )?;
        // A share of no designs is "-", not NaN.
        let share = |p: f64, n: usize| {
            if n == 0 || !p.is_finite() {
                format!("{:>7}", "-")
            } else {
                format!("{:>5.1} %", 100.0 * p)
            }
        };
        for (c, with, p_with, without, p_without) in &self.cause_checks {
            writeln!(
                f,
                "  {:<w$}{:>6} designs: {} {}; {:>6} without: {}",
                c.label(),
                with,
                share(*p_with, *with),
                c.failure_label(),
                without,
                share(*p_without, *without),
                w = width - 2
            )?;
        }
        let r = |(r, n): (Option<f64>, usize)| match r {
            Some(r) => format!("r = {r:.2} over {n} designs"),
            None => format!("- ({n} designs)"),
        };
        writeln!(
            f,
            "distance vs (2/pi) r wmax, upright to the end        {}",
            r(self.estimate_correlation)
        )?;
        writeln!(
            f,
            "distance vs (2/pi) r wmax, walked forward upright    {}",
            r(self.estimate_correlation_forward)
        )?;
        write!(
            f,
            "distance vs the gait's no-slip distance, upright     {}",
            r(self.gait_correlation)
        )
    }
}
