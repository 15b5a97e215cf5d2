//! One flipped bit anywhere in a database (issue 27): 224 seeded flips, 14 in each table
//! and index of a run stopped in the middle (so that the step in flight, the `pending`
//! table, has rows too), each in its own copy. Every copy is either refused by `verify`
//! with an error naming what is damaged, or provably harmless: every table the search and
//! the user read holds what the undamaged file holds (so a resume reads what it would have
//! read), and the first such copy of each table, resumed to its end, gives the reference
//! library. No command panics on any copy; none gives a different library silently.
//! (The stopped file differs with the moment of the kill, so the flips land on different
//! rows from one run of the test to the next; what each must come to is the same.)

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use strider_tests::{binary, export, first_difference, run, sqlite, temp_dir, workspace_root};

const TINY: &str = "tests/fixtures/tiny.toml";

/// Flips per table or index (16 of them: 224 in all).
const FLIPS_PER_TABLE: usize = 14;

/// What a flip came to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Fate {
    /// `verify` refused the copy, naming the damaged row (table and key).
    RefusedRow,
    /// `verify` refused it through SQLite, which names the page or the b-tree (damage
    /// to the file's structure, below any row).
    RefusedFile,
    /// Nothing the search or a user reads changed, and the copy resumed to the
    /// reference library.
    Harmless,
    /// Some command ended other than with 0 or 1.
    Panic,
    /// `verify` passed, yet something read differs, or the resumed library does.
    Diverged,
}

/// What the search and a user read, table by table (the workers table is a log of
/// connections: informational, read by nothing that decides).
const READ_TABLES: [&str; 7] = [
    "SELECT * FROM experiment",
    "SELECT * FROM runs ORDER BY id",
    "SELECT * FROM candidates ORDER BY run_id, number",
    "SELECT * FROM cells ORDER BY run_id, cell",
    "SELECT * FROM infeasible_cells ORDER BY run_id, cell",
    "SELECT * FROM generations ORDER BY run_id, generation",
    "SELECT * FROM pending ORDER BY run_id, number",
];

/// Every read table's rows, or None when the sqlite3 shell cannot read them.
fn contents(db: &Path) -> Option<Vec<String>> {
    READ_TABLES
        .iter()
        .map(|q| {
            let out = Command::new("sqlite3").arg(db).arg(q).output().ok()?;
            out.status
                .success()
                .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
        })
        .collect()
}

/// Runs the tiny experiment into `db` and kills the coordinator (SIGKILL) at the first
/// progress line after generation 5 at which the step in flight has rows stored. The run
/// can commit that step between the look and the kill, leaving `pending` empty (every
/// flip there harmless, so the test could not tell a refusal from nothing): then it is
/// run again from scratch, a few times at most.
fn stopped_run(db: &Path) {
    for _ in 0..5 {
        for suffix in ["", "-wal", "-shm"] {
            let _ = std::fs::remove_file(format!("{}{suffix}", db.display()));
        }
        stop_run_once(db);
        if sqlite(db, "SELECT COUNT(*) FROM pending").trim() != "0" {
            return;
        }
    }
    panic!("five killed runs all committed their step in flight before the kill");
}

