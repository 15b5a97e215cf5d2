//! `report`: the experiment's report, one HTML page with its pictures (SVG and PNG) and
//! tables (CSV).

use super::open::open_existing;
use super::Exit;
use crate::results::report::{png, Inputs, RunData};
use anyhow::{bail, Context};
use std::path::PathBuf;
use strider_common::RunId;
use strider_process::files::Outputs;

/// Arguments of `report`.
#[derive(clap::Args)]
pub struct ReportArgs {
    /// Database file.
    #[arg(long)]
    db: PathBuf,
    /// Directory to write into (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// The run whose library is drawn (its id; the one with the best design by default).
    #[arg(long)]
    run: Option<RunId>,
}

/// Writes the report into `--out`.
pub async fn execute(args: ReportArgs) -> anyhow::Result<Exit> {
    let (path, out, run) = (args.db.as_path(), args.out.as_path(), args.run);
    let (db, experiment) = open_existing(path).await?;
    let mut runs = Vec::new();
    for r in db.runs().await? {
        let generations = db
            .generations(r.id)
            .await?
            .into_iter()
            .map(|(g, _, s)| (g, s))
            .collect();
        runs.push(RunData {
            id: r.id,
            scheme: r.spec.scheme,
            repeat: r.spec.repeat,
            library: r.library,
            infeasible: r.infeasible,
            generations,
        });
    }
    if let Some(id) = run {
        if !runs.iter().any(|r| r.id == id) {
            bail!("the database has no run {id}");
        }
    }
    let chosen = run.unwrap_or_else(|| {
        runs.iter()
            .flat_map(|r| r.library.elites().map(move |(_, e)| (r.id, e.fitness)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(RunId(0), |(id, _)| id)
    });
    let max = strider_common::reference::max();
    let report = crate::results::report::build(&Inputs {
        experiment: &experiment,
        runs: &runs,
        chosen,
        reference: Some((&max, "MAX")),
    });
    // Every file is written, or none (a directory this command made is removed again).
    let made = !out.exists();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut files = Outputs::new();
    files.add(out.join("report.html"), report.html.as_bytes());
    let fonts = png::fonts();
    if fonts.is_empty() {
        eprintln!("warning: no system fonts found: the PNG pictures will have no text (the SVG and HTML are complete); install fonts-dejavu-core");
    }
    for p in &report.pictures {
        files.add(out.join(format!("{}.svg", p.name)), p.svg.as_bytes());
        files.add(
            out.join(format!("{}.png", p.name)),
            png::render(&p.svg, &fonts)?,
        );
    }
    for t in &report.tables {
        files.add(out.join(format!("{}.csv", t.name)), t.csv.as_bytes());
    }
    if let Err(e) = files.commit() {
        if made {
            let _ = std::fs::remove_dir(out);
        }
        return Err(e.into());
    }
    eprintln!(
        "wrote {} ({} pictures as SVG and PNG, {} tables as CSV)",
        out.join("report.html").display(),
        report.pictures.len(),
        report.tables.len()
    );
    Ok(Exit::Success)
}
