//! `inspect`: a genome's masses, start-pose height, features, cell and static brief
//! checks, without simulating.

use super::{context, emit};
use std::path::PathBuf;
use strider_common::inspect::Inspection;
use strider_common::Genome;

/// Arguments of `inspect`.
#[derive(clap::Args)]
pub struct InspectArgs {
    /// Genome file (.json or .toml).
    genome: PathBuf,
    /// Take the brief and feature grid from this experiment file (paper defaults otherwise).
    #[arg(long)]
    experiment: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

/// Prints the inspection.
pub fn execute(args: InspectArgs) -> anyhow::Result<()> {
    let InspectArgs {
        genome,
        experiment,
        json,
    } = args;
    let g = Genome::load(&genome)?;
    let ctx = context(experiment.as_deref())?;
    emit(&Inspection::of(&g, &ctx.brief, &ctx.grid), json)
}
