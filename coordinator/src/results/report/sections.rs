//! The report's sections, one function each, in the order of [`SECTIONS`]: each writes
//! its heading, words, pictures and tables into the [`Page`].

use super::charts::{line_chart, Series, SCHEME_COLOURS};
use super::maps::{marginals_svg, stacking_svg, Scale};
use super::svg::escape;
use super::table::{add_table, add_table_with_csv, count, csv, num, text, Cell};
use super::{push_picture, Inputs, Page, Picture, RunData, Table, SECTIONS};
use crate::qd::library::{GenerationStats, Library};
use crate::results::analysis::mann_whitney::MannWhitney;
use crate::results::analysis::rules::{Rule, MIN_RULE_DESIGNS};
use crate::results::analysis::summary::{mean_sd, Summary};
use std::fmt::Write;
use strider_common::drawing::design_svg;
use strider_common::features::FEATURE_NAMES;
use strider_common::params::CONTROLLER_PARAMS;
use strider_common::{BodyPlan, Experiment, Features, StartPose};

/// Per scheme, one series of `figure` over generations (mean and sd over repeats).
fn series(e: &Experiment, runs: &[RunData], figure: fn(&GenerationStats) -> f64) -> Vec<Series> {
    e.schemes
        .iter()
        .enumerate()
        .map(|(k, &scheme)| {
            let mine: Vec<&RunData> = runs.iter().filter(|r| r.scheme == scheme).collect();
            let last = mine
                .iter()
                .filter_map(|r| r.generations.last().map(|g| g.0))
                .max()
                .unwrap_or(0);
            let points = (0..=last)
                .filter_map(|g| {
                    let v: Vec<f64> = mine
                        .iter()
                        .filter_map(|r| r.generations.iter().find(|x| x.0 == g))
                        .map(|x| figure(&x.1))
                        // A fitness of an empty library is no figure (not 0).
                        .filter(|v| v.is_finite())
                        .collect();
                    (!v.is_empty()).then(|| {
                        let m = mean_sd(&v);
                        (f64::from(g), m.mean, m.sd)
                    })
                })
                .collect();
            Series {
                name: scheme.name().to_string(),
                colour: SCHEME_COLOURS[k % SCHEME_COLOURS.len()],
                points,
            }
        })
        .collect()
}

/// A library's fitness figure, NaN while the library is empty (the statistics hold 0
/// there, which is no design's fitness).
fn fitness(s: &GenerationStats, figure: f64) -> f64 {
    if s.elites == 0 {
        f64::NAN
    } else {
        figure
    }
}

/// The figures of Figure 3: (file stem, title, axis label, figure).
type Figure = (
    &'static str,
    &'static str,
    &'static str,
    fn(&GenerationStats) -> f64,
);
const FIGURES: [Figure; 5] = [
    ("qd_score", "QD score", "QD score (sum of fitness)", |s| {
        s.qd_score
    }),
    (
        "best_fitness",
        "Best fitness in the library",
        "fitness",
        |s| fitness(s, s.max_fitness),
    ),
    (
        "mean_fitness",
        "Mean fitness of the library",
        "fitness",
        |s| fitness(s, s.mean_fitness),
    ),
    (
        "lowest_fitness",
        "Lowest fitness in the library",
        "fitness",
        |s| fitness(s, s.min_fitness),
    ),
    ("coverage", "Coverage (cells filled)", "coverage, %", |s| {
        100.0 * s.coverage
    }),
];

