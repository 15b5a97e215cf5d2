//! The progress display as a user sees it: a bar redrawn in place on a terminal (a real
//! pseudo-terminal from util-linux's `script`), plain periodic lines in a pipe or a log.

use std::process::Command;
use strider_tests::{binary, export, installed, skip_without, temp_dir, workspace_root};

/// The escape that clears the line before a bar is redrawn over it.
const CLEAR_LINE: &str = "\x1b[2K";

/// Runs `args` of binary `name` on a 120-column pseudo-terminal with `env` set; returns
/// everything it wrote there (stdout and stderr together, as a terminal shows them).
fn on_a_terminal(name: &str, args: &[&str], env: &[(&str, &str)]) -> Option<String> {
    if !installed("script") {
        skip_without("util-linux's script (a pseudo-terminal)");
        return None;
    }
    let command = format!(
        "stty cols 120; exec {} {}",
        binary(name).display(),
        args.join(" ")
    );
    let out = Command::new("script")
        .args(["-qec", &command, "/dev/null"])
        .envs(env.iter().copied())
        .env("TERM", "xterm")
        .env_remove("NO_COLOR")
        .current_dir(workspace_root())
        .output()
        .expect("script starts");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{name} {args:?} on a terminal: {text}"
    );
    Some(text)
}

#[test]
fn run_draws_a_bar_on_a_terminal_and_plain_lines_in_a_pipe() {
    let dir = temp_dir("terminal-run");
    let (tty_db, pipe_db) = (dir.join("tty.db"), dir.join("pipe.db"));
    let experiment = "tests/fixtures/tiny.toml";
    let Some(screen) = on_a_terminal(
        "strider-coordinator",
        &[
            "run",
            experiment,
            "--db",
            tty_db.to_str().unwrap(),
            "--workers",
            "2",
            "--progress-every",
            "0.2",
        ],
        &[],
    ) else {
        return;
    };
    // The bar: candidates of the budget (2 runs of 12 + 12 x 16), redrawn in place.
    assert!(screen.contains("/408 candidates"), "no bar: {screen}");
    assert!(
        screen.contains(CLEAR_LINE),
        "the bar is not redrawn: {screen}"
    );
    // No periodic line while the bar is up: only the closing one ("100.0 % done").
    assert_eq!(screen.matches("% done").count(), 1, "{screen}");
    assert!(screen.contains("100.0 % done"), "{screen}");
    assert!(screen.contains("experiment `tiny` finished"), "{screen}");

    let piped = Command::new(binary("strider-coordinator"))
        .args(["run", experiment, "--db", pipe_db.to_str().unwrap()])
        .args(["--workers", "2", "--progress-every", "0.2"])
        .current_dir(workspace_root())
        .output()
        .expect("coordinator starts");
    assert!(piped.status.success());
    let log = String::from_utf8_lossy(&piped.stderr);
    assert!(
        !log.contains(CLEAR_LINE),
        "terminal escapes in a pipe: {log}"
    );
    assert!(log.contains("100.0 % done"), "{log}");
    // The display is only a display: the same library either way.
    strider_tests::assert_same_library(&export(&tty_db), &export(&pipe_db));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn survey_draws_a_bar_on_a_terminal_unless_asked_for_lines() {
    let args = ["survey", "--count", "60", "--threads", "2"];
    let Some(screen) = on_a_terminal("strider-worker", &args, &[]) else {
        return;
    };
    assert!(screen.contains("/60 designs"), "no bar: {screen}");
    assert!(screen.contains(CLEAR_LINE), "{screen}");
    // The survey's table still follows.
    assert!(screen.contains("random genomes, static scheme"), "{screen}");

    let lines = on_a_terminal("strider-worker", &args, &[("STRIDER_PROGRESS", "lines")]).unwrap();
    assert!(!lines.contains("/60 designs"), "{lines}");
    assert!(!lines.contains(CLEAR_LINE), "{lines}");
    assert!(lines.contains("random genomes, static scheme"), "{lines}");
}
