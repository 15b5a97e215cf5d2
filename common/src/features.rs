//! The six MAP-Elites features and the cell index (docs/model.md section 10).

use crate::body_plan::BodyPlan;
use crate::genome::Morphology;
use crate::params::{LINK_LENGTH, M};
use serde::{Deserialize, Serialize};

/// Number of features.
pub const FEATURE_COUNT: usize = 6;

/// Feature names, d1 first.
pub const FEATURE_NAMES: [&str; FEATURE_COUNT] = [
    "total_leg_length",
    "total_mass",
    "legs_per_side",
    "wall_thickness",
    "length_mult",
    "width_mult",
];

/// Feature units, d1 first ("" for a count or a multiplier).
pub const FEATURE_UNITS: [&str; FEATURE_COUNT] = ["m", "kg", "", "m", "", ""];

/// The whole values feature `i` can take, where it takes only whole values (d3, legs per
/// side: an integer parameter), else None. Bins of such a feature are named by the values
/// they hold ("3"), not by their edges ("2.80–3.60").
pub fn whole_values(i: usize) -> Option<std::ops::RangeInclusive<i64>> {
    let spec = M::LegsPerSide.spec();
    (FEATURE_NAMES[i] == spec.name && spec.kind == crate::params::ParamKind::Integer)
        .then(|| spec.min.ceil() as i64..=spec.max.floor() as i64)
}

/// Feature values d1..d6 of one design.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Features(pub [f64; FEATURE_COUNT]);

impl Features {
    /// d1 leg length before scaling (m), d2 total mass with payload (kg), d3 legs per side,
    /// d4 tube wall thickness (m), d5 length multiplier, d6 width multiplier.
    pub fn of(m: &Morphology, plan: &BodyPlan) -> Self {
        Features([
            LINK_LENGTH.iter().map(|&p| m.get(p)).sum(),
            plan.total_mass(),
            m.get(M::LegsPerSide),
            m.get(M::WallThickness),
            m.get(M::LengthMult),
            m.get(M::WidthMult),
        ])
    }
}

/// One feature's binning window: `bins` equal bins over `[min, max]`; values outside go
/// to the edge bins.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FeatureRange {
    /// Lower bound.
    pub min: f64,
    /// Upper bound.
    pub max: f64,
}

/// The binning of all six features.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FeatureGrid {
    /// Bins per feature.
    pub bins: u32,
    /// d1 total leg length before scaling, m.
    pub total_leg_length: FeatureRange,
    /// d2 total mass with payload, kg.
    pub total_mass: FeatureRange,
    /// d3 legs per side.
    pub legs_per_side: FeatureRange,
    /// d4 tube wall thickness, m.
    pub wall_thickness: FeatureRange,
    /// d5 leg length multiplier.
    pub length_mult: FeatureRange,
    /// d6 leg width multiplier.
    pub width_mult: FeatureRange,
}

impl Default for FeatureGrid {
    /// The paper's grid: 5 bins each, 15,625 cells.
    fn default() -> Self {
        let r = |min, max| FeatureRange { min, max };
        Self {
            bins: 5,
            total_leg_length: r(2.0, 2.8),
            total_mass: r(50.0, 75.0),
            legs_per_side: r(2.0, 6.0),
            wall_thickness: r(0.001, 0.01),
            length_mult: r(-0.2, 0.2),
            width_mult: r(-0.2, 0.2),
        }
    }
}

/// The bin of each feature.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Bins(pub [u32; FEATURE_COUNT]);

/// A cell of the library: the bins flattened with d1 most significant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(transparent)]
pub struct CellIndex(pub u32);

/// A feature value that cannot be binned.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("feature `{name}` is {value}, which cannot be placed in a cell")]
pub struct FeatureError {
    pub name: &'static str,
    /// The offending value.
    pub value: f64,
}

impl FeatureGrid {
    /// The six ranges, d1 first.
    pub fn ranges(&self) -> [FeatureRange; FEATURE_COUNT] {
        [
            self.total_leg_length,
            self.total_mass,
            self.legs_per_side,
            self.wall_thickness,
            self.length_mult,
            self.width_mult,
        ]
    }

    /// Number of cells, `bins^6`.
    pub fn cell_count(&self) -> u32 {
        self.bins.pow(FEATURE_COUNT as u32)
    }

    /// Bin of one value: the number of interior bin edges at or below it, so a value on an
    /// edge goes to the upper bin, the exact maximum to the last bin, and anything outside
    /// the range to the nearer edge bin.
    pub fn bin(&self, range: FeatureRange, value: f64) -> Option<u32> {
        if value.is_nan() {
            return None;
        }
        let width = range.max - range.min;
        Some(
            (1..self.bins)
                .filter(|&k| value >= range.min + width * f64::from(k) / f64::from(self.bins))
                .count() as u32,
        )
    }