/// Section 1: the figures of the paper's Figure 3 per generation, and QD score against
/// evaluations.
pub(super) fn progress(out: &mut Page, inp: &Inputs<'_>) {
    let (e, runs) = (inp.experiment, inp.runs);
    let Page {
        html: page,
        pictures,
        tables,
        ..
    } = out;
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[0]);
    page.push_str("<p>For each scheme, the mean over its repeats (line) and one standard deviation either side (band).</p>\n");
    page.push_str("<p>The QD score is the quality-diversity field's headline figure: the sum of fitness over the filled cells of the feasible library (as pyribs defines it, with offset 0: fitness, 1 / cost of transport, is never negative). Evaluations are candidates drawn and checked, as the exports count them: the initial population's draws (those the pre-check refused before simulating included), then the offspring of each generation; an ES candidate is up to 21 trials. On the evaluations axis, the mean over a scheme's repeats.</p>\n");
    // Evaluations by the end of generation g: the mean over the scheme's runs that got
    // there of the stored count.
    let evaluations = |scheme: &str, g: f64| {
        let counts: Vec<f64> = runs
            .iter()
            .filter(|r| r.scheme.name() == scheme)
            .filter_map(|r| {
                let at = r.generations.iter().position(|(k, _)| f64::from(*k) == g)?;
                r.evaluations.get(at).map(|&n| n as f64)
            })
            .collect();
        if counts.is_empty() {
            e.run.candidates_by(g as u32) as f64
        } else {
            counts.iter().sum::<f64>() / counts.len() as f64
        }
    };
    let mut gen_rows = Vec::new();
    for (stem, title, label, figure) in FIGURES {
        let s = series(e, runs, figure);
        for sc in &s {
            for &(g, m, sd) in &sc.points {
                gen_rows.push(vec![
                    sc.name.clone(),
                    stem.to_string(),
                    format!("{g}"),
                    format!("{}", evaluations(&sc.name, g)),
                    format!("{m}"),
                    format!("{sd}"),
                ]);
            }
        }
        pictures.push(Picture {
            name: stem.to_string(),
            caption: if label == "fitness" {
                format!("{title}, per generation: mean ± sd over the repeats whose library holds a design; no point while none does (an empty library has no fitness).")
            } else {
                format!("{title}, per generation: mean ± sd over repeats.")
            },
            svg: line_chart(title, "generation", label, &s),
        });
        if stem == "qd_score" {
            let by_evaluations: Vec<Series> = s
                .iter()
                .map(|sc| Series {
                    points: sc
                        .points
                        .iter()
                        .map(|&(g, m, sd)| (evaluations(&sc.name, g), m, sd))
                        .collect(),
                    ..sc.clone()
                })
                .collect();
            pictures.push(Picture {
                name: "qd_score_by_evaluations".into(),
                caption: "QD score against evaluations (candidates drawn and checked, the pre-check's refusals included; mean over repeats): mean ± sd over repeats."
                    .into(),
                svg: line_chart(
                    "QD score against evaluations",
                    "evaluations (candidates)",
                    label,
                    &by_evaluations,
                ),
            });
        }
    }
    tables.push(Table {
        name: "per_generation".into(),
        csv: csv(
            &[
                "scheme",
                "figure",
                "generation",
                "evaluations",
                "mean",
                "sd",
            ]
            .map(String::from),
            &gen_rows,
        ),
    });
    for p in pictures.iter() {
        push_picture(page, p);
    }
}

/// Section 2: each scheme's final library, and the Mann-Whitney tests between schemes.
pub(super) fn schemes(out: &mut Page, summary: &Summary) {
    let Page {
        html: page, tables, ..
    } = out;
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[1]);
    let header: Vec<String> = [
        "scheme",
        "repeats",
        "best fitness (mean)",
        "best fitness (sd)",
        "coverage % (mean)",
        "coverage % (sd)",
    ]
    .map(String::from)
    .to_vec();
    let rows: Vec<Vec<Cell>> = summary
        .schemes
        .iter()
        .map(|s| {
            vec![
                text(s.scheme.name()),
                count(s.repeats as u64),
                num(s.best.mean, 4),
                // One repeat has no spread to show.
                if s.repeats > 1 {
                    num(s.best.sd, 4)
                } else {
                    Cell::Empty
                },
                num(100.0 * s.coverage.mean, 3),
                if s.repeats > 1 {
                    num(100.0 * s.coverage.sd, 3)
                } else {
                    Cell::Empty
                },
            ]
        })
        .collect();
    page.push_str("<p>The library at the end of each run, per scheme.</p>\n");
    add_table(page, tables, "final_by_scheme", &header, &rows);
    let header: Vec<String> = [
        "schemes",
        "measure",
        "U",
        "p (two-sided)",
        "method",
        "in words",
    ]
    .map(String::from)
    .to_vec();
    let mut rows = Vec::new();
    for c in &summary.comparisons {
        for (measure, t) in [
            ("final best fitness", &c.best),
            ("final coverage", &c.coverage),
        ] {
            rows.push(vec![
                text(format!("{} vs {}", c.schemes.0.name(), c.schemes.1.name())),
                text(measure),
                num(t.u1.min(t.u2), 1),
                num(t.p, 4),
                text(format!("{:?}", t.method).to_lowercase()),
                text(words(t)),
            ]);
        }
    }
    if rows.is_empty() {
        // No empty table: there is nothing to test.
        page.push_str("<p>Only one scheme: no Mann-Whitney test between schemes.</p>\n");
        return;
    }
    page.push_str("<p>Mann-Whitney U tests between every pair of schemes (two-sided, tie-corrected; exact for small samples without ties, normal approximation otherwise).</p>\n");
    add_table(page, tables, "mann_whitney", &header, &rows);
}

fn words(t: &MannWhitney) -> String {
    if t.significant(0.05) {
        "significant at 0.05 (p < 0.05)".into()
    } else {
        "not significant at 0.05".into()
    }
}

/// The rule as the paper's Table 6 writes it: target = mean + terms.
fn formula(r: &Rule) -> String {
    r.to_string()
        .split("   [mean error")
        .next()
        .unwrap_or_default()
        .to_string()
}

