//! The command line of `strider-coordinator`: its arguments and one module per command.
//! `main` parses, calls [`execute`] and turns the [`Exit`] into a status.

pub mod analyse;
pub mod check;
pub mod export;
mod open;
pub mod report;
pub mod run;
pub mod serve;
pub mod status;
pub mod verify;

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::time::Duration;
use strider_process::{default_threads, UsageError};

/// `strider-coordinator`'s arguments.
#[derive(Parser)]
#[command(
    name = "strider-coordinator",
    // The whole build identity (commit, architecture, profile, arithmetic): what a
    // coordinator compares with each worker's.
    version = strider_common::build_version(),
    long_version = strider_common::build_version(),
    about = "Strider coordinator: runs MAP-Elites experiments"
)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Subcommand)]
pub enum Command {
    /// Run an experiment on this machine, on all cores; resumes when the database exists.
    Run(run::RunArgs),
    /// Serve an experiment to workers over gRPC; resumes when the database exists. Stops
    /// when every run is finished (or on SIGTERM / Ctrl-C), everything committed.
    Serve(serve::ServeArgs),
    /// Print the progress of every run of a running coordinator.
    Status(status::StatusArgs),
    /// Write every elite (cell, fitness, genome) and every generation's statistics.
    Export(export::ExportArgs),
    /// Write the experiment's report: one self-contained HTML page, its pictures as SVG and
    /// PNG, its tables as CSV.
    Report(report::ReportArgs),
    /// Check a database against itself: replay every run from its stored candidates (each
    /// genome must be the one its run draws, and the libraries and positions must come out
    /// as stored), then simulate a sample of the stored candidates again (outcomes must
    /// match bit for bit). Exit 0 when all agree, 1 naming where they part.
    Verify(verify::VerifyArgs),
    /// Summarise an experiment: final figures per scheme, Mann-Whitney tests between
    /// schemes, the top designs' mean features and controllers, and the design rules.
    Analyse(analyse::AnalyseArgs),
    /// Validate an experiment file and list the runs it defines.
    Check(check::CheckArgs),
}

/// How a command ended when it did not fail.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    /// It did what it was asked.
    Success,
    /// `serve` stopped leasing for `--stop-leasing-after` before the experiment finished.
    NotFinished,
    /// `run` was stopped by this signal before the experiment finished.
    Stopped(i32),
    /// `verify` found the database disagreeing with itself.
    Disagrees,
}

/// Runs one command.
pub fn execute(command: Command) -> anyhow::Result<Exit> {
    match command {
        Command::Run(args) => run::execute(args),
        Command::Serve(args) => serve::execute(args),
        Command::Status(args) => runtime()?.block_on(status::execute(args)),
        Command::Export(args) => runtime()?.block_on(export::execute(args)),
        Command::Report(args) => runtime()?.block_on(report::execute(args)),
        Command::Verify(args) => runtime()?.block_on(verify::execute(args)),
        Command::Analyse(args) => runtime()?.block_on(analyse::execute(args)),
        Command::Check(args) => check::execute(args),
    }
}

/// `serve` and the offline commands: the service's own cores, up to four (SQLite's writer
/// has its own thread).
fn runtime() -> anyhow::Result<tokio::runtime::Runtime> {
    let threads = default_threads().get().clamp(1, 4);
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(threads)
        .enable_all()
        .build()
        .context("starting the async runtime")
}

fn init_logs() -> anyhow::Result<()> {
    strider_process::init_logs().map_err(|e| UsageError(e).into())
}

/// Logs for a command whose own lines say what happens: warnings and errors unless
/// STRIDER_LOG or RUST_LOG asks for more.
#[cfg(feature = "simulator")]
fn init_quiet_logs() -> anyhow::Result<()> {
    strider_process::init_logs_at("warn").map_err(|e| UsageError(e).into())
}

/// A positive number of seconds given as `--name`.
fn seconds(name: &str, s: f64) -> anyhow::Result<Duration> {
    if !(s.is_finite() && s > 0.0) {
        return Err(
            UsageError(format!("--{name}: {s} is not a positive number of seconds")).into(),
        );
    }
    Ok(Duration::from_secs_f64(s))
}
