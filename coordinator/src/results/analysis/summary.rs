//! The design-assist summary of an experiment (the paper's sections 6 and 7) as plain data: final
//! figures per scheme, Mann-Whitney tests between schemes, the top designs' mean
//! features (the paper's Table 5), each repeat's best controller, and the design rules
//! (Table 6). `strider-coordinator analyse` prints it.

use super::mann_whitney::{mann_whitney, MannWhitney};
use super::rules::{mine_rules, Rules, MIN_RULE_DESIGNS};
use crate::qd::library::{GenerationStats, InfeasibleLibrary, Library};
use std::fmt;
use strider_common::features::{FEATURE_COUNT, FEATURE_NAMES};
use strider_common::genome::ParamVector;
use strider_common::params::{CONTROLLER_LEN, CONTROLLER_PARAMS};
use strider_common::{BodyPlan, Features, Scheme, Shortfall};

/// Share of each scheme's designs (pooled over repeats, by fitness) the rules and Table 5
/// are drawn from.
pub const TOP_SHARE: f64 = 0.1;
/// The rule threshold on sqrt(eigenvalue).
pub const RULE_THRESHOLD: f64 = 0.2;

/// One run's inputs to the summary.
pub struct RunResult<'a> {
    pub scheme: Scheme,
    /// Its library at the end.
    pub library: &'a Library,
    /// Its infeasible library at the end (empty under the paper's method).
    pub infeasible: &'a InfeasibleLibrary,
    /// Its last generation's statistics.
    pub last: GenerationStats,
}

/// Mean and sample standard deviation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeanSd {
    pub mean: f64,
    /// Sample standard deviation (0 for one value).
    pub sd: f64,
}

/// Mean and sample standard deviation of `v` (not empty).
pub fn mean_sd(v: &[f64]) -> MeanSd {
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    MeanSd { mean, sd }
}

/// One scheme's part of the summary.
pub struct SchemeSummary {
    pub scheme: Scheme,
    /// Runs of it.
    pub repeats: usize,
    /// Final best fitness over repeats.
    pub best: MeanSd,
    /// Final coverage over repeats.
    pub coverage: MeanSd,
    /// Designs in the top share, pooled over repeats.
    pub top_designs: usize,
    /// Their mean features d1..d6.
    pub top_features: [f64; FEATURE_COUNT],
    /// Mean controller of each repeat's best design.
    pub best_controller: [f64; CONTROLLER_LEN],
    /// Repeats whose library holds a design (those the mean controller is over).
    pub repeats_with_designs: usize,
    /// Design rules from the top designs (None with fewer than [`MIN_RULE_DESIGNS`]).
    pub rules: Option<Rules>,
    /// Where the brief binds.
    pub frontier: Frontier,
}

/// Where the brief binds, over a scheme's repeats (mean ± sd of cell counts).
pub struct Frontier {
    /// Cells holding a design that meets the whole brief.
    pub feasible: MeanSd,
    /// Cells holding only designs that miss it.
    pub infeasible_only: MeanSd,
    /// Of those, how many per constraint that binds (mean over repeats), nearest the brief
    /// first.
    pub binding: Vec<(Shortfall, f64)>,
}

/// The frontier of some runs.
pub fn frontier<'r, 'a: 'r>(runs: impl IntoIterator<Item = &'r RunResult<'a>> + Clone) -> Frontier {
    let n = runs.clone().into_iter().count().max(1) as f64;
    let only = |r: &RunResult<'_>| {
        r.infeasible
            .elites()
            .filter(|(c, _)| r.library.get(*c).is_none())
            .map(|(_, e)| e.shortfall)
            .collect::<Vec<_>>()
    };
    let feasible: Vec<f64> = runs
        .clone()
        .into_iter()
        .map(|r| r.library.len() as f64)
        .collect();
    let infeasible_only: Vec<f64> = runs
        .clone()
        .into_iter()
        .map(|r| only(r).len() as f64)
        .collect();
    let binding = Shortfall::ALL
        .iter()
        .map(|&s| {
            let total: usize = runs
                .clone()
                .into_iter()
                .map(|r| only(r).iter().filter(|x| **x == s).count())
                .sum();
            (s, total as f64 / n)
        })
        .collect();
    let or_zero = |v: &[f64]| {
        if v.is_empty() {
            MeanSd { mean: 0.0, sd: 0.0 }
        } else {
            mean_sd(v)
        }
    };
    Frontier {
        feasible: or_zero(&feasible),
        infeasible_only: or_zero(&infeasible_only),
        binding,
    }
}