/// Sections 3 and 4: the chosen run's library as a dimensional stacking, and the best
/// fitness per pair of features.
pub(super) fn library(out: &mut Page, inp: &Inputs<'_>, chosen: Option<&RunData>) {
    let (e, runs) = (inp.experiment, inp.runs);
    let payload = e.brief.payload;
    let Page {
        html: page,
        pictures,
        ..
    } = out;
    let scale = Scale::robust(
        runs.iter()
            .flat_map(|r| r.library.elites().map(|(_, el)| el.fitness)),
    );
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[2]);
    if let Some(run) = chosen {
        let marked = inp.reference.and_then(|(g, name)| {
            let plan = BodyPlan::new(&g.morphology, payload);
            e.features
                .cell_of(&Features::of(&g.morphology, &plan))
                .ok()
                .map(|c| (c, name))
        });
        let title = format!(
            "Run {} ({}, repeat {}): {} designs in {} cells",
            run.id,
            run.scheme.name(),
            run.repeat,
            run.library.len(),
            e.features.cell_count()
        );
        let stack = Picture {
            name: "library_map".into(),
            caption: format!("{title}. Each small square is one cell of the six-dimensional map, coloured by the fitness of its design (grey: no design). Features nest from the outside in: d1 then d3 then d5 across, d2 then d4 then d6 up; heavy lines separate the outer blocks.{}", marked.map_or(String::new(), |(_, n)| format!(" The red ring marks {n}."))),
            svg: stacking_svg(&e.features, &run.library, scale, marked, &title),
        };
        push_picture(page, &stack);
        pictures.push(stack);
        let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[3]);
        let marg = Picture {
            name: "pair_maps".into(),
            caption: "For every pair of features, the best fitness found for each pair of their bins (same colour scale; grey: no design).".into(),
            svg: marginals_svg(&e.features, &run.library, scale, &format!("Run {}: best fitness per pair of features", run.id)),
        };
        push_picture(page, &marg);
        pictures.push(marg);
    } else {
        page.push_str("<p>No run has a library yet.</p>\n");
    }
}

/// Section 6: the paper's Table 5 (mean features of the top 10 %) and the best
/// controllers.
pub(super) fn best_designs(out: &mut Page, summary: &Summary) {
    let Page {
        html: page, tables, ..
    } = out;
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[5]);
    let mut header = vec!["scheme".to_string(), "designs".to_string()];
    header.extend(
        FEATURE_NAMES
            .iter()
            .enumerate()
            .map(|(i, n)| format!("d{} {n}", i + 1)),
    );
    let rows: Vec<Vec<Cell>> = summary
        .schemes
        .iter()
        .map(|s| {
            let mut r = vec![text(s.scheme.name()), count(s.top_designs as u64)];
            r.extend(s.top_features.iter().map(|&v| num(v, 4)));
            r
        })
        .collect();
    page.push_str("<p>Mean feature values of the top 10 % of designs of each scheme, pooled over repeats (the paper's Table 5).</p>\n");
    add_table(page, tables, "top_designs_features", &header, &rows);
    let mut header = vec!["scheme".to_string()];
    header.extend(CONTROLLER_PARAMS.iter().map(|p| p.name.to_string()));
    let rows: Vec<Vec<Cell>> = summary
        .schemes
        .iter()
        .map(|s| {
            let mut r = vec![text(s.scheme.name())];
            r.extend(s.best_controller.iter().map(|&v| num(v, 4)));
            r
        })
        .collect();
    page.push_str("<p>Mean controller of the best design of each repeat, per scheme.</p>\n");
    add_table(page, tables, "best_controllers", &header, &rows);
}

