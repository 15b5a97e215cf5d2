//! Databases made by older builds open with today's build and resume as they began:
//! before feasible-infeasible search (schema 0002, a run of the paper's method killed at
//! generation 2 of 6: `tests/fixtures/pre-0003.sql`, dumped with `sqlite3 .dump`),
//! migration 0003 fills in every stored candidate's shortfall and names the method the
//! experiment was started with; before infeasible tournaments (schema 0003, killed at
//! generation 3 of 10: `tests/fixtures/pre-0004.sql`), migrations 0004 and 0005 name the
//! uniform selection it drew infeasible parents with and the tilt limit it checked after
//! the trial.

use std::process::Command;
use strider_tests::{export, installed, run_ok, skip_without, temp_dir, workspace_root};

fn load(dump: &str, dir: &std::path::Path) -> std::path::PathBuf {
    let db = dir.join("old.db");
    let dump = workspace_root().join("tests/fixtures").join(dump);
    let loaded = Command::new("sqlite3")
        .arg(&db)
        .arg(format!(".read {}", dump.display()))
        .status()
        .unwrap();
    assert!(loaded.success());
    db
}

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
    let dir = temp_dir("migration-0003");
    let db = load("pre-0003.sql", &dir);
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
    assert_eq!(sql(&db, "SELECT MAX(version) FROM _sqlx_migrations"), "13");
    assert_eq!(sql(&db, "SELECT generation, finished FROM runs"), "6|1");
    // Both tables that name shortfalls take the one of migration 0012.
    assert_eq!(
        sql(
            &db,
            "SELECT COUNT(*) FROM sqlite_master WHERE name IN ('candidates', 'infeasible_cells') AND sql LIKE '%''friction_sensitive''%'"
        ),
        "2"
    );
    // Its experiment row, stored before rows had checksums, was given one (migration 0011).
    assert_eq!(sql(&db, "SELECT checksum IS NOT NULL FROM experiment"), "1");

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

#[test]
fn a_database_made_before_migration_0004_resumes_with_uniform_infeasible_parents() {
    if !installed("sqlite3") {
        return skip_without("sqlite3 (apt-get install sqlite3)");
    }
    let dir = temp_dir("migration-0004");
    let db = load("pre-0004.sql", &dir);
    assert_eq!(sql(&db, "SELECT MAX(version) FROM _sqlx_migrations"), "3");
    assert_eq!(sql(&db, "SELECT generation, finished FROM runs"), "3|0");
    assert!(!sql(&db, "SELECT definition FROM experiment").contains("infeasible_tournament"));

    let out = run_ok(
        "strider-coordinator",
        &["run", "--db", db.to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("resuming experiment `pre-0004`"), "{err}");
    assert_eq!(sql(&db, "SELECT MAX(version) FROM _sqlx_migrations"), "13");
    assert_eq!(sql(&db, "SELECT generation, finished FROM runs"), "10|1");
    let definition = sql(&db, "SELECT definition FROM experiment");
    assert!(
        definition.contains("[search]\ninfeasible_tournament = 1\n"),
        "{definition}"
    );
    // Made before the friction margin's floors and the shove were the defaults, it says
    // it had none (0013), and the tilt limit it checked (0005).
    assert!(
        definition.contains(
            "[trial]\npush_speed = 0.0\nfriction_margin = 0.0\nupright_after_max_tilt_degrees = 180.0\n"
        ),
        "{definition}"
    );

    // It goes on exactly as a copy whose stored experiment says `infeasible_tournament = 1`
    // itself, and not as one that says today's default (4). (Comparing with the experiment
    // run whole no longer works: the fixture's first generations were simulated by an
    // older model of the joint drives, docs/model.md section 6.)
    let resume_copy = |name: &str, tournament: u32| {
        let copy_dir = dir.join(name);
        std::fs::create_dir_all(&copy_dir).unwrap();
        let copy = load("pre-0004.sql", &copy_dir);
        let q = format!(
            "UPDATE experiment SET definition = replace(definition, '[search]' || char(10), \
             '[search]' || char(10) || 'infeasible_tournament = {tournament}' || char(10))"
        );
        sql(&copy, &q);
        run_ok(
            "strider-coordinator",
            &["run", "--db", copy.to_str().unwrap()],
        );
        copy
    };
    let said_one = resume_copy("one", 1);
    let said_four = resume_copy("four", 4);
    let libraries = |db: &std::path::Path| {
        let run = &export(db)["runs"][0];
        (run["elites"].clone(), run["infeasible"].clone())
    };
    let resumed = libraries(&db);
    assert_eq!(resumed, libraries(&said_one));
    assert_ne!(resumed, libraries(&said_four));
    assert_eq!(sql(&db, "PRAGMA integrity_check"), "ok");
    std::fs::remove_dir_all(&dir).unwrap();
}
