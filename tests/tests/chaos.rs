//! A run through a storm of failures ends exactly as `run` ends it (issue 14): on one
//! served run, a seeded schedule of at least 10 coordinator SIGKILLs (each followed by a
//! restart on the same database) and 20 worker events (SIGKILL, SIGTERM, SIGSTOP past the
//! lease then SIGCONT, a client that takes 64 leases and drops its stream) at random
//! times, and 12 faults of issue 27's list among them: a second coordinator on the live
//! database through another name (symbolic link, hard link) or the same one, a session
//! that sends a NaN fitness (refused, the session goes on), a wrong secret, a worker given
//! a secret with a control character, read commands on the live file. At the end every
//! candidate row (outcomes and placements included), the library and every generation's
//! statistics equal `run`'s, and no candidate failed for want of a worker.

use std::path::Path;
use std::process::Command;
use std::time::Duration;
use strider_proto::v1::{self, worker_message, worker_service_client::WorkerServiceClient};
use strider_tests::coordinator::{serve_command, start_serving};
use strider_tests::{
    assert_same_library, binary, candidate_rows, export, free_port, run_builds, temp_dir, Process,
};

const FIXTURE: &str = "tests/fixtures/chaos.toml";
const SECRET: &str = "chaos-secret-0123456789abcdef";
/// Generous bounds: CI machines are slow and busy.
const START: Duration = Duration::from_secs(60);
const FINISH: Duration = Duration::from_secs(600);
const COORDINATOR_KILLS: usize = 10;
const WORKER_EVENTS: usize = 20;
const WORKERS: usize = 3;
const FAULTS: usize = 12;

/// An event of the schedule.
#[derive(Clone, Copy, Debug)]
enum Event {
    CoordinatorKill,
    Worker,
    /// One of issue 27's list, drawn when it comes.
    Fault,
}

/// splitmix64: the schedule's generator, seeded, so a failing schedule can be replayed.
struct Schedule(u64);

impl Schedule {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }

    /// A pause before the next event: 20 to 220 ms.
    fn pause(&mut self) -> Duration {
        Duration::from_millis(20 + self.below(200))
    }
}

fn serve(dir: &Path, db: &Path, port: u16) -> Process {
    let listen = format!("127.0.0.1:{port}");
    let secret = strider_tests::secret_file(dir, SECRET);
    let mut cmd = serve_command(FIXTURE, db, &listen, &secret);
    cmd.args(["--lease-seconds", "1", "--progress-every", "0.5"])
        // Events come 20 to 220 ms apart, shorter than a trial here, so the schedule can kill
        // or stall the worker simulating one candidate, then the next that takes it, and so
        // on: by the attempt rule (distinct workers dying while simulating it) that candidate
        // rightly fails after --max-attempts (seen in CI: SIGKILL, SIGKILL, SIGSTOP in a row).
        // Above the number of worker events no candidate can; the rule itself is tested in
        // the scheduler's and the service's tests. Here the point is that faults change
        // nothing else.
        .args(["--max-attempts", &(WORKER_EVENTS + 1).to_string()]);
    start_serving(cmd).0
}

fn worker(dir: &Path, url: &str, name: &str) -> Process {
    let mut cmd = Command::new(binary("strider-worker"));
    cmd.args(["--connect", url, "--threads", "1", "--name", name])
        .args([
            "--token-file",
            strider_tests::secret_file(dir, SECRET).to_str().unwrap(),
        ])
        .args(["--max-backoff-seconds", "0.3", "--drain-seconds", "2"]);
    Process::spawn(name, cmd)
}

