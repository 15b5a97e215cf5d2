//! `strider-coordinator report`: the whole experiment for a robot designer, as one
//! self-contained HTML page (pictures inline), the pictures as separate SVG files (the
//! CLI adds PNG), and the tables as CSV. Plain functions from plain data to text; reading
//! the database and writing files is the CLI's job.

pub mod charts;
pub mod maps;
pub mod png;
pub mod svg;

use crate::qd::library::{GenerationStats, InfeasibleLibrary, Library};
use crate::results::analysis::mann_whitney::MannWhitney;
use crate::results::analysis::rules::{Rule, MIN_RULE_DESIGNS};
use crate::results::analysis::summary::{mean_sd, summarise, RunResult, Summary};
use charts::{line_chart, Series, SCHEME_COLOURS};
use maps::{frontier_marginals_svg, frontier_svg, marginals_svg, stacking_svg, Scale};
use std::fmt::Write;
use strider_common::drawing::design_svg;
use strider_common::features::FEATURE_NAMES;
use strider_common::params::CONTROLLER_PARAMS;
use strider_common::{BodyPlan, CellIndex, Experiment, Features, Genome, Scheme, StartPose};
use svg::escape;

/// One run as the report reads it.
pub struct RunData {
    pub id: i64,
    pub scheme: Scheme,
    pub repeat: u32,
    /// Its library now.
    pub library: Library,
    /// Its infeasible library now (empty under the paper's method).
    pub infeasible: InfeasibleLibrary,
    /// Every committed generation's statistics, in order.
    pub generations: Vec<(u32, GenerationStats)>,
}

/// A picture: file stem, caption, SVG.
pub struct Picture {
    /// File name without extension.
    pub name: String,
    /// What it shows, in words.
    pub caption: String,
    pub svg: String,
}

/// A table: file stem and CSV text.
pub struct Table {
    /// File name without extension.
    pub name: String,
    /// CSV text with a header line.
    pub csv: String,
}

/// Everything the report writes.
pub struct Report {
    /// The page.
    pub html: String,
    /// The pictures (also inline in the page).
    pub pictures: Vec<Picture>,
    /// The tables (also on the page).
    pub tables: Vec<Table>,
}

/// The section headings of the page, in order (tests check each is there).
pub const SECTIONS: [&str; 8] = [
    "Progress per generation",
    "Comparing schemes",
    "The library of one run",
    "Best designs per pair of features",
    "Where the brief binds",
    "What the best designs look like",
    "Design rules",
    "Drawings of chosen designs",
];

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
        |s| s.max_fitness,
    ),
    (
        "mean_fitness",
        "Mean fitness of the library",
        "fitness",
        |s| s.mean_fitness,
    ),
    (
        "lowest_fitness",
        "Lowest fitness in the library",
        "fitness",
        |s| s.min_fitness,
    ),
    ("coverage", "Coverage (cells filled)", "coverage, %", |s| {
        100.0 * s.coverage
    }),
];

/// One entry of a table: on the page a number is rounded for reading; in the CSV it is
/// written whole (shortest exact form), so a script reads what was computed.
#[derive(Clone, Debug, PartialEq)]
enum Cell {
    /// Words.
    Text(String),
    /// A number and the decimals shown on the page.
    Number(f64, usize),
    /// Nothing (not applicable).
    Empty,
}

impl Cell {
    fn page(&self) -> String {
        match self {
            Cell::Text(t) => t.clone(),
            Cell::Number(v, decimals) => format!("{v:.decimals$}"),
            Cell::Empty => String::new(),
        }
    }

    fn csv(&self) -> String {
        match self {
            Cell::Text(t) => t.clone(),
            Cell::Number(v, _) => format!("{v}"),
            Cell::Empty => String::new(),
        }
    }
}

/// Words in a table.
fn text(t: impl Into<String>) -> Cell {
    Cell::Text(t.into())
}

/// A number shown with `decimals` decimals.
fn num(v: f64, decimals: usize) -> Cell {
    Cell::Number(v, decimals)
}

