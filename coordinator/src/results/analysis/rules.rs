//! Design rules (the paper's section 7): linear relations among the six
//! features of the best designs, from the thin axes of their scaled covariance.
//!
//! Scale each feature by its root-mean-square s_j (about zero, as the paper does), take the
//! covariance of (g - mean) / s, eigen-decompose it, and keep every eigenvector whose
//! sqrt(eigenvalue) is at most the threshold (0.2), thinnest first. Each kept eigenvector v
//! says v . (g - mean) / s ~ 0; solved for the feature k with the largest |v_k| it reads
//! g_k = mean_k + sum_j a_j (g_j - mean_j), with a_j = -(v_j / v_k)(s_k / s_j), terms in
//! order of decreasing |v_j|.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use std::fmt;
use strider_common::features::{FEATURE_COUNT, FEATURE_NAMES};

/// One design rule.
#[derive(Clone, Debug, PartialEq)]
pub struct Rule {
    /// The feature it predicts (0-based: d1 is 0).
    pub target: usize,
    /// Mean of every feature over the designs.
    pub means: [f64; FEATURE_COUNT],
    /// (feature, coefficient on (d_j - mean_j)), by decreasing weight in the eigenvector.
    pub terms: Vec<(usize, f64)>,
    /// sqrt(eigenvalue): the scaled spread of the designs across the rule.
    pub spread: f64,
    /// Mean |actual - predicted| of the target over the designs, as a fraction of its
    /// root-mean-square.
    pub mean_error: f64,
}

impl Rule {
    /// The rule's prediction of its target for one design.
    pub fn predict(&self, g: &[f64; FEATURE_COUNT]) -> f64 {
        self.means[self.target]
            + self
                .terms
                .iter()
                .map(|&(j, a)| a * (g[j] - self.means[j]))
                .sum::<f64>()
    }
}

impl Rule {
    /// The rule as a plain linear model: (intercept, coefficient of each feature), so that
    /// target = intercept + sum over j of coefficient_j x d_j (the target's own is 0).
    pub fn linear(&self) -> (f64, [f64; FEATURE_COUNT]) {
        let mut coefficients = [0.0; FEATURE_COUNT];
        let mut intercept = self.means[self.target];
        for &(j, a) in &self.terms {
            coefficients[j] = a;
            intercept -= a * self.means[j];
        }
        (intercept, coefficients)
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let k = self.target;
        write!(f, "{} = {:.4}", FEATURE_NAMES[k], self.means[k])?;
        for &(j, a) in &self.terms {
            let sign = if a < 0.0 { '-' } else { '+' };
            // (d - m) for a positive mean, (d + |m|) for a negative one.
            let (op, m) = if self.means[j] < 0.0 {
                ('+', -self.means[j])
            } else {
                ('-', self.means[j])
            };
            write!(
                f,
                " {sign} {:.3e} ({} {op} {m:.4})",
                a.abs(),
                FEATURE_NAMES[j]
            )?;
        }
        write!(f, "   [mean error {:.1} %]", 100.0 * self.mean_error)
    }
}

/// Fewer designs than this give no rules: a six-feature covariance from a handful of
/// designs has thin axes by construction (below 7 designs, at least one exactly thin), so a
/// "rule" from them describes those designs, not a trend.
pub const MIN_RULE_DESIGNS: usize = 30;

/// The rules found, and those the threshold dropped.
#[derive(Clone, Debug, PartialEq)]
pub struct Rules {
    /// sqrt(eigenvalue) <= threshold, thinnest first.
    pub kept: Vec<Rule>,
    /// The others, thinnest first.
    pub dropped: Vec<Rule>,
    /// Features every design holds at one value, with that value: no rule predicts them
    /// or uses them ("legs_per_side = 2 + 0 x ..." said nothing).
    pub constant: Vec<(usize, f64)>,
}

/// Why rules could not be mined.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RulesError {
    #[error("need at least {MIN_RULE_DESIGNS} designs, got {0}")]
    TooFew(usize),
    #[error("a design holds a feature that is not a finite number")]
    NotFinite,
}

/// Mines design rules from designs given as six-feature vectors (at least
/// [`MIN_RULE_DESIGNS`]). A feature that does not vary over them is listed as constant and
/// left out: the rules are the thin axes of the varying features alone.
pub fn mine_rules(designs: &[[f64; FEATURE_COUNT]], threshold: f64) -> Result<Rules, RulesError> {
    let n = designs.len();
    if n < MIN_RULE_DESIGNS {
        return Err(RulesError::TooFew(n));
    }
    if designs.iter().flatten().any(|v| !v.is_finite()) {
        return Err(RulesError::NotFinite);
    }
    let (varying, constant): (Vec<usize>, Vec<usize>) =
        (0..FEATURE_COUNT).partition(|&j| designs.iter().any(|g| g[j] != designs[0][j]));
    let constant = constant.into_iter().map(|j| (j, designs[0][j])).collect();
    let nf = n as f64;
    let means: [f64; FEATURE_COUNT] =
        std::array::from_fn(|j| designs.iter().map(|g| g[j]).sum::<f64>() / nf);
    if varying.is_empty() {
        return Ok(Rules {
            kept: Vec::new(),
            dropped: Vec::new(),
            constant,
        });
    }
    // Each varying feature scaled by its root-mean-square (non-zero, as it varies).
    let scale: Vec<f64> = varying
        .iter()
        .map(|&j| (designs.iter().map(|g| g[j] * g[j]).sum::<f64>() / nf).sqrt())
        .collect();
    let m = varying.len();
    let mut cov = DMatrix::<f64>::zeros(m, m);
    for g in designs {
        let z = DVector::from_fn(m, |a, _| (g[varying[a]] - means[varying[a]]) / scale[a]);
        cov += &z * z.transpose();
    }
    cov /= nf;
    let eigen = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..m).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    let (mut kept, mut dropped) = (Vec::new(), Vec::new());
    for i in order {
        let v = eigen.eigenvectors.column(i);
        let spread = eigen.eigenvalues[i].max(0.0).sqrt();
        let k = (0..m)
            .max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
            .expect("a feature varies: the designs are not all one");
        let mut others: Vec<usize> = (0..m).filter(|&a| a != k).collect();
        others.sort_by(|&a, &b| v[b].abs().total_cmp(&v[a].abs()));
        let mut rule = Rule {
            target: varying[k],
            means,
            terms: others
                .into_iter()
                .map(|a| (varying[a], -(v[a] / v[k]) * (scale[k] / scale[a])))
                .collect(),
            spread,
            mean_error: 0.0,
        };
        rule.mean_error = designs
            .iter()
            .map(|g| (g[varying[k]] - rule.predict(g)).abs())
            .sum::<f64>()
            / nf
            / scale[k];
        if spread <= threshold {
            kept.push(rule);
        } else {
            dropped.push(rule);
        }
    }
    Ok(Rules {
        kept,
        dropped,
        constant,
    })
}