/// A client that says Hello with 64 slots, takes what it is leased (for up to a second)
/// and drops its stream without a word. Returns how many leases it took.
fn lease_and_drop(rt: &tokio::runtime::Runtime, url: &str) -> usize {
    rt.block_on(async {
        let Ok(mut client) = WorkerServiceClient::connect(url.to_string()).await else {
            return 0; // the coordinator is restarting
        };
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        tx.send(v1::WorkerMessage {
            kind: Some(worker_message::Kind::Hello(v1::Hello {
                protocol_version: strider_proto::PROTOCOL_VERSION,
                worker_name: "lease-and-drop".into(),
                slots: 64,
                build: strider_common::build_id(),
                replaces: 0,
                reference_trial: strider_worker::reference_trial::digest(),
            })),
        })
        .await
        .unwrap();
        let mut request = tonic::Request::new(tokio_stream::wrappers::ReceiverStream::new(rx));
        request
            .metadata_mut()
            .insert("authorization", format!("Bearer {SECRET}").parse().unwrap());
        let Ok(response) = client.work(request).await else {
            return 0;
        };
        let mut inbound = response.into_inner();
        let mut taken = 0;
        let until = tokio::time::Instant::now() + Duration::from_secs(1);
        while taken < 64 {
            match tokio::time::timeout_at(until, inbound.message()).await {
                Ok(Ok(Some(m))) => {
                    if matches!(m.kind, Some(v1::coordinator_message::Kind::Assignment(_))) {
                        taken += 1;
                    }
                }
                _ => break,
            }
        }
        drop(tx);
        taken
    })
}

/// One fault of issue 27's list, drawn from the schedule, against the live coordinator
/// (pid `live`): each must be refused with a clear error, or read without writing, and
/// change nothing. Returns what it did.
fn fault(
    schedule: &mut Schedule,
    rt: &tokio::runtime::Runtime,
    dir: &Path,
    db: &Path,
    url: &str,
    live: u32,
) -> String {
    let coordinator = |args: &[&str]| {
        Command::new(binary("strider-coordinator"))
            .args(args)
            .current_dir(strider_tests::workspace_root())
            .output()
            .unwrap()
    };
    let refused_with = |out: &std::process::Output, what: &str, wanted: &str| {
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{what}: {err}");
        assert!(err.contains(wanted), "{what}: {err}");
    };
    match schedule.below(6) {
        kind @ 0..=2 => {
            // A second coordinator on the live file: by its own name, a symbolic link, a
            // hard link. Refused before it opens anything; no log left beside the name.
            let name = match kind {
                0 => db.to_path_buf(),
                1 => {
                    let link = dir.join("symlink.db");
                    let _ = std::fs::remove_file(&link);
                    std::os::unix::fs::symlink(db, &link).unwrap();
                    link
                }
                _ => {
                    let link = dir.join("hard.db");
                    let _ = std::fs::remove_file(&link);
                    std::fs::hard_link(db, &link).unwrap();
                    link
                }
            };
            let port = free_port().to_string();
            let out = coordinator(&[
                "serve",
                "--db",
                name.to_str().unwrap(),
                "--experiment",
                FIXTURE,
                "--listen",
                &format!("127.0.0.1:{port}"),
                "--token-file",
                strider_tests::secret_file(dir, SECRET).to_str().unwrap(),
            ]);
            let wanted = if kind == 2 {
                "has 2 names (hard links)".to_string()
            } else {
                format!("pid {live}")
            };
            refused_with(&out, &format!("second coordinator {name:?}"), &wanted);
            if kind > 0 {
                let mut log = name.as_os_str().to_owned();
                log.push("-wal");
                assert!(!Path::new(&log).exists(), "a log was left beside {name:?}");
                std::fs::remove_file(&name).unwrap();
            }
            [
                "second coordinator, same name",
                "second coordinator, symbolic link",
                "second coordinator, hard link",
            ][kind as usize]
                .to_string()
        }
        3 => format!("NaN fitness: {}", nan_fitness(rt, url)),
        4 => {
            // A wrong secret, then a worker whose secret a header cannot carry.
            let status = rt.block_on(async {
                let mut client = WorkerServiceClient::connect(url.to_string()).await.unwrap();
                let mut request =
                    tonic::Request::new(tokio_stream::iter(Vec::<v1::WorkerMessage>::new()));
                request.metadata_mut().insert(
                    "authorization",
                    "Bearer not-the-secret-0123456789abcdef".parse().unwrap(),
                );
                client.work(request).await.err()
            });
            assert_eq!(status.map(|s| s.code()), Some(tonic::Code::Unauthenticated));
            let bad = dir.join("bell.secret");
            std::fs::write(&bad, "chaos-secret-0123456789\u{7}abcdef\n").unwrap();
            let out = Command::new(binary("strider-worker"))
                .args(["--connect", url, "--token-file", bad.to_str().unwrap()])
                .output()
                .unwrap();
            refused_with(
                &out,
                "worker with a control character in its secret",
                "at character",
            );
            "wrong secret; secret with a control character".to_string()
        }
        _ => {
            // The read commands on the live file: they read through its log, write nothing.
            let d = db.to_str().unwrap();
            for args in [vec!["export", "--db", d], vec!["analyse", "--db", d]] {
                let out = coordinator(&args);
                assert!(
                    out.status.success(),
                    "{args:?} on the live database: {}",
                    String::from_utf8_lossy(&out.stderr)
                );
            }
            "export and analyse on the live database".to_string()
        }
    }
}

