//! Design rules (spec section 6, the paper's section 7): linear relations among the six
//! features of the best designs, from the thin axes of their scaled covariance.
//!
//! Scale each feature by its root-mean-square s_j (about zero, as the paper does), take the
//! covariance of (g - mean) / s, eigen-decompose it, and keep every eigenvector whose
//! sqrt(eigenvalue) is at most the threshold (0.2), thinnest first. Each kept eigenvector v
//! says v . (g - mean) / s ~ 0; solved for the feature k with the largest |v_k| it reads
//! g_k = mean_k + sum_j a_j (g_j - mean_j), with a_j = -(v_j / v_k)(s_k / s_j), terms in
//! order of decreasing |v_j|.

use nalgebra::{SMatrix, SVector, SymmetricEigen};
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

/// The rules found, and those the threshold dropped.
#[derive(Clone, Debug, PartialEq)]
pub struct Rules {
    /// sqrt(eigenvalue) <= threshold, thinnest first.
    pub kept: Vec<Rule>,
    /// The others, thinnest first.
    pub dropped: Vec<Rule>,
}

/// Why rules could not be mined.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RulesError {
    #[error("need at least 2 designs, got {0}")]
    TooFew(usize),
    #[error("feature d{0} is zero in every design, so it has no scale")]
    ZeroScale(usize),
    #[error("a design holds a feature that is not a finite number")]
    NotFinite,
}

type Mat = SMatrix<f64, FEATURE_COUNT, FEATURE_COUNT>;
type Vec6 = SVector<f64, FEATURE_COUNT>;

/// Mines design rules from designs given as six-feature vectors.
pub fn mine_rules(designs: &[[f64; FEATURE_COUNT]], threshold: f64) -> Result<Rules, RulesError> {
    let n = designs.len();
    if n < 2 {
        return Err(RulesError::TooFew(n));
    }
    if designs.iter().flatten().any(|v| !v.is_finite()) {
        return Err(RulesError::NotFinite);
    }
    let nf = n as f64;
    let rows: Vec<Vec6> = designs.iter().map(|g| Vec6::from_column_slice(g)).collect();
    let mean: Vec6 = rows.iter().sum::<Vec6>() / nf;
    let scale: Vec6 = rows
        .iter()
        .map(|g| g.component_mul(g))
        .sum::<Vec6>()
        .map(|s| (s / nf).sqrt());
    if let Some(j) = scale.iter().position(|&s| s == 0.0) {
        return Err(RulesError::ZeroScale(j + 1));
    }
    let mut cov = Mat::zeros();
    for g in &rows {
        let z = (g - mean).component_div(&scale);
        cov += z * z.transpose();
    }
    cov /= nf;
    let eigen = SymmetricEigen::new(cov);
    let mut order: Vec<usize> = (0..FEATURE_COUNT).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[a].total_cmp(&eigen.eigenvalues[b]));
    let (mut kept, mut dropped) = (Vec::new(), Vec::new());
    for i in order {
        let v = eigen.eigenvectors.column(i);
        let spread = eigen.eigenvalues[i].max(0.0).sqrt();
        let k = (0..FEATURE_COUNT)
            .max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
            .expect("six features");
        let mut others: Vec<usize> = (0..FEATURE_COUNT).filter(|&j| j != k).collect();
        others.sort_by(|&a, &b| v[b].abs().total_cmp(&v[a].abs()));
        let mut rule = Rule {
            target: k,
            means: mean.into(),
            terms: others
                .into_iter()
                .map(|j| (j, -(v[j] / v[k]) * (scale[k] / scale[j])))
                .collect(),
            spread,
            mean_error: 0.0,
        };
        rule.mean_error = designs
            .iter()
            .map(|g| (g[k] - rule.predict(g)).abs())
            .sum::<f64>()
            / nf
            / scale[k];
        if spread <= threshold {
            kept.push(rule);
        } else {
            dropped.push(rule);
        }
    }
    Ok(Rules { kept, dropped })
}
