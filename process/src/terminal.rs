//! A progress bar on a terminal, and plain lines everywhere else.
//!
//! On a terminal a long command (`run`, `serve`, `survey`) draws one bar on stderr with its
//! rate and the time left; the log lines print above it (the log writer of
//! [`crate::init_logs`] hides the bar while it writes). When stderr is a file, a
//! pipe or a batch job's log, there is no bar and the command prints its periodic lines
//! instead, which read well in a log. `STRIDER_PROGRESS=lines` asks for the lines on a
//! terminal too (for a screen recording, or a terminal that draws bars badly).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::Write;
use std::sync::Mutex;
use std::time::Duration;

/// The bar being drawn, if any, so that log lines can hide it while they print.
static ACTIVE: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// Whether this process draws bars: stderr is a terminal, `TERM` is not `dumb`, and
/// `STRIDER_PROGRESS` is not `lines`.
pub fn bars_wanted() -> bool {
    std::io::IsTerminal::is_terminal(&std::io::stderr())
        && std::env::var("TERM").map_or(true, |t| t != "dumb")
        && std::env::var("STRIDER_PROGRESS").map_or(true, |v| v.trim() != "lines")
}

/// A progress bar on stderr, shown while it lives; cleared when dropped.
pub struct Bar {
    bar: ProgressBar,
}

impl Bar {
    /// A bar of `len` steps of `unit` (`designs`, `‰`), or `None` where
    /// [`bars_wanted`] says no: the caller prints its plain lines then.
    pub fn start(len: u64, unit: &str) -> Option<Bar> {
        if !bars_wanted() {
            return None;
        }
        let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr_with_hz(4));
        let template = format!(
            "{{spinner}} {{elapsed_precise}} [{{bar:24}}] {{pos}}/{{len}} {unit} {{wide_msg}}"
        );
        bar.set_style(
            ProgressStyle::with_template(&template)
                .expect("a valid template")
                .progress_chars("=> "),
        );
        bar.enable_steady_tick(Duration::from_millis(250));
        *ACTIVE.lock().unwrap_or_else(|e| e.into_inner()) = Some(bar.clone());
        Some(Bar { bar })
    }

    /// Moves the bar to `pos` of its length.
    pub fn set_position(&self, pos: u64) {
        self.bar.set_position(pos);
    }

    /// The text after the counts: rate, time left, what the run has found.
    pub fn set_message(&self, message: String) {
        self.bar.set_message(message);
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
        let mut active = ACTIVE.lock().unwrap_or_else(|e| e.into_inner());
        *active = None;
    }
}

/// Writes `bytes` to stderr whole, with the active bar (if any) hidden meanwhile so that
/// the text lands above it and the bar is redrawn below.
pub fn write_stderr(bytes: &[u8]) -> std::io::Result<()> {
    let bar = ACTIVE
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .as_ref()
        .cloned();
    match bar {
        Some(bar) => bar.suspend(|| std::io::stderr().lock().write_all(bytes)),
        None => std::io::stderr().lock().write_all(bytes),
    }
}

/// [`eprintln!`] through [`write_stderr`]: a line that does not tear the bar.
#[macro_export]
macro_rules! note {
    ($($t:tt)*) => {{
        let mut line = format!($($t)*);
        line.push('\n');
        let _ = $crate::terminal::write_stderr(line.as_bytes());
    }};
}

/// The log writer: each event is formatted whole, then written by one [`write_stderr`].
#[derive(Clone, Copy, Default)]
pub struct LogWriter;

impl Write for LogWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        write_stderr(buf)?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        std::io::stderr().flush()
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for LogWriter {
    type Writer = LogWriter;

    fn make_writer(&'a self) -> LogWriter {
        LogWriter
    }
}
