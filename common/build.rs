//! Names the commit this build is made from, for `build_id()`: two commits of one version
//! can simulate differently, and the coordinator refuses a worker of another build.
//!
//! The commit is `STRIDER_COMMIT` if set (a container build copies the tree without `.git`
//! and passes it as a build argument), else `git rev-parse HEAD` here, else "unknown".

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=STRIDER_COMMIT");
    let given = std::env::var("STRIDER_COMMIT")
        .ok()
        .map(|c| c.trim().to_owned())
        .filter(|c| !c.is_empty());
    let commit = given
        .or_else(git_commit)
        .unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=STRIDER_COMMIT={commit}");
}

/// HEAD's commit, shortened to 12 hex digits, with the files that move when HEAD does
/// named for cargo to watch (only existing ones: a missing file would rerun every build).
fn git_commit() -> Option<String> {
    let dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR")?);
    let commit = git(&dir, &["rev-parse", "--short=12", "HEAD"])?;
    let mut watched = vec![git(&dir, &["rev-parse", "--git-path", "HEAD"])?];
    if let Some(branch) = git(&dir, &["symbolic-ref", "-q", "HEAD"]) {
        watched.extend(git(&dir, &["rev-parse", "--git-path", &branch]));
    }
    watched.extend(git(&dir, &["rev-parse", "--git-path", "packed-refs"]));
    for path in watched {
        let path = dir.join(path);
        if path.exists() {
            println!("cargo:rerun-if-changed={}", path.display());
        }
    }
    Some(commit)
}

/// One git command's trimmed output, or `None` if git is missing or fails (no repository).
fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    let text = String::from_utf8(out.stdout).ok()?.trim().to_owned();
    (!text.is_empty()).then_some(text)
}
