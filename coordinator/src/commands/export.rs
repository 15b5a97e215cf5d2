//! `export`: the library as JSON or CSV, or one elite as a genome file or URDF.

use super::open::{open_existing, selected_runs};
use super::Exit;
use crate::db::EliteFilter;
use crate::results::export::{self as library_export, EliteChoice};
use anyhow::Context;
use clap::ValueEnum;
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use strider_common::RunId;
use strider_common::{BodyPlan, CellIndex, Outcome};
use strider_process::outln;

/// What `export` writes.
#[derive(Clone, Copy, ValueEnum)]
pub enum Format {
    /// Everything: elites, infeasible elites and per-generation statistics.
    Json,
    /// One row per elite: features, trial figures and genome.
    Csv,
    /// One row per run and generation: the library's statistics.
    GenerationsCsv,
}

/// Arguments of `export`.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// Database file.
    #[arg(long)]
    db: PathBuf,
    /// Only this run (its id, from 0).
    #[arg(long)]
    run: Option<RunId>,
    /// Output format.
    #[arg(long, value_enum, default_value = "json")]
    format: Format,
    /// One elite instead of all: RUN:CELL (the cell's feasible elite, or its infeasible
    /// one where it has no feasible one), or `best` (of --run, or of the experiment).
    /// Alone, its genome file (JSON, as `strider-worker eval` and `inspect` read it) is
    /// written to standard output (or to --genome FILE); with --urdf, its design as URDF.
    #[arg(long)]
    elite: Option<EliteChoice>,
    /// Write the chosen elite's genome file here instead of to standard output.
    #[arg(long, requires = "elite", conflicts_with = "urdf")]
    genome: Option<PathBuf>,
    /// Write the chosen elite's design here as URDF (links with masses and inertias,
    /// revolute joints with axes and the motors' limits).
    #[arg(long, requires = "elite")]
    urdf: Option<PathBuf>,
}

/// Writes what the arguments choose.
pub async fn execute(args: ExportArgs) -> anyhow::Result<Exit> {
    match (args.elite, &args.urdf) {
        (Some(elite), Some(urdf)) => export_urdf(&args.db, args.run, elite, urdf).await?,
        (Some(elite), None) => {
            export_genome(&args.db, args.run, elite, args.genome.as_deref()).await?
        }
        _ => export_all(&args.db, args.run, args.format).await?,
    }
    Ok(Exit::Success)
}

/// Every elite and every generation's statistics of the chosen runs.
async fn export_all(path: &Path, only: Option<RunId>, format: Format) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs = selected_runs(&db, only).await?;
    let mut rows = Vec::new();
    for r in &runs {
        let outcomes: HashMap<CellIndex, Outcome> = db
            .list_elites(
                &EliteFilter {
                    run: Some(r.id),
                    ..EliteFilter::default()
                },
                0,
                u32::MAX,
            )
            .await?
            .into_iter()
            .map(|e| (e.cell, e.outcome))
            .collect();
        rows.push(library_export::rows(r, &outcomes));
    }
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    match format {
        Format::Json => {
            let mut json = Vec::new();
            for (r, rows) in runs.iter().zip(&rows) {
                let generations: Vec<_> = db
                    .generations(r.id)
                    .await?
                    .into_iter()
                    .map(|(g, evaluations, s)| {
                        // Coverage in per cent, as everywhere a user reads it.
                        let mut stats = serde_json::to_value(s).unwrap_or_default();
                        if let Some(o) = stats.as_object_mut() {
                            o.remove("coverage");
                            o.insert("coverage_percent".into(), library_export::coverage_percent(s.coverage).into());
                        }
                        serde_json::json!({"generation": g, "evaluations": evaluations, "stats": stats})
                    })
                    .collect();
                let elites: Vec<_> = rows.iter().map(library_export::json).collect();
                let infeasible: Vec<_> = db
                    .list_infeasible(r.id)
                    .await?
                    .iter()
                    .map(library_export::infeasible_json)
                    .collect();
                json.push(serde_json::json!({
                    "run": r.id, "scheme": r.spec.scheme.name(), "repeat": r.spec.repeat, "seed": r.spec.seed.0,
                    "generation": r.generation, "finished": r.finished, "generations": generations, "elites": elites,
                    "infeasible": infeasible,
                }));
            }
            serde_json::to_writer_pretty(
                &mut out,
                &serde_json::json!({"experiment": experiment.name, "runs": json}),
            )?;
            writeln!(out)?;
        }
        Format::Csv => {
            writeln!(out, "{}", library_export::csv_header())?;
            for row in rows.iter().flatten() {
                writeln!(out, "{}", library_export::csv_line(row))?;
            }
        }
        Format::GenerationsCsv => {
            writeln!(out, "{}", library_export::GENERATIONS_CSV_HEADER)?;
            for r in &runs {
                let mut cumulative = 0;
                for (g, evaluations, s) in db.generations(r.id).await? {
                    cumulative += evaluations;
                    let line =
                        library_export::generations_csv_line(r, g, (evaluations, cumulative), &s);
                    writeln!(out, "{line}")?;
                }
            }
        }
    }
    out.flush()?;
    Ok(())
}

/// `export --elite E [--genome FILE]`: one elite's genome file, to standard output or FILE.
async fn export_genome(
    path: &Path,
    only: Option<RunId>,
    choice: EliteChoice,
    to: Option<&Path>,
) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs = selected_runs(&db, only).await?;
    let found = library_export::find(&runs, choice, experiment.features.cell_count())
        .map_err(anyhow::Error::msg)?;
    match to {
        Some(file) => {
            std::fs::write(file, found.genome.to_json_pretty() + "\n")
                .with_context(|| format!("writing {}", file.display()))?;
            eprintln!("{found} -> {}", file.display());
        }
        None => {
            outln!("{}", found.genome.to_json_pretty());
            eprintln!("{found}");
        }
    }
    Ok(())
}

/// `export --elite E --urdf FILE`: one elite's design as URDF.
async fn export_urdf(
    path: &Path,
    only: Option<RunId>,
    choice: EliteChoice,
    urdf: &Path,
) -> anyhow::Result<()> {
    let (db, experiment) = open_existing(path).await?;
    let runs = selected_runs(&db, only).await?;
    let found = library_export::find(&runs, choice, experiment.features.cell_count())
        .map_err(anyhow::Error::msg)?;
    let plan = BodyPlan::new(&found.genome.morphology, experiment.brief.payload);
    let name = library_export::urdf_robot_name(&experiment.name, found.run, found.cell);
    let files = strider_common::urdf::files(&name, &plan, &found.genome.controller, urdf);
    let pose = files[1].0.clone();
    let mut out = strider_process::files::Outputs::new();
    for (path, text) in files {
        out.add(path, text);
    }
    out.commit()?;
    eprintln!(
        "{found}, {:.2} kg, {} legs -> {} (start pose: {})",
        plan.total_mass(),
        plan.legs.len(),
        urdf.display(),
        pose.display()
    );
    Ok(())
}