/// One try of [`stopped_run`].
fn stop_run_once(db: &Path) {
    let mut child = Command::new(binary("strider-coordinator"))
        .args(["run", TINY, "--db", db.to_str().unwrap(), "--workers", "2"])
        .args(["--progress-every", "0.05"])
        .current_dir(workspace_root())
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let mut past = false;
    let mut stopped = false;
    for line in stderr.lines() {
        let line = line.unwrap();
        past |= line.contains("generation 5/12");
        if past && sqlite(db, "SELECT COUNT(*) FROM pending").trim() != "0" {
            stopped = true;
            break;
        }
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(stopped, "the run ended before a step in flight was stored");
    // Everything into the main file, so that the flips reach every row.
    sqlite(db, "PRAGMA wal_checkpoint(TRUNCATE)");
}

/// Whether a refusal names what is damaged: a row (its table and key) or, for damage
/// below the rows, SQLite's own finding.
fn fate_of_refusal(out: &str) -> Option<Fate> {
    let names_row = out.contains("table ")
        || out.contains(" candidate ")
        || out.contains(" generation ")
        || out.contains("run ") && out.contains("seed")
        || out.contains("the experiment")
        || out.contains("migration ");
    // SQLite's own refusals: its integrity check, or a query the damaged schema breaks.
    let sqlite_says = out.contains("error returned from database")
        || out.contains("malformed")
        || out.contains("integrity check")
        || out.contains("not a database")
        || out.contains("corrupt");
    if names_row {
        Some(Fate::RefusedRow)
    } else if sqlite_says {
        Some(Fate::RefusedFile)
    } else {
        None
    }
}

fn output(out: &std::process::Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Exit code of a finished command: 101 for a panic, -1 for a signal.
fn code(out: &std::process::Output) -> i32 {
    out.status.code().unwrap_or(-1)
}

#[test]
fn every_flipped_bit_in_every_table_is_refused_naming_it_or_changes_nothing() {
    let dir = temp_dir("byte-flips");
    let reference = dir.join("reference.db");
    strider_tests::run_ok(
        "strider-coordinator",
        &["run", TINY, "--db", reference.to_str().unwrap()],
    );
    let want_library = export(&reference);
    let db = dir.join("stopped.db");
    stopped_run(&db);
    let whole = std::fs::read(&db).unwrap();
    let want = contents(&db).expect("the undamaged copy reads");
    let page_size: usize = sqlite(&db, "PRAGMA page_size").trim().parse().unwrap();
    // Every table and index (sqlite_schema included) with its pages.
    let mut pages: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for line in sqlite(&db, "SELECT name, pageno FROM dbstat ORDER BY name, pageno").lines() {
        let (name, page) = line.rsplit_once('|').unwrap();
        pages
            .entry(name.to_string())
            .or_default()
            .push(page.parse().unwrap());
    }
    for table in [
        "experiment",
        "runs",
        "candidates",
        "cells",
        "infeasible_cells",
        "generations",
        "pending",
        "workers",
    ] {
        assert!(pages.contains_key(table), "no pages for {table}: {pages:?}");
    }
    assert!(pages.len() >= 16, "{} tables and indexes", pages.len());

    // A seeded generator (64-bit LCG, Knuth's MMIX constants): the same flips every run.
    let mut state: u64 = 27;
    let mut next = move |below: usize| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 33) as usize) % below
    };
    // Most of a small table's page is free space, where a flip is harmless by
    // construction: so 10 of each table's flips land in its pages' cell content areas
    // (the rows themselves), the other 4 anywhere in a page (headers, cell pointers).
    let mut flips: Vec<(String, usize, u8)> = Vec::new();
    for (name, p) in &pages {
        for k in 0..FLIPS_PER_TABLE {
            let page = p[next(p.len())];
            let base = (page - 1) * page_size;
            // The b-tree page header (after the file header on page 1): bytes 5-6 are
            // where the cell content area starts (0 meaning 65536).
            let header = base + if page == 1 { 100 } else { 0 };
            let content = match u16::from_be_bytes([whole[header + 5], whole[header + 6]]) {
                0 => 65536,
                c => usize::from(c),
            }
            .min(page_size - 1);
            let offset = if k < 10 {
                content + next(page_size - content)
            } else {
                next(page_size)
            };
            flips.push((name.clone(), base + offset, 1 << next(8)));
        }
    }

    let mut table: BTreeMap<String, BTreeMap<Fate, usize>> = BTreeMap::new();
    let mut failures: Vec<String> = Vec::new();
    let mut resumed_tables: Vec<String> = Vec::new();
    for (i, (name, at, bit)) in flips.iter().enumerate() {
        let mut bytes = whole.clone();
        bytes[*at] ^= bit;
        let copy = dir.join(format!("flip-{i}.db"));
        std::fs::write(&copy, &bytes).unwrap();
        let c = copy.to_str().unwrap();
        let what = format!("flip {i} ({name}, byte {at}, bit {bit:#04x})");
        let verified = run(
            "strider-coordinator",
            &["verify", "--db", c, "--sample", "0"],
        );
        let exported = run("strider-coordinator", &["export", "--db", c]);
        let fate = if [code(&verified), code(&exported)]
            .iter()
            .any(|c| *c != 0 && *c != 1)
        {
            failures.push(format!(
                "{what}: a panic: {}{}",
                output(&verified),
                output(&exported)
            ));
            Fate::Panic
        } else if code(&verified) == 1 {
            let out = output(&verified);
            fate_of_refusal(&out).unwrap_or_else(|| {
                failures.push(format!("{what}: refused without naming where: {out}"));
                Fate::Diverged
            })
        } else if contents(&copy).as_ref() != Some(&want) {
            failures.push(format!(
                "{what}: verify passed, yet a table reads otherwise"
            ));
            Fate::Diverged
        } else if resumed_tables.contains(name) {
            // Every table reads as before: the resume reads what it read (shown once per
            // table below, by resuming).
            Fate::Harmless
        } else {
            resumed_tables.push(name.clone());
            // Resumed to its end (a refusal here is fine: a clear error, nothing changed).
            let resumed = run("strider-coordinator", &["run", "--db", c]);
            match code(&resumed) {
                0 => {
                    if let Some(d) = first_difference(&export(&copy), &want_library, "") {
                        failures.push(format!("{what}: resumed to another library: {d}"));
                        Fate::Diverged
                    } else {
                        Fate::Harmless
                    }
                }
                // Refused at the resume: a clear error (a damaged migration record is
                // what sqlx checks when it opens a file to write).
                1 => {
                    let out = output(&resumed);
                    eprintln!("{what}: verify passed, the resume refused: {out}");
                    fate_of_refusal(&out).unwrap_or(Fate::RefusedFile)
                }
                _ => {
                    failures.push(format!("{what}: the resume: {}", output(&resumed)));
                    Fate::Panic
                }
            }
        };
        *table
            .entry(name.clone())
            .or_default()
            .entry(fate)
            .or_default() += 1;
        for side in ["", "-wal", "-shm", ".lock"] {
            let _ = std::fs::remove_file(format!("{c}{side}"));
        }
    }

    // The table the issue asks for: flips per table -> refused / harmless / panic /
    // diverged.
    eprintln!(
        "{:<36} {:>5} {:>12} {:>13} {:>8} {:>5} {:>8}",
        "table or index", "flips", "refused: row", "refused: file", "harmless", "panic", "diverged"
    );
    let mut totals = [0usize; 5];
    for (name, fates) in &table {
        let n = |f: Fate| fates.get(&f).copied().unwrap_or(0);
        let row = [
            n(Fate::RefusedRow),
            n(Fate::RefusedFile),
            n(Fate::Harmless),
            n(Fate::Panic),
            n(Fate::Diverged),
        ];
        for (t, v) in totals.iter_mut().zip(row) {
            *t += v;
        }
        eprintln!(
            "{:<36} {:>5} {:>12} {:>13} {:>8} {:>5} {:>8}",
            name,
            row.iter().sum::<usize>(),
            row[0],
            row[1],
            row[2],
            row[3],
            row[4]
        );
    }
    eprintln!(
        "{:<36} {:>5} {:>12} {:>13} {:>8} {:>5} {:>8}",
        "all",
        flips.len(),
        totals[0],
        totals[1],
        totals[2],
        totals[3],
        totals[4]
    );
    assert!(flips.len() >= 200);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // A test that nothing reaches proves nothing: flips must have been refused in the
    // tables that hold rows.
    for t in ["candidates", "generations", "pending", "runs", "cells"] {
        assert!(
            table[t].get(&Fate::RefusedRow).copied().unwrap_or(0) > 0,
            "no flip in {t} was refused naming its row: {:?}",
            table[t]
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
