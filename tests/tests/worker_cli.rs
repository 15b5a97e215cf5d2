//! `strider-worker eval`, `random`, `survey`, `reference-trial` and `--version` as a user
//! runs them.

use strider_tests::run;

fn stdout(out: &std::process::Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout.clone()).unwrap()
}

#[test]
fn eval_max_reports_its_walk_and_writes_a_trace() {
    let dir = std::env::temp_dir().join(format!("strider-eval-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trace = dir.join("max.csv");
    let out = run(
        "strider-worker",
        &[
            "eval",
            "designs/max.json",
            "--json",
            "--trace",
            trace.to_str().unwrap(),
        ],
    );
    let o: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    // MAX walks but does not reach 1 m/s under STATIC: rejected for speed alone.
    assert_eq!(o["outcome"], "rejected", "{o}");
    assert_eq!(o["violations"][0]["constraint"], "speed");
    let distance = o["stats"]["distance"].as_f64().unwrap();
    assert!(distance > 2.0, "{distance}");

    let csv = std::fs::read_to_string(&trace).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    // time, pose (7), energy, then 18 angles, 18 torques and the 18 joint targets.
    assert_eq!(header.len(), 9 + 3 * 18);
    assert_eq!(header[9], "r0_q0_rad");
    assert_eq!(header[9 + 2 * 18], "r0_target0_rad");
    let rows: Vec<&str> = lines.collect();
    // One row per control step: the 5 s trial and the second it must stay up after it.
    assert_eq!(rows.len(), 180, "one row per control step");
    let last: Vec<f64> = rows[149].split(',').map(|v| v.parse().unwrap()).collect();
    assert!((last[0] - 5.0).abs() < 1e-9);
    // The trace's energy at the end of the trial is the outcome's.
    let energy = o["stats"]["energy"].as_f64().unwrap();
    assert!(
        (last[8] - energy).abs() < 1e-3 * energy,
        "{} vs {energy}",
        last[8]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn random_regenerates_a_candidate_from_its_seed() {
    let a = stdout(&run(
        "strider-worker",
        &["random", "--seed", "4", "--candidate", "17"],
    ));
    let b = stdout(&run(
        "strider-worker",
        &["random", "--seed", "4", "--candidate", "17"],
    ));
    let c = stdout(&run(
        "strider-worker",
        &["random", "--seed", "4", "--candidate", "18"],
    ));
    assert_eq!(a, b);
    assert_ne!(a, c);
    let g: serde_json::Value = serde_json::from_str(&a).unwrap();
    assert!(g["morphology"]["legs_per_side"].is_u64());
}

#[test]
fn survey_counts_add_up() {
    let out = run(
        "strider-worker",
        &["survey", "--count", "300", "--json", "--threads", "2"],
    );
    let s: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let sum = |t: &serde_json::Value, k: &str| -> u64 {
        t[k].as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .sum()
    };
    let all = &s["all"];
    assert_eq!(all["drawn"], 300);
    // Every design ends in exactly one verdict, and each leg count's tallies add up to
    // the whole.
    assert_eq!(sum(all, "verdicts"), 300);
    let groups = s["per_leg_count"].as_array().unwrap();
    assert_eq!(groups.len(), 5);
    let drawn: u64 = groups.iter().map(|g| g[1]["drawn"].as_u64().unwrap()).sum();
    assert_eq!(drawn, 300);
    // Every failed trial has a computed cause or is counted as having none.
    let verdicts = all["verdicts"].as_array().unwrap();
    let passed = verdicts.last().unwrap().as_u64().unwrap();
    let rejected: u64 = verdicts[..3].iter().map(|v| v.as_u64().unwrap()).sum();
    let failed_trials = 300 - rejected - passed;
    assert_eq!(
        sum(all, "causes") + all["unexplained"].as_u64().unwrap(),
        failed_trials
    );
    assert!(
        all["mass_fails"].as_u64().unwrap() + all["height_fails"].as_u64().unwrap()
            >= rejected - verdicts[2].as_u64().unwrap()
    );
}

#[test]
fn eval_refuses_an_unknown_scheme() {
    let out = run(
        "strider-worker",
        &["eval", "designs/max.json", "--scheme", "walk"],
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("unknown scheme `walk`"), "{err}");
}

#[test]
fn eval_refuses_a_picture_not_named_svg_before_simulating() {
    // The pictures are SVG: a `.png` name would give a file no viewer opens as PNG.
    let dir = strider_tests::temp_dir("eval-picture-name");
    let png = dir.join("film.png");
    let out = run(
        "strider-worker",
        &[
            "eval",
            "designs/max.json",
            "--filmstrip",
            png.to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--filmstrip writes SVG: name the file .svg") && err.contains("film.png"),
        "{err}"
    );
    assert!(!png.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn eval_writes_every_file_asked_for_or_none() {
    let dir = strider_tests::temp_dir("eval-all-or-none");
    let (trace, svg) = (dir.join("t.csv"), dir.join("max.svg"));
    // A directory where the drawing goes: it cannot be written, so the trace is not left
    // behind either.
    std::fs::create_dir(&svg).unwrap();
    let out = run(
        "strider-worker",
        &[
            "eval",
            "designs/max.json",
            "--trace",
            trace.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains(&format!("writing {}", svg.display())), "{err}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["max.svg"], "only the directory in the way");
    // With the way clear, both are written.
    std::fs::remove_dir(&svg).unwrap();
    let out = run(
        "strider-worker",
        &[
            "eval",
            "designs/max.json",
            "--trace",
            trace.to_str().unwrap(),
            "--svg",
            svg.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(std::fs::read_to_string(&trace)
        .unwrap()
        .starts_with("time_s,x_forward_m,y_up_m,z_right_m"));
    assert!(std::fs::read_to_string(&svg).unwrap().ends_with("</svg>\n"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn eval_draws_the_design_to_scale_and_replays_the_trial() {
    let dir = strider_tests::temp_dir("eval-drawings");
    let (svg, replay) = (dir.join("max.svg"), dir.join("max-replay.svg"));
    let out = run(
        "strider-worker",
        &[
            "eval",
            "designs/max.json",
            "--svg",
            svg.to_str().unwrap(),
            "--replay",
            replay.to_str().unwrap(),
        ],
    );
    stdout(&out);
    let drawing = std::fs::read_to_string(&svg).unwrap();
    assert!(drawing.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
    assert!(drawing.trim_end().ends_with("</svg>"));
    for label in [
        ">side<",
        ">front<",
        ">top<",
        ">1 m<",
        "max.json (static scheme)",
    ] {
        assert!(drawing.contains(label), "no {label} in the drawing");
    }
    // MAX: a body and 6 legs of 3 links, in each of the 3 views.
    assert_eq!(drawing.matches("<polygon").count(), 3 * (1 + 6 * 3));

    let animation = std::fs::read_to_string(&replay).unwrap();
    assert!(animation.trim_end().ends_with("</svg>"));
    // 20 frames per simulated second over the trial, each shown in turn, looping.
    let frames = animation
        .matches("<animate attributeName=\"display\"")
        .count();
    assert!(frames >= 20, "{frames} frames");
    assert_eq!(animation.matches("<polygon").count(), frames * (1 + 6 * 3));
    assert!(animation.contains("repeatCount=\"indefinite\""));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_worker_without_a_secret_is_refused_at_once_naming_the_flag() {
    // Port 9 (discard): nothing answers there; the worker must not try.
    let out = std::process::Command::new(strider_tests::binary("strider-worker"))
        .args(["--connect", "http://127.0.0.1:9", "--give-up-after", "600"])
        .env_remove("STRIDER_SECRET")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no secret: pass --token-file FILE or set STRIDER_SECRET"),
        "{err}"
    );
}

#[test]
fn version_gives_the_whole_build_identity() {
    // What a coordinator compares with each worker's Hello, so a user can compare the two
    // before deploying: version, commit, architecture, profile, arithmetic.
    let build = strider_common::build_id();
    let tail = build.strip_prefix("strider ").unwrap();
    assert!(tail.contains("(commit "), "{build}");
    for binary in ["strider-worker", "strider-coordinator"] {
        for flag in ["--version", "-V"] {
            let out = run(binary, &[flag]);
            assert!(out.status.success(), "{binary} {flag}");
            assert_eq!(stdout(&out), format!("{binary} {tail}\n"), "{flag}");
        }
    }
}

#[test]
fn reference_trial_prints_the_digest_a_coordinator_compares() {
    // The digest this build's Hello carries on this machine, and the build identity: what
    // a user compares across partitions before a run (docs/operations.md).
    let out = run("strider-worker", &["reference-trial"]);
    assert_eq!(
        stdout(&out),
        format!(
            "{:016x}  {}\n",
            strider_worker::reference_trial::digest(),
            strider_common::build_id()
        )
    );
}

#[test]
fn eval_says_what_a_feasible_design_passed_besides_its_trial() {
    // A design that meets the brief at the defaults: the table names the long window and
    // the confirming trials it passed, so a user reading "valid" knows what was checked.
    let out = run(
        "strider-worker",
        &["eval", "worker/tests/fixtures/walks_on_every_floor.json"],
    );
    let text = stdout(&out);
    assert!(text.contains("outcome            valid"), "{text}");
    assert!(
        text.contains("checked            stayed up 15 s after the trial; met the brief as written again on floors of friction 0.6 and 1 and at 480 Hz (staying up 1 s after it)"),
        "{text}"
    );
}
