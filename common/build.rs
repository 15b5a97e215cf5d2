//! Names the commit this build is made from, for `build_id()`: two commits of one version
//! can simulate differently, and the coordinator refuses a worker of another build.
//!
//! The commit is `STRIDER_COMMIT` if set (a container build copies the tree without `.git`
//! and passes it as a build argument), else git's HEAD for this workspace, else "unknown"
//! (with a warning saying why). Always 12 hex digits, so that a native build and a
//! container build of one commit name it alike.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Hex digits of the commit in the build identity.
const DIGITS: usize = 12;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=STRIDER_COMMIT");
    let given = std::env::var("STRIDER_COMMIT")
        .ok()
        .map(|c| c.trim().to_ascii_lowercase())
        .filter(|c| !c.is_empty());
    let from_git = git_commit();
    let commit = match (given, from_git) {
        (Some(given), git) => {
            let ok = given.len() >= DIGITS && given.chars().all(|c| c.is_ascii_hexdigit());
            if !ok {
                panic!(
                    "STRIDER_COMMIT is {given:?}: it must be a commit's hex digits, at least \
                     {DIGITS} of them (`git rev-parse HEAD`)"
                );
            }
            let given = given[..DIGITS].to_owned();
            if let Ok(git) = git {
                if git != given {
                    println!(
                        "cargo:warning=STRIDER_COMMIT ({given}) is not this tree's HEAD \
                         ({git}); the build identity names {given}"
                    );
                }
            }
            given
        }
        (None, Ok(git)) => git,
        (None, Err(why)) => {
            // Look again once the repository changes (say, git is told to trust it).
            let repository = manifest_dir().join("../.git");
            if repository.exists() {
                println!("cargo:rerun-if-changed={}", repository.display());
            }
            println!(
                "cargo:warning=the build identity names no commit (\"unknown\"): {why}; set \
                 STRIDER_COMMIT to the commit's hex digits"
            );
            "unknown".into()
        }
    };
    println!("cargo:rustc-env=STRIDER_COMMIT={commit}");
}

/// This workspace's HEAD, shortened to `DIGITS`, with the files that move when HEAD does
/// named for cargo to watch; or why there is none.
fn git_commit() -> Result<String, String> {
    let dir = manifest_dir();
    // The workspace's own repository, not one that happens to hold an unpacked copy of it.
    let top = canonical(Path::new(&git(&dir, &["rev-parse", "--show-toplevel"])?));
    let workspace = canonical(&dir.join(".."));
    if top != workspace {
        return Err(format!(
            "{} is inside the git repository at {}, not a repository of its own",
            workspace.display(),
            top.display()
        ));
    }
    let full = git(&dir, &["rev-parse", "HEAD"])?;
    // Git appends to logs/HEAD whenever HEAD moves (a commit, a checkout, a reset), whether
    // the branch's ref is loose or packed; HEAD and the refs cover a repository without
    // reflogs, reftable its newer ref store.
    let mut watched = Vec::new();
    for path in ["HEAD", "logs/HEAD", "packed-refs", "reftable/tables.list"] {
        watched.push(git(&dir, &["rev-parse", "--git-path", path])?);
    }
    if let Ok(branch) = git(&dir, &["symbolic-ref", "-q", "HEAD"]) {
        watched.push(git(&dir, &["rev-parse", "--git-path", &branch])?);
    }
    for path in watched {
        // Only existing files: cargo reruns the script every build for a missing one.
        let path = dir.join(path);
        if path.exists() {
            println!("cargo:rerun-if-changed={}", path.display());
        }
    }
    Ok(full.chars().take(DIGITS).collect())
}

fn manifest_dir() -> PathBuf {
    PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"))
}

fn canonical(path: &Path) -> PathBuf {
    path.canonicalize().unwrap_or_else(|_| path.to_owned())
}

/// One git command's trimmed output, or what went wrong (git missing, no repository, a
/// repository git will not read as this user).
fn git(dir: &Path, args: &[&str]) -> Result<String, String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(dir)
        .output()
        .map_err(|e| format!("git could not run: {e}"))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        return Err(format!(
            "`git {}` failed: {}",
            args.join(" "),
            err.lines().next().unwrap_or("").trim()
        ));
    }
    let text = String::from_utf8_lossy(&out.stdout).trim().to_owned();
    if text.is_empty() {
        return Err(format!("`git {}` said nothing", args.join(" ")));
    }
    Ok(text)
}
