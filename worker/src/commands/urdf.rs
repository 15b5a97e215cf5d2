//! `urdf`: a genome's design as URDF, for ROS, Gazebo, PyBullet or MuJoCo's importer.

use super::context;
use std::path::PathBuf;
use strider_common::{BodyPlan, Genome};

/// Arguments of `urdf`.
#[derive(clap::Args)]
pub struct UrdfArgs {
    /// Genome file (.json or .toml).
    genome: PathBuf,
    /// Where to write it.
    #[arg(long)]
    out: PathBuf,
    /// Take the payload from this experiment file (the paper's otherwise).
    #[arg(long)]
    experiment: Option<PathBuf>,
}

/// Writes the URDF and its start pose.
pub fn execute(args: UrdfArgs) -> anyhow::Result<()> {
    let UrdfArgs {
        genome,
        out,
        experiment,
    } = args;
    let g = Genome::load(&genome)?;
    let ctx = context(experiment.as_deref())?;
    let plan = BodyPlan::new(&g.morphology, ctx.brief.payload);
    let name = genome
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("design");
    let files = strider_common::urdf::files(name, &plan, &g.controller, &out);
    let pose = files[1].0.clone();
    let mut outputs = strider_process::files::Outputs::new();
    for (path, text) in files {
        outputs.add(path, text);
    }
    outputs.commit()?;
    eprintln!(
        "{}: {:.2} kg, {} legs -> {} (start pose: {})",
        genome.display(),
        plan.total_mass(),
        plan.legs.len(),
        out.display(),
        pose.display()
    );
    Ok(())
}
