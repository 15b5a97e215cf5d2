//! `strider-coordinator`: owns the MAP-Elites library. For now it validates experiment
//! files; the service, database and runs come with the service issue.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use strider_common::Experiment;

#[derive(Parser)]
#[command(
    name = "strider-coordinator",
    version,
    about = "Strider coordinator: runs MAP-Elites experiments"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Validate an experiment file and list the runs it defines.
    Check {
        /// Experiment file (TOML).
        experiment: PathBuf,
    },
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
        Command::Check { experiment } => {
            let e = Experiment::load(&experiment)?;
            let runs = e.runs();
            println!(
                "experiment `{}`: {} runs; each {} initial designs, then {} generations of {} ({} offspring)",
                e.name,
                runs.len(),
                e.run.initial_population,
                e.run.generations,
                e.run.offspring_per_generation,
                e.offspring_per_run()
            );
            println!(
                "trial {} s at {} Hz control, physics step {:.5} s; brief: mass <= {} kg, height >= {} m, speed >= {} m/s, payload {} kg",
                e.run.trial_seconds,
                e.run.control_hz,
                e.run.physics_dt(),
                e.brief.max_mass,
                e.brief.min_height,
                e.brief.min_speed,
                e.brief.payload
            );
            for r in runs {
                println!(
                    "  {:<7} repeat {:>3}  seed {}",
                    r.scheme, r.repeat, r.seed.0
                );
            }
            Ok(())
        }
    }
}
