//! The command line of `strider-worker`: its arguments and one module per command. With
//! no command it works for a coordinator ([`connect`]). `main` parses, calls [`execute`]
//! and turns the outcome into an exit status.

pub mod connect;
pub mod eval;
pub mod fidelity;
pub mod inspect;
pub mod random;
pub mod survey;
pub mod urdf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::path::Path;
use strider_common::{EvalContext, Experiment};
use strider_process::{out, outln};

/// `strider-worker`'s arguments.
#[derive(Parser)]
#[command(
    name = "strider-worker",
    // The whole build identity (commit, architecture, profile, arithmetic): what a
    // coordinator compares with each worker's.
    version = strider_common::build_version(),
    long_version = strider_common::build_version(),
    about = "Strider worker: evaluates robot designs"
)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Cli {
    /// A command; none to work for a coordinator.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Working for a coordinator.
    #[command(flatten)]
    pub connect: connect::ConnectArgs,
}

/// The commands.
#[derive(Subcommand)]
pub enum Command {
    /// Simulate one genome and print its outcome.
    Eval(eval::EvalArgs),
    /// Print a genome's masses, start-pose height, features, cell and static brief checks.
    Inspect(inspect::InspectArgs),
    /// Write a genome's design as URDF (links with masses and inertias, revolute joints with
    /// axes and the motors' limits), for ROS, Gazebo, PyBullet or MuJoCo's importer.
    Urdf(urdf::UrdfArgs),
    /// Print the genome's parameter table (Markdown): names, ranges, units, groups.
    Params,
    /// Print the random genome a run draws as candidate N (JSON).
    Random(random::RandomArgs),
    /// Evaluate random genomes and report how often each constraint of the brief fails.
    Survey(survey::SurveyArgs),
    /// Evaluate designs at several physics steps and stay-up windows: does the verdict
    /// depend on the step?
    Fidelity(fidelity::FidelityArgs),
    /// Print this machine's reference-trial digest, which a coordinator compares with its
    /// own for every worker, and the build identity: run it on each kind of node (`srun
    /// strider-worker reference-trial`) to see before a run whether they compute alike.
    ReferenceTrial,
}

/// Runs the command, or works for a coordinator when there is none.
pub fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        None => connect::execute(cli.connect),
        Some(Command::Eval(args)) => eval::execute(args),
        Some(Command::Inspect(args)) => inspect::execute(args),
        Some(Command::Urdf(args)) => urdf::execute(args),
        Some(Command::Params) => {
            out!("{}", strider_common::params::markdown_table());
            Ok(())
        }
        Some(Command::Random(args)) => random::execute(args),
        Some(Command::Survey(args)) => survey::execute(args),
        Some(Command::Fidelity(args)) => fidelity::execute(args),
        Some(Command::ReferenceTrial) => {
            outln!(
                "{:016x}  {}",
                crate::reference_trial::digest(),
                strider_common::build_id()
            );
            Ok(())
        }
    }
}

/// The evaluation context of an experiment file, or the paper's.
fn context(experiment: Option<&Path>) -> anyhow::Result<EvalContext> {
    Ok(match experiment {
        Some(path) => EvalContext::of(&Experiment::load(path)?),
        None => EvalContext::paper(),
    })
}

/// Prints a report as pretty JSON or as its table.
fn emit<T: serde::Serialize + std::fmt::Display>(report: &T, json: bool) -> anyhow::Result<()> {
    if json {
        let text = serde_json::to_string_pretty(report).context("serialising the report")?;
        outln!("{text}");
    } else {
        outln!("{report}");
    }
    Ok(())
}