/// A session holding the secret that takes one lease and answers it with a NaN fitness:
/// refused with a `ResultRefused` on the same stream (no attempt counted), then dropped.
fn nan_fitness(rt: &tokio::runtime::Runtime, url: &str) -> &'static str {
    rt.block_on(async {
        let mut client = WorkerServiceClient::connect(url.to_string()).await.unwrap();
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        tx.send(v1::WorkerMessage {
            kind: Some(worker_message::Kind::Hello(v1::Hello {
                protocol_version: strider_proto::PROTOCOL_VERSION,
                worker_name: "nan-sender".into(),
                slots: 1,
                build: strider_common::build_id(),
                replaces: 0,
                reference_trial: strider_worker::reference_trial::digest(),
            })),
        })
        .await
        .unwrap();
        let mut request = tonic::Request::new(tokio_stream::wrappers::ReceiverStream::new(rx));
        request
            .metadata_mut()
            .insert("authorization", format!("Bearer {SECRET}").parse().unwrap());
        let mut inbound = client.work(request).await.unwrap().into_inner();
        // Between generations nothing may be free for a while: then there is nothing to
        // answer, and the session ends.
        let until = tokio::time::Instant::now() + Duration::from_secs(2);
        let id = loop {
            match tokio::time::timeout_at(until, inbound.message()).await {
                Ok(Ok(Some(v1::CoordinatorMessage {
                    kind: Some(v1::coordinator_message::Kind::Assignment(a)),
                }))) => break a.id,
                Ok(Ok(Some(_))) => {}
                Ok(other) => panic!("the session ended before an assignment: {other:?}"),
                Err(_) => return "no candidate free",
            }
        };
        let nan = v1::Outcome {
            kind: Some(v1::outcome::Kind::Valid(v1::Valid {
                fitness: f64::NAN,
                stats: Some(v1::TrialStats::default()),
                features: vec![0.0; 6],
                cell: 0,
                outranked: false,
            })),
            controller: vec![0.0; 7],
        };
        tx.send(v1::WorkerMessage {
            kind: Some(worker_message::Kind::Result(v1::Result {
                id,
                outcome: Some(nan),
                seconds: 0.1,
            })),
        })
        .await
        .unwrap();
        let until = tokio::time::Instant::now() + START;
        loop {
            match tokio::time::timeout_at(until, inbound.message()).await {
                Ok(Ok(Some(v1::CoordinatorMessage {
                    kind: Some(v1::coordinator_message::Kind::ResultRefused(r)),
                }))) => {
                    assert_eq!(r.code, "InvalidArgument", "{r:?}");
                    assert_eq!(r.id, id);
                    return "refused, the session went on";
                }
                Ok(Ok(Some(_))) => {}
                other => panic!("no refusal for a NaN fitness: {other:?}"),
            }
        }
    })
}

