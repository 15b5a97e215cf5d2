//! The library maps coloured by the brief: green where a design meets it, else by what the
//! nearest design there misses, with its legend.

use super::*;

/// A colour per constraint that binds, nearest the brief first (and the feasible colour).
pub const FEASIBLE_COLOUR: &str = "#1b7837";

fn shortfall_colour(s: Shortfall) -> &'static str {
    match s {
        Shortfall::StepSensitive => "#a6dba0",
        Shortfall::FrictionSensitive => "#b8e186",
        Shortfall::Speed => "#f1b82d",
        Shortfall::Backward => "#a6611a",
        Shortfall::Skating => "#4393c3",
        Shortfall::Fell => "#d7301f",
        Shortfall::SelfContact => "#7b3294",
        Shortfall::Unstable => "#252525",
    }
}

/// What a cell of the frontier holds: a feasible design, else the nearest infeasible one's
/// shortfall.
fn frontier_colour(
    library: &Library,
    infeasible: &InfeasibleLibrary,
    cell: CellIndex,
) -> Option<&'static str> {
    if library.get(cell).is_some() {
        Some(FEASIBLE_COLOUR)
    } else {
        infeasible.get(cell).map(|e| shortfall_colour(e.shortfall))
    }
}

fn frontier_legend(s: &mut String, x: f64, y: f64) {
    let items = std::iter::once(("meets the brief", FEASIBLE_COLOUR)).chain(
        Shortfall::ALL
            .iter()
            .map(|&sh| (sh.label(), shortfall_colour(sh))),
    );
    for (k, (label, fill)) in items.enumerate() {
        let x = x + k as f64 * 110.0;
        let _ = writeln!(
            s,
            r##"<rect x="{x:.1}" y="{:.1}" width="12" height="12" fill="{fill}"/>"##,
            y - 10.0
        );
        text(s, x + 16.0, y, 11.0, "start", label);
    }
}

/// The brief's frontier of one run by dimensional stacking: each cell coloured by whether
/// it holds a design that meets the brief, or else by what its nearest design misses.
pub fn frontier_svg(
    grid: &FeatureGrid,
    library: &Library,
    infeasible: &InfeasibleLibrary,
    marked: Option<(CellIndex, &str)>,
    title: &str,
) -> String {
    let mut s = String::new();
    let cells: std::collections::BTreeSet<CellIndex> = library
        .elites()
        .map(|(c, _)| c)
        .chain(infeasible.elites().map(|(c, _)| c))
        .collect();
    let painted = cells
        .into_iter()
        .filter_map(|c| frontier_colour(library, infeasible, c).map(|f| (c, f.to_string())));
    let side = stack(&mut s, grid, painted, marked, title);
    frontier_legend(&mut s, LEFT, TOP + side + 60.0);
    let (w, h) = stacked_size(grid, side);
    document(w, h.max(TOP + side + 90.0), &s)
}

/// The frontier per pair of features: a pair of bins is green when some cell in it holds a
/// design that meets the brief, else coloured by what the nearest design there misses.
pub fn frontier_marginals_svg(
    grid: &FeatureGrid,
    library: &Library,
    infeasible: &InfeasibleLibrary,
    title: &str,
) -> String {
    let b = grid.bins as usize;
    let mut s = String::new();
    let height = pair_maps(&mut s, grid, title, |i, j| {
        let mut best: Vec<Vec<Option<Standing>>> = vec![vec![None; b]; b];
        let mut paint: Vec<Vec<Option<String>>> = vec![vec![None; b]; b];
        for (cell, _) in library.elites() {
            let d = grid.bins_of_cell(cell).0;
            paint[d[i] as usize][d[j] as usize] = Some(FEASIBLE_COLOUR.into());
        }
        for (cell, e) in infeasible.elites() {
            let d = grid.bins_of_cell(cell).0;
            let (x, y) = (d[i] as usize, d[j] as usize);
            if paint[x][y].as_deref() == Some(FEASIBLE_COLOUR) {
                continue;
            }
            if best[x][y].is_none_or(|old| e.standing.beats(&old)) {
                best[x][y] = Some(e.standing);
                paint[x][y] = Some(shortfall_colour(e.shortfall).into());
            }
        }
        paint
            .into_iter()
            .map(|row| row.into_iter().map(|c| c.map(|c| (c, None))).collect())
            .collect()
    });
    frontier_legend(&mut s, 50.0, height);
    document(
        70.0 + 5.0 * (f64::from(grid.bins) * super::PAIR_CELL + super::PAIR_GAP),
        height + 30.0,
        &s,
    )
}
