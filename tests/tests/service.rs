//! The distributed service over real sockets with the real binaries: `serve` and
//! `strider-worker --connect` processes, killed, stopped and restarted for real. Every
//! run must end in the library `run` builds on one machine.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Duration;
use strider_coordinator::db::Db;
use strider_tests::coordinator::{integrity, serve_command, start_serving};
use strider_tests::{
    assert_same_library, binary, export, free_port, library_run_builds, temp_dir, Process,
};

const FIXTURE: &str = "tests/fixtures/service.toml";
const SECRET: &str = "test-secret-0123456789abcdef";
/// Generous bounds: CI machines are slow and busy; a healthy run takes seconds.
const START: Duration = Duration::from_secs(60);
const FINISH: Duration = Duration::from_secs(300);

fn secret_file(dir: &Path) -> PathBuf {
    strider_tests::secret_file(dir, SECRET)
}

/// The library `run` builds on one machine (computed once per test process).
fn reference() -> &'static serde_json::Value {
    static REFERENCE: OnceLock<serde_json::Value> = OnceLock::new();
    REFERENCE.get_or_init(|| library_run_builds(FIXTURE))
}

/// Starts `serve` on 127.0.0.1:`port` (0: any) and waits until it listens; returns it
/// with the URL workers use.
fn serve(dir: &Path, db: &Path, port: u16, lease: &str) -> (Process, String) {
    serve_with(dir, db, port, lease, &[])
}

fn serve_with(dir: &Path, db: &Path, port: u16, lease: &str, extra: &[&str]) -> (Process, String) {
    let listen = format!("127.0.0.1:{port}");
    let mut cmd = serve_command(FIXTURE, db, &listen, &secret_file(dir));
    cmd.args(["--lease-seconds", lease, "--progress-every", "0.1"])
        .args(extra);
    start_serving(cmd)
}

fn worker(dir: &Path, url: &str, name: &str) -> Process {
    let mut cmd = Command::new(binary("strider-worker"));
    cmd.args(["--connect", url, "--threads", "1", "--name", name])
        .args(["--token-file", secret_file(dir).to_str().unwrap()])
        .args(["--max-backoff-seconds", "0.5", "--drain-seconds", "5"]);
    Process::spawn(name, cmd)
}

fn finish(coordinator: &mut Process) {
    let status = coordinator.wait_exit(FINISH);
    assert!(
        status.success(),
        "coordinator failed:\n{}",
        coordinator.log()
    );
}

