//! `strider-coordinator run` on one machine: the same library whatever the thread count,
//! and nothing lost when the coordinator is killed at any point and restarted.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use strider_tests::coordinator::integrity;
use strider_tests::{
    assert_same_library, binary, export, other_trigonometry_shim, run, run_ok, skip_without,
    sqlite, temp_dir, workspace_root,
};

const TINY: &str = "tests/fixtures/tiny.toml";

/// Runs the tiny experiment to its end; returns what the run said on stderr.
fn run_to_end(db: &Path, workers: &str) -> String {
    let out = run(
        "strider-coordinator",
        &[
            "run",
            TINY,
            "--db",
            db.to_str().unwrap(),
            "--workers",
            workers,
        ],
    );
    let said = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{said}");
    said
}

#[test]
fn one_thread_and_two_threads_give_identical_libraries() {
    let dir = temp_dir("threads");
    let (one, two) = (dir.join("one.db"), dir.join("two.db"));
    let said = [run_to_end(&one, "1"), run_to_end(&two, "2")];
    // A run that ended cleanly leaves no lock file, log or shared memory beside its
    // database: the .db alone.
    for (db, said) in [&one, &two].into_iter().zip(&said) {
        for left in ["db.lock", "db-wal", "db-shm"] {
            let f = db.with_extension(left);
            assert!(
                !f.exists(),
                "{} was left behind; the run said:\n{said}",
                f.display()
            );
        }
    }
    let (a, b) = (export(&one), export(&two));
    assert_same_library(&a, &b);
    // Both runs finished all 12 generations and hold elites.
    for r in a["runs"].as_array().unwrap() {
        assert_eq!(r["finished"], true);
        assert_eq!(
            r["generations"].as_array().unwrap().len(),
            13,
            "generation 0 plus 12"
        );
        assert!(!r["elites"].as_array().unwrap().is_empty());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_coordinator_killed_anywhere_resumes_to_the_same_library() {
    let dir = temp_dir("kill");
    let reference = dir.join("reference.db");
    run_to_end(&reference, "2");
    let expected = export(&reference);

    let db = dir.join("killed.db");
    // Kill it right after it reports each of these (the progress line is printed every
    // 50 ms), while it evaluates what follows.
    for mark in ["initial", "generation 2/12", "generation 5/12"] {
        let mut child = Command::new(binary("strider-coordinator"))
            .args(["run", TINY, "--db", db.to_str().unwrap(), "--workers", "2"])
            .args(["--progress-every", "0.05"])
            .current_dir(workspace_root())
            .stderr(Stdio::piped())
            .stdout(Stdio::null())
            .spawn()
            .unwrap();
        let stderr = BufReader::new(child.stderr.take().unwrap());
        let mut seen = false;
        for line in stderr.lines() {
            if line.unwrap().contains(mark) {
                seen = true;
                break;
            }
        }
        child.kill().unwrap(); // SIGKILL
        child.wait().unwrap();
        assert!(seen, "the run ended before reporting `{mark}`");
        assert_eq!(integrity(&db), "ok", "after a kill at `{mark}`");
    }
    run_to_end(&db, "1");
    assert_eq!(integrity(&db), "ok");
    assert_same_library(&export(&db), &expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A database records what made it: the build identity and the machine's reference-trial
/// digest. Resumed on a node whose C library computes otherwise (glibc's `sin` and `cos`
/// one ulp up, preloaded), which the build identity alone cannot tell, `run` and `verify`
/// say so; resumed where it started, nothing is said. LD_PRELOAD is the GNU loader's.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn a_run_resumed_on_a_node_that_computes_otherwise_says_so() {
    let dir = temp_dir("other-node");
    let Some(shim) = other_trigonometry_shim(&dir) else {
        return skip_without("cc, to build the libm shim");
    };
    let db = dir.join("x.db");
    run_to_end(&db, "2");
    let made_by = sqlite(&db, "SELECT build FROM experiment");
    let made_by = made_by.trim();
    assert!(
        made_by.starts_with(&strider_common::build_id()) && made_by.contains(", reference trial "),
        "{made_by}"
    );
    // Resumed where it started: no warning (nor the embedded worker's that the service
    // went: a finished experiment starts none).
    let here = run_to_end(&db, "2");
    assert!(
        !here.contains("warning") && !here.contains("WARN"),
        "{here}"
    );
    let on_the_other_node = |args: &[&str]| {
        let out = Command::new(binary("strider-coordinator"))
            .args(args)
            .args(["--db", db.to_str().unwrap()])
            .env("LD_PRELOAD", &shim)
            .current_dir(workspace_root())
            .output()
            .unwrap();
        (
            out.status,
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (status, there) = on_the_other_node(&["run", TINY]);
    assert!(status.success(), "{there}");
    let warning = format!(
        "was started by {made_by}; this is {}, reference trial ",
        strider_common::build_id()
    );
    assert!(there.contains(&warning), "{there}");
    assert!(!there.contains(&format!("this is {made_by}")), "{there}");
    let (_, verified) = on_the_other_node(&["verify"]);
    assert!(
        verified.contains(&format!("was made by {made_by}; this is ")),
        "{verified}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_different_experiment_is_refused_and_more_generations_extend_a_finished_run() {
    let dir = temp_dir("mismatch");
    let db = dir.join("x.db");
    run_to_end(&db, "2");
    // The tiny experiment with one setting changed.
    let variant = |name: &str, from: &str, to: &str| {
        let file = dir.join(name);
        let text = std::fs::read_to_string(workspace_root().join(TINY)).unwrap();
        assert!(text.contains(from), "{from}");
        std::fs::write(&file, text.replace(from, to)).unwrap();
        file
    };
    let run_with = |file: &Path, db: &Path| {
        run(
            "strider-coordinator",
            &["run", file.to_str().unwrap(), "--db", db.to_str().unwrap()],
        )
    };
    let refused = |file: &Path, why: &str| {
        let out = run_with(file, &db);
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(why), "{err}");
    };
    refused(
        &variant("seed.toml", "seed = 11", "seed = 12"),
        "holds a different experiment (seed: 11 in the database, 12 given)",
    );
    refused(
        &variant("shorter.toml", "generations = 12", "generations = 11"),
        "run.generations: 12 in the database, 11 given: a run cannot be shortened",
    );
    // Resuming a finished experiment with its own file changes nothing.
    let before = export(&db);
    run_to_end(&db, "2");
    assert_same_library(&export(&db), &before);
    // More generations: the finished runs go on, to the library a run of that many
    // builds from the start.
    let longer = variant("longer.toml", "generations = 12", "generations = 14");
    let out = run_with(&longer, &db);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("extending experiment `tiny` from 12 to 14 generations"),
        "{err}"
    );
    let fresh = dir.join("fresh.db");
    let out = run_with(&longer, &fresh);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let extended = export(&db);
    assert_same_library(&extended, &export(&fresh));
    for r in extended["runs"].as_array().unwrap() {
        assert_eq!(r["finished"], true);
        assert_eq!(r["generations"].as_array().unwrap().len(), 15);
    }
    assert_eq!(integrity(&db), "ok");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_run_started_from_initial_designs_goes_on_and_verifies_from_its_database_alone() {
    // The tiny experiment cut to 2 generations, started from MAX (a file beside the
    // experiment file): MAX is candidate 0 of both runs. With the file gone, the database
    // alone resumes the experiment and verifies it (every run's candidates drawn again
    // from the stored experiment, MAX's included, and its libraries rebuilt).
    let dir = temp_dir("initial-designs");
    let max = std::fs::read_to_string(workspace_root().join("designs/max.json")).unwrap();
    std::fs::write(dir.join("seeds.json"), format!("[{max}]")).unwrap();
    let text = std::fs::read_to_string(workspace_root().join(TINY))
        .unwrap()
        .replace(
            "seed = 11\n",
            "seed = 11\ninitial_designs = \"seeds.json\"\n",
        )
        .replace("generations = 12", "generations = 2");
    let file = dir.join("seeded.toml");
    std::fs::write(&file, text).unwrap();
    let db = dir.join("s.db");
    let db_arg = db.to_str().unwrap();
    run_ok(
        "strider-coordinator",
        &["run", file.to_str().unwrap(), "--db", db_arg],
    );
    let max: serde_json::Value = serde_json::from_str(&max).unwrap();
    let firsts = sqlite(
        &db,
        "SELECT genome FROM candidates WHERE generation = 0 AND number = 0 ORDER BY run_id",
    );
    let firsts: Vec<serde_json::Value> = firsts
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(firsts.len(), 2, "{firsts:?}");
    for g in &firsts {
        assert_eq!(g["morphology"], max["morphology"]);
    }
    std::fs::remove_file(dir.join("seeds.json")).unwrap();
    let out = run_ok("strider-coordinator", &["run", "--db", db_arg]);
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(said.contains("resuming experiment `tiny`"), "{said}");
    run_ok(
        "strider-coordinator",
        &["verify", "--db", db_arg, "--sample", "0"],
    );
    // And the file the experiment names must be there to start one.
    let out = run(
        "strider-coordinator",
        &[
            "run",
            file.to_str().unwrap(),
            "--db",
            dir.join("t.db").to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("`initial_designs` cannot read") && err.contains("seeds.json"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn export_csv_has_one_row_per_elite_with_every_parameter_and_the_best_exports_to_urdf() {
    let dir = temp_dir("csv");
    let db = dir.join("c.db");
    run_to_end(&db, "2");
    let json = export(&db);
    let elites: usize = json["runs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["elites"].as_array().unwrap().len())
        .sum();
    let out = run(
        "strider-coordinator",
        &["export", "--db", db.to_str().unwrap(), "--format", "csv"],
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    // Identity and fitness, 6 features, 5 trial figures, 43 + 7 genome parameters; no
    // name twice (pandas would rename the second).
    assert_eq!(header.len(), 6 + 6 + 5 + 43 + 7);
    assert_eq!(header[6], "feature_total_leg_length");
    assert_eq!(header[12], "distance");
    assert_eq!(header[17], "genome_body_half_x");
    let unique: std::collections::HashSet<&&str> = header.iter().collect();
    assert_eq!(unique.len(), header.len(), "{header:?}");
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), elites);
    // pandas reads both CSVs as written: the README's lines, run by Debian's Python.
    let csv_file = dir.join("library.csv");
    std::fs::write(&csv_file, &text).unwrap();
    let out = run(
        "strider-coordinator",
        &[
            "export",
            "--db",
            db.to_str().unwrap(),
            "--format",
            "generations-csv",
        ],
    );
    assert!(out.status.success());
    let generations_file = dir.join("generations.csv");
    std::fs::write(&generations_file, &out.stdout).unwrap();
    pandas_reads(&csv_file, &generations_file, elites);
    for row in &rows {
        assert_eq!(row.len(), header.len());
        // Every elite passed a trial: its features and figures are there.
        assert!(
            row[6..17].iter().all(|v| v.parse::<f64>().is_ok()),
            "{row:?}"
        );
    }

    // The fittest elite as URDF: a standard parser loads it, and its links weigh what
    // the trial's robot weighed.
    let best = rows
        .iter()
        .max_by(|a, b| {
            let f = |r: &Vec<&str>| r[5].parse::<f64>().unwrap();
            f(a).total_cmp(&f(b))
        })
        .unwrap();
    let urdf = dir.join("best.urdf");
    run_ok(
        "strider-coordinator",
        &[
            "export",
            "--db",
            db.to_str().unwrap(),
            "--elite",
            "best",
            "--urdf",
            urdf.to_str().unwrap(),
        ],
    );
    let robot = urdf_rs::read_file(&urdf).expect("the URDF parses");
    let mass: f64 = robot.links.iter().map(|l| l.inertial.mass.value).sum();
    let trial_mass: f64 = best[header
        .iter()
        .position(|h| *h == "feature_total_mass")
        .unwrap()]
    .parse()
    .unwrap();
    assert!((mass - trial_mass).abs() < 1e-9, "{mass} vs {trial_mass}");
    assert!(
        robot.name.contains(&format!("cell_{}", best[3])),
        "{}",
        robot.name
    );
    // The same elite's genome file, to run again or draw without the database: it loads,
    // and `strider-worker urdf` makes the same robot of it.
    let out = run_ok(
        "strider-coordinator",
        &["export", "--db", db.to_str().unwrap(), "--elite", "best"],
    );
    let genome_file = dir.join("best.json");
    std::fs::write(&genome_file, &out.stdout).unwrap();
    strider_common::Genome::load(&genome_file).expect("the exported genome loads");
    // --genome FILE writes the very same file.
    let to_file = dir.join("best-to-file.json");
    run_ok(
        "strider-coordinator",
        &[
            "export",
            "--db",
            db.to_str().unwrap(),
            "--elite",
            "best",
            "--genome",
            to_file.to_str().unwrap(),
        ],
    );
    assert_eq!(std::fs::read(&to_file).unwrap(), out.stdout);
    let again = dir.join("again.urdf");
    run_ok(
        "strider-worker",
        &[
            "urdf",
            genome_file.to_str().unwrap(),
            "--out",
            again.to_str().unwrap(),
            "--experiment",
            TINY,
        ],
    );
    let robot_again = urdf_rs::read_file(&again).expect("the URDF parses");
    let mass_again: f64 = robot_again
        .links
        .iter()
        .map(|l| l.inertial.mass.value)
        .sum();
    assert_eq!(mass_again.to_bits(), mass.to_bits());
    // Both wrote the start pose beside the URDF, the same one: a joint angle for every
    // joint, the body at its start height.
    let pose = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.join(name)).unwrap()).unwrap()
    };
    let (first, second) = (pose("best.start_pose.json"), pose("again.start_pose.json"));
    assert_eq!(first, second);
    assert_eq!(
        first["joints"].as_object().unwrap().len(),
        robot.joints.len()
    );
    assert!(first["base_xyz"][2].as_f64().unwrap() > 0.5, "{first}");
    // A cell past the grid is out of range (15,625 cells: 0 to 15,624).
    let refused = |elite: &str| {
        let out = run(
            "strider-coordinator",
            &[
                "export",
                "--db",
                db.to_str().unwrap(),
                "--elite",
                elite,
                "--urdf",
                urdf.to_str().unwrap(),
            ],
        );
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = refused("0:4000000000");
    assert!(
        err.contains("cell 4000000000 is out of range: cells are numbered 0 to 15624"),
        "{err}"
    );
    // A cell in range that holds nothing, feasible or not, says so.
    let held = sqlite(
        &db,
        "SELECT cell FROM cells WHERE run_id = 0 UNION SELECT cell FROM infeasible_cells \
         WHERE run_id = 0",
    );
    let held: std::collections::HashSet<u32> = held.lines().map(|c| c.parse().unwrap()).collect();
    let empty = (0..).find(|c| !held.contains(c)).unwrap();
    let err = refused(&format!("0:{empty}"));
    assert!(
        err.contains(&format!(
            "run 0 has no design in cell {empty}, feasible or not"
        )),
        "{err}"
    );
    // A cell that holds only an infeasible design (a near miss): its genome and URDF are
    // exported, and stderr says it is not feasible and what it misses.
    let near_miss = sqlite(
        &db,
        "SELECT cell, shortfall FROM infeasible_cells WHERE run_id = 0 AND cell NOT IN \
         (SELECT cell FROM cells WHERE run_id = 0) ORDER BY cell LIMIT 1",
    );
    let (cell, shortfall) = near_miss
        .trim()
        .split_once('|')
        .expect("an infeasible-only cell");
    let choice = format!("0:{cell}");
    let out = run_ok(
        "strider-coordinator",
        &["export", "--db", db.to_str().unwrap(), "--elite", &choice],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!(
            "run 0, cell {cell}: no feasible design; the infeasible library's elite (short of \
             the brief: {shortfall}"
        )),
        "{err}"
    );
    let exported: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let library = export(&db);
    let stored = library["runs"][0]["infeasible"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["cell"].as_u64() == cell.parse().ok())
        .expect("the cell is in the infeasible library's export");
    assert_eq!(exported, stored["genome"]);
    let near_miss_urdf = dir.join("near-miss.urdf");
    run_ok(
        "strider-coordinator",
        &[
            "export",
            "--db",
            db.to_str().unwrap(),
            "--elite",
            &choice,
            "--urdf",
            near_miss_urdf.to_str().unwrap(),
        ],
    );
    urdf_rs::read_file(&near_miss_urdf).expect("the near miss's URDF parses");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn analyse_prints_every_section() {
    let dir = temp_dir("analyse");
    let db = dir.join("a.db");
    run_to_end(&db, "2");
    let out = run(
        "strider-coordinator",
        &["analyse", "--db", db.to_str().unwrap()],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    for section in [
        "Final library, per scheme",
        "static  2 repeats: best fitness",
        "Mann-Whitney U tests between schemes",
        "Mean features of the top 10 % designs (Table 5)",
        "Mean controller of each repeat's best design",
        "Design rules from the top designs (Table 6",
    ] {
        assert!(text.contains(section), "missing `{section}` in:\n{text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_papers_method_places_only_designs_that_meet_the_brief() {
    if !strider_tests::installed("sqlite3") {
        return strider_tests::skip_without("sqlite3 (apt-get install sqlite3)");
    }
    let dir = temp_dir("reject");
    let file = dir.join("reject.toml");
    let text = std::fs::read_to_string(workspace_root().join(TINY)).unwrap();
    std::fs::write(
        &file,
        format!("{text}\n[search]\nconstraints = \"reject\"\n")
            .replace("repeats = 2", "repeats = 1"),
    )
    .unwrap();
    let db = dir.join("reject.db");
    run_ok(
        "strider-coordinator",
        &["run", file.to_str().unwrap(), "--db", db.to_str().unwrap()],
    );
    let sql = |q: &str| {
        let out = Command::new("sqlite3").arg(&db).arg(q).output().unwrap();
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    // The initial population was drawn until 12 designs met the brief: every draw before
    // the twelfth valid one is stored, and only valid designs hold cells.
    let (valid, drawn): (u64, u64) = {
        let v = sql("SELECT SUM(kind = 'valid'), COUNT(*) FROM candidates WHERE generation = 0");
        let (a, b) = v.split_once('|').unwrap();
        (a.parse().unwrap(), b.parse().unwrap())
    };
    assert_eq!(valid, 12);
    assert!(
        drawn > 12,
        "random designs rarely meet even a lowered brief"
    );
    assert_eq!(
        sql("SELECT MAX(number) FROM candidates WHERE generation = 0"),
        sql("SELECT MAX(number) FROM candidates WHERE generation = 0 AND kind = 'valid'"),
        "the initial population ends at its last passing design"
    );
    assert_eq!(sql("SELECT COUNT(*) FROM infeasible_cells"), "0");
    assert_eq!(
        sql("SELECT COUNT(*) FROM cells c JOIN candidates d ON d.run_id = c.run_id AND d.number = c.candidate WHERE d.kind <> 'valid'"),
        "0"
    );
    assert_eq!(
        sql("SELECT COUNT(*) FROM candidates WHERE infeasible_placement IS NOT NULL"),
        "0"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ctrl_c_and_sigterm_stop_run_honestly_and_the_next_run_finishes_the_same_library() {
    let expected = strider_tests::library_run_builds("tests/fixtures/service.toml");
    let dir = temp_dir("local-stops");
    let db = dir.join("stopped.db");
    for (signal, status) in [(libc::SIGINT, 130), (libc::SIGTERM, 143)] {
        // Stopped in the middle: after its first progress line, before the last generation.
        let mark = "results/s";
        let mut cmd = Command::new(binary("strider-coordinator"));
        cmd.args(["run", "tests/fixtures/service.toml", "--db"])
            .arg(&db)
            .args(["--workers", "1", "--progress-every", "0.1"]);
        let mut p = strider_tests::Process::spawn("run", cmd);
        p.wait_for_line(
            mark,
            |l| l.contains(mark),
            std::time::Duration::from_secs(300),
        );
        assert!(!p.log().contains("generation 20/20"), "{}", p.log());
        // Progress says how much is done (and, once it can tell, the time left).
        assert!(p.log().contains("% done"), "{}", p.log());
        p.signal(signal);
        let got = p.wait_exit(std::time::Duration::from_secs(60));
        // Not "finished", and not 0: a script can tell a stopped run from a done one.
        assert_eq!(got.code(), Some(status), "{}", p.log());
        assert!(p.log().contains("stopped before the end"), "{}", p.log());
        // The stop is said at once, and the embedded service's INFO lines stay out of a
        // local run's account (STRIDER_LOG=info brings them back).
        assert!(
            p.log().contains("stopping: the trials in flight"),
            "{}",
            p.log()
        );
        assert!(!p.log().contains(" INFO "), "{}", p.log());
        assert!(
            !p.log().contains("finished: `strider-coordinator export"),
            "{}",
            p.log()
        );
    }
    let out = run(
        "strider-coordinator",
        &["run", "--db", db.to_str().unwrap(), "--workers", "2"],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_same_library(&export(&db), &expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Whether process `pid` catches `signal` (its handler installed): /proc's `SigCgt` mask.
fn catches(pid: u32, signal: i32) -> bool {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("SigCgt:"))
        .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
        .is_some_and(|mask| mask & (1 << (signal - 1)) != 0)
}

#[test]
fn a_sigterm_while_run_is_still_opening_stops_it_cleanly_once_open() {
    let dir = temp_dir("local-early-stop");
    let db = dir.join("early.db");
    // The experiment comes through a named pipe: `run` waits reading it, before it opens
    // its database, for as long as the test likes.
    let fifo = dir.join("experiment.toml");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: mkfifo(3) on a NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo");
    let mut cmd = Command::new(binary("strider-coordinator"));
    cmd.arg("run")
        .arg(&fifo)
        .arg("--db")
        .arg(&db)
        .args(["--workers", "1"]);
    let mut p = strider_tests::Process::spawn("run", cmd);
    // Polled, bounded: the handler is installed before the experiment is read.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while !catches(p.pid(), libc::SIGTERM) {
        assert!(p.exited().is_none(), "it exited:\n{}", p.log());
        assert!(
            std::time::Instant::now() < deadline,
            "SIGTERM not caught while reading the experiment:\n{}",
            p.log()
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    p.signal(libc::SIGTERM);
    // Only now can it read its experiment and open the database. The pipe is opened
    // without blocking (refused while no reader has it open), so a `run` that exited
    // instead of reading fails the test rather than hanging it.
    let writer = loop {
        use std::os::unix::fs::OpenOptionsExt;
        match std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(&fifo)
        {
            Ok(f) => break f,
            Err(e) if e.raw_os_error() == Some(libc::ENXIO) => {
                assert!(p.exited().is_none(), "it exited:\n{}", p.log());
                assert!(
                    std::time::Instant::now() < deadline,
                    "the pipe has no reader"
                );
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            Err(e) => panic!("opening the pipe: {e}"),
        }
    };
    // The experiment is far smaller than a pipe's buffer: written whole at once.
    std::io::Write::write_all(
        &mut &writer,
        &std::fs::read(workspace_root().join(TINY)).unwrap(),
    )
    .unwrap();
    drop(writer);
    let got = p.wait_exit(std::time::Duration::from_secs(60));
    assert_eq!(got.code(), Some(143), "{}", p.log());
    assert!(p.log().contains("stopped before the end"), "{}", p.log());
    assert_eq!(integrity(&db), "ok");
    // And the next run goes on from that database.
    let said = run_to_end(&db, "1");
    assert!(said.contains("finished"), "{said}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn export_analyse_and_verify_read_a_database_on_a_read_only_mount() {
    let dir = temp_dir("read-only-mount");
    let db = dir.join("finished.db");
    run_to_end(&db, "2");
    let expected = export(&db);
    // A private mount namespace (as an unprivileged user where allowed) with the
    // directory bind-mounted read-only over itself: what a backup on a read-only share is.
    let script = format!(
        "mount --bind {d} {d} && mount -o remount,ro,bind {d} && \
         if touch {d}/probe 2>/dev/null; then echo WRITABLE; exit 3; fi && \
         {bin} export --db {db} > {d}.json && \
         {bin} analyse --db {db} > /dev/null && \
         {bin} verify --db {db} --sample 2",
        d = dir.display(),
        db = db.display(),
        bin = binary("strider-coordinator").display()
    );
    let probe = Command::new("unshare")
        .args(["-rm", "true"])
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !probe {
        strider_tests::skip_without("unshare -rm (user and mount namespaces) is not available");
        return;
    }
    let out = Command::new("unshare")
        .args(["-rm", "sh", "-c", &script])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success(),
        "{err}\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let json = dir.with_extension("json");
    let read: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_same_library(&read, &expected);
    std::fs::remove_file(json).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Reads the library and per-generation CSVs with pandas, as the README's "Reading the
/// results" does, and checks what a user relies on: the columns, unrenamed and numeric.
fn pandas_reads(library: &std::path::Path, generations: &std::path::Path, elites: usize) {
    const PYTHON: &str = "/usr/bin/python3";
    let has_pandas = Command::new(PYTHON)
        .args(["-c", "import pandas"])
        .status()
        .is_ok_and(|s| s.success());
    if !has_pandas {
        return strider_tests::skip_without(
            "pandas for /usr/bin/python3 (apt-get install python3-pandas; .ci/run does)",
        );
    }
    let script = r#"
import sys
import pandas as pd
lib = pd.read_csv(sys.argv[1])
gen = pd.read_csv(sys.argv[2])
assert not any('.' in c for c in lib.columns), 'pandas renamed a column'
features = [c for c in lib.columns if c.startswith('feature_')]
genome = [c for c in lib.columns if c.startswith('genome_')]
assert len(features) == 6 and len(genome) == 50, (features, len(genome))
numeric = lib.drop(columns=['scheme']).select_dtypes('number').columns
assert len(numeric) == len(lib.columns) - 1, 'a column is not numeric'
best = lib.loc[lib.fitness.idxmax()]
assert best.fitness > 0 and best.feature_total_mass > 0
last = gen.sort_values('generation').groupby('run').last()
assert {'qd_score', 'coverage_percent', 'cumulative_evaluations', 'feasible_elites'} <= set(gen.columns)
assert (gen.groupby('run').cumulative_evaluations.diff().dropna() > 0).all()
assert (gen.groupby('run').generation.count() == 13).all(), gen.groupby('run').generation.count()
print(len(lib), int(last.feasible_elites.sum()))
"#;
    let out = Command::new(PYTHON)
        .args(["-c", script])
        .arg(library)
        .arg(generations)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // pandas counted every elite, in the CSV and in the last generation's statistics.
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        format!("{elites} {elites}")
    );
}
