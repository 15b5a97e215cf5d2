//! `analyse`: final figures per scheme, Mann-Whitney tests between schemes, the top
//! designs, and the design rules, as text.

use super::open::open_existing;
use super::Exit;
use crate::results::analysis::summary::{summarise, RunResult};
use anyhow::bail;
use std::path::PathBuf;
use strider_process::out;

/// Arguments of `analyse`.
#[derive(clap::Args)]
pub struct AnalyseArgs {
    /// Database file.
    #[arg(long)]
    db: PathBuf,
}

/// Prints the summary.
pub async fn execute(args: AnalyseArgs) -> anyhow::Result<Exit> {
    let path = args.db.as_path();
    let (db, experiment) = open_existing(path).await?;
    let runs = db.runs().await?;
    let mut results = Vec::new();
    for r in &runs {
        let Some((_, _, last)) = db.generations(r.id).await?.pop() else {
            continue; // no generation committed yet
        };
        results.push(RunResult {
            scheme: r.spec.scheme,
            library: &r.library,
            infeasible: &r.infeasible,
            last,
        });
    }
    if results.is_empty() {
        bail!("no run has finished its initial population yet");
    }
    let unfinished = runs.iter().filter(|r| !r.finished).count();
    if unfinished > 0 {
        eprintln!("note: {unfinished} runs are not finished; figures are from their last committed generation");
    }
    out!(
        "{}",
        summarise(&results, &experiment.schemes, experiment.brief.payload)
    );
    Ok(Exit::Success)
}
