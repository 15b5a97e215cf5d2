//! `verify` and the checks on resume catch what SQLite cannot see (issue 14): a finished
//! database agrees with itself; an edited genome, outcome, seed, next candidate, fitness
//! column or deleted cell is named, and the cheap checks refuse to resume from the edits
//! they can see.

use std::path::{Path, PathBuf};
use strider_tests::{run, run_ok, sqlite, temp_dir};

const FIXTURE: &str = "tests/fixtures/service.toml";

/// The fixture experiment run to its end into `db`.
fn finished_run(db: &Path) {
    run_ok(
        "strider-coordinator",
        &[
            "run",
            FIXTURE,
            "--db",
            db.to_str().unwrap(),
            "--workers",
            "2",
        ],
    );
}

/// A copy of `db` with `sql` applied.
fn corrupted(db: &Path, name: &str, sql: &str) -> PathBuf {
    let copy = db.with_file_name(format!("{name}.db"));
    std::fs::copy(db, &copy).unwrap();
    sqlite(&copy, sql);
    copy
}

/// `verify`'s exit status and output.
fn verify(db: &Path, sample: &str) -> (i32, String) {
    let out = run(
        "strider-coordinator",
        &["verify", "--db", db.to_str().unwrap(), "--sample", sample],
    );
    (
        out.status.code().unwrap(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// Whether `run` on the database refuses to resume, naming `what`.
fn resume_refused(db: &Path, what: &str) {
    let out = run(
        "strider-coordinator",
        &["run", "--db", db.to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("is inconsistent") && err.contains(what),
        "{err}"
    );
}

#[test]
fn verify_and_resume_catch_edits_sqlite_cannot_see() {
    let dir = temp_dir("verify");
    let db = dir.join("whole.db");
    finished_run(&db);
    let (code, out) = verify(&db, "30");
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("agrees with itself"), "{out}");
    assert!(out.contains("30 identical, 0 different"), "{out}");

    // One digit of an offspring's genome (its range still holds).
    let genome = corrupted(
        &db,
        "genome",
        "UPDATE candidates SET genome = json_set(genome, '$.morphology.body_half_x', \
         json_extract(genome, '$.morphology.body_half_x') - 0.001) \
         WHERE run_id = 0 AND number = (SELECT MIN(number) FROM candidates WHERE run_id = 0 \
         AND generation = 3 AND json_extract(genome, '$.morphology.body_half_x') > 0.5)",
    );
    let (code, out) = verify(&genome, "0");
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("the stored genome is not the one"), "{out}");

    // An outcome's controller (the first stored candidate: the sample always holds it).
    let outcome = corrupted(
        &db,
        "outcome",
        "UPDATE candidates SET outcome = json_set(outcome, '$.controller.stride_frequency', \
         json_extract(outcome, '$.controller.stride_frequency') + 0.001) \
         WHERE run_id = 0 AND number = 0",
    );
    let (code, out) = verify(&outcome, "1");
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("simulated again it gives"), "{out}");

    // The seed of a run.
    let seed = corrupted(&db, "seed", "UPDATE runs SET seed = seed + 1 WHERE id = 0");
    let (code, out) = verify(&seed, "0");
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("seed"), "{out}");
    resume_refused(&seed, "seed");

    // The next candidate of a run.
    let next = corrupted(
        &db,
        "next",
        "UPDATE runs SET next_candidate = next_candidate + 3 WHERE id = 1",
    );
    let (code, out) = verify(&next, "0");
    assert_eq!(code, 1, "{out}");
    resume_refused(&next, "next candidate");

    // A generation's stored figures (before, verify said the file agreed with itself, and
    // the curves and the generations export read the changed figure).
    let generations = corrupted(
        &db,
        "generations",
        "UPDATE generations SET mean_fitness = mean_fitness * 1.01 + 0.001 \
         WHERE run_id = 0 AND generation = 2",
    );
    let (code, out) = verify(&generations, "0");
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("1 generations rows do not match their checksums")
            && out.contains("(run 0 generation 2)"),
        "{out}"
    );
    // The resume refuses it too (before: it went on from the changed figures), and the
    // readers of the figures name the row.
    resume_refused(&generations, "run 0 generation 2");
    let out = run(
        "strider-coordinator",
        &[
            "export",
            "--db",
            generations.to_str().unwrap(),
            "--format",
            "generations-csv",
        ],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("table generations, run 0 generation 2")
            && err.contains("does not match its checksum"),
        "{err}"
    );
    // Without its checksum (a row written before checksums) the replay still sees it.
    let unchecked = corrupted(
        &generations,
        "generations-unchecked",
        "UPDATE generations SET checksum = NULL WHERE run_id = 0 AND generation = 2",
    );
    let (code, out) = verify(&unchecked, "0");
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("the generations table's row for generation 2"),
        "{out}"
    );
    // The stored experiment: a byte of its definition (here a changed minimum speed, which
    // would judge the rest of the run by another brief), which SQLite cannot see.
    let definition = corrupted(
        &db,
        "definition",
        "UPDATE experiment SET definition = replace(definition, 'min_speed = 0.05', \
         'min_speed = 0.06')",
    );
    assert_ne!(
        sqlite(&definition, "SELECT definition FROM experiment"),
        sqlite(&db, "SELECT definition FROM experiment"),
        "the edit changed the definition"
    );
    let (code, out) = verify(&definition, "0");
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("table experiment, row 1") && out.contains("does not match its checksum"),
        "{out}"
    );
    let out = run(
        "strider-coordinator",
        &["run", "--db", definition.to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("table experiment, row 1"), "{err}");

    // An undamaged file passes SQLite's own check, which verify now runs.
    assert!(verify(&db, "0").1.contains("integrity check: ok"));

    // An elite's fitness column.
    let fitness = corrupted(
        &db,
        "fitness",
        "UPDATE candidates SET fitness = fitness * 1.5 \
         WHERE (run_id, number) IN (SELECT run_id, candidate FROM cells LIMIT 1)",
    );
    let (code, out) = verify(&fitness, "0");
    assert_eq!(code, 1, "{out}");
    assert!(
        out.contains("column does not say what its outcome says"),
        "{out}"
    );
    resume_refused(&fitness, "library cells");

    // A deleted cell of the library.
    let cell = corrupted(
        &db,
        "cell",
        "DELETE FROM cells WHERE rowid = (SELECT MIN(rowid) FROM cells)",
    );
    let (code, out) = verify(&cell, "0");
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("elites, the replay"), "{out}");
    resume_refused(&cell, "hold no elite");

    // One digit of a library holder's genome: the search breeds from it after a resume.
    let holder = corrupted(
        &db,
        "holder",
        "UPDATE candidates SET genome = json_set(genome, '$.morphology.body_half_x', \
         json_extract(genome, '$.morphology.body_half_x') + 0.001) \
         WHERE (run_id, number) IN (SELECT run_id, candidate FROM cells LIMIT 1)",
    );
    let (code, out) = verify(&holder, "0");
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("do not match their checksums"), "{out}");
    resume_refused(&holder, "do not match their checksums");

    // An elite's fitness changed everywhere it is written, consistently: only the row's
    // checksum still knows.
    let everywhere = corrupted(
        &db,
        "everywhere",
        "UPDATE candidates SET fitness = fitness * 2, \
         outcome = json_set(outcome, '$.fitness', json_extract(outcome, '$.fitness') * 2) \
         WHERE (run_id, number) IN (SELECT run_id, candidate FROM cells LIMIT 1); \
         UPDATE cells SET fitness = fitness * 2 WHERE rowid = (SELECT MIN(rowid) FROM cells);",
    );
    resume_refused(&everywhere, "do not match their checksums");

    std::fs::remove_dir_all(&dir).unwrap();
}