/// A count.
fn count(v: u64) -> Cell {
    Cell::Number(v as f64, 0)
}

fn html_table(out: &mut String, header: &[String], rows: &[Vec<Cell>]) {
    out.push_str("<table>\n<tr>");
    for h in header {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    out.push_str("</tr>\n");
    for r in rows {
        out.push_str("<tr>");
        for c in r {
            let _ = write!(out, "<td>{}</td>", escape(&c.page()));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</table>\n");
}

/// A table on the page and as `name`.csv.
fn add_table(
    page: &mut String,
    tables: &mut Vec<Table>,
    name: &str,
    header: &[String],
    rows: &[Vec<Cell>],
) {
    add_table_with_csv(page, tables, name, header, rows, header, rows);
}

/// A table on the page, and as `name`.csv with its own columns (more than the page shows).
fn add_table_with_csv(
    page: &mut String,
    tables: &mut Vec<Table>,
    name: &str,
    header: &[String],
    rows: &[Vec<Cell>],
    csv_header: &[String],
    csv_rows: &[Vec<Cell>],
) {
    html_table(page, header, rows);
    let csv_rows: Vec<Vec<String>> = csv_rows
        .iter()
        .map(|r| r.iter().map(Cell::csv).collect())
        .collect();
    tables.push(Table {
        name: name.into(),
        csv: csv(csv_header, &csv_rows),
    });
}

fn csv(header: &[String], rows: &[Vec<String>]) -> String {
    let quote = |s: &String| {
        if s.contains([',', '"', '\n']) {
            format!("\"{}\"", s.replace('"', "\"\""))
        } else {
            s.clone()
        }
    };
    let mut out = header.iter().map(quote).collect::<Vec<_>>().join(",");
    out.push('\n');
    for r in rows {
        out.push_str(&r.iter().map(quote).collect::<Vec<_>>().join(","));
        out.push('\n');
    }
    out
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

/// What the report needs besides the runs.
pub struct Inputs<'a> {
    pub experiment: &'a Experiment,
    /// Every run.
    pub runs: &'a [RunData],
    /// The run whose library is drawn (its id).
    pub chosen: i64,
    /// The reference design marked on the library map, with its name.
    pub reference: Option<(&'a Genome, &'a str)>,
}

/// Builds the report.
pub fn build(inp: &Inputs<'_>) -> Report {
    let e = inp.experiment;
    let runs = inp.runs;
    let payload = e.brief.payload;
    let mut pictures = Vec::new();
    let mut tables = Vec::new();
    let mut page = String::new();

    // 1. Progress per generation.
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[0]);
    page.push_str("<p>For each scheme, the mean over its repeats (line) and one standard deviation either side (band).</p>\n");
    page.push_str("<p>The QD score is the quality-diversity field's headline figure: the sum of fitness over the filled cells of the feasible library (as pyribs defines it, with offset 0: fitness, 1 / cost of transport, is never negative). Evaluations are candidates: the initial population, then offspring per generation (an ES candidate is up to 21 trials).</p>\n");
    // Candidates evaluated by the end of generation g (the initial draws refused before
    // simulating aside).
    let evaluations = |g: f64| {
        f64::from(e.run.initial_population) + g * f64::from(e.run.offspring_per_generation)
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
                    format!("{}", evaluations(g)),
                    format!("{m}"),
                    format!("{sd}"),
                ]);
            }
        }
        pictures.push(Picture {
            name: stem.to_string(),
            caption: format!("{title}, per generation: mean ± sd over repeats."),
            svg: line_chart(title, "generation", label, &s),
        });
        if stem == "qd_score" {
            let by_evaluations: Vec<Series> = s
                .iter()
                .map(|sc| Series {
                    points: sc
                        .points
                        .iter()
                        .map(|&(g, m, sd)| (evaluations(g), m, sd))
                        .collect(),
                    ..sc.clone()
                })
                .collect();
            pictures.push(Picture {
                name: "qd_score_by_evaluations".into(),
                caption: "QD score against evaluations (candidates): mean ± sd over repeats."
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
    for p in &pictures {
        push_picture(&mut page, p);
    }

    // 2. Comparing schemes.
    let finished: Vec<RunResult<'_>> = runs
        .iter()
        .filter_map(|r| {
            r.generations.last().map(|(_, last)| RunResult {
                scheme: r.scheme,
                library: &r.library,
                infeasible: &r.infeasible,
                last: *last,
            })
        })
        .collect();
    let summary: Summary = summarise(&finished, &e.schemes, payload);
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
                num(s.best.sd, 4),
                num(100.0 * s.coverage.mean, 3),
                num(100.0 * s.coverage.sd, 3),
            ]
        })
        .collect();
    page.push_str("<p>The library at the end of each run, per scheme.</p>\n");
    add_table(&mut page, &mut tables, "final_by_scheme", &header, &rows);
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
    page.push_str("<p>Mann-Whitney U tests between every pair of schemes (two-sided, tie-corrected; exact for small samples without ties, normal approximation otherwise).</p>\n");
    if rows.is_empty() {
        page.push_str("<p>Only one scheme: nothing to compare.</p>\n");
    }
    add_table(&mut page, &mut tables, "mann_whitney", &header, &rows);

    // 3 and 4. One run's library.
    let scale = Scale::robust(
        runs.iter()
            .flat_map(|r| r.library.elites().map(|(_, el)| el.fitness)),
    );
    let chosen = runs.iter().find(|r| r.id == inp.chosen).or(runs.first());
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
        push_picture(&mut page, &stack);
        pictures.push(stack);
        let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[3]);
        let marg = Picture {
            name: "pair_maps".into(),
            caption: "For every pair of features, the best fitness found for each pair of their bins (same colour scale; grey: no design).".into(),
            svg: marginals_svg(&e.features, &run.library, scale, &format!("Run {}: best fitness per pair of features", run.id)),
        };
        push_picture(&mut page, &marg);
        pictures.push(marg);
    } else {
        page.push_str("<p>No run has a library yet.</p>\n");
    }

    // 5. The brief's frontier.
    let _ = writeln!(page, "<h2>{}</h2>", SECTIONS[4]);
    frontier_section(&mut page, &mut pictures, &mut tables, inp, &summary, chosen);

    // 6. Table 5 and the controllers.
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
    add_table(
        &mut page,
        &mut tables,
        "top_designs_features",
        &header,
        &rows,
    );
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
    add_table(&mut page, &mut tables, "best_controllers", &header, &rows);

    // 6. Rules.
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
        &mut page,
        &mut tables,
        "design_rules",
        &header,
        &rows,
        &csv_header,
        &csv_rows,
    );

    // 7. Drawings.
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
                "{label}: run {} cell {}, fitness {:.3}, {} legs, {:.1} kg, {:.2} m tall",
                run.id,
                cell.0,
                el.fitness,
                plan.legs.len(),
                plan.total_mass(),
                pose.height
            );
            let p = Picture {
                name: format!("design_{}", k + 1),
                caption: title.clone(),
                svg: design_svg(&plan, &pose, &title),
            };
            push_picture(&mut page, &p);
            pictures.push(p);
        }
    }

    let html = page_html(e, runs, &page, &tables);
    Report {
        html,
        pictures,
        tables,
    }
}