#[test]
fn one_worker_and_three_workers_build_the_library_run_builds() {
    let expected = reference();
    for workers in [1, 3] {
        let dir = temp_dir(&format!("service-{workers}-workers"));
        let db = dir.join("served.db");
        let (mut coordinator, url) = serve(&dir, &db, 0, "60");
        let mut ws: Vec<Process> = (0..workers)
            .map(|i| worker(&dir, &url, &format!("worker-{i}")))
            .collect();
        finish(&mut coordinator);
        // Told that the experiment is finished, every worker exits by itself.
        for w in &mut ws {
            assert!(w.wait_exit(START).success(), "{}", w.log());
        }
        assert_same_library(&export(&db), expected);
        assert_eq!(integrity(&db), "ok");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn killed_stopped_and_terminated_workers_change_nothing() {
    let expected = reference();
    let dir = temp_dir("service-faults");
    let db = dir.join("faults.db");
    let (mut coordinator, url) = serve(&dir, &db, 0, "2");
    // The first worker connects, is leased candidates, and is stopped holding them.
    let stopped = worker(&dir, &url, "stopped");
    coordinator.wait_for_line(
        "for the first worker",
        |l| l.contains("worker connected"),
        START,
    );
    stopped.signal(libc::SIGSTOP);
    let killed = worker(&dir, &url, "killed");
    let mut terminated = worker(&dir, &url, "terminated");
    let mut steady = worker(&dir, &url, "steady");
    // Its leases run out and go to the others.
    coordinator.wait_for_line(
        "about expired leases",
        |l| l.contains("leases expired"),
        START,
    );
    coordinator.wait_for_line("at generation 3", |l| l.contains("generation 3/20"), FINISH);
    killed.signal(libc::SIGKILL);
    // The stopped worker wakes up and sends its stale results: they change nothing.
    stopped.signal(libc::SIGCONT);
    coordinator.wait_for_line("at generation 6", |l| l.contains("generation 6/20"), FINISH);
    // SIGTERM: the worker gives back or finishes what it holds and exits cleanly.
    terminated.signal(libc::SIGTERM);
    let status = terminated.wait_exit(Duration::from_secs(30));
    assert!(status.success(), "{}", terminated.log());
    assert!(
        terminated.log().contains("shutting down"),
        "{}",
        terminated.log()
    );
    finish(&mut coordinator);
    assert!(steady.wait_exit(START).success());
    // The stalled worker's late results were taken or ignored, never refused: it stayed
    // to the end and left when told the experiment was finished.
    let mut stopped = stopped;
    let status = stopped.wait_exit(START);
    assert!(status.success(), "{status:?}\n{}", stopped.log());
    drop(killed);
    assert_same_library(&export(&db), expected);
    assert_eq!(integrity(&db), "ok");
    // The worker that left on SIGTERM closed its stream cleanly (it waits for the
    // coordinator to close its side): no HTTP/2 error in the coordinator's record.
    assert_eq!(
        strider_tests::sqlite(
            &db,
            "SELECT left_because FROM workers WHERE name = 'terminated'"
        )
        .trim(),
        "the worker closed its stream"
    );
    // The killed worker's connection was lost, and its record says so.
    let killed_left = strider_tests::sqlite(
        &db,
        "SELECT left_because FROM workers WHERE name = 'killed'",
    );
    assert!(
        killed_left.starts_with("the connection was"),
        "{killed_left}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_coordinator_killed_and_restarted_resumes_and_its_workers_come_back() {
    let expected = reference();
    let dir = temp_dir("service-restart");
    let db = dir.join("restart.db");
    let port = free_port();
    let url = format!("http://127.0.0.1:{port}");
    // Workers first: they wait for the coordinator by themselves.
    let mut ws: Vec<Process> = (0..2)
        .map(|i| worker(&dir, &url, &format!("early-{i}")))
        .collect();
    for w in &ws {
        w.wait_for_line("retrying", |l| l.contains("retrying"), START);
    }
    for mark in ["generation 2/20", "generation 7/20"] {
        let (coordinator, _) = serve(&dir, &db, port, "60");
        coordinator.wait_for_line(mark, |l| l.contains(mark), FINISH);
        coordinator.signal(libc::SIGKILL);
        drop(coordinator);
        assert_eq!(integrity(&db), "ok", "after a kill at {mark}");
    }
    let (mut coordinator, _) = serve(&dir, &db, port, "60");
    finish(&mut coordinator);
    for w in &mut ws {
        assert!(w.wait_exit(START).success(), "{}", w.log());
    }
    // The sessions the killed coordinators left open were closed, with the reason.
    let open = strider_tests::sqlite(
        &db,
        "SELECT COUNT(*) FROM workers WHERE disconnected_at IS NULL OR left_because IS NULL",
    );
    assert_eq!(open.trim(), "0");
    let closed = strider_tests::sqlite(
        &db,
        "SELECT COUNT(*) FROM workers WHERE left_because LIKE 'the coordinator stopped first%'",
    );
    assert!(closed.trim().parse::<u32>().unwrap() >= 2, "{closed}");
    assert_same_library(&export(&db), expected);
    assert_eq!(integrity(&db), "ok");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_coordinator_stopped_a_while_says_so_and_its_workers_stay() {
    let expected = reference();
    let dir = temp_dir("service-stopped");
    let db = dir.join("stopped.db");
    let (mut coordinator, url) = serve(&dir, &db, 0, "60");
    let mut w = worker(&dir, &url, "patient");
    coordinator.wait_for_line("at generation 2", |l| l.contains("generation 2/20"), FINISH);
    // Stopped (an admin's SIGSTOP, a Slurm job suspended) for longer than its clock takes
    // for a stop, shorter than the workers' keepalive allows (20 s).
    let stop = Duration::from_secs(13);
    coordinator.signal(libc::SIGSTOP);
    std::thread::sleep(stop);
    coordinator.signal(libc::SIGCONT);
    let said = coordinator.wait_for_line(
        "the stop noticed",
        |l| l.contains("this process was stopped for"),
        START,
    );
    // Its rates and time left leave the stop out: it measured the whole of it.
    let seconds: f64 = said
        .split("stopped for ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no duration in {said:?}"));
    assert!(seconds >= stop.as_secs_f64() - 1.0, "{said}");
    finish(&mut coordinator);
    assert!(w.wait_exit(START).success(), "{}", w.log());
    // The worker's session outlived the stop: one session, left when the run finished.
    assert_eq!(
        strider_tests::sqlite(&db, "SELECT COUNT(*), MAX(left_because) FROM workers").trim(),
        "1|the experiment is finished"
    );
    assert_same_library(&export(&db), expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_worker_told_to_give_up_waits_while_its_coordinator_serves_and_exits_69_once_it_is_gone() {
    let dir = temp_dir("service-give-up");
    let db = dir.join("give-up.db");
    let (coordinator, url) = serve(&dir, &db, 0, "60");
    let mut cmd = Command::new(binary("strider-worker"));
    cmd.args(["--connect", &url, "--threads", "1", "--name", "patient"])
        .args(["--token-file", secret_file(&dir).to_str().unwrap()])
        .args(["--max-backoff-seconds", "0.2", "--give-up-after", "1"]);
    let mut w = Process::spawn("patient", cmd);
    w.wait_for_line("connected", |l| l.contains("connected to"), START);
    // Served for longer than the limit: the limit counts only time without a coordinator.
    coordinator.wait_for_line("generation 3", |l| l.contains("generation 3/20"), FINISH);
    assert!(w.exited().is_none(), "gave up while served:\n{}", w.log());
    coordinator.signal(libc::SIGKILL);
    drop(coordinator);
    let status = w.wait_exit(START);
    assert_eq!(status.code(), Some(69), "{}", w.log());
    assert!(w.log().contains("giving up"), "{}", w.log());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn worker_and_coordinator_refuse_the_same_weak_secret_the_same_way() {
    let dir = temp_dir("service-weak-secret");
    let weak = dir.join("weak");
    std::fs::write(&weak, "short secret\n").unwrap();
    let worker = Command::new(binary("strider-worker"))
        .args(["--connect", "http://127.0.0.1:9", "--token-file"])
        .arg(&weak)
        .output()
        .unwrap();
    let serve = Command::new(binary("strider-coordinator"))
        .args(["serve", "--db"])
        .arg(dir.join("never.db"))
        .args([
            "--experiment",
            FIXTURE,
            "--listen",
            "127.0.0.1:0",
            "--token-file",
        ])
        .arg(&weak)
        .output()
        .unwrap();
    for out in [&worker, &serve] {
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("at least 16 characters"), "{err}");
    }
    assert!(!dir.join("never.db").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_benchmark_worker_finishes_a_run_with_made_up_results() {
    let dir = temp_dir("service-instant");
    let db = dir.join("instant.db");
    let (mut coordinator, url) = serve(&dir, &db, 0, "60");
    let mut cmd = Command::new(binary("strider-worker"));
    cmd.args(["--connect", &url, "--threads", "2", "--name", "bench"])
        .args(["--token-file", secret_file(&dir).to_str().unwrap()])
        .arg("--benchmark-instant-results");
    let mut w = Process::spawn("bench", cmd);
    finish(&mut coordinator);
    assert!(w.wait_exit(START).success(), "{}", w.log());
    let unfinished = strider_tests::sqlite(&db, "SELECT COUNT(*) FROM runs WHERE NOT finished");
    assert_eq!(unfinished.trim(), "0");
    // The one worker session sent results (the rest were settled by the prechecks).
    let sent = strider_tests::sqlite(&db, "SELECT results FROM workers");
    assert!(sent.trim().parse::<u64>().unwrap() > 0, "{sent}");
    assert_eq!(integrity(&db), "ok");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn two_workers_with_more_slots_than_a_generation_both_work_through_one_run() {
    // One run, generations of 60, and two workers of 32 threads: each keeps 64 candidates
    // in hand. Whichever asked first could lease every generation whole (with release
    // builds, 20,268 results against 0, BENCHMARKS.md; who asks first is a race, which
    // these debug builds do not always lose the same way). Now each is leased its share
    // of a scarce step (Scheduler::lease_cap, tested in coordinator/tests/scheduler.rs):
    // here, that the run ends with both working, neither starved by the other's share.
    let dir = temp_dir("service-share");
    let db = dir.join("share.db");
    let experiment = dir.join("one-run.toml");
    std::fs::write(
        &experiment,
        "name = \"one-run\"\nschemes = [\"static\"]\nrepeats = 1\nseed = 3\n\
         [run]\nphysics_substeps = 2\ninitial_population = 6\n\
         offspring_per_generation = 60\ngenerations = 60\n",
    )
    .unwrap();
    let mut cmd = serve_command(
        experiment.to_str().unwrap(),
        &db,
        "127.0.0.1:0",
        &secret_file(&dir),
    );
    cmd.args(["--progress-every", "1"]);
    let (mut coordinator, url) = start_serving(cmd);
    let mut workers: Vec<Process> = ["a", "b"]
        .into_iter()
        .map(|name| {
            let mut cmd = Command::new(binary("strider-worker"));
            cmd.args(["--connect", &url, "--threads", "32", "--name", name])
                .args(["--token-file", secret_file(&dir).to_str().unwrap()])
                .arg("--benchmark-instant-results");
            Process::spawn(name, cmd)
        })
        .collect();
    finish(&mut coordinator);
    for w in &mut workers {
        assert!(w.wait_exit(START).success(), "{}", w.log());
    }
    let rows = strider_tests::sqlite(
        &db,
        "SELECT name, SUM(results) FROM workers GROUP BY name ORDER BY name",
    );
    let results: Vec<u64> = rows
        .lines()
        .map(|l| l.split('|').nth(1).unwrap().parse().unwrap())
        .collect();
    assert_eq!(results.len(), 2, "{rows}");
    let total: u64 = results.iter().sum();
    // Even halves but for the generations one worker ran before the other connected.
    println!("results per worker:\n{rows}");
    for r in &results {
        assert!(4 * r >= total, "results per worker:\n{rows}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `GET path` over plain HTTP; the whole response.
fn http_get(addr: &str, path: &str) -> String {
    use std::io::{Read, Write};
    let mut c = std::net::TcpStream::connect(addr).unwrap();
    c.set_read_timeout(Some(START)).unwrap();
    write!(c, "GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut out = String::new();
    c.read_to_string(&mut out).unwrap();
    out
}

#[test]
fn a_coordinator_out_of_time_stops_leasing_exits_cleanly_and_the_next_one_finishes_the_run() {
    let expected = reference();
    let dir = temp_dir("service-out-of-time");
    let db = dir.join("batch.db");
    let (mut coordinator, url) = serve_with(
        &dir,
        &db,
        0,
        "60",
        &[
            "--stop-leasing-after",
            "1",
            "--metrics",
            "127.0.0.1:0",
            "--backup",
            dir.join("copy.db").to_str().unwrap(),
        ],
    );
    let metrics = coordinator
        .wait_for_line(
            "naming the metrics address",
            |l| l.contains("metrics on"),
            START,
        )
        .rsplit("http://")
        .next()
        .unwrap()
        .trim_end_matches("/metrics")
        .trim()
        .to_string();
    // The worker is stopped holding its candidates, so the run cannot end by itself.
    let worker1 = worker(&dir, &url, "first-job");
    coordinator.wait_for_line("for the worker", |l| l.contains("worker connected"), START);
    worker1.signal(libc::SIGSTOP);
    coordinator.wait_for_line(
        "that it stopped leasing",
        |l| l.contains("stopped leasing"),
        START,
    );
    // Prometheus sees every run (the coordinator waits for the stopped worker's leases).
    let page = http_get(&metrics, "/metrics");
    assert!(page.starts_with("HTTP/1.1 200 OK"), "{page}");
    for run in 0..2 {
        let sample =
            format!("strider_run_generation{{run=\"{run}\",scheme=\"static\",repeat=\"{run}\"}} ");
        assert!(page.contains(&sample), "no {sample:?} in\n{page}");
    }
    // Every counter is named as Prometheus expects, with `_total`.
    let counters: Vec<&str> = page
        .lines()
        .filter_map(|l| l.strip_prefix("# TYPE ")?.strip_suffix(" counter"))
        .collect();
    assert!(counters.contains(&"strider_results_total"), "{page}");
    assert!(
        counters.iter().all(|c| c.ends_with("_total")),
        "{counters:?}"
    );
    assert!(page.contains("strider_workers_connected 1"), "{page}");
    assert!(http_get(&metrics, "/other").starts_with("HTTP/1.1 404"));
    // The worker wakes and hands in what it held; then the coordinator exits by itself.
    worker1.signal(libc::SIGCONT);
    let status = coordinator.wait_exit(FINISH);
    // 75 (EX_TEMPFAIL) says "not finished: serve again", for batch scripts.
    assert_eq!(status.code(), Some(75), "{}", coordinator.log());
    assert!(
        coordinator.log().contains("every lease is back"),
        "{}",
        coordinator.log()
    );
    drop(worker1);
    let unfinished = tokio::runtime::Runtime::new().unwrap().block_on(async {
        let runs = Db::open(&db, false).await.unwrap().runs().await.unwrap();
        runs.iter().filter(|r| !r.finished).count()
    });
    assert!(unfinished > 0, "the first job should have been cut short");
    assert_eq!(integrity(&db), "ok");
    // The copy written on the way out is the whole database as the job left it.
    let copy = dir.join("copy.db");
    assert_eq!(integrity(&copy), "ok");
    assert_eq!(export(&copy), export(&db));
    // The next job resumes from the database and ends where one uninterrupted run does.
    let (mut coordinator, url) = serve(&dir, &db, 0, "60");
    let mut worker2 = worker(&dir, &url, "second-job");
    finish(&mut coordinator);
    assert!(worker2.wait_exit(START).success(), "{}", worker2.log());
    assert_same_library(&export(&db), expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_second_coordinator_on_the_same_database_is_refused_naming_the_first() {
    let dir = temp_dir("service-lock");
    let db = dir.join("locked.db");
    let (mut first, _) = serve(&dir, &db, 0, "60");
    let secret = secret_file(&dir);
    let (db_arg, secret_arg) = (db.to_str().unwrap(), secret.to_str().unwrap());
    let second_serve = [
        "serve",
        "--db",
        db_arg,
        "--experiment",
        FIXTURE,
        "--listen",
        "127.0.0.1:0",
        "--token-file",
        secret_arg,
    ];
    let second_run = ["run", FIXTURE, "--db", db_arg];
    for args in [&second_serve[..], &second_run[..]] {
        let out = Command::new(binary("strider-coordinator"))
            .args(args)
            .current_dir(strider_tests::workspace_root())
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("is in use by another coordinator")
                && err.contains(&format!("pid {}", first.pid())),
            "{args:?}: {err}"
        );
    }
    // The rule is for the file, not the name (before, both of these started a second
    // writer: the hard link's own log then shrank the database to a quarter, unreadable).
    let symlink = dir.join("symlink.db");
    std::os::unix::fs::symlink(&db, &symlink).unwrap();
    let hard = dir.join("hard.db");
    for (name, wanted) in [
        (&symlink, format!("pid {}", first.pid())),
        (&hard, "has 2 names (hard links)".to_string()),
    ] {
        if name == &hard {
            std::fs::hard_link(&db, &hard).unwrap();
        }
        let out = Command::new(binary("strider-coordinator"))
            .args(["run", FIXTURE, "--db", name.to_str().unwrap()])
            .current_dir(strider_tests::workspace_root())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name:?}: {err}");
        assert!(err.contains(&wanted), "{name:?}: {err}");
    }
    let mut log_of_the_link = hard.as_os_str().to_owned();
    log_of_the_link.push("-wal");
    assert!(
        !Path::new(&log_of_the_link).exists(),
        "the refused open left a log beside the link"
    );
    std::fs::remove_file(&hard).unwrap();
    // The first goes on undisturbed, and stops cleanly.
    first.signal(libc::SIGTERM);
    assert!(first.wait_exit(FINISH).success(), "{}", first.log());
    assert_eq!(integrity(&db), "ok");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn after_a_clean_stop_the_database_file_alone_is_whole() {
    let dir = temp_dir("service-clean-exit");
    let db = dir.join("clean.db");
    let (mut coordinator, url) = serve(&dir, &db, 0, "60");
    let w = worker(&dir, &url, "w");
    coordinator.wait_for_line("generation 3", |l| l.contains("generation 3/20"), FINISH);
    coordinator.signal(libc::SIGTERM);
    assert!(
        coordinator.wait_exit(FINISH).success(),
        "{}",
        coordinator.log()
    );
    drop(w);
    // Every worker session is closed, with a reason.
    let open = strider_tests::sqlite(
        &db,
        "SELECT COUNT(*) FROM workers WHERE disconnected_at IS NULL OR left_because IS NULL",
    );
    assert_eq!(open.trim(), "0");
    // The log was copied in and emptied: the .db alone, copied elsewhere, is the database.
    let wal = dir.join("clean.db-wal");
    assert!(
        !wal.exists() || std::fs::metadata(&wal).unwrap().len() == 0,
        "a clean exit leaves no write-ahead log to replay"
    );
    let copy_dir = dir.join("copy");
    std::fs::create_dir_all(&copy_dir).unwrap();
    let copy = copy_dir.join("clean.db");
    std::fs::copy(&db, &copy).unwrap();
    assert_eq!(integrity(&copy), "ok");
    assert_same_library(&export(&copy), &export(&db));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_backup_that_fails_at_exit_warns_and_the_run_stands() {
    let dir = temp_dir("service-backup-fails");
    let db = dir.join("live.db");
    // The copy's directory does not exist: every copy fails.
    let backup = dir.join("missing-directory").join("copy.db");
    let (mut coordinator, url) = serve_with(
        &dir,
        &db,
        0,
        "60",
        &[
            "--backup",
            backup.to_str().unwrap(),
            "--backup-every",
            "3600",
        ],
    );
    let w = worker(&dir, &url, "w");
    coordinator.wait_for_line("generation 2", |l| l.contains("generation 2/20"), FINISH);
    coordinator.signal(libc::SIGTERM);
    let status = coordinator.wait_exit(FINISH);
    drop(w);
    assert!(
        status.success(),
        "a failed copy must not fail the run: {}",
        coordinator.log()
    );
    let log = coordinator.log();
    assert!(
        log.contains(&backup.display().to_string()) && log.contains("complete and committed"),
        "{log}"
    );
    assert!(!dir.join("missing-directory").exists());
    // Serving again resumes and finishes: the failure was not a reason to stop.
    let (mut again, url) = serve_with(
        &dir,
        &db,
        0,
        "60",
        &[
            "--backup",
            backup.to_str().unwrap(),
            "--backup-every",
            "3600",
        ],
    );
    let w = worker(&dir, &url, "w2");
    assert!(again.wait_exit(FINISH).success(), "{}", again.log());
    drop(w);
    let library = export(&db);
    assert!(library["runs"]
        .as_array()
        .unwrap()
        .iter()
        .all(|r| r["finished"] == true));
    std::fs::remove_dir_all(&dir).unwrap();
}
