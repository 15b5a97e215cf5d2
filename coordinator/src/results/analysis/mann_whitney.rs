//! The Mann-Whitney U test, two-sided: exact when the samples are small and tie-free,
//! otherwise the normal approximation with tie correction and continuity correction.

use std::fmt;

/// How the p-value was computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// From the exact null distribution of U (no ties).
    Exact,
    /// Normal approximation, tie- and continuity-corrected.
    Normal,
}

/// The test's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MannWhitney {
    /// U of the first sample (pairs in which it is larger, ties counting half).
    pub u1: f64,
    /// U of the second sample, `n1 n2 - u1`.
    pub u2: f64,
    /// Two-sided p-value.
    pub p: f64,
    /// How `p` was computed.
    pub method: Method,
}

impl MannWhitney {
    /// Whether the difference is significant at level `alpha`.
    pub fn significant(&self, alpha: f64) -> bool {
        self.p < alpha
    }
}

impl fmt::Display for MannWhitney {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "U = {} (p = {:.4}, {}): {}",
            self.u1.min(self.u2),
            self.p,
            match self.method {
                Method::Exact => "exact",
                Method::Normal => "normal approximation",
            },
            if self.significant(0.05) {
                "significant at 0.05"
            } else {
                "not significant at 0.05"
            }
        )
    }
}

/// Why a test could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TestError {
    #[error("a sample is empty")]
    Empty,
    #[error("a sample holds a value that is not a finite number")]
    NotFinite,
}

/// Largest n1 * n2 for which the exact distribution is used.
const EXACT_LIMIT: usize = 2500;

/// Two-sided Mann-Whitney U test of `x` against `y`.
pub fn mann_whitney(x: &[f64], y: &[f64]) -> Result<MannWhitney, TestError> {
    if x.is_empty() || y.is_empty() {
        return Err(TestError::Empty);
    }
    if x.iter().chain(y).any(|v| !v.is_finite()) {
        return Err(TestError::NotFinite);
    }
    let (n1, n2) = (x.len(), y.len());
    let n = n1 + n2;
    // Rank the pooled sample, ties sharing the average rank.
    let mut pooled: Vec<(f64, bool)> = x
        .iter()
        .map(|&v| (v, true))
        .chain(y.iter().map(|&v| (v, false)))
        .collect();
    pooled.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut rank_sum_x = 0.0;
    let mut tie_term = 0.0; // sum of t^3 - t over tie groups
    let mut i = 0;
    while i < n {
        let mut j = i;
        while j + 1 < n && pooled[j + 1].0 == pooled[i].0 {
            j += 1;
        }
        let t = (j - i + 1) as f64;
        let rank = (i + j) as f64 / 2.0 + 1.0;
        rank_sum_x += rank * pooled[i..=j].iter().filter(|p| p.1).count() as f64;
        tie_term += t * t * t - t;
        i = j + 1;
    }
    let (f1, f2) = (n1 as f64, n2 as f64);
    let u1 = rank_sum_x - f1 * (f1 + 1.0) / 2.0;
    let u2 = f1 * f2 - u1;
    if tie_term == 0.0 && n1 * n2 <= EXACT_LIMIT {
        let p = (2.0 * exact_cdf(n1, n2, u1.min(u2) as usize)).min(1.0);
        return Ok(MannWhitney {
            u1,
            u2,
            p,
            method: Method::Exact,
        });
    }
    let nf = n as f64;
    let mean = f1 * f2 / 2.0;
    let variance = f1 * f2 / 12.0 * ((nf + 1.0) - tie_term / (nf * (nf - 1.0)));
    let p = if variance <= 0.0 {
        1.0 // every value tied: no evidence of a difference
    } else {
        let z = ((u1 - mean).abs() - 0.5).max(0.0) / variance.sqrt();
        erfc(z / std::f64::consts::SQRT_2).min(1.0)
    };
    Ok(MannWhitney {
        u1,
        u2,
        p,
        method: Method::Normal,
    })
}

/// P(U <= u) under the null hypothesis, for samples of n1 and n2 without ties.
fn exact_cdf(n1: usize, n2: usize, u: usize) -> f64 {
    // counts[a][b][k]: arrangements of a x's and b y's with U = k, built up row by row.
    // f(a, b, k) = f(a - 1, b, k - b) + f(a, b - 1, k).
    let max_u = n1 * n2;
    let mut prev: Vec<Vec<f64>> = vec![vec![0.0; max_u + 1]; n2 + 1];
    for row in prev.iter_mut() {
        row[0] = 1.0; // a = 0: one arrangement, U = 0
    }
    for a in 1..=n1 {
        let mut cur: Vec<Vec<f64>> = vec![vec![0.0; max_u + 1]; n2 + 1];
        cur[0][0] = 1.0; // b = 0
        for b in 1..=n2 {
            for k in 0..=a * b {
                let from_x = if k >= b { prev[b][k - b] } else { 0.0 };
                cur[b][k] = from_x + cur[b - 1][k];
            }
        }
        prev = cur;
    }
    let counts = &prev[n2];
    let total: f64 = counts.iter().sum();
    counts[..=u.min(max_u)].iter().sum::<f64>() / total
}

/// The complementary error function (Numerical Recipes' Chebyshev fit, relative error
/// below 1.2e-7 everywhere).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.265_512_23
            + t * (1.000_023_68
                + t * (0.374_091_96
                    + t * (0.096_784_18
                        + t * (-0.186_288_06
                            + t * (0.278_868_07
                                + t * (-1.135_203_98
                                    + t * (1.488_515_87
                                        + t * (-0.822_152_23 + t * 0.170_872_77)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}