/// Section 7: the design rules (the paper's Table 6), kept and dropped, with notes for
/// schemes with too few designs and for constant features.
pub(super) fn rules(out: &mut Page, summary: &Summary) {
    let Page {
        html: page, tables, ..
    } = out;
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[6]);
    let _ = writeln!(page, "<p>Linear relations the top 10 % of designs keep (the paper's Table 6): each predicts one feature from the others, named as in the maps. Rules are mined only from at least {MIN_RULE_DESIGNS} designs, and a feature that every one of them shares is named as constant and left out of every rule. A rule is kept when the designs spread across it by at most 0.2 (scaled); the others are listed as dropped. <code>design_rules.csv</code> holds each rule as numbers: target = intercept + the sum of coefficient x feature.</p>");
    let header: Vec<String> = [
        "scheme",
        "designs",
        "kept",
        "rule",
        "spread",
        "mean error %",
    ]
    .map(String::from)
    .to_vec();
    let mut csv_header: Vec<String> = ["scheme", "designs", "kept", "target", "intercept"]
        .map(String::from)
        .to_vec();
    csv_header.extend(FEATURE_NAMES.iter().map(|n| format!("coef_{n}")));
    csv_header.extend(["spread", "mean_error"].map(String::from));
    let (mut rows, mut csv_rows) = (Vec::new(), Vec::new());
    let mut notes = Vec::new();
    for s in &summary.schemes {
        let Some(rules) = &s.rules else {
            notes.push(format!(
                "{}: no rules from {} designs (rules need at least {MIN_RULE_DESIGNS}).",
                s.scheme.name(),
                s.top_designs
            ));
            continue;
        };
        for &(j, v) in &rules.constant {
            notes.push(format!(
                "{}: {} = {v} in every one of its {} designs (constant: in no rule).",
                s.scheme.name(),
                FEATURE_NAMES[j],
                s.top_designs
            ));
        }
        for (kept, list) in [("kept", &rules.kept), ("dropped", &rules.dropped)] {
            for r in list {
                rows.push(vec![
                    text(s.scheme.name()),
                    count(s.top_designs as u64),
                    text(kept),
                    text(formula(r)),
                    num(r.spread, 3),
                    num(100.0 * r.mean_error, 2),
                ]);
                let (intercept, coefficients) = r.linear();
                let mut row = vec![
                    text(s.scheme.name()),
                    count(s.top_designs as u64),
                    text(kept),
                    text(FEATURE_NAMES[r.target]),
                    Cell::Number(intercept, 4),
                ];
                row.extend(coefficients.iter().enumerate().map(|(j, &a)| {
                    // The target, and a constant feature, have no coefficient.
                    if j == r.target || rules.constant.iter().any(|&(c, _)| c == j) {
                        Cell::Empty
                    } else {
                        Cell::Number(a, 4)
                    }
                }));
                row.extend([num(r.spread, 3), num(r.mean_error, 4)]);
                csv_rows.push(row);
            }
        }
    }
    for note in &notes {
        let _ = writeln!(page, "<p class=\"warning\">{}</p>", escape(note));
    }
    add_table_with_csv(
        page,
        tables,
        "design_rules",
        &header,
        &rows,
        &csv_header,
        &csv_rows,
    );
}

/// Section 8: side, front and top drawings of up to four designs spread across the map.
pub(super) fn drawings(out: &mut Page, inp: &Inputs<'_>, chosen: Option<&RunData>) {
    let e = inp.experiment;
    let payload = e.brief.payload;
    let Page {
        html: page,
        pictures,
        ..
    } = out;
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[7]);
    page.push_str("<p>Side, front and top views of each design at its start pose, to scale (the bar is 1 m); right legs blue, left legs orange.</p>\n");
    if let Some(run) = chosen {
        for (k, (label, cell, el)) in chosen_designs(&e.features, &run.library)
            .into_iter()
            .enumerate()
        {
            let plan = BodyPlan::new(&el.genome.morphology, payload);
            let pose = StartPose::new(&plan, &el.genome.controller);
            let title = format!(
                "{label}: run {} cell {}, fitness {:.3}, {} legs, {:.1} kg ({:.1} kg with the {} kg payload), {:.2} m tall",
                run.id,
                cell.0,
                el.fitness,
                plan.legs.len(),
                plan.mass_without_payload(),
                plan.total_mass(),
                payload,
                pose.height
            );
            let p = Picture {
                name: format!("design_{}", k + 1),
                caption: title.clone(),
                svg: design_svg(&plan, &pose, &title),
            };
            push_picture(page, &p);
            pictures.push(p);
        }
    }
}

/// The best design of the library, then the fittest of each other legs-per-side bin
/// (d3), up to four in all: designs spread across the map.
fn chosen_designs<'a>(
    grid: &strider_common::FeatureGrid,
    library: &'a Library,
) -> Vec<(
    String,
    strider_common::CellIndex,
    &'a crate::qd::library::Elite,
)> {
    let mut best_per_bin: Vec<Option<(strider_common::CellIndex, &crate::qd::library::Elite)>> =
        vec![None; grid.bins as usize];
    for (cell, el) in library.elites() {
        let slot = &mut best_per_bin[grid.bins_of_cell(cell).0[2] as usize];
        if slot.is_none_or(|(_, b)| el.fitness > b.fitness) {
            *slot = Some((cell, el));
        }
    }
    let mut picks: Vec<_> = best_per_bin.into_iter().flatten().collect();
    picks.sort_by(|a, b| b.1.fitness.total_cmp(&a.1.fitness));
    picks
        .into_iter()
        .take(4)
        .enumerate()
        .map(|(k, (c, el))| {
            let label = if k == 0 {
                "The best design".to_string()
            } else {
                format!("Best with d3 in bin {}", grid.bins_of_cell(c).0[2])
            };
            (label, c, el)
        })
        .collect()
}
