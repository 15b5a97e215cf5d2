//! A coordinator for a test: the `serve` command on 127.0.0.1, started and waited for
//! until it says it serves, and the database checks a test ends with.

use crate::{binary, Process};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// How long a coordinator may take to say it serves (a test build beside it is slow).
pub const START: Duration = Duration::from_secs(60);

/// `strider-coordinator serve` for `experiment` (a path from the workspace root) writing
/// `db`, listening on `listen`, with the worker token in `token_file`. Add flags to it.
pub fn serve_command(experiment: &str, db: &Path, listen: &str, token_file: &Path) -> Command {
    let mut cmd = Command::new(binary("strider-coordinator"));
    cmd.args([
        "serve",
        "--db",
        db.to_str().unwrap(),
        "--experiment",
        experiment,
    ])
    .args(["--listen", listen])
    .args(["--token-file", token_file.to_str().unwrap()]);
    cmd
}

/// Starts a coordinator from its `serve` command and waits until it says it serves;
/// returns it with the URL its workers use.
pub fn start_serving(cmd: Command) -> (Process, String) {
    let p = Process::spawn("coordinator", cmd);
    let url = wait_serving(&p);
    (p, url)
}

/// Waits until a coordinator says it serves; returns the URL it names.
pub fn wait_serving(p: &Process) -> String {
    let line = p.wait_for_line(
        "saying it serves",
        |l| l.contains("serving experiment"),
        START,
    );
    line.rsplit(" on ")
        .next()
        .expect("the line names the URL")
        .trim()
        .to_string()
}

/// SQLite's integrity check of a database, `ok` when it is sound.
pub fn integrity(db: &Path) -> String {
    tokio::runtime::Runtime::new().unwrap().block_on(async {
        strider_coordinator::db::Db::open(db, false)
            .await
            .unwrap()
            .integrity_check()
            .await
            .unwrap()
            .join("\n")
    })
}
