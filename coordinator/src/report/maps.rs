//! The six-dimensional library as pictures: dimensional stacking (spec section 6:
//! x = (d1 b + d3) b + d5, y = (d2 b + d4) b + d6, heavier lines every b^2 cells, the
//! reference design marked) and the fifteen best-per-pair marginal maps.

use super::svg::{colour, colour_bar, document, text, vertical_text, EMPTY};
use crate::library::Library;
use std::fmt::Write;
use strider_common::features::{FEATURE_COUNT, FEATURE_NAMES};
use strider_common::{CellIndex, FeatureGrid};

/// A fixed fitness scale for every map of a report, so colours compare across pictures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Fitness drawn darkest.
    pub lo: f64,
    /// Fitness drawn brightest.
    pub hi: f64,
}

impl Scale {
    fn t(&self, f: f64) -> f64 {
        if self.hi > self.lo {
            (f - self.lo) / (self.hi - self.lo)
        } else {
            1.0
        }
    }
}

/// Where a cell sits in the stacked picture: (column, row from the bottom).
pub fn stacked_position(grid: &FeatureGrid, cell: CellIndex) -> (u32, u32) {
    let b = grid.bins;
    let d = grid.bins_of_cell(cell).0;
    ((d[0] * b + d[2]) * b + d[4], (d[1] * b + d[3]) * b + d[5])
}

const CELL: f64 = 5.0;
const LEFT: f64 = 120.0;
const TOP: f64 = 50.0;

fn bin_label(grid: &FeatureGrid, feature: usize, bin: u32) -> String {
    let r = grid.ranges()[feature];
    let w = (r.max - r.min) / f64::from(grid.bins);
    let lo = r.min + w * f64::from(bin);
    format!("{}–{}", short(lo), short(lo + w))
}

