//! A database made by the build before feasible-infeasible search (schema 0002, a run of
//! the paper's method killed at generation 2 of 6: `tests/fixtures/pre-0003.sql`, dumped
//! with `sqlite3 .dump`) opens with today's build: migration 0003 fills in every stored
//! candidate's shortfall, names the method the experiment was started with, and the run
//! resumes with it to the end.

use std::process::Command;
use strider_tests::{export, installed, run_ok, skip_without, temp_dir, workspace_root};

fn sql(db: &std::path::Path, query: &str) -> String {
    let out = Command::new("sqlite3")
        .arg(db)
        .arg(query)
        .output()
        .expect("sqlite3 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}

#[test]
fn a_database_made_before_migration_0003_resumes_with_the_method_it_began_with() {
    if !installed("sqlite3") {
        return skip_without("sqlite3 (apt-get install sqlite3)");
    }
    let dir = temp_dir("migration");
    let db = dir.join("old.db");
    let dump = workspace_root().join("tests/fixtures/pre-0003.sql");
    let loaded = Command::new("sqlite3")
        .arg(&db)
        .arg(format!(".read {}", dump.display()))
        .status()
        .unwrap();
    assert!(loaded.success());
    assert_eq!(sql(&db, "SELECT MAX(version) FROM _sqlx_migrations"), "2");
    let before = sql(&db, "SELECT COUNT(*) FROM candidates");
    assert_eq!(sql(&db, "SELECT generation, finished FROM runs"), "2|0");

    // Resumed without the experiment file: from the database alone.
    let out = run_ok(
        "strider-coordinator",
        &["run", "--db", db.to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("resuming experiment `pre-0003`"), "{err}");
    assert_eq!(sql(&db, "SELECT MAX(version) FROM _sqlx_migrations"), "3");
    assert_eq!(sql(&db, "SELECT generation, finished FROM runs"), "6|1");

    // The stored experiment says how it began: the paper's method.
    let definition = sql(&db, "SELECT definition FROM experiment");
    assert!(
        definition.contains("[search]") && definition.contains("constraints = \"reject\""),
        "{definition}"
    );
    // Candidates stored before the migration got their shortfall from their outcomes, and
    // the ones after it have one too: every simulated candidate that missed the brief.
    let missing = sql(
        &db,
        "SELECT COUNT(*) FROM candidates WHERE shortfall IS NULL AND kind <> 'valid' \
         AND json_type(outcome, '$.stats') = 'object'",
    );
    assert_eq!(missing, "0");
    assert!(
        sql(&db, "SELECT COUNT(*) FROM candidates")
            .parse::<u64>()
            .unwrap()
            > before.parse().unwrap()
    );
    // The paper's method keeps no infeasible library.
    assert_eq!(sql(&db, "SELECT COUNT(*) FROM infeasible_cells"), "0");
    let library = export(&db);
    let run = &library["runs"][0];
    assert_eq!(run["finished"], true);
    assert!(!run["elites"].as_array().unwrap().is_empty());
    assert!(run["infeasible"].as_array().unwrap().is_empty());
    assert_eq!(sql(&db, "PRAGMA integrity_check"), "ok");
    std::fs::remove_dir_all(&dir).unwrap();
}