    /// Bins of all six features; NaN is refused.
    pub fn bins_of(&self, f: &Features) -> Result<Bins, FeatureError> {
        let mut bins = [0; FEATURE_COUNT];
        for (j, (range, &value)) in self.ranges().iter().zip(&f.0).enumerate() {
            bins[j] = self.bin(*range, value).ok_or(FeatureError {
                name: FEATURE_NAMES[j],
                value,
            })?;
        }
        Ok(Bins(bins))
    }

    /// The cell of a design.
    pub fn cell_of(&self, f: &Features) -> Result<CellIndex, FeatureError> {
        Ok(self.cell_index(self.bins_of(f)?))
    }

    /// Flattens bins, d1 most significant.
    pub fn cell_index(&self, b: Bins) -> CellIndex {
        CellIndex(b.0.iter().fold(0, |acc, &x| acc * self.bins + x))
    }

    /// Unflattens a cell index.
    pub fn bins_of_cell(&self, c: CellIndex) -> Bins {
        let mut out = [0; FEATURE_COUNT];
        let mut rest = c.0;
        for slot in out.iter_mut().rev() {
            *slot = rest % self.bins;
            rest /= self.bins;
        }
        Bins(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn grid() -> FeatureGrid {
        FeatureGrid::default()
    }

    #[test]
    fn bins_at_the_edges() {
        let g = grid();
        let r = g.total_leg_length; // [2.0, 2.8], edges at 2.16, 2.32, 2.48, 2.64
        let eps = 1e-9;
        assert_eq!(g.bin(r, 2.0), Some(0), "exact minimum");
        assert_eq!(g.bin(r, 2.0 + eps), Some(0), "just inside the minimum");
        assert_eq!(g.bin(r, 2.0 - eps), Some(0), "just below: edge bin");
        assert_eq!(g.bin(r, -100.0), Some(0), "far below: edge bin");
        assert_eq!(g.bin(r, 2.8), Some(4), "exact maximum");
        assert_eq!(g.bin(r, 2.8 - eps), Some(4), "just inside the maximum");
        assert_eq!(g.bin(r, 2.8 + eps), Some(4), "just above: edge bin");
        assert_eq!(g.bin(r, f64::INFINITY), Some(4));
        assert_eq!(g.bin(r, f64::NEG_INFINITY), Some(0));
        // An interior edge belongs to the bin above it.
        let edge = 2.0 + 0.8 * 2.0 / 5.0;
        assert_eq!(g.bin(r, edge), Some(2));
        assert_eq!(g.bin(r, edge - eps), Some(1));
        assert_eq!(g.bin(r, f64::NAN), None);
    }

    #[test]
    fn legs_per_side_bin_is_n_minus_2() {
        let g = grid();
        for n in 2..=6 {
            assert_eq!(g.bin(g.legs_per_side, f64::from(n)), Some(n - 2));
        }
    }

    #[test]
    fn nan_feature_is_refused_by_name() {
        let f = Features([2.3, f64::NAN, 3.0, 0.003, 0.0, 0.0]);
        let e = grid().cell_of(&f).unwrap_err();
        assert_eq!(e.name, "total_mass");
        assert!(e.to_string().contains("total_mass"));
    }

    #[test]
    fn cell_index_orders_d1_first() {
        let g = grid();
        assert_eq!(g.cell_count(), 15_625);
        assert_eq!(g.cell_index(Bins([0, 0, 0, 0, 0, 1])), CellIndex(1));
        assert_eq!(g.cell_index(Bins([1, 0, 0, 0, 0, 0])), CellIndex(3125));
        assert_eq!(g.cell_index(Bins([4; 6])), CellIndex(15_624));
    }

    proptest! {
        #[test]
        fn cell_round_trips(b in prop::array::uniform6(0u32..5)) {
            let g = grid();
            let c = g.cell_index(Bins(b));
            prop_assert!(c.0 < g.cell_count());
            prop_assert_eq!(g.bins_of_cell(c), Bins(b));
        }

        #[test]
        fn bins_are_monotone_and_bounded(a in -10.0f64..10.0, b in -10.0f64..10.0) {
            let g = grid();
            let r = g.length_mult;
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            let (bl, bh) = (g.bin(r, lo).unwrap(), g.bin(r, hi).unwrap());
            prop_assert!(bl <= bh && bh < 5);
        }
    }
}