fn short(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 10.0 {
        format!("{v:.0}")
    } else if v.abs() >= 0.1 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// The whole library of one run by dimensional stacking; `marked` is the reference
/// design's cell (drawn as a red ring).
pub fn stacking_svg(
    grid: &FeatureGrid,
    library: &Library,
    scale: Scale,
    marked: Option<(CellIndex, &str)>,
    title: &str,
) -> String {
    let b = grid.bins;
    let n = b * b * b;
    let side = f64::from(n) * CELL;
    let mut s = String::new();
    text(&mut s, LEFT, 22.0, 14.0, "start", title);
    let _ = writeln!(
        s,
        r#"<rect x="{LEFT}" y="{TOP}" width="{side}" height="{side}" fill="{EMPTY}"/>"#
    );
    for (cell, e) in library.elites() {
        let (x, y) = stacked_position(grid, cell);
        let _ = writeln!(
            s,
            r#"<rect x="{:.1}" y="{:.1}" width="{CELL}" height="{CELL}" fill="{}"/>"#,
            LEFT + f64::from(x) * CELL,
            TOP + side - f64::from(y + 1) * CELL,
            colour(scale.t(e.fitness))
        );
    }
    // Lines between blocks: thin every b cells, heavy every b^2.
    for k in 0..=n {
        let (w, c) = if k % (b * b) == 0 {
            (1.6, "#222")
        } else if k % b == 0 {
            (0.5, "#999")
        } else {
            continue;
        };
        let p = f64::from(k) * CELL;
        let _ = writeln!(
            s,
            r#"<line x1="{:.1}" y1="{TOP}" x2="{:.1}" y2="{:.1}" stroke="{c}" stroke-width="{w}"/><line x1="{LEFT}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{c}" stroke-width="{w}"/>"#,
            LEFT + p,
            LEFT + p,
            TOP + side,
            TOP + side - p,
            LEFT + side,
            TOP + side - p
        );
    }
    // Outer bins labelled along the axes.
    let block = f64::from(b * b) * CELL;
    for k in 0..b {
        text(
            &mut s,
            LEFT + (f64::from(k) + 0.5) * block,
            TOP + side + 16.0,
            11.0,
            "middle",
            &bin_label(grid, 0, k),
        );
        vertical_text(
            &mut s,
            LEFT - 12.0,
            TOP + side - (f64::from(k) + 0.5) * block,
            11.0,
            &bin_label(grid, 1, k),
        );
    }
    text(
        &mut s,
        LEFT + side / 2.0,
        TOP + side + 34.0,
        12.0,
        "middle",
        &format!(
            "across: d1 {} (blocks) › d3 {} › d5 {} (innermost)",
            FEATURE_NAMES[0], FEATURE_NAMES[2], FEATURE_NAMES[4]
        ),
    );
    vertical_text(
        &mut s,
        LEFT - 34.0,
        TOP + side / 2.0,
        12.0,
        &format!(
            "up: d2 {} (blocks) › d4 {} › d6 {} (innermost)",
            FEATURE_NAMES[1], FEATURE_NAMES[3], FEATURE_NAMES[5]
        ),
    );
    if let Some((cell, name)) = marked {
        let (x, y) = stacked_position(grid, cell);
        let (cx, cy) = (
            LEFT + (f64::from(x) + 0.5) * CELL,
            TOP + side - (f64::from(y) + 0.5) * CELL,
        );
        let _ = writeln!(
            s,
            r#"<circle cx="{cx:.1}" cy="{cy:.1}" r="7" fill="none" stroke="red" stroke-width="2"/>"#
        );
        text(&mut s, cx + 10.0, cy - 8.0, 12.0, "start", name);
    }
    colour_bar(&mut s, LEFT, TOP + side + 50.0, 300.0, scale.lo, scale.hi);
    document(LEFT + side + 30.0, TOP + side + 100.0, &s)
}

/// Best fitness per pair of bins of features `i` and `j` (None: no elite there),
/// indexed `[bin_i][bin_j]`.
pub fn marginal(
    grid: &FeatureGrid,
    library: &Library,
    i: usize,
    j: usize,
) -> Vec<Vec<Option<f64>>> {
    let b = grid.bins as usize;
    let mut m = vec![vec![None; b]; b];
    for (cell, e) in library.elites() {
        let d = grid.bins_of_cell(cell).0;
        let slot: &mut Option<f64> = &mut m[d[i] as usize][d[j] as usize];
        if slot.is_none_or(|f| e.fitness > f) {
            *slot = Some(e.fitness);
        }
    }
    m
}

/// The fifteen marginal maps (every pair of features, best fitness per pair of bins)
/// in one picture.
pub fn marginals_svg(grid: &FeatureGrid, library: &Library, scale: Scale, title: &str) -> String {
    let b = f64::from(grid.bins);
    let cell = 18.0;
    let map = b * cell;
    let (gap_x, gap_y) = (map + 70.0, map + 70.0);
    let cols = 5;
    let mut s = String::new();
    text(&mut s, 20.0, 22.0, 14.0, "start", title);
    let pairs = (0..FEATURE_COUNT).flat_map(|i| (i + 1..FEATURE_COUNT).map(move |j| (i, j)));
    for (k, (i, j)) in pairs.enumerate() {
        let (ox, oy) = (
            50.0 + (k % cols) as f64 * gap_x,
            50.0 + (k / cols) as f64 * gap_y,
        );
        for (bi, row) in marginal(grid, library, i, j).iter().enumerate() {
            for (bj, v) in row.iter().enumerate() {
                let fill = v.map_or(EMPTY.to_string(), |f| colour(scale.t(f)));
                let _ = writeln!(
                    s,
                    r##"<rect x="{:.1}" y="{:.1}" width="{cell}" height="{cell}" fill="{fill}" stroke="#fff" stroke-width="0.5"/>"##,
                    ox + bi as f64 * cell,
                    oy + map - (bj as f64 + 1.0) * cell
                );
            }
        }
        let _ = writeln!(
            s,
            r##"<rect x="{ox:.1}" y="{oy:.1}" width="{map}" height="{map}" fill="none" stroke="#333"/>"##
        );
        text(
            &mut s,
            ox + map / 2.0,
            oy + map + 14.0,
            10.0,
            "middle",
            &format!("d{} {} →", i + 1, FEATURE_NAMES[i]),
        );
        vertical_text(
            &mut s,
            ox - 8.0,
            oy + map / 2.0,
            10.0,
            &format!("d{} {} →", j + 1, FEATURE_NAMES[j]),
        );
    }
    let height = 50.0 + 3.0 * gap_y + 10.0;
    colour_bar(&mut s, 50.0, height, 300.0, scale.lo, scale.hi);
    document(50.0 + cols as f64 * gap_x, height + 40.0, &s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stacking_nests_d1_d3_d5_across_and_d2_d4_d6_up() {
        let grid = FeatureGrid::default();
        let cell = grid.cell_index(strider_common::features::Bins([1, 2, 3, 4, 0, 1]));
        // x = (1*5 + 3)*5 + 0 = 40, y = (2*5 + 4)*5 + 1 = 71.
        assert_eq!(stacked_position(&grid, cell), (40, 71));
        let last = grid.cell_index(strider_common::features::Bins([4; 6]));
        assert_eq!(stacked_position(&grid, last), (124, 124));
    }
}