/// Text that is not UTF-8 where the database holds text (a flipped high bit in a genome,
/// an outcome, the stored experiment): every command that reads it refuses with an error
/// naming the table, the row and the column; none panics (before: exit 101 from `run`,
/// `verify`, `export` and `analyse`).
#[test]
fn text_that_is_not_utf8_is_refused_naming_its_row_never_a_panic() {
    let dir = temp_dir("verify-utf8");
    let db = dir.join("whole.db");
    finished_run(&db);
    // The elite of the lowest occupied cell of run 0: read by the resume, `verify`,
    // `export` and `analyse`.
    let elite = sqlite(
        &db,
        "SELECT candidate FROM cells WHERE run_id = 0 ORDER BY cell LIMIT 1",
    );
    let elite = elite.trim();
    // 0xFF can start no UTF-8 character.
    let bad_text = "CAST(X'7B22FF227D' AS TEXT)";
    let cases = [
        (
            "genome",
            format!(
                "UPDATE candidates SET genome = {bad_text} WHERE run_id = 0 AND number = {elite}"
            ),
            format!("run 0 candidate {elite}"),
            "genome",
        ),
        (
            "outcome",
            format!(
                "UPDATE candidates SET outcome = {bad_text} WHERE run_id = 0 AND number = {elite}"
            ),
            format!("run 0 candidate {elite}"),
            "outcome",
        ),
        (
            "experiment",
            format!("UPDATE experiment SET definition = {bad_text}"),
            "experiment".to_string(),
            "definition",
        ),
    ];
    let path = |p: &Path| p.to_str().unwrap().to_string();
    for (name, sql, row, column) in cases {
        let damaged = corrupted(&db, name, &sql);
        let d = path(&damaged);
        for args in [
            vec!["verify", "--db", &d, "--sample", "0"],
            vec!["run", "--db", &d],
            vec!["export", "--db", &d],
            vec!["analyse", "--db", &d],
        ] {
            let out = run("strider-coordinator", &args);
            let err = String::from_utf8_lossy(&out.stderr);
            let all = format!("{}{err}", String::from_utf8_lossy(&out.stdout));
            assert_eq!(out.status.code(), Some(1), "{name}: {args:?}: {all}");
            // `verify` lists the damaged row among those that fail their checksums; the
            // others' errors name the column too.
            assert!(
                all.contains(&row),
                "{name}: {args:?} should name {row}: {all}"
            );
            assert!(
                args[0] == "verify" || err.contains(column),
                "{name}: {args:?} should name column {column}: {err}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The read commands write nothing: a `VACUUM INTO` backup (rollback journal, as SQLite
/// writes it) keeps every byte through verify, export, analyse and report, and gains no
/// log or index files (before: its journal mode was switched to WAL, changing its hash).
#[test]
fn read_commands_leave_a_backup_byte_for_byte_as_it_was() {
    let dir = temp_dir("verify-readonly");
    let db = dir.join("whole.db");
    finished_run(&db);
    let backup = dir.join("backup.db");
    sqlite(&db, &format!("VACUUM INTO '{}'", backup.display()));
    let before = std::fs::read(&backup).unwrap();
    let b = backup.to_str().unwrap();
    let out_dir = dir.join("report");
    for args in [
        vec!["verify", "--db", b, "--sample", "0"],
        vec!["export", "--db", b],
        vec!["analyse", "--db", b],
        vec!["report", "--db", b, "--out", out_dir.to_str().unwrap()],
    ] {
        run_ok("strider-coordinator", &args);
        assert!(
            std::fs::read(&backup).unwrap() == before,
            "{args:?} changed the backup"
        );
        for side in ["-wal", "-shm"] {
            let mut p = backup.as_os_str().to_owned();
            p.push(side);
            assert!(!Path::new(&p).exists(), "{args:?} left {side} beside it");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The main file emptied (truncated, or replaced by a new empty one) beside a log that
/// still holds frames: refused, and both left as they were, not started afresh.
#[test]
fn an_empty_database_beside_its_log_is_refused_not_started_again() {
    let dir = temp_dir("verify-empty");
    // Emptied, then deleted (before, a deleted database started afresh and its log was
    // deleted with the frames in it).
    for missing in [false, true] {
        let db = dir.join("lost.db");
        if missing {
            let _ = std::fs::remove_file(&db);
        } else {
            std::fs::write(&db, b"").unwrap();
        }
        let wal = dir.join("lost.db-wal");
        std::fs::write(&wal, vec![7u8; 8192]).unwrap();
        let out = run(
            "strider-coordinator",
            &["run", FIXTURE, "--db", db.to_str().unwrap()],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.contains("is missing or empty but its write-ahead log") && err.contains("restore"),
            "{err}"
        );
        if missing {
            assert!(!db.exists(), "a database was created beside the log");
        } else {
            assert_eq!(std::fs::metadata(&db).unwrap().len(), 0);
        }
        assert_eq!(std::fs::read(&wal).unwrap(), vec![7u8; 8192]);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
