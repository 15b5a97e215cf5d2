//! `strider-coordinator report`: the whole experiment for a robot designer, as one
//! self-contained HTML page (pictures inline), the pictures as separate SVG files (the
//! CLI adds PNG), and the tables as CSV. Plain functions from plain data to text; reading
//! the database and writing files is the CLI's job.

pub mod charts;
pub mod designs;
mod frontier;
pub mod maps;
pub mod png;
mod sections;
pub mod svg;
mod table;

use crate::qd::library::{GenerationStats, InfeasibleLibrary, Library};
use crate::results::analysis::summary::{summarise, RunResult, Summary};
use std::fmt::Write;
use strider_common::{Experiment, Genome, RunId, Scheme};
use svg::escape;

/// One run as the report reads it.
pub struct RunData {
    pub id: RunId,
    pub scheme: Scheme,
    pub repeat: u32,
    /// Its library now.
    pub library: Library,
    /// Its infeasible library now (empty under the paper's method).
    pub infeasible: InfeasibleLibrary,
    /// Every committed generation's statistics, in order.
    pub generations: Vec<(u32, GenerationStats)>,
    /// Evaluations by the end of each of those generations: candidates drawn and checked,
    /// those refused before simulating included (the exports' `cumulative_evaluations`).
    pub evaluations: Vec<u64>,
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
    /// Each design's files (genome, URDF, start pose, drawing, replay), in `designs/`.
    pub files: Vec<designs::DesignFile>,
}

/// The section headings of the page, in order (tests check each is there).
pub const SECTIONS: [&str; 9] = [
    "Progress per generation",
    "Comparing schemes",
    "The library of one run",
    "Best designs per pair of features",
    "Where the brief binds",
    "What the best designs look like",
    "Design rules",
    "Drawings of chosen designs",
    "Every design: table, scatter and cards",
];

/// What the report needs besides the runs.
pub struct Inputs<'a> {
    pub experiment: &'a Experiment,
    /// Every run.
    pub runs: &'a [RunData],
    /// The run whose library is drawn (its id).
    pub chosen: RunId,
    /// The reference design marked on the library map, with its name.
    pub reference: Option<(&'a Genome, &'a str)>,
    /// The drawn run's stored trials and replays (None: figures from the library only).
    pub trials: Option<&'a designs::DesignTrials>,
}

/// The page as the sections write it: its HTML body, pictures and tables.
#[derive(Default)]
pub(super) struct Page {
    html: String,
    pictures: Vec<Picture>,
    tables: Vec<Table>,
    files: Vec<designs::DesignFile>,
}

/// Builds the report: each section in the order of [`SECTIONS`].
pub fn build(inp: &Inputs<'_>) -> Report {
    let (e, runs) = (inp.experiment, inp.runs);
    let mut out = Page::default();
    sections::progress(&mut out, inp);
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
    let summary: Summary = summarise(&finished, &e.schemes, e.brief.payload);
    sections::schemes(&mut out, &summary);
    let chosen = runs.iter().find(|r| r.id == inp.chosen).or(runs.first());
    sections::library(&mut out, inp, chosen);
    frontier::frontier(&mut out, inp, &summary, chosen);
    sections::best_designs(&mut out, &summary);
    sections::rules(&mut out, &summary);
    sections::drawings(&mut out, inp, chosen);
    designs::workbench(&mut out, inp, chosen);
    let html = page_html(e, runs, &out.html, &out.tables);
    Report {
        html,
        pictures: out.pictures,
        tables: out.tables,
        files: out.files,
    }
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

pub(super) fn push_picture(page: &mut String, p: &Picture) {
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
        r##"<!DOCTYPE html>
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
{css}
</style>
</head>
<body>
<h1>Strider report: experiment “{name}”</h1>
<p>{runs} ({schemes}; {repeats} each), {finished} finished. Initial population {init}, then up to {gens} generations of {off}. Fitness is 1 / cost of transport: higher walks further on less energy. Tables as CSV: {links}</p>
<p><a href="#workbench">Browse every design</a>: click a cell of a map, a row or a point for its design card.</p>
{body}
<script>
{script}
</script>
</body>
</html>
"##,
        name = escape(&e.name),
        runs = counted(runs.len(), "run"),
        schemes = e
            .schemes
            .iter()
            .map(|s| s.name())
            .collect::<Vec<_>>()
            .join(", "),
        repeats = counted(e.repeats as usize, "repeat"),
        init = e.run.initial_population,
        gens = e.run.generations,
        off = e.run.offspring_per_generation,
        css = include_str!("workbench.css"),
        script = include_str!("workbench.js"),
    )
}

/// `n` things, in words: "1 run", "2 runs".
fn counted(n: usize, thing: &str) -> String {
    if n == 1 {
        format!("1 {thing}")
    } else {
        format!("{n} {thing}s")
    }
}
