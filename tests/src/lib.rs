//! Helpers for the integration tests: building, locating and running the real binaries.

use std::path::PathBuf;
use std::process::{Command, Output};
use std::sync::OnceLock;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The profile directory the tests were built into (`target/debug` or `target/release`).
fn profile_dir() -> PathBuf {
    let mut dir = std::env::current_exe().expect("test executable path");
    dir.pop();
    if dir.ends_with("deps") {
        dir.pop();
    }
    dir
}

/// Builds every workspace binary once per test process, in the tests' own profile, so a
/// test never runs a stale binary (cargo does not rebuild other packages' binaries for an
/// integration-test crate by itself).
fn ensure_built() {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        let dir = profile_dir();
        let target = dir.parent().expect("profile dir has a parent");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.args(["build", "--workspace", "--bins", "--quiet"])
            .env("CARGO_TARGET_DIR", target)
            .current_dir(workspace_root());
        if dir.ends_with("release") {
            cmd.arg("--release");
        }
        let status = cmd.status().expect("cargo runs");
        assert!(status.success(), "building the workspace binaries failed");
    });
}

/// Path of a workspace binary, freshly built.
pub fn binary(name: &str) -> PathBuf {
    ensure_built();
    profile_dir().join(name)
}

/// Runs a workspace binary with arguments, from the workspace root.
pub fn run(name: &str, args: &[&str]) -> Output {
    Command::new(binary(name))
        .args(args)
        .current_dir(workspace_root())
        .output()
        .expect("binary starts")
}
