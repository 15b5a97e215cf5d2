//! `strider-worker`: the worker process. For now it inspects genomes; simulation and the
//! coordinator connection come with the trial and service issues.

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use strider_common::inspect::Inspection;
use strider_common::{Experiment, FeatureGrid, Genome};

#[derive(Parser)]
#[command(
    name = "strider-worker",
    version,
    about = "Strider worker: evaluates robot designs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print a genome's masses, start-pose height, features, cell and static brief checks.
    Inspect {
        /// Genome file (.json or .toml).
        genome: PathBuf,
        /// Take the brief and feature grid from this experiment file (paper defaults otherwise).
        #[arg(long)]
        experiment: Option<PathBuf>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Print the genome's parameter table (Markdown): names, ranges, units, groups.
    Params,
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Inspect {
            genome,
            experiment,
            json,
        } => {
            let g = Genome::load(&genome)?;
            let (brief, grid) = match experiment {
                Some(path) => {
                    let e = Experiment::load(&path)?;
                    (e.brief, e.features)
                }
                None => (Default::default(), FeatureGrid::default()),
            };
            let report = Inspection::of(&g, &brief, &grid);
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&report).context("serialising the report")?
                );
            } else {
                println!("{report}");
            }
            Ok(())
        }
        Command::Params => {
            print!("{}", strider_common::params::markdown_table());
            Ok(())
        }
    }
}
