//! `strider-coordinator`: owns the MAP-Elites library. `run` runs an experiment on this
//! machine, `serve` serves it to workers over gRPC (both resume from their database),
//! `status` asks a running coordinator for progress, `export`, `report`, `verify` and
//! `analyse` read the library, `check` validates an experiment file. Each command lives in
//! `strider_coordinator::commands`; this parses and turns outcomes into exit statuses.

use clap::Parser;
use std::process::ExitCode;
use strider_coordinator::commands::{execute, Cli, Exit};
use strider_process::{closed_pipe, report, EXIT_FAILURE};

/// The trials' allocator (the embedded simulator's): rapier allocates and frees buffers every
/// physics step; mimalloc makes a trial about 1.14x faster than glibc's malloc, same results.
#[cfg(feature = "simulator")]
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// `serve`'s exit status when it stopped for `--stop-leasing-after` before the experiment
/// finished (EX_TEMPFAIL: serve again on the same database to go on).
const EXIT_NOT_FINISHED: u8 = 75;

fn main() -> ExitCode {
    match execute(Cli::parse().command) {
        Ok(Exit::Success) => ExitCode::SUCCESS,
        Ok(Exit::NotFinished) => ExitCode::from(EXIT_NOT_FINISHED),
        // 128 + the signal, as a shell reports a process the signal ended.
        Ok(Exit::Stopped(signal)) => ExitCode::from(128 + signal.clamp(0, 127) as u8),
        Ok(Exit::Disagrees) => ExitCode::from(EXIT_FAILURE),
        // `export ... | head`: the reader had enough; not an error.
        Err(e) if closed_pipe(e.as_ref()) => ExitCode::SUCCESS,
        Err(e) => ExitCode::from(report(e.as_ref())),
    }
}
