//! Process plumbing both binaries share: the log setup, the exit status of an error, a
//! reader that closed the pipe, how many threads to use, the stop signal, the host name,
//! and the terminal's progress bar (`terminal`). Nothing of the wire contract
//! (`strider-proto`) or the model (`strider-common`).

pub mod files;
pub mod terminal;

/// A command line that cannot run as given (a flag out of range, a bad log filter): exits
/// 2, as clap's own usage errors do. Every other error (a file that does not load, a
/// database, the network) exits 1.
#[derive(Debug)]
pub struct UsageError(pub String);

impl std::fmt::Display for UsageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

/// An error and its causes on one line, each cause once: a cause whose text the message
/// already holds (thiserror messages that quote their source, SQLite's text wrapped at
/// three levels) is not printed again.
pub fn error_text(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let c_text = c.to_string();
        if !text.contains(&c_text) {
            text.push_str(": ");
            text.push_str(&c_text);
        }
        cause = c.source();
    }
    text
}

/// Prints `e` as `error: ...` on stderr and returns its exit status: [`EXIT_USAGE`] when
/// a [`UsageError`] is in its chain, [`EXIT_FAILURE`] otherwise.
pub fn report(e: &(dyn std::error::Error + 'static)) -> u8 {
    eprintln!("error: {}", error_text(e));
    let mut cause = Some(e);
    while let Some(c) = cause {
        if c.is::<UsageError>() {
            return EXIT_USAGE;
        }
        cause = c.source();
    }
    EXIT_FAILURE
}

/// Exit status of a usage error.
pub const EXIT_USAGE: u8 = 2;
/// Exit status of any other error.
pub const EXIT_FAILURE: u8 = 1;

/// Crates whose debug output is wire frames, not Strider's story: kept at `info` under a
/// debug or trace filter unless it names them (`STRIDER_LOG=debug` was 2,200 lines of h2
/// frames per run).
const QUIET: [&str; 4] = ["h2", "hyper", "hyper_util", "tower"];

/// Logs to stderr at the level `STRIDER_LOG` (else `RUST_LOG`, else `info`) sets, in
/// colour only on a terminal and without `NO_COLOR` (no-color.org). A filter that does
/// not parse is an error naming the variable, not silently `info`.
pub fn init_logs() -> Result<(), String> {
    init_logs_at("info")
}

/// As [`init_logs`], with `default` where neither variable is set (a local `run` shows
/// its progress line and warnings, not the service's comings and goings).
pub fn init_logs_at(default: &str) -> Result<(), String> {
    // An empty variable is an unset one.
    let set = |name: &str| std::env::var(name).ok().filter(|v| !v.trim().is_empty());
    let (var, text) = match (set("STRIDER_LOG"), set("RUST_LOG")) {
        (Some(s), _) => ("STRIDER_LOG", s),
        (None, Some(r)) => ("RUST_LOG", r),
        _ => ("", default.to_string()),
    };
    let mut directives = text.clone();
    let verbose = text.contains("debug") || text.contains("trace");
    // The targets the filter names (`target=level` or `target[span]=level`).
    let named: Vec<&str> = text
        .split(',')
        .filter_map(|d| d.split(['=', '[']).next())
        .map(str::trim)
        .collect();
    for q in QUIET {
        if verbose && !named.contains(&q) {
            directives.push_str(&format!(",{q}=info"));
        }
    }
    let filter = tracing_subscriber::EnvFilter::builder()
        .parse(&directives)
        .map_err(|e| format!("{var}: {text:?} is not a log filter ({e}); try info, debug or strider_coordinator=debug"))?;
    let colour = std::io::IsTerminal::is_terminal(&std::io::stderr())
        && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty());
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(terminal::LogWriter)
        .with_ansi(colour)
        .try_init();
    Ok(())
}

/// A count with its noun, singular for one: `1 worker`, `0 workers`, `3 runs`.
pub fn count_words(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}

/// A duration for people: `40 s`, `12 min`, `3 h 05 min`.
pub fn duration_words(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    match s {
        0..=89 => format!("{s} s"),
        90..=5399 => format!("{} min", (s + 30) / 60),
        _ => {
            let minutes = (s + 30) / 60;
            format!("{} h {:02} min", minutes / 60, minutes % 60)
        }
    }
}

/// Parses a count of threads or workers on the command line: a whole number of at least 1
/// (clap's own parser of `NonZeroUsize` says "number would be zero for non-zero type").
pub fn at_least_one(text: &str) -> Result<std::num::NonZeroUsize, String> {
    let n: usize = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a whole number"))?;
    std::num::NonZeroUsize::new(n).ok_or_else(|| "must be at least 1".to_string())
}