/// A Mann-Whitney comparison of two schemes.
pub struct Comparison {
    /// The two schemes.
    pub schemes: (Scheme, Scheme),
    /// On final best fitness.
    pub best: MannWhitney,
    /// On final coverage.
    pub coverage: MannWhitney,
}

/// The whole summary.
pub struct Summary {
    /// Per scheme, in the experiment's order.
    pub schemes: Vec<SchemeSummary>,
    /// Every pair of schemes.
    pub comparisons: Vec<Comparison>,
}

/// Summarises finished runs; `payload` is the brief's (it enters the mass feature).
pub fn summarise(runs: &[RunResult<'_>], schemes: &[Scheme], payload: f64) -> Summary {
    let per: Vec<SchemeSummary> = schemes
        .iter()
        .filter_map(|&scheme| {
            let mine: Vec<&RunResult<'_>> = runs.iter().filter(|r| r.scheme == scheme).collect();
            (!mine.is_empty()).then(|| scheme_summary(scheme, &mine, payload))
        })
        .collect();
    let mut comparisons = Vec::new();
    for (i, a) in schemes.iter().enumerate() {
        for b in &schemes[i + 1..] {
            let take = |s: Scheme, f: fn(&GenerationStats) -> f64| -> Vec<f64> {
                runs.iter()
                    .filter(|r| r.scheme == s)
                    .map(|r| f(&r.last))
                    .collect()
            };
            let (best_a, best_b) = (take(*a, |s| s.max_fitness), take(*b, |s| s.max_fitness));
            let (cov_a, cov_b) = (take(*a, |s| s.coverage), take(*b, |s| s.coverage));
            if let (Ok(best), Ok(coverage)) =
                (mann_whitney(&best_a, &best_b), mann_whitney(&cov_a, &cov_b))
            {
                comparisons.push(Comparison {
                    schemes: (*a, *b),
                    best,
                    coverage,
                });
            }
        }
    }
    Summary {
        schemes: per,
        comparisons,
    }
}

fn scheme_summary(scheme: Scheme, runs: &[&RunResult<'_>], payload: f64) -> SchemeSummary {
    let best = mean_sd(&runs.iter().map(|r| r.last.max_fitness).collect::<Vec<_>>());
    let coverage = mean_sd(&runs.iter().map(|r| r.last.coverage).collect::<Vec<_>>());
    // Pool every elite, best first; keep the top share (at least one).
    let mut pooled: Vec<(f64, [f64; FEATURE_COUNT])> = runs
        .iter()
        .flat_map(|r| r.library.elites())
        .map(|(_, e)| {
            let plan = BodyPlan::new(&e.genome.morphology, payload);
            (e.fitness, Features::of(&e.genome.morphology, &plan).0)
        })
        .collect();
    pooled.sort_by(|a, b| b.0.total_cmp(&a.0));
    let top = ((pooled.len() as f64 * TOP_SHARE).ceil() as usize)
        .clamp(1, pooled.len().max(1))
        .min(pooled.len());
    let designs: Vec<[f64; FEATURE_COUNT]> = pooled[..top].iter().map(|d| d.1).collect();
    let mut top_features = [0.0; FEATURE_COUNT];
    for d in &designs {
        for (acc, v) in top_features.iter_mut().zip(d) {
            *acc += v / designs.len() as f64;
        }
    }
    let mut best_controller = [0.0; CONTROLLER_LEN];
    let bests: Vec<_> = runs
        .iter()
        .filter_map(|r| {
            r.library
                .elites()
                .map(|(_, e)| e)
                .max_by(|a, b| a.fitness.total_cmp(&b.fitness))
        })
        .collect();
    for e in &bests {
        for (acc, v) in best_controller.iter_mut().zip(e.genome.controller.values()) {
            *acc += v / bests.len() as f64;
        }
    }
    SchemeSummary {
        scheme,
        repeats: runs.len(),
        best,
        coverage,
        top_designs: designs.len(),
        top_features,
        best_controller,
        repeats_with_designs: bests.len(),
        rules: mine_rules(&designs, RULE_THRESHOLD).ok(),
        frontier: frontier(runs.iter().copied()),
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "Final library, per scheme (mean ± sd over repeats)")?;
        for s in &self.schemes {
            let repeats = if s.repeats == 1 {
                "1 repeat".to_string()
            } else {
                format!("{} repeats", s.repeats)
            };
            // One repeat has no spread; an empty library has no best fitness (its
            // statistics hold 0).
            let spread = |m: MeanSd, scale: f64, decimals: usize| {
                if s.repeats > 1 {
                    format!(
                        "{:.decimals$} ± {:.decimals$}",
                        scale * m.mean,
                        scale * m.sd
                    )
                } else {
                    format!("{:.decimals$}", scale * m.mean)
                }
            };
            let best = if s.repeats_with_designs == 0 {
                "none (no design meets the brief)".to_string()
            } else {
                spread(s.best, 1.0, 4)
            };
            writeln!(
                f,
                "  {:<7} {repeats}: best fitness {best}, coverage {} %",
                s.scheme,
                spread(s.coverage, 100.0, 3)
            )?;
        }
        writeln!(
            f,
            "\nWhere the brief binds: cells with a design that meets it, cells with only designs\nthat miss it, and what those miss (mean over repeats)"
        )?;
        for s in &self.schemes {
            let fr = &s.frontier;
            let count = |m: MeanSd| {
                if s.repeats > 1 {
                    format!("{:.1} ± {:.1}", m.mean, m.sd)
                } else {
                    format!("{:.0}", m.mean)
                }
            };
            write!(
                f,
                "  {:<7} feasible {}, infeasible only {}:",
                s.scheme,
                count(fr.feasible),
                count(fr.infeasible_only)
            )?;
            for (shortfall, n) in &fr.binding {
                write!(f, " {} {n:.1}", shortfall.name())?;
            }
            writeln!(f)?;
        }
        writeln!(f, "\nMann-Whitney U tests between schemes (two-sided)")?;
        if self.comparisons.is_empty() {
            writeln!(f, "  (one scheme only)")?;
        }
        for c in &self.comparisons {
            writeln!(
                f,
                "  {} vs {}: best fitness {}",
                c.schemes.0, c.schemes.1, c.best
            )?;
            writeln!(
                f,
                "  {} vs {}: coverage {}",
                c.schemes.0, c.schemes.1, c.coverage
            )?;
        }
        writeln!(
            f,
            "\nMean features of the top {:.0} % designs (Table 5)",
            100.0 * TOP_SHARE
        )?;
        for s in &self.schemes {
            if s.top_designs == 0 {
                writeln!(f, "  {:<7} no design meets the brief", s.scheme)?;
                continue;
            }
            write!(f, "  {:<7} ({} designs):", s.scheme, s.top_designs)?;
            for (name, v) in FEATURE_NAMES.iter().zip(&s.top_features) {
                write!(f, " {name} {v:.4}")?;
            }
            writeln!(f)?;
        }
        writeln!(f, "\nMean controller of each repeat's best design")?;
        for s in &self.schemes {
            if s.repeats_with_designs == 0 {
                writeln!(f, "  {:<7} no design meets the brief", s.scheme)?;
                continue;
            }
            write!(
                f,
                "  {:<7} ({} of {} repeats):",
                s.scheme, s.repeats_with_designs, s.repeats
            )?;
            for (p, v) in CONTROLLER_PARAMS.iter().zip(&s.best_controller) {
                write!(f, " {} {v:.3}", p.name)?;
            }
            writeln!(f)?;
        }
        writeln!(
            f,
            "\nDesign rules from the top designs (Table 6; sqrt(eigenvalue) <= {RULE_THRESHOLD})"
        )?;
        for s in &self.schemes {
            match &s.rules {
                None => writeln!(
                    f,
                    "  {}: none mined from {} designs (rules need at least {MIN_RULE_DESIGNS})",
                    s.scheme, s.top_designs
                )?,
                Some(r) => {
                    writeln!(
                        f,
                        "  {}: from {} designs, {} kept, {} dropped by the threshold",
                        s.scheme,
                        s.top_designs,
                        r.kept.len(),
                        r.dropped.len()
                    )?;
                    for &(j, v) in &r.constant {
                        writeln!(
                            f,
                            "    {} = {v} in every design (constant: in no rule)",
                            FEATURE_NAMES[j]
                        )?;
                    }
                    for rule in &r.kept {
                        writeln!(f, "    {rule}")?;
                    }
                }
            }
        }
        Ok(())
    }
}
