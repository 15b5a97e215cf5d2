//! Section 5, where the brief binds: cells per scheme that meet it or only miss it, the
//! chosen run's frontier maps, and the infeasible designs nearest the brief.

use super::maps::{frontier_marginals_svg, frontier_svg};
use super::svg::escape;
use super::table::{add_table, count, num, text, Cell};
use super::{push_picture, Inputs, Page, Picture, RunData, SECTIONS};
use crate::results::analysis::summary::Summary;
use std::fmt::Write;
use strider_common::{BodyPlan, CellIndex, StartPose};

/// How many infeasible designs nearest the brief the report lists.
const NEAREST: usize = 10;

/// The brief's frontier: cells per scheme that meet it or only miss it and what binds, the
/// chosen run's frontier maps, and the infeasible designs nearest the brief.
pub(super) fn frontier(
    out: &mut Page,
    inp: &Inputs<'_>,
    summary: &Summary,
    chosen: Option<&RunData>,
) {
    let Page {
        html: page,
        pictures,
        tables,
        ..
    } = out;
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[4]);
    let e = inp.experiment;
    page.push_str("<p>Cells holding a design that meets the whole brief (feasible), cells holding only designs that miss it (from the infeasible library, kept by feasible-infeasible search), and, for those, the constraint that binds (mean over repeats).</p>\n");
    page.push_str("<dl class=\"shortfalls\">\n");
    for sh in strider_common::Shortfall::ALL {
        let _ = writeln!(
            page,
            "<dt>{}</dt><dd>{}</dd>",
            sh.label(),
            escape(sh.meaning())
        );
    }
    page.push_str("</dl>\n");
    let mut header: Vec<String> = ["scheme", "feasible cells", "infeasible-only cells"]
        .map(String::from)
        .to_vec();
    header.extend(
        strider_common::Shortfall::ALL
            .iter()
            .map(|s| format!("binding: {}", s.name())),
    );
    let rows: Vec<Vec<Cell>> = summary
        .schemes
        .iter()
        .map(|s| {
            let f = &s.frontier;
            let mut r = vec![
                text(s.scheme.name()),
                num(f.feasible.mean, 1),
                num(f.infeasible_only.mean, 1),
            ];
            r.extend(f.binding.iter().map(|&(_, n)| num(n, 1)));
            r
        })
        .collect();
    add_table(page, tables, "frontier_by_scheme", &header, &rows);
    if let Some(run) = chosen {
        let title = format!(
            "Run {} ({}, repeat {}): {} cells meet the brief, {} hold only designs that miss it",
            run.id,
            run.scheme.name(),
            run.repeat,
            run.library.len(),
            run.infeasible
                .elites()
                .filter(|(c, _)| run.library.get(*c).is_none())
                .count()
        );
        let map = Picture {
            name: "frontier_map".into(),
            caption: format!("{title}. The library map of the section above, each cell coloured green when it holds a design that meets the brief, else by what its nearest design misses (grey: nothing simulated there)."),
            svg: frontier_svg(&e.features, &run.library, &run.infeasible, None, &title),
        };
        push_picture(page, &map);
        pictures.push(map);
        let pairs = Picture {
            name: "frontier_pair_maps".into(),
            caption: "Per pair of features: green where some design meets the brief, else coloured by what the nearest design there misses.".into(),
            svg: frontier_marginals_svg(&e.features, &run.library, &run.infeasible, &format!("Run {}: where the brief binds, per pair of features", run.id)),
        };
        push_picture(page, &pairs);
        pictures.push(pairs);
    }
    // The infeasible designs nearest the brief, over every run.
    let mut nearest: Vec<(&RunData, CellIndex, &crate::qd::library::InfeasibleElite)> = inp
        .runs
        .iter()
        .flat_map(|r| r.infeasible.elites().map(move |(c, el)| (r, c, el)))
        .collect();
    nearest.sort_by_key(|n| std::cmp::Reverse(n.2.standing));
    nearest.truncate(NEAREST);
    let header: Vec<String> = [
        "run",
        "scheme",
        "cell",
        "misses",
        "speed m/s",
        "ended at s",
        "legs per side",
        "mass kg (without payload)",
        "height m",
    ]
    .map(String::from)
    .to_vec();
    let rows: Vec<Vec<Cell>> = nearest
        .iter()
        .map(|(r, cell, el)| {
            let plan = BodyPlan::new(&el.genome.morphology, e.brief.payload);
            let pose = StartPose::new(&plan, &el.genome.controller);
            let (speed, ended) = match el.standing {
                strider_common::Standing::TooSlow { speed } => (num(speed, 3), Cell::Empty),
                strider_common::Standing::EndedEarly { at_time } => (Cell::Empty, num(at_time, 2)),
                _ => (Cell::Empty, Cell::Empty),
            };
            vec![
                count(u64::from(r.id.0)),
                text(r.scheme.name()),
                count(u64::from(cell.0)),
                text(el.shortfall.name()),
                speed,
                ended,
                count(plan.legs_per_side() as u64),
                num(plan.mass_without_payload(), 1),
                num(pose.height, 2),
            ]
        })
        .collect();
    page.push_str("<p>The infeasible designs nearest the brief (mass without payload; start-pose height).</p>\n");
    if rows.is_empty() {
        page.push_str("<p>No infeasible library: this experiment rejects designs that miss the brief (the paper's method).</p>\n");
    }
    add_table(page, tables, "nearest_infeasible", &header, &rows);
}