/// The number of threads to use by default: every core.
pub fn default_threads() -> std::num::NonZeroUsize {
    std::thread::available_parallelism().unwrap_or(std::num::NonZeroUsize::MIN)
}

/// Writes a line to standard output and returns from the enclosing function on an error,
/// which `closed_pipe` then recognises: a reader that closed the pipe early (`| head`)
/// ends a command quietly.
#[macro_export]
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout().lock(), $($t)*)?
    }};
}

/// `outln!` without the newline.
#[macro_export]
macro_rules! out {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        write!(std::io::stdout().lock(), $($t)*)?
    }};
}

/// Whether `e` comes from writing to a pipe whose reader has gone (`strider-coordinator
/// analyse | head`): the reader had enough, so the command ends quietly with success.
/// SIGPIPE is left ignored, as Rust sets it: the same binaries serve gRPC, where a peer
/// that goes away must not kill the process.
pub fn closed_pipe(e: &(dyn std::error::Error + 'static)) -> bool {
    let mut cause = Some(e);
    while let Some(c) = cause {
        let kind = c
            .downcast_ref::<std::io::Error>()
            .map(|io| io.kind())
            .or_else(|| {
                c.downcast_ref::<serde_json::Error>()
                    .and_then(|j| j.io_error_kind())
            });
        if kind == Some(std::io::ErrorKind::BrokenPipe) {
            return true;
        }
        cause = c.source();
    }
    false
}

/// SIGTERM and Ctrl-C (SIGINT), caught from the moment [`StopSignals::catch`] returns:
/// made before a command opens its database, so that a signal while it opens (a resume
/// reads its whole library first) stops it cleanly once open, rather than killing it by
/// the signal's default action (a Slurm job cancelled as it starts reported a failure).
pub struct StopSignals {
    #[cfg(unix)]
    term: tokio::signal::unix::Signal,
    #[cfg(unix)]
    interrupt: tokio::signal::unix::Signal,
}

impl StopSignals {
    /// Catches both signals from now on (within a tokio runtime).
    pub fn catch() -> std::io::Result<Self> {
        #[cfg(unix)]
        {
            use tokio::signal::unix::{signal, SignalKind};
            Ok(Self {
                term: signal(SignalKind::terminate())?,
                interrupt: signal(SignalKind::interrupt())?,
            })
        }
        #[cfg(not(unix))]
        Ok(Self {})
    }

    /// Completes on the first signal caught since [`StopSignals::catch`] (at once if one
    /// came already) and says which: 15 or 2.
    pub async fn recv(&mut self) -> i32 {
        #[cfg(unix)]
        {
            tokio::select! {
                _ = self.term.recv() => 15,
                _ = self.interrupt.recv() => 2,
            }
        }
        #[cfg(not(unix))]
        {
            let _ = tokio::signal::ctrl_c().await;
            2
        }
    }
}

/// CPU time the calling thread has used, s: what a computation costs whatever else the
/// machine runs (wall time stretches with load; `check` read 2,578 h loaded and 702 h
/// quiet). None where the platform has no thread clock.
pub fn thread_cpu_seconds() -> Option<f64> {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes one timespec through a valid pointer.
        let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        (r == 0).then_some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
    }
    #[cfg(not(unix))]
    {
        None
    }
}

/// This machine's host name (`localhost` where it cannot be read).
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "localhost".into())
}

#[cfg(test)]
mod tests {
    use super::{closed_pipe, duration_words};

    #[test]
    fn durations_read_as_seconds_minutes_or_hours() {
        assert_eq!(duration_words(-3.0), "0 s");
        assert_eq!(duration_words(40.4), "40 s");
        assert_eq!(duration_words(89.0), "89 s");
        assert_eq!(duration_words(90.0), "2 min");
        assert_eq!(duration_words(719.0), "12 min");
        assert_eq!(duration_words(5399.0), "90 min");
        assert_eq!(duration_words(5400.0), "1 h 30 min");
        assert_eq!(duration_words(11_100.0), "3 h 05 min");
    }

    /// An error with a cause, as context wrappers make.
    #[derive(Debug)]
    struct Wrapped(std::io::Error);
    impl std::fmt::Display for Wrapped {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("writing the table")
        }
    }
    impl std::error::Error for Wrapped {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.0)
        }
    }

    #[test]
    fn a_closed_pipe_is_found_under_context_and_other_errors_are_not_one() {
        let pipe = || std::io::Error::from(std::io::ErrorKind::BrokenPipe);
        assert!(closed_pipe(&pipe()));
        assert!(closed_pipe(&Wrapped(pipe())));
        assert!(closed_pipe(&serde_json::Error::io(pipe())));
        let denied = std::io::Error::from(std::io::ErrorKind::PermissionDenied);
        assert!(!closed_pipe(&Wrapped(denied)));
    }
}