/// How many infeasible designs nearest the brief the report lists.
const NEAREST: usize = 10;

/// The brief's frontier: cells per scheme that meet it or only miss it and what binds, the
/// chosen run's frontier maps, and the infeasible designs nearest the brief.
fn frontier_section(
    page: &mut String,
    pictures: &mut Vec<Picture>,
    tables: &mut Vec<Table>,
    inp: &Inputs<'_>,
    summary: &Summary,
    chosen: Option<&RunData>,
) {
    let e = inp.experiment;
    page.push_str("<p>Cells holding a design that meets the whole brief (feasible), cells holding only designs that miss it (from the infeasible library, kept by feasible-infeasible search), and, for those, the constraint that binds: too slow, backward, fell, self-contact or unstable (mean over repeats).</p>\n");
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
        "mass kg",
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
                count(r.id as u64),
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

/// Pictures narrower than this (px) sit side by side on the page, as small multiples: six
/// curves one under another were a long scroll (seen in a headless-Chromium screenshot).
const SMALL_PICTURE: f64 = 600.0;

/// The width an SVG document states, px.
fn svg_width(svg: &str) -> Option<f64> {
    let head = &svg[..svg.find('>')?];
    let at = head.find(" width=\"")? + " width=\"".len();
    head[at..].split('"').next()?.parse().ok()
}

fn push_picture(page: &mut String, p: &Picture) {
    let class = match svg_width(&p.svg) {
        Some(w) if w < SMALL_PICTURE => " class=\"small\"",
        _ => "",
    };
    let _ = writeln!(
        page,
        "<figure id=\"{}\"{class}>\n{}<figcaption>{} <a href=\"{}.svg\">SVG</a> · <a href=\"{}.png\">PNG</a></figcaption>\n</figure>",
        p.name,
        p.svg,
        escape(&p.caption),
        p.name,
        p.name
    );
}

fn page_html(e: &Experiment, runs: &[RunData], body: &str, tables: &[Table]) -> String {
    let finished = runs
        .iter()
        .filter(|r| {
            r.generations
                .last()
                .is_some_and(|g| g.0 >= e.run.generations)
        })
        .count();
    let mut links = String::new();
    for t in tables {
        let _ = write!(links, "<a href=\"{}.csv\">{}.csv</a> ", t.name, t.name);
    }
    format!(
        r#"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>Strider report: {name}</title>
<style>
body {{ font-family: sans-serif; max-width: 1200px; margin: 2em auto; color: #222; }}
table {{ border-collapse: collapse; margin: 0.5em 0 1.5em; }}
th, td {{ border: 1px solid #bbb; padding: 3px 8px; text-align: right; font-size: 90%; }}
th {{ background: #f0f0f0; }}
td:first-child, th:first-child {{ text-align: left; }}
figure {{ margin: 1em 0 2em; overflow-x: auto; }}
figure > svg {{ max-width: 100%; height: auto; }}
figcaption {{ font-size: 90%; color: #444; max-width: 900px; }}
figure.small {{ display: inline-block; vertical-align: top; width: 540px; margin-right: 1.5em; }}
figure.small figcaption {{ max-width: 520px; }}
</style>
</head>
<body>
<h1>Strider report: experiment “{name}”</h1>
<p>{runs} runs ({schemes}; {repeats} repeats each), {finished} finished. Initial population {init}, then up to {gens} generations of {off}. Fitness is 1 / cost of transport: higher walks further on less energy. Tables as CSV: {links}</p>
{body}
</body>
</html>
"#,
        name = escape(&e.name),
        runs = runs.len(),
        schemes = e
            .schemes
            .iter()
            .map(|s| s.name())
            .collect::<Vec<_>>()
            .join(", "),
        repeats = e.repeats,
        init = e.run.initial_population,
        gens = e.run.generations,
        off = e.run.offspring_per_generation,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_quotes_what_needs_quoting() {
        let out = csv(
            &["a".into(), "b".into()],
            &[vec!["x, y".into(), "say \"hi\"".into()]],
        );
        assert_eq!(out, "a,b\n\"x, y\",\"say \"\"hi\"\"\"\n");
    }

    #[test]
    fn numbers_are_rounded_on_the_page_and_whole_in_the_csv() {
        let mut page = String::new();
        let mut tables = Vec::new();
        add_table(
            &mut page,
            &mut tables,
            "t",
            &["p".into(), "n".into(), "note".into()],
            &[vec![num(0.000123456789, 4), count(7), Cell::Empty]],
        );
        assert!(
            page.contains("<td>0.0001</td><td>7</td><td></td>"),
            "{page}"
        );
        assert_eq!(tables[0].csv, "p,n,note\n0.000123456789,7,\n");
    }
}