#[test]
fn a_run_through_coordinator_kills_and_worker_faults_ends_as_run_ends_it() {
    let (expected, expected_rows) = run_builds(FIXTURE);
    let dir = temp_dir("chaos");
    let db = dir.join("chaos.db");
    let port = free_port();
    let url = format!("http://127.0.0.1:{port}");
    let rt = tokio::runtime::Runtime::new().unwrap();
    let mut schedule = Schedule(0x5EED_0014);

    let mut coordinator = serve(&dir, &db, port);
    let mut spawned = 0;
    let mut next_worker = |dir: &Path| {
        spawned += 1;
        worker(dir, &url, &format!("worker-{spawned}"))
    };
    let mut workers: Vec<Process> = (0..WORKERS).map(|_| next_worker(&dir)).collect();
    coordinator.wait_for_line("for a worker", |l| l.contains("worker connected"), START);

    // Worker events and coordinator kills, interleaved in a seeded order.
    let mut events: Vec<Event> = [
        vec![Event::CoordinatorKill; COORDINATOR_KILLS],
        vec![Event::Worker; WORKER_EVENTS],
        vec![Event::Fault; FAULTS],
    ]
    .concat();
    for i in (1..events.len()).rev() {
        events.swap(i, schedule.below(i as u64 + 1) as usize);
    }
    let mut log = Vec::new();
    for event in events {
        std::thread::sleep(schedule.pause());
        assert!(
            coordinator.exited().is_none(),
            "the run finished before the schedule did (after {log:?}): make the fixture longer\n{}",
            coordinator.log()
        );
        match event {
            Event::CoordinatorKill => {
                coordinator.signal(libc::SIGKILL);
                drop(coordinator);
                coordinator = serve(&dir, &db, port);
                log.push("coordinator SIGKILL".to_string());
                continue;
            }
            Event::Fault => {
                log.push(fault(
                    &mut schedule,
                    &rt,
                    &dir,
                    &db,
                    &url,
                    coordinator.pid(),
                ));
                continue;
            }
            Event::Worker => {}
        }
        let w = schedule.below(WORKERS as u64) as usize;
        match schedule.below(4) {
            0 => {
                workers[w].signal(libc::SIGKILL);
                workers[w] = next_worker(&dir);
                log.push(format!("worker {w} SIGKILL"));
            }
            1 => {
                workers[w].signal(libc::SIGTERM);
                let status = workers[w].wait_exit(START);
                // A worker signalled before it armed its handler (just started, on a loaded
                // machine) dies of the signal, as any Unix process does; it had not
                // connected, so it held nothing. Once connected it stops cleanly.
                let worker_log = workers[w].log();
                let unarmed = std::os::unix::process::ExitStatusExt::signal(&status)
                    == Some(libc::SIGTERM)
                    && !worker_log.contains("connected to");
                assert!(
                    status.success() || unarmed,
                    "{status:?}; its log:\n{worker_log}"
                );
                workers[w] = next_worker(&dir);
                log.push(format!("worker {w} SIGTERM"));
            }
            2 => {
                // Past the 1 s lease: its leases expire and go to the others.
                workers[w].signal(libc::SIGSTOP);
                std::thread::sleep(Duration::from_millis(1500));
                workers[w].signal(libc::SIGCONT);
                log.push(format!("worker {w} SIGSTOP 1.5 s"));
            }
            _ => {
                let taken = lease_and_drop(&rt, &url);
                log.push(format!("{taken} leases taken and dropped"));
            }
        }
    }
    eprintln!("chaos schedule: {log:?}");

    let status = coordinator.wait_exit(FINISH);
    assert!(
        status.success(),
        "coordinator failed:\n{}",
        coordinator.log()
    );
    for w in &mut workers {
        // A worker stopped last may still be reconnecting; every one exits by itself.
        assert!(w.wait_exit(START).success(), "{}", w.log());
    }
    let rows = candidate_rows(&db);
    assert!(
        !rows.contains("evaluation_failed"),
        "a candidate failed for want of a worker"
    );
    assert_same_library(&export(&db), &expected);
    if rows != expected_rows {
        let first = rows
            .lines()
            .zip(expected_rows.lines())
            .find(|(a, b)| a != b);
        panic!(
            "the candidates differ from run's ({} rows against {}); first difference:\n{first:?}",
            rows.lines().count(),
            expected_rows.lines().count()
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
