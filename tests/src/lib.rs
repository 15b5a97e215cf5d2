//! Helpers for the integration tests: building, locating and running the real binaries.

pub mod coordinator;
pub mod slurm;
pub mod webdriver;

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
/// integration-test crate by itself). `--tests` makes cargo resolve features as
/// `cargo test` does (dev-dependencies included), so this reuses the dependencies the
/// tests were built with instead of building a second copy of them.
fn ensure_built() {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        let dir = profile_dir();
        let target = dir.parent().expect("profile dir has a parent");
        let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
        let mut cmd = Command::new(cargo);
        cmd.args(["build", "--workspace", "--bins", "--tests", "--quiet"])
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

/// A fresh, empty directory for one test.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strider-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Runs a workspace binary like [`run`] and panics with its stderr unless it succeeded.
pub fn run_ok(name: &str, args: &[&str]) -> Output {
    let out = run(name, args);
    assert!(
        out.status.success(),
        "{name} {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Says a test is skipped because `what` is missing; fails instead when
/// `STRIDER_REQUIRE_TOOLS` is set (CI sets it after installing everything: it never skips).
pub fn skip_without(what: &str) {
    assert!(
        std::env::var_os("STRIDER_REQUIRE_TOOLS").is_none(),
        "STRIDER_REQUIRE_TOOLS is set, but {what}"
    );
    eprintln!("SKIPPED: {what}");
}

/// Whether `program` is on PATH (or in the system's sbin directories).
pub fn installed(program: &str) -> bool {
    which(program).is_some()
}

/// Where `program` is on the PATH (or in /usr/sbin, /sbin).
pub fn which(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/sbin"].map(PathBuf::from))
        .map(|d| d.join(program))
        .find(|p| p.is_file())
}

/// A C library shim that rounds `sin` and `cos` one ulp up
/// (`tests/fixtures/other-trigonometry.c`), built in `dir` with `cc`, for `LD_PRELOAD`: a
/// process that loads it computes as on a node with another C library. `None` without `cc`.
pub fn other_trigonometry_shim(dir: &std::path::Path) -> Option<PathBuf> {
    let cc = which("cc")?;
    let shim = dir.join("libother-trigonometry.so");
    let built = Command::new(cc)
        .args(["-shared", "-fPIC", "-O2", "-fno-builtin", "-o"])
        .arg(&shim)
        .arg(workspace_root().join("tests/fixtures/other-trigonometry.c"))
        .args(["-ldl", "-lm"])
        .output()
        .expect("running cc");
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    Some(shim)
}

/// The secret file of a test directory, written once (atomically): rewriting it while a
/// process started earlier reads it would hand that process an empty secret.
pub fn secret_file(dir: &std::path::Path, secret: &str) -> PathBuf {
    let f = dir.join("secret");
    if !f.exists() {
        let tmp = dir.join("secret.tmp");
        std::fs::write(&tmp, format!("{secret}\n")).expect("writing the secret");
        std::fs::rename(&tmp, &f).expect("renaming the secret");
    }
    f
}

/// The library `strider-coordinator run` builds for an experiment file on this machine
/// (2 threads): what every distributed run of it must end in.
pub fn library_run_builds(experiment: &str) -> serde_json::Value {
    run_builds(experiment).0
}

/// What `strider-coordinator run` builds for an experiment file on this machine: the
/// export (library and generations) and every candidate row ([`candidate_rows`]).
pub fn run_builds(experiment: &str) -> (serde_json::Value, String) {
    let dir = temp_dir(&format!(
        "reference-{}",
        std::path::Path::new(experiment)
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("experiment")
    ));
    let db = dir.join("reference.db");
    run_ok(
        "strider-coordinator",
        &[
            "run",
            experiment,
            "--db",
            db.to_str().expect("utf-8 path"),
            "--workers",
            "2",
        ],
    );
    let e = export(&db);
    let rows = candidate_rows(&db);
    std::fs::remove_dir_all(&dir).expect("removing the reference's directory");
    (e, rows)
}

/// Every row of the `candidates` table in order, outcomes and placements included, as
/// the sqlite3 shell prints them (`.ci/run` installs it): equal for two databases
/// exactly when every candidate was drawn, evaluated and placed alike.
pub fn candidate_rows(db: &std::path::Path) -> String {
    sqlite(db, "SELECT * FROM candidates ORDER BY run_id, number")
}

/// What the sqlite3 shell prints for `sql` on `db` (`.ci/run` installs it).
pub fn sqlite(db: &std::path::Path, sql: &str) -> String {
    let out = Command::new("sqlite3")
        .arg(db)
        .arg(sql)
        .output()
        .expect("sqlite3 is installed (.ci/run installs it)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8 rows")
}

/// The whole library and every generation's statistics, as `export` writes them.
pub fn export(db: &std::path::Path) -> serde_json::Value {
    let out = run(
        "strider-coordinator",
        &["export", "--db", db.to_str().expect("utf-8 path")],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("export writes JSON")
}

/// Where two JSON values first differ, as `path: a vs b`.
pub fn first_difference(
    a: &serde_json::Value,
    b: &serde_json::Value,
    path: &str,
) -> Option<String> {
    use serde_json::Value::{Array, Object};
    match (a, b) {
        (Object(x), Object(y)) => {
            x.keys()
                .chain(y.keys())
                .find_map(|k| match (x.get(k), y.get(k)) {
                    (Some(p), Some(q)) => first_difference(p, q, &format!("{path}.{k}")),
                    _ => Some(format!("{path}.{k}: present on one side only")),
                })
        }
        (Array(x), Array(y)) if x.len() == y.len() => x
            .iter()
            .zip(y)
            .enumerate()
            .find_map(|(i, (p, q))| first_difference(p, q, &format!("{path}[{i}]"))),
        _ if a == b => None,
        _ => Some(format!("{path}: {a} vs {b}")),
    }
}

/// Panics, naming the first difference, unless two exports hold the same library and
/// statistics.
pub fn assert_same_library(a: &serde_json::Value, b: &serde_json::Value) {
    if let Some(d) = first_difference(a, b, "") {
        panic!("the libraries differ at {d}");
    }
}

/// A process started by a test: its stderr is collected line by line (and can be waited
/// on), and it is killed and reaped when dropped, so no test leaves processes behind.
pub struct Process {
    child: std::process::Child,
    lines: std::sync::mpsc::Receiver<String>,
    log: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
    /// The thread reading stderr: finished once the pipe is closed.
    reader: std::thread::JoinHandle<()>,
    name: String,
}

/// How long [`Process::wait_exit`] waits, after the exit, for the rest of its stderr.
const READ_TAIL: std::time::Duration = std::time::Duration::from_secs(5);

impl Process {
    /// Starts `cmd` with stderr captured.
    pub fn spawn(name: &str, mut cmd: Command) -> Self {
        use std::io::BufRead;
        cmd.stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .current_dir(workspace_root());
        let mut child = cmd.spawn().expect("process starts");
        let stderr = child.stderr.take().expect("piped stderr");
        let (tx, lines) = std::sync::mpsc::channel();
        let log = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let keep = log.clone();
        let reader = std::thread::spawn(move || {
            for line in std::io::BufReader::new(stderr).lines() {
                let Ok(line) = line else { break };
                keep.lock().expect("log lock").push(line.clone());
                let _ = tx.send(line);
            }
        });
        Self {
            child,
            lines,
            log,
            reader,
            name: name.into(),
        }
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Everything it has written to stderr so far.
    pub fn log(&self) -> String {
        self.log.lock().expect("log lock").join("\n")
    }

    /// Waits for a stderr line (from now on) that satisfies `pred`; panics with the log
    /// when none comes within `timeout` or the process ends first.
    pub fn wait_for_line(
        &self,
        what: &str,
        pred: impl Fn(&str) -> bool,
        timeout: std::time::Duration,
    ) -> String {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) if pred(&line) => return line,
                Ok(_) => {}
                Err(e) => panic!(
                    "{}: no line {what} ({e:?}); its log:\n{}",
                    self.name,
                    self.log()
                ),
            }
        }
    }

    /// Sends a signal (`libc::SIGSTOP`, ...).
    pub fn signal(&self, signal: i32) {
        // SAFETY: kill(2) on a child we own and have not reaped.
        let r = unsafe { libc::kill(self.child.id() as i32, signal) };
        assert_eq!(r, 0, "kill({}, {signal})", self.child.id());
    }

    /// Its exit status if it has exited, without waiting.
    pub fn exited(&mut self) -> Option<std::process::ExitStatus> {
        self.child.try_wait().expect("try_wait")
    }

    /// Waits for it to exit by itself within `timeout`; panics with the log otherwise.
    pub fn wait_exit(&mut self, timeout: std::time::Duration) -> std::process::ExitStatus {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                // Its last lines may still be in the pipe: read to the end (bounded, as a
                // process it started may hold the pipe open after it; not cut by the exit's
                // deadline, which the process met).
                let read_by = std::time::Instant::now() + READ_TAIL;
                while !self.reader.is_finished() && std::time::Instant::now() < read_by {
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
                return status;
            }
            assert!(
                std::time::Instant::now() < deadline,
                "{} did not exit within {timeout:?}; its log:\n{}",
                self.name,
                self.log()
            );
            // Polls the exit status: std offers no blocking wait with a time limit.
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A TCP port free on 127.0.0.1 right now (for a coordinator that must come back on the
/// same port after a restart).
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// Runs `ip args...`; an `ip` that cannot start reads as a refusal.
pub fn ip(args: &[&str]) -> std::process::Output {
    Command::new("ip")
        .args(args)
        .output()
        .unwrap_or_else(|e| std::process::Output {
            status: std::os::unix::process::ExitStatusExt::from_raw(1 << 8),
            stdout: Vec::new(),
            stderr: format!("ip: {e}").into_bytes(),
        })
}

/// Runs `ip args...` and panics with its stderr unless it succeeded.
pub fn ip_ok(args: &[&str]) {
    let out = ip(args);
    assert!(
        out.status.success(),
        "ip {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
}
