//! The six-dimensional library as pictures: dimensional stacking (the paper's section 6:
//! x = (d1 b + d3) b + d5, y = (d2 b + d4) b + d6, heavier lines every b^2 cells, the
//! reference design marked) and the fifteen best-per-pair marginal maps.

use super::svg::{colour, colour_bar, document, escape, text, vertical_text, EMPTY};
use crate::qd::library::{InfeasibleLibrary, Library};
use std::fmt::Write;
use strider_common::features::{FEATURE_COUNT, FEATURE_NAMES, FEATURE_UNITS};
use strider_common::{CellIndex, FeatureGrid, Shortfall, Standing};

mod frontier;

pub use frontier::{frontier_marginals_svg, frontier_svg, FEASIBLE_COLOUR};

/// A fixed fitness scale for every map of a report, so colours compare across pictures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Fitness drawn darkest.
    pub lo: f64,
    /// Fitness drawn brightest (and everything above it).
    pub hi: f64,
    /// The highest fitness drawn, when above `hi`.
    pub max: f64,
}

/// The quantile of fitness the colours top out at: one outlier (30.5 against a median of
/// 2.0) drew every other cell in the same dark colour on a linear scale up to the maximum.
pub const TOP_QUANTILE: f64 = 0.95;

impl Scale {
    /// From 0 to the [`TOP_QUANTILE`] of `fitness` (nearest rank), noting the maximum.
    pub fn robust(fitness: impl IntoIterator<Item = f64>) -> Self {
        let mut v: Vec<f64> = fitness.into_iter().filter(|f| f.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let max = v.last().copied().unwrap_or(0.0);
        let hi = if v.is_empty() {
            0.0
        } else {
            let rank = (TOP_QUANTILE * v.len() as f64).ceil() as usize;
            v[rank.clamp(1, v.len()) - 1]
        };
        Scale { lo: 0.0, hi, max }
    }

    /// The colour bar's note: how the top of the scale was chosen.
    fn note(&self) -> String {
        if self.max > self.hi {
            format!(
                "linear; colours top out at the {:.0}th percentile of fitness ({:.2}); the best is {:.2}",
                100.0 * TOP_QUANTILE,
                self.hi,
                self.max
            )
        } else {
            "linear, up to the best fitness".into()
        }
    }

    fn t(&self, f: f64) -> f64 {
        if self.hi > self.lo {
            ((f - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0)
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

/// A bin's range with its unit; the edge bins are open, since values outside the window
/// go to them (the first bin of total_mass holds designs under 50 kg too: "< 55 kg").
fn bin_label(grid: &FeatureGrid, feature: usize, bin: u32) -> String {
    let r = grid.ranges()[feature];
    if let Some(values) = strider_common::features::whole_values(feature) {
        // The whole values the bin holds: "3", "5–6", or "none" for a bin between two.
        let held: Vec<i64> = values
            .filter(|&v| grid.bin(r, v as f64) == Some(bin))
            .collect();
        return match (held.first(), held.last()) {
            (Some(a), Some(b)) if a == b => format!("{a}"),
            (Some(a), Some(b)) => format!("{a}–{b}"),
            _ => "none".into(),
        };
    }
    let w = (r.max - r.min) / f64::from(grid.bins);
    let lo = r.min + w * f64::from(bin);
    let unit = match FEATURE_UNITS[feature] {
        "" => String::new(),
        u => format!(" {u}"),
    };
    if grid.bins == 1 {
        "all".into()
    } else if bin == 0 {
        format!("< {}{unit}", short(lo + w))
    } else if bin + 1 == grid.bins {
        format!("≥ {}{unit}", short(lo))
    } else {
        format!("{}–{}{unit}", short(lo), short(lo + w))
    }
}

/// A feature's axis title: its d-number, name and unit (the mass is with the payload,
/// and says so: the brief's mass limit and the near-miss table are without it).
fn axis_title(feature: usize) -> String {
    match (FEATURE_UNITS[feature], FEATURE_NAMES[feature]) {
        ("", name) => format!("d{} {name}", feature + 1),
        (u, name @ "total_mass") => format!("d{} {name} ({u}, with payload)", feature + 1),
        (u, name) => format!("d{} {name} ({u})", feature + 1),
    }
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
    let mut s = String::new();
    let painted = library
        .elites()
        .map(|(cell, e)| (cell, colour(scale.t(e.fitness))));
    let side = stack(&mut s, grid, painted, marked, title);
    colour_bar(
        &mut s,
        LEFT,
        TOP + side + 50.0,
        300.0,
        scale.lo,
        scale.hi,
        &scale.note(),
    );
    let (w, h) = stacked_size(grid, side);
    document(w, h.max(TOP + side + 100.0), &s)
}

/// Draws the stacked grid with `painted` cells into `s`; returns its side, px.
fn stack(
    s: &mut String,
    grid: &FeatureGrid,
    painted: impl Iterator<Item = (CellIndex, String)>,
    marked: Option<(CellIndex, &str)>,
    title: &str,
) -> f64 {
    let b = grid.bins;
    let n = b * b * b;
    let side = f64::from(n) * CELL;
    text(s, LEFT, 22.0, 14.0, "start", title);
    let _ = writeln!(
        s,
        r#"<rect x="{LEFT}" y="{TOP}" width="{side}" height="{side}" fill="{EMPTY}"/>"#
    );
    for (cell, fill) in painted {
        let (x, y) = stacked_position(grid, cell);
        // The cell number lets the page open the design there (workbench.js).
        let _ = writeln!(
            s,
            r#"<rect x="{:.1}" y="{:.1}" width="{CELL}" height="{CELL}" fill="{fill}" data-cell="{}"/>"#,
            LEFT + f64::from(x) * CELL,
            TOP + side - f64::from(y + 1) * CELL,
            cell.0
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
            s,
            LEFT + (f64::from(k) + 0.5) * block,
            TOP + side + 16.0,
            11.0,
            "middle",
            &bin_label(grid, 0, k),
        );
        vertical_text(
            s,
            LEFT - 12.0,
            TOP + side - (f64::from(k) + 0.5) * block,
            11.0,
            &bin_label(grid, 1, k),
        );
    }
    text(
        s,
        LEFT + side / 2.0,
        TOP + side + 34.0,
        12.0,
        "middle",
        &format!(
            "across: {} (blocks) › {} › {} (innermost)",
            axis_title(0),
            axis_title(2),
            axis_title(4)
        ),
    );
    vertical_text(
        s,
        LEFT - 34.0,
        TOP + side / 2.0,
        12.0,
        &format!(
            "up: {} (blocks) › {} › {} (innermost)",
            axis_title(1),
            axis_title(3),
            axis_title(5)
        ),
    );
    if b > 1 {
        stack_key(s, grid, LEFT + side + KEY_GAP, TOP);
    }
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
        text(s, cx + 10.0, cy - 8.0, 12.0, "start", name);
    }
    side
}

/// Cell side in the key, px: large enough for the innermost tick labels.
const KEY_CELL: f64 = 14.0;
/// Space between the map and its key, px (the key's left labels sit in it).
const KEY_GAP: f64 = 80.0;
/// Room right of the key for the innermost rows' labels, px.
const KEY_RIGHT: f64 = 90.0;

/// Width and height of a stacked picture whose map is `side` px, with its key.
fn stacked_size(grid: &FeatureGrid, side: f64) -> (f64, f64) {
    let key = f64::from(grid.bins * grid.bins) * KEY_CELL;
    (LEFT + side + KEY_GAP + key + KEY_RIGHT, TOP + key + 160.0)
}

/// The key to the map's inner levels: one block (d1 and d2 fixed) drawn large, with the
/// middle level's bins (d3 across, d4 up) and the innermost level's (d5, d6) labelled,
/// since the map itself has room only for the outer labels.
fn stack_key(s: &mut String, grid: &FeatureGrid, x0: f64, y0: f64) {
    let b = grid.bins;
    let n = b * b;
    let side = f64::from(n) * KEY_CELL;
    let middle = f64::from(b) * KEY_CELL;
    let y_top = y0 + 72.0;
    text(
        s,
        x0,
        y0 - 8.0,
        12.0,
        "start",
        "Key: one block of the map, enlarged",
    );
    text(
        s,
        x0,
        y0 + 8.0,
        10.0,
        "start",
        "(every block of the map repeats it, and every sub-block the innermost ticks)",
    );
    let _ = writeln!(
        s,
        r##"<rect x="{x0:.1}" y="{y_top:.1}" width="{side}" height="{side}" fill="{EMPTY}" stroke="#222" stroke-width="1.6"/>"##
    );
    for k in 1..n {
        let (w, c) = if k % b == 0 {
            (1.0, "#666")
        } else {
            (0.4, "#bbb")
        };
        let p = f64::from(k) * KEY_CELL;
        let _ = writeln!(
            s,
            r#"<line x1="{:.1}" y1="{y_top:.1}" x2="{:.1}" y2="{:.1}" stroke="{c}" stroke-width="{w}"/><line x1="{x0:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{c}" stroke-width="{w}"/>"#,
            x0 + p,
            x0 + p,
            y_top + side,
            y_top + side - p,
            x0 + side,
            y_top + side - p
        );
    }
    // Middle level: d3 under each column of sub-blocks, d4 left of each row.
    for k in 0..b {
        let c = f64::from(k) + 0.5;
        text(
            s,
            x0 + c * middle,
            y_top + side + 14.0,
            8.5,
            "middle",
            &bin_label(grid, 2, k),
        );
        vertical_text(
            s,
            x0 - 10.0,
            y_top + side - c * middle,
            8.5,
            &bin_label(grid, 3, k),
        );
    }
    text(
        s,
        x0 + side / 2.0,
        y_top + side + 30.0,
        11.0,
        "middle",
        &format!("{} (middle level, across)", axis_title(2)),
    );
    vertical_text(
        s,
        x0 - 26.0,
        y_top + side / 2.0,
        11.0,
        &format!("{} (middle level, up)", axis_title(3)),
    );
    // Innermost level: d5 above the left column of sub-blocks, d6 right of the bottom row.
    for k in 0..b {
        let c = f64::from(k) + 0.5;
        let _ = writeln!(
            s,
            r#"<text x="{x:.1}" y="{y:.1}" font-family="sans-serif" font-size="8" text-anchor="start" transform="rotate(-90 {x:.1} {y:.1})">{}</text>"#,
            escape(&bin_label(grid, 4, k)),
            x = x0 + c * KEY_CELL + 2.5,
            y = y_top - 3.0,
        );
        text(
            s,
            x0 + side + 4.0,
            y_top + side - c * KEY_CELL + 3.0,
            8.0,
            "start",
            &bin_label(grid, 5, k),
        );
    }
    let innermost = [
        format!("innermost level: {} across (ticks above)", axis_title(4)),
        format!("and {} up (ticks at right)", axis_title(5)),
    ];
    for (i, line) in innermost.iter().enumerate() {
        text(
            s,
            x0,
            y_top + side + 48.0 + 14.0 * i as f64,
            11.0,
            "start",
            line,
        );
    }
}

/// Best fitness per pair of bins of features `i` and `j`, with the cell that holds it
/// (None: no elite there), indexed `[bin_i][bin_j]`.
pub fn marginal(
    grid: &FeatureGrid,
    library: &Library,
    i: usize,
    j: usize,
) -> Vec<Vec<Option<(f64, CellIndex)>>> {
    let b = grid.bins as usize;
    let mut m = vec![vec![None; b]; b];
    for (cell, e) in library.elites() {
        let d = grid.bins_of_cell(cell).0;
        let slot: &mut Option<(f64, CellIndex)> = &mut m[d[i] as usize][d[j] as usize];
        if slot.is_none_or(|(f, _)| e.fitness > f) {
            *slot = Some((e.fitness, cell));
        }
    }
    m
}

/// The fifteen marginal maps (every pair of features, best fitness per pair of bins)
/// in one picture.
pub fn marginals_svg(grid: &FeatureGrid, library: &Library, scale: Scale, title: &str) -> String {
    let mut s = String::new();
    let height = pair_maps(&mut s, grid, title, |i, j| {
        marginal(grid, library, i, j)
            .into_iter()
            .map(|row| {
                row.into_iter()
                    .map(|v| v.map(|(f, cell)| (colour(scale.t(f)), Some(cell))))
                    .collect()
            })
            .collect()
    });
    colour_bar(
        &mut s,
        50.0,
        height,
        300.0,
        scale.lo,
        scale.hi,
        &scale.note(),
    );
    // Room for the colour bar's note (42 px below its top, 10 px type).
    document(
        70.0 + 5.0 * (f64::from(grid.bins) * PAIR_CELL + PAIR_GAP),
        height + 52.0,
        &s,
    )
}

/// A pair map's block, px.
const PAIR_CELL: f64 = 24.0;
/// Room between pair maps for their bin and axis labels, px.
const PAIR_GAP: f64 = 120.0;
/// The first row of pair maps starts this far down, below the title, px.
const PAIR_TOP: f64 = 70.0;

/// Draws the fifteen pair maps into `s`, each bin pair filled by `fill(i, j)[bin_i][bin_j]`
/// (grey when None), with the cell a click there opens if any; returns the height used, px.
fn pair_maps(
    s: &mut String,
    grid: &FeatureGrid,
    title: &str,
    fill: impl Fn(usize, usize) -> Vec<Vec<Option<(String, Option<CellIndex>)>>>,
) -> f64 {
    let b = f64::from(grid.bins);
    let cell = PAIR_CELL;
    let map = b * cell;
    let (gap_x, gap_y) = (map + PAIR_GAP, map + PAIR_GAP);
    let cols = 5;
    text(s, 20.0, 22.0, 14.0, "start", title);
    let pairs = (0..FEATURE_COUNT).flat_map(|i| (i + 1..FEATURE_COUNT).map(move |j| (i, j)));
    for (k, (i, j)) in pairs.enumerate() {
        let (ox, oy) = (
            70.0 + (k % cols) as f64 * gap_x,
            PAIR_TOP + (k / cols) as f64 * gap_y,
        );
        for (bi, row) in fill(i, j).iter().enumerate() {
            for (bj, v) in row.iter().enumerate() {
                let data = match v {
                    Some((_, Some(c))) => format!(r#" data-cell="{}""#, c.0),
                    _ => String::new(),
                };
                // Hovered, a block says which bins it is (the page's script adds the
                // design's figures).
                let _ = writeln!(
                    s,
                    r##"<rect x="{:.1}" y="{:.1}" width="{cell}" height="{cell}" fill="{}" stroke="#fff" stroke-width="0.5"{data}><title>d{} {}, d{} {}</title></rect>"##,
                    ox + bi as f64 * cell,
                    oy + map - (bj as f64 + 1.0) * cell,
                    v.as_ref().map_or(EMPTY, |(c, _)| c.as_str()),
                    i + 1,
                    escape(&bin_label(grid, i, bi as u32)),
                    j + 1,
                    escape(&bin_label(grid, j, bj as u32)),
                );
            }
        }
        let _ = writeln!(
            s,
            r##"<rect x="{ox:.1}" y="{oy:.1}" width="{map}" height="{map}" fill="none" stroke="#333"/>"##
        );
        // The first and last bins named at the axes' ends, the title between.
        let last = grid.bins - 1;
        text(s, ox, oy + map + 11.0, 8.0, "start", &bin_label(grid, i, 0));
        text(
            s,
            ox + map,
            oy + map + 11.0,
            8.0,
            "end",
            &bin_label(grid, i, last),
        );
        text(
            s,
            ox + map / 2.0,
            oy + map + 24.0,
            10.0,
            "middle",
            &format!("{} →", axis_title(i)),
        );
        text(s, ox - 3.0, oy + map, 8.0, "end", &bin_label(grid, j, 0));
        text(s, ox - 3.0, oy + 8.0, 8.0, "end", &bin_label(grid, j, last));
        vertical_text(
            s,
            ox - 52.0,
            oy + map / 2.0,
            9.0,
            &format!("{} →", axis_title(j)),
        );
    }
    PAIR_TOP + 3.0 * gap_y + 10.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_bins_are_open_and_every_label_has_its_unit() {
        let grid = FeatureGrid::default();
        // total_mass: 5 bins over 50 to 75 kg; designs under 50 kg go to the first.
        let labels: Vec<String> = (0..5).map(|b| bin_label(&grid, 1, b)).collect();
        assert_eq!(
            labels,
            ["< 55 kg", "55–60 kg", "60–65 kg", "65–70 kg", "≥ 70 kg"]
        );
        assert_eq!(bin_label(&grid, 0, 1), "2.16–2.32 m");
        // Legs per side is a whole number: its bins are named by the counts they hold.
        let legs: Vec<String> = (0..5).map(|b| bin_label(&grid, 2, b)).collect();
        assert_eq!(legs, ["2", "3", "4", "5", "6"]);
        assert_eq!(axis_title(1), "d2 total_mass (kg, with payload)");
        assert_eq!(axis_title(4), "d5 length_mult");
    }

    #[test]
    fn one_outlier_does_not_set_the_top_of_the_colour_scale() {
        let mut fitness: Vec<f64> = (0..99).map(|k| 1.0 + f64::from(k) / 98.0).collect();
        fitness.push(30.5);
        let scale = Scale::robust(fitness);
        assert_eq!(scale.max, 30.5);
        // The 95th of 100 values by nearest rank.
        assert!((scale.hi - (1.0 + 94.0 / 98.0)).abs() < 1e-12, "{scale:?}");
        assert_eq!(scale.t(30.5), 1.0);
        assert!(scale.t(1.5) > 0.7 && scale.t(1.5) < 0.8);
        assert!(scale.note().contains("95th percentile"), "{}", scale.note());
        let even = Scale::robust([1.0, 2.0]);
        assert_eq!((even.hi, even.max), (2.0, 2.0));
        assert!(!even.note().contains("percentile"));
    }

    #[test]
    fn the_stacked_map_labels_every_level_of_every_feature() {
        let grid = FeatureGrid::default();
        let svg = stacking_svg(&grid, &Library::new(), Scale::robust([1.0]), None, "t");
        // Outer bins on the map, middle and innermost bins in its key, each feature's
        // every bin with its unit.
        for feature in 0..FEATURE_COUNT {
            for bin in 0..grid.bins {
                let label = escape(&bin_label(&grid, feature, bin));
                assert!(
                    svg.contains(&format!(">{label}</text>")),
                    "d{} bin {bin}: {label}",
                    feature + 1
                );
            }
        }
        assert!(svg.contains("middle level, across"), "{svg}");
        assert!(svg.contains("innermost level: d5"), "{svg}");
    }

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
