//! The model's command-line surface: `strider-worker inspect` and
//! `strider-coordinator check`, on good and bad files.

use std::path::PathBuf;
use strider_tests::{run, workspace_root};

fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strider-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn max_json() -> serde_json::Value {
    serde_json::from_str(
        &std::fs::read_to_string(workspace_root().join("designs/max.json")).unwrap(),
    )
    .unwrap()
}

/// Runs `inspect` on a genome text and returns (exit code, stderr).
fn inspect_text(name: &str, text: &str) -> (i32, String) {
    let path = temp_file(name, text);
    let out = run("strider-worker", &["inspect", path.to_str().unwrap()]);
    (
        out.status.code().unwrap(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn inspect_max_reports_mass_height_and_cell() {
    let out = run("strider-worker", &["inspect", "designs/max.json", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // The reference design: a hexapod about 2.2 m tall and about 60 kg (docs/model.md).
    assert_eq!(r["legs_per_side"], 3);
    let mass = r["mass_without_payload"].as_f64().unwrap();
    // 2.0 x 0.2 x 0.4 m of foam (27.2 kg) + 7.5 kg avionics + six legs of 3.232 kg.
    assert!((mass - 54.093_384).abs() < 1e-5, "{mass}");
    let height = r["height"].as_f64().unwrap();
    assert!((2.2..2.4).contains(&height), "{height}");
    assert_eq!(r["violations"].as_array().unwrap().len(), 0);
    assert_eq!(r["cell"], 13887);

    let table = run("strider-worker", &["inspect", "designs/max.json"]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(text.contains("static brief checks   pass"), "{text}");
}

#[test]
fn inspect_names_a_missing_parameter() {
    let mut g = max_json();
    g["morphology"]
        .as_object_mut()
        .unwrap()
        .remove("wall_thickness");
    let (code, err) = inspect_text("missing.json", &g.to_string());
    assert_eq!(code, 1, "a file that does not load is a runtime error");
    assert!(
        err.contains("missing morphology parameter(s): wall_thickness"),
        "{err}"
    );
}

#[test]
fn inspect_names_an_out_of_range_value() {
    let mut g = max_json();
    g["morphology"]["legs_per_side"] = serde_json::json!(9);
    let (code, err) = inspect_text("range.json", &g.to_string());
    assert_eq!(code, 1, "a file that does not load is a runtime error");
    assert!(
        err.contains("`legs_per_side` = 9 is outside its range [2, 6]"),
        "{err}"
    );
}

#[test]
fn inspect_names_a_wrong_type() {
    let mut g = max_json();
    g["morphology"]["motor0_damping"] = serde_json::json!(true);
    let (code, err) = inspect_text("type.json", &g.to_string());
    assert_eq!(code, 1, "a file that does not load is a runtime error");
    assert!(
        err.contains("`motor0_damping` must be a number, found boolean true"),
        "{err}"
    );
}

#[test]
fn inspect_names_a_nan() {
    // JSON cannot carry NaN; TOML genome files can.
    let mut text = String::from("[morphology]\n");
    let g = max_json();
    for (k, v) in g["morphology"].as_object().unwrap() {
        let v = if k == "link2_width" {
            "nan".to_string()
        } else {
            v.to_string()
        };
        text.push_str(&format!("{k} = {v}\n"));
    }
    text.push_str("[controller]\n");
    for (k, v) in g["controller"].as_object().unwrap() {
        text.push_str(&format!("{k} = {v}\n"));
    }
    let (code, err) = inspect_text("nan.toml", &text);
    assert_eq!(code, 1, "a file that does not load is a runtime error");
    assert!(err.contains("`link2_width` is NaN"), "{err}");
}

#[test]
fn inspect_reports_an_unreadable_file() {
    let out = run(
        "strider-worker",
        &["inspect", "designs/does-not-exist.json"],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot read genome file designs/does-not-exist.json"),
        "{err}"
    );
    // The cause once, not once per level of the error chain.
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
}

#[test]
fn check_lists_the_paper_runs() {
    let out = run("strider-coordinator", &["check", "experiments/paper.toml"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("experiment `paper`: 60 runs"), "{text}");
    assert!(text.contains("es      repeat  19  seed 20"), "{text}");
    // What it will cost: 60 x (400 + 240,000) candidates; ES candidates are 21 trials each.
    assert!(
        text.contains(
            "cost: 14424000 candidates, 110584000 trials (an ES candidate is up to 21 trials); an initial random design refused before its trial (mass, height, start pose) is drawn again, stored but not counted here"
        ),
        "{text}"
    );
    // And how long, from full-length trials simulated now on this machine.
    assert!(text.contains("time on this machine's"), "{text}");
    // Split by scheme: an ES candidate is 21 trials.
    assert!(
        text.contains("  es      20 runs x 240400 candidates x 21 trials = 100968000 trials, "),
        "{text}"
    );
    assert!(
        text.contains("  static  20 runs x 240400 candidates x 1 trial = 4808000 trials, "),
        "{text}"
    );
    assert!(text.contains("trials of MAX to their end in"), "{text}");
    // A design that meets the brief costs more: its window and confirming trials are
    // said, and what they come to: the trial and its 15-s window, the two floors' with
    // it, and the finer step's with its own 1-s window (2 x 6 s): 72 s against the 6 s
    // of one that misses the brief.
    assert!(
        text.contains("a design that meets the brief and is fitter than its cell's elite walks its 15-s window and is simulated again before it counts: on floors of friction 1 and 0.6 (2 trials, each with that window), then at 2x the physics steps (2 trials' time, with a 1-s window): 72 s of simulation at the run's step against 6 s for one that misses the brief, up to 12.0 trials' time in all for such a trial (under ES, every child that meets the brief and beats its parent)"),
        "{text}"
    );
    // The figure is not called a bound: it is not one.
    assert!(text.contains("an estimate, not a bound"), "{text}");
    assert!(!text.contains("at most"), "{text}");
    assert!(
        text.contains(
            "(15 s when it is fast enough for the brief, shoved sideways by 0.3 m/s at its start)"
        ),
        "{text}"
    );

    let out = run(
        "strider-coordinator",
        &["check", "experiments/paper.toml", "--no-calibration"],
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.contains("from MAX's trial on the development machine"),
        "{text}"
    );
    assert!(!text.contains("measured now"), "{text}");
}

/// What `check --no-calibration` prints for an experiment of one STATIC run with `trial`
/// as its `[trial]` table.
fn check_text(file: &str, trial: &str) -> String {
    let path = temp_file(
        file,
        &format!("name = \"x\"\nschemes = [\"static\"]\nrepeats = 1\nseed = 1\n[trial]\n{trial}"),
    );
    let out = run(
        "strider-coordinator",
        &["check", path.to_str().unwrap(), "--no-calibration"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn check_says_what_the_confirming_floors_cost() {
    let text = check_text(
        "floors.toml",
        "friction_margin = 0.25\nconfirm_substeps_factor = 1\n",
    );
    // The run's floor at 0.8: a quarter less and more grip, the values fidelity takes.
    assert!(
        text.contains("simulated again before it counts: on floors of friction 1 and 0.6 (2 trials, each with that window): 60 s of simulation at the run's step against 6 s for one that misses the brief, up to 10.0 trials' time in all for such a candidate"),
        "{text}"
    );
    assert!(!text.contains("physics steps ("), "{text}");
    // The finer step alone.
    let text = check_text("finer.toml", "friction_margin = 0.0\n");
    assert!(
        text.contains("simulated again before it counts: at 2x the physics steps (2 trials' time, with a 1-s window): 32 s of simulation at the run's step against 6 s for one that misses the brief, up to 5.3 trials' time in all"),
        "{text}"
    );
    // The finer step with the long window too (`confirm_substeps_upright_seconds`).
    let text = check_text(
        "finer-long.toml",
        "friction_margin = 0.0\nconfirm_substeps_upright_seconds = 15\n",
    );
    assert!(
        text.contains("simulated again before it counts: at 2x the physics steps (2 trials' time, with that window): 60 s of simulation at the run's step against 6 s for one that misses the brief, up to 10.0 trials' time in all"),
        "{text}"
    );
    // No ES here, so nothing said of ES candidates.
    assert!(!text.contains("ES"), "{text}");
    // No long window: the confirmations alone, and no window named.
    let text = check_text("nowindow.toml", "upright_after_feasible_seconds = 0\n");
    assert!(
        text.contains("fitter than its cell's elite is simulated again before it counts: on floors of friction 1 and 0.6 (2 trials), then at 2x the physics steps (2 trials' time): 30 s of simulation at the run's step against 6 s for one that misses the brief, up to 5.0 trials' time in all"),
        "{text}"
    );
    assert!(!text.contains("-s window"), "{text}");
}

#[test]
fn check_refuses_a_bad_experiment_by_field() {
    let path = temp_file(
        "bad.toml",
        "name = \"x\"\nschemes = [\"static\"]\nrepeats = 1\nseed = 1\n[run]\ncontrol_hz = 0.0\n",
    );
    let out = run("strider-coordinator", &["check", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("`run.control_hz` is 0; allowed: 1 to 1000"),
        "{err}"
    );
}

#[test]
fn fidelity_checks_a_design_at_another_friction() {
    // MAX at the run's friction and on a floor like wet ice: the coefficient reaches the
    // contacts (its feet slip and it hardly moves), one CSV row per setting.
    let genomes = temp_file("max-array.json", &format!("[{}]", max_json()));
    let csv = genomes.with_file_name("fidelity-friction.csv");
    let out = run(
        "strider-worker",
        &[
            "fidelity",
            "--genomes",
            genomes.to_str().unwrap(),
            "--substeps",
            "8",
            "--friction",
            "0.05",
            "--threads",
            "1",
            "--csv",
            csv.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    let col = |name: &str| rows[0].iter().position(|c| *c == name).unwrap();
    let (friction, distance) = (col("friction"), col("distance"));
    assert_eq!(rows.len(), 3, "{text}");
    assert_eq!(rows[1][friction], "0.8");
    assert_eq!(rows[2][friction], "0.05");
    // The window a design fast enough is judged by is said, not only the shorter one.
    assert_eq!(rows[1][col("upright_after_seconds")], "1");
    assert_eq!(rows[1][col("upright_after_feasible_seconds")], "15");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("8 substeps, up 1 s after (15 s if fast enough), friction 0.8"),
        "{table}"
    );
    let d = |r: usize| rows[r][distance].parse::<f64>().unwrap_or(0.0);
    assert!(d(1) > 2.0, "{text}");
    assert!(d(2) < 0.5 * d(1), "{text}");
    // A coefficient out of range is refused by name.
    let out = run(
        "strider-worker",
        &[
            "fidelity",
            "--genomes",
            genomes.to_str().unwrap(),
            "--friction",
            "5",
        ],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--friction 5: a friction coefficient is from 0.01 to 2"),
        "{err}"
    );
    // And so is a shove out of range.
    let out = run(
        "strider-worker",
        &[
            "fidelity",
            "--genomes",
            genomes.to_str().unwrap(),
            "--push",
            "3",
        ],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--push 3: a shove is from 0 to 2 m/s"),
        "{err}"
    );
}

#[test]
fn docs_parameter_table_matches_the_code() {
    let doc = std::fs::read_to_string(workspace_root().join("docs/model.md")).unwrap();
    let begin = doc.find("<!-- params:begin -->\n").expect("begin marker")
        + "<!-- params:begin -->\n".len();
    let end = doc.find("<!-- params:end -->").expect("end marker");
    let out = run("strider-worker", &["params"]);
    assert_eq!(
        &doc[begin..end],
        String::from_utf8(out.stdout).unwrap(),
        "docs/model.md's parameter table is stale: paste `strider-worker params` between the markers"
    );
}

#[test]
fn a_reader_that_closes_the_pipe_early_ends_the_command_quietly() {
    use std::io::{BufRead, BufReader};
    // 3,000 runs: about 100 KB of listing, more than a pipe holds, so the writer is still
    // writing when the reader goes.
    let dir = strider_tests::temp_dir("pipe");
    let file = dir.join("many.toml");
    std::fs::write(
        &file,
        "name = \"many\"\nschemes = [\"static\", \"genome\", \"es\"]\nrepeats = 1000\nseed = 1\n",
    )
    .unwrap();
    let mut child = std::process::Command::new(strider_tests::binary("strider-coordinator"))
        .args(["check", file.to_str().unwrap()])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("experiment `many`"), "{first}");
    // The reader is dropped here, like `| head -1`.
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(out.status.code(), Some(0), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_log_filter_that_does_not_parse_is_a_usage_error_naming_the_variable() {
    let dir = strider_tests::temp_dir("bad-log-filter");
    let db = dir.join("x.db");
    let out = std::process::Command::new(strider_tests::binary("strider-coordinator"))
        .args([
            "run",
            "tests/fixtures/service.toml",
            "--db",
            db.to_str().unwrap(),
        ])
        .env("STRIDER_LOG", "info,[[[")
        .current_dir(strider_tests::workspace_root())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("STRIDER_LOG") && err.contains("not a log filter"),
        "{err}"
    );
    assert!(!db.exists(), "nothing ran");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_count_of_zero_threads_or_workers_says_it_must_be_at_least_one() {
    // clap's own parser said "number would be zero for non-zero type".
    for (binary, args) in [
        ("strider-coordinator", &["run", "--workers", "0"][..]),
        // --threads, as the worker's, is the name; --workers stays as an alias.
        ("strider-coordinator", &["run", "--threads", "0"][..]),
        (
            "strider-coordinator",
            &["report", "--db", "x.db", "--out", "r", "--threads", "0"],
        ),
        (
            "strider-coordinator",
            &["verify", "--db", "x.db", "--workers", "0"],
        ),
        ("strider-worker", &["survey", "--threads", "0"]),
        ("strider-worker", &["fidelity", "--threads", "0"]),
        (
            "strider-worker",
            &["--connect", "http://127.0.0.1:9", "--threads", "0"],
        ),
        ("strider-worker", &["survey", "--threads", "two"]),
    ] {
        let out = run(binary, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{binary} {args:?}: {err}");
        assert!(
            err.contains("must be at least 1") || err.contains("`two` is not a whole number"),
            "{binary} {args:?}: {err}"
        );
        assert!(!err.contains("non-zero type"), "{err}");
    }
}
