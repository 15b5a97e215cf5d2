//! `strider-worker`: evaluates robot designs. `--connect URL` (or `--address-file F`)
//! works for a coordinator on every core; `eval` simulates one genome; `inspect`, `params`,
//! `random` and `urdf` describe genomes without simulating; `survey` measures how often
//! random designs pass the brief. Each command lives in `strider_worker::commands`; this
//! parses and turns outcomes into exit statuses.

use clap::Parser;
use std::process::ExitCode;
use strider_process::{closed_pipe, report};
use strider_worker::client::WorkerError;
use strider_worker::commands::{execute, Cli};

/// The trials' allocator: rapier allocates and frees buffers every physics step;
/// mimalloc makes a trial about 1.14x faster than glibc's malloc, same results.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Exit status of a worker that gave up waiting for a coordinator (`--give-up-after`);
/// sysexits.h's EX_UNAVAILABLE.
const EXIT_GAVE_UP: u8 = 69;

fn main() -> ExitCode {
    match execute(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        // `survey | head`: the reader had enough; not an error.
        Err(e) if closed_pipe(e.as_ref()) => ExitCode::SUCCESS,
        Err(e) if matches!(e.downcast_ref(), Some(WorkerError::GaveUp(_))) => {
            report(e.as_ref());
            ExitCode::from(EXIT_GAVE_UP)
        }
        Err(e) => ExitCode::from(report(e.as_ref())),
    }
}
