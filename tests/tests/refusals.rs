//! Bad callers get a clear gRPC error and change nothing: no secret or a wrong one, another
//! protocol version, a worker of another CPU arithmetic, architecture or commit, or whose
//! node steps the robot differently (its reference trial), a NaN
//! fitness, a message over the size limit, a candidate nobody leased them, another run's
//! candidate. A raw client speaks the protocol here, as a broken or hostile worker would.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};
use strider_common::rng::CandidateSeed;
use strider_common::EvalContext;
use strider_common::Genome;
use strider_proto::convert::scheme_from_wire;
use strider_proto::v1::{
    self, client_service_client::ClientServiceClient, coordinator_message, worker_message,
    worker_service_client::WorkerServiceClient, CoordinatorMessage, WorkerMessage,
};
use strider_tests::coordinator::{serve_command, start_serving};
use strider_tests::{binary, other_trigonometry_shim, skip_without, temp_dir, Process};
use strider_worker::evaluate::evaluate;
use tokio::sync::mpsc;
use tonic::transport::Channel;
use tonic::{Code, Request, Status, Streaming};

const FIXTURE: &str = "tests/fixtures/service.toml";
const SECRET: &str = "refusals-secret-0123456789abcdef";

fn authorised<T>(message: T) -> Request<T> {
    let mut r = Request::new(message);
    r.metadata_mut()
        .insert("authorization", format!("Bearer {SECRET}").parse().unwrap());
    r
}

fn hello(version: u32) -> WorkerMessage {
    hello_replacing(version, 0)
}

/// A Hello naming the session it replaces (0: none).
fn hello_replacing(version: u32, replaces: u64) -> WorkerMessage {
    WorkerMessage {
        kind: Some(worker_message::Kind::Hello(v1::Hello {
            protocol_version: version,
            worker_name: "raw test client".into(),
            slots: 4,
            build: strider_common::build_id(),
            replaces,
            reference_trial: strider_worker::reference_trial::digest(),
        })),
    }
}

/// `serve` on the fixture in a new directory `name` with the test's secret: the
/// directory, the database, the coordinator and its URL.
fn serving(name: &str) -> (PathBuf, PathBuf, Process, String) {
    let dir = temp_dir(name);
    let secret = dir.join("secret");
    std::fs::write(&secret, SECRET).unwrap();
    let db = dir.join(format!("{name}.db"));
    let (coordinator, url) = start_serving(serve_command(FIXTURE, &db, "127.0.0.1:0", &secret));
    (dir, db, coordinator, url)
}

/// A connected channel to `url`.
async fn channel(url: &str) -> Channel {
    Channel::from_shared(url.to_string())
        .unwrap()
        .connect()
        .await
        .unwrap()
}

/// A worker stream: what to send, what came back.
struct Stream {
    tx: mpsc::Sender<WorkerMessage>,
    rx: Streaming<CoordinatorMessage>,
}

/// A Hello naming `build` is refused as another build, the message naming both builds.
async fn refused_as_another_build(channel: &Channel, name: &str, build: &str) {
    let hello = WorkerMessage {
        kind: Some(worker_message::Kind::Hello(v1::Hello {
            protocol_version: 1,
            worker_name: name.into(),
            slots: 4,
            build: build.into(),
            replaces: 0,
            reference_trial: strider_worker::reference_trial::digest(),
        })),
    };
    let s = match open(channel, hello).await {
        Err(s) => s,
        Ok(mut st) => st.rx.message().await.unwrap_err(),
    };
    assert_eq!(s.code(), Code::FailedPrecondition, "{name}");
    let ours = strider_common::build_id();
    assert!(
        s.message().contains(build) && s.message().contains(&ours),
        "{}",
        s.message()
    );
}

async fn open(channel: &Channel, first: WorkerMessage) -> Result<Stream, Status> {
    let (tx, out) = mpsc::channel(16);
    tx.send(first).await.unwrap();
    let mut client = WorkerServiceClient::new(channel.clone());
    let rx = client
        .work(authorised(tokio_stream::wrappers::ReceiverStream::new(out)))
        .await?
        .into_inner();
    Ok(Stream { tx, rx })
}

/// Opens a stream and reads the Welcome and the first assignment (within 60 s).
async fn assigned(channel: &Channel) -> (Stream, v1::Assignment) {
    tokio::time::timeout(Duration::from_secs(60), first_assignment(channel))
        .await
        .expect("no assignment came within 60 s")
}

async fn first_assignment(channel: &Channel) -> (Stream, v1::Assignment) {
    let mut s = open(channel, hello(1)).await.unwrap();
    let welcome = s.rx.message().await.unwrap().unwrap();
    assert!(matches!(
        welcome.kind,
        Some(coordinator_message::Kind::Welcome(_))
    ));
    match s.rx.message().await.unwrap().unwrap().kind {
        Some(coordinator_message::Kind::Assignment(a)) => (s, a),
        other => panic!("expected an assignment, got {other:?}"),
    }
}

/// Sends a result and returns the status that ends the stream.
async fn refused_ending(mut s: Stream, id: v1::CandidateId, outcome: v1::Outcome) -> Status {
    s.tx.send(result(id, outcome)).await.unwrap();
    loop {
        match s.rx.message().await {
            Ok(Some(_)) => {} // further assignments
            Ok(None) => panic!("the stream ended without an error"),
            Err(status) => return status,
        }
    }
}

fn result(id: v1::CandidateId, outcome: v1::Outcome) -> WorkerMessage {
    WorkerMessage {
        kind: Some(worker_message::Kind::Result(v1::Result {
            id: Some(id),
            outcome: Some(outcome),
            seconds: 0.1,
        })),
    }
}

/// Sends a result and returns the refusal that answers it: the stream goes on.
async fn refused(s: &mut Stream, id: v1::CandidateId, outcome: v1::Outcome) -> v1::ResultRefused {
    s.tx.send(result(id, outcome)).await.unwrap();
    tokio::time::timeout(Duration::from_secs(60), next_refusal(s))
        .await
        .unwrap_or_else(|_| panic!("no refusal came within 60 s for {id:?}"))
}

async fn next_refusal(s: &mut Stream) -> v1::ResultRefused {
    loop {
        match s.rx.message().await {
            Ok(Some(CoordinatorMessage {
                kind: Some(coordinator_message::Kind::ResultRefused(r)),
            })) => return r,
            Ok(Some(_)) => {} // further assignments
            Ok(None) => panic!("the stream ended instead of a refusal"),
            Err(status) => panic!("the stream ended instead of a refusal: {status:?}"),
        }
    }
}

fn real_outcome(a: &v1::Assignment) -> v1::Outcome {
    let e =
        strider_common::Experiment::load(&strider_tests::workspace_root().join(FIXTURE)).unwrap();
    let genome = Genome::try_from(a.genome.as_ref().unwrap()).unwrap();
    let id = a.id.unwrap();
    let o = evaluate(
        &EvalContext::of(&e),
        &genome,
        scheme_from_wire(a.scheme).unwrap(),
        CandidateSeed::new(a.run_seed, id.number),
    );
    (&o).into()
}

/// One number the query returns, read with the sqlite3 shell.
fn sqlite_count(db: &Path, sql: &str) -> i64 {
    strider_tests::sqlite(db, sql).trim().parse().unwrap()
}

/// Results the database holds from workers (sqlite3, the tool a user would open it with):
/// stored in the current step or applied (candidates settled without a trial have no
/// statistics), and counted per worker.
fn results_in(db: &Path) -> (i64, i64) {
    let count = |sql: &str| sqlite_count(db, sql);
    (
        count("SELECT COUNT(*) FROM pending WHERE status = 'done' AND worker IS NOT NULL")
            + count("SELECT COUNT(*) FROM candidates WHERE kind != 'rejected' OR outcome NOT LIKE '%\"stats\":null%'"),
        count("SELECT COALESCE(SUM(results), 0) FROM workers"),
    )
}

#[test]
fn bad_requests_are_refused_with_a_clear_status_and_change_nothing() {
    let (dir, db, coordinator, url) = serving("refusals");
    tokio::runtime::Runtime::new().unwrap().block_on(async {
        let channel = channel(&url).await;

        // Health answers without the secret (probes and load balancers have none).
        let mut health = tonic_health::pb::health_client::HealthClient::new(channel.clone());
        let h = health
            .check(tonic_health::pb::HealthCheckRequest {
                service: String::new(),
            })
            .await
            .unwrap();
        assert_eq!(h.into_inner().status, 1, "SERVING");

        // Reflection answers in both versions (Python's reflection client and older grpcurl
        // speak v1alpha) and lists health beside Strider's services.
        {
            use tonic_reflection::pb::v1alpha::{
                server_reflection_client::ServerReflectionClient,
                server_reflection_request::MessageRequest,
                server_reflection_response::MessageResponse, ServerReflectionRequest,
            };
            let mut reflection = ServerReflectionClient::new(channel.clone());
            let request = ServerReflectionRequest {
                host: String::new(),
                message_request: Some(MessageRequest::ListServices(String::new())),
            };
            let mut answers = reflection
                .server_reflection_info(authorised(tokio_stream::iter([request])))
                .await
                .expect("v1alpha reflection is served")
                .into_inner();
            let answer = answers.message().await.unwrap().unwrap();
            let Some(MessageResponse::ListServicesResponse(list)) = answer.message_response else {
                panic!("not a service list: {answer:?}");
            };
            let names: Vec<String> = list.service.into_iter().map(|s| s.name).collect();
            for wanted in [
                "strider.v1.WorkerService",
                "strider.v1.ClientService",
                "grpc.health.v1.Health",
            ] {
                assert!(
                    names.iter().any(|n| n == wanted),
                    "{wanted} not in {names:?}"
                );
            }
        }

        // No secret, or a wrong one.
        let mut client = ClientServiceClient::new(channel.clone());
        let s = client
            .get_progress(v1::ProgressRequest {
                protocol_version: 1,
            })
            .await
            .unwrap_err();
        assert_eq!(s.code(), Code::Unauthenticated);
        assert!(s.message().contains("missing secret"), "{}", s.message());
        let mut wrong = Request::new(v1::ProgressRequest {
            protocol_version: 1,
        });
        wrong.metadata_mut().insert(
            "authorization",
            "Bearer refusals-secret-0123456789abcdeX".parse().unwrap(),
        );
        let s = client.get_progress(wrong).await.unwrap_err();
        assert_eq!(s.code(), Code::Unauthenticated);
        let (tx, out) = mpsc::channel(1);
        tx.send(hello(1)).await.unwrap();
        let s = WorkerServiceClient::new(channel.clone())
            .work(tokio_stream::wrappers::ReceiverStream::new(out))
            .await
            .unwrap_err();
        assert_eq!(s.code(), Code::Unauthenticated);

        // Another protocol version: both versions named.
        let s = match open(&channel, hello(2)).await {
            Err(s) => s,
            Ok(mut st) => st.rx.message().await.unwrap_err(),
        };
        assert_eq!(s.code(), Code::FailedPrecondition);
        assert!(
            s.message().contains("version 2") && s.message().contains("version 1"),
            "{}",
            s.message()
        );
        let s = client
            .get_progress(authorised(v1::ProgressRequest {
                protocol_version: 7,
            }))
            .await
            .unwrap_err();
        assert_eq!(s.code(), Code::FailedPrecondition);

        // The same build on a CPU that does the arithmetic the other way (the C library's
        // sin and cos with fused multiply-add or not: other bits, docs/rapier.md): refused,
        // both named.
        let ours = strider_common::build_id();
        let theirs = match strider_common::cpu_arithmetic() {
            Some("fused multiply-add") => {
                ours.replace("fused multiply-add", "separate multiply and add")
            }
            Some(_) => ours.replace("separate multiply and add", "fused multiply-add"),
            None => format!("{ours} on another CPU"),
        };
        assert_ne!(ours, theirs);
        refused_as_another_build(&channel, "a worker on another CPU", &theirs).await;

        // The same build for another architecture (another C library, other SIMD in the
        // geometry): refused, both named.
        let arch = std::env::consts::ARCH;
        let other = if arch == "aarch64" {
            "x86_64"
        } else {
            "aarch64"
        };
        let theirs = ours.replacen(&format!(", {arch},"), &format!(", {other},"), 1);
        assert_ne!(ours, theirs);
        refused_as_another_build(&channel, "a worker of another architecture", &theirs).await;

        // The same commit compiled for other instruction-set extensions (`-C
        // target-cpu=native`: rapier's SIMD types fuse their multiply-adds only when
        // compiled for FMA, measured to change trials' bits): refused, both named.
        let theirs = match ours.find(", compiled for ") {
            Some(at) => format!("{})", &ours[..at]),
            None => format!(
                "{}, compiled for avx+avx2+fma)",
                ours.strip_suffix(')')
                    .unwrap_or_else(|| panic!("{ours} does not end in ')'"))
            ),
        };
        assert_ne!(ours, theirs);
        refused_as_another_build(&channel, "a worker compiled for other extensions", &theirs).await;

        // The same version built from another commit (other physics, perhaps): refused.
        let ours_commit = ours
            .split("(commit ")
            .nth(1)
            .and_then(|rest| rest.split(',').next())
            .unwrap_or_else(|| panic!("{ours} names no commit"));
        let theirs = ours.replacen(&format!("commit {ours_commit},"), "commit 0123456789ab,", 1);
        assert!(ours_commit != "0123456789ab" && theirs != ours);
        refused_as_another_build(&channel, "a worker of another commit", &theirs).await;

        // The same build on a node that computes differently (another C library's `sin`,
        // which the build identity cannot name): its reference trial's digest is not the
        // coordinator's own. Refused, both digests named; and one that sent no digest. A
        // client with this process's digest (the same build on this machine) is admitted.
        let ours_digest = strider_worker::reference_trial::digest();
        let mut first = open(&channel, hello(1)).await.unwrap();
        assert!(matches!(
            first.rx.message().await.unwrap().unwrap().kind,
            Some(coordinator_message::Kind::Welcome(_))
        ));
        for (digest, wanted) in [
            (ours_digest ^ 1, format!("{:016x}", ours_digest ^ 1)),
            (0, "none sent".to_string()),
        ] {
            let mut other = hello(1);
            if let Some(worker_message::Kind::Hello(h)) = &mut other.kind {
                h.worker_name = "a node with another libm".into();
                h.reference_trial = digest;
            }
            let s = match open(&channel, other).await {
                Err(s) => s,
                Ok(mut st) => st.rx.message().await.unwrap_err(),
            };
            assert_eq!(s.code(), Code::FailedPrecondition, "{}", s.message());
            assert!(s.message().contains(&wanted), "{}", s.message());
            if digest != 0 {
                assert!(
                    s.message()
                        .contains(&format!("this coordinator's {ours_digest:016x}")),
                    "{}",
                    s.message()
                );
            }
        }
        drop(first);

        // A message over the size limit (1 MiB): refused with the reason, not an OK end.
        let (big, b) = assigned(&channel).await;
        let mut huge = real_outcome(&b);
        huge.kind = Some(v1::outcome::Kind::Valid(v1::Valid {
            fitness: 1.0,
            stats: Some(v1::TrialStats::default()),
            features: vec![0.5; 200_000],
            cell: 0,
            outranked: false,
        }));
        let s = refused_ending(big, b.id.unwrap(), huge).await;
        assert_eq!(s.code(), Code::ResourceExhausted);
        assert!(s.message().contains("too large"), "{}", s.message());

        // A refused result changes nothing and the session goes on: the same stream
        // answers every refusal below, then still takes the good result of the same
        // candidate (before, each refusal ended the session and cost the candidate an
        // attempt: five refusals failed it).
        let (mut st, a) = assigned(&channel).await;
        // NaN fitness, five times over.
        let mut nan = real_outcome(&a);
        nan.kind = Some(v1::outcome::Kind::Valid(v1::Valid {
            fitness: f64::NAN,
            stats: Some(v1::TrialStats::default()),
            features: vec![0.0; 6],
            cell: 0,
            outranked: false,
        }));
        for _ in 0..5 {
            let r = refused(&mut st, a.id.unwrap(), nan.clone()).await;
            assert_eq!(r.code, "InvalidArgument");
            assert!(r.reason.contains("fitness"), "{}", r.reason);
            assert_eq!(r.id, a.id);
        }

        // Marked outranked, though it was drawn with no bar (an initial design): its
        // confirming trials were owed. Its features and cell are its design's own, so
        // that only the mark is wrong.
        assert_eq!(a.to_beat, None);
        let mut skipped = real_outcome(&a);
        let genome = Genome::try_from(a.genome.as_ref().unwrap()).unwrap();
        let e = strider_common::Experiment::load(&strider_tests::workspace_root().join(FIXTURE))
            .unwrap();
        let plan = strider_common::BodyPlan::new(&genome.morphology, e.brief.payload);
        let features = strider_common::Features::of(&genome.morphology, &plan);
        skipped.kind = Some(v1::outcome::Kind::Valid(v1::Valid {
            fitness: 1.0,
            stats: Some(v1::TrialStats::default()),
            features: features.0.to_vec(),
            cell: e.features.cell_of(&features).unwrap().0,
            outranked: true,
        }));
        let r = refused(&mut st, a.id.unwrap(), skipped).await;
        assert_eq!(r.code, "InvalidArgument");
        assert!(r.reason.contains("outcome.valid.outranked"), "{}", r.reason);

        // A candidate nobody leased to this worker.
        let mut unknown = a.id.unwrap();
        unknown.number += 1_000_000;
        let r = refused(&mut st, unknown, real_outcome(&a)).await;
        assert_eq!(r.code, "FailedPrecondition");
        assert!(
            r.reason.contains("not leased to this worker"),
            "{}",
            r.reason
        );

        // A candidate leased to another worker (a result for one already settled would
        // be a duplicate, ignored without a word).
        let (other, b) = assigned(&channel).await;
        let r = refused(&mut st, b.id.unwrap(), real_outcome(&b)).await;
        assert_eq!(r.code, "FailedPrecondition");
        assert!(
            r.reason.contains("not leased to this worker"),
            "{}",
            r.reason
        );
        drop(other);

        // A run that does not exist.
        let mut missing = a.id.unwrap();
        missing.run = 9;
        let r = refused(&mut st, missing, real_outcome(&a)).await;
        assert_eq!(r.code, "FailedPrecondition");

        // Paging with a token the server never issued.
        let s = client
            .list_elites(authorised(v1::ListElitesRequest {
                protocol_version: 1,
                page_token: "bogus".into(),
                ..Default::default()
            }))
            .await
            .unwrap_err();
        assert_eq!(s.code(), Code::InvalidArgument);
        assert!(s.message().contains("page_token"), "{}", s.message());

        // The refused candidate's good result, on the same stream, is stored; sent again
        // it is a duplicate, acknowledged and ignored without ending the stream.
        st.tx
            .send(result(a.id.unwrap(), real_outcome(&a)))
            .await
            .unwrap();
        st.tx
            .send(result(a.id.unwrap(), real_outcome(&a)))
            .await
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(60);
        // The writer commits in milliseconds; poll the file until the result is there.
        while results_in(&db).0 < 1 {
            assert!(
                Instant::now() < deadline,
                "the good result never reached the database; coordinator log:\n{}",
                coordinator.log()
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        // Then a malformed message of another kind still ends the session with its reason.
        st.tx.send(WorkerMessage { kind: None }).await.unwrap();
        let ended = loop {
            match st.rx.message().await {
                Ok(Some(_)) => {}
                Ok(None) => panic!("the stream ended without an error"),
                Err(status) => break status,
            }
        };
        assert_eq!(ended.code(), Code::InvalidArgument);
        assert!(
            ended.message().contains("empty message"),
            "{}",
            ended.message()
        );
        drop(st);
        // Every session, refused or not, ends by recording what its worker sent.
        while sqlite_count(
            &db,
            "SELECT COUNT(*) FROM workers WHERE disconnected_at IS NULL",
        ) > 0
        {
            assert!(
                Instant::now() < deadline,
                "a worker session never ended; coordinator log:\n{}",
                coordinator.log()
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    });
    // Exactly the one good result; none of the refused ones, and no attempt counted.
    let (stored, _) = results_in(&db);
    assert_eq!(stored, 1);
    assert_eq!(
        sqlite_count(
            &db,
            "SELECT COUNT(*) FROM candidates WHERE outcome LIKE '%evaluation_failed%'"
        ) + sqlite_count(&db, "SELECT COALESCE(SUM(attempts), 0) FROM pending"),
        0,
        "a refusal counted an attempt"
    );
    drop(coordinator);
    let (_, counted) = results_in(&db);
    assert_eq!(counted, 1, "the workers table counts one result in all");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// 200 connections that never speak, against a coordinator limited to 64 file
/// descriptors: each is closed at its handshake deadline, and health answers meanwhile
/// (before the deadline they held a descriptor each for ever and starved the process).
#[test]
fn connections_that_never_speak_are_closed_and_starve_nothing() {
    use std::io::Read;
    let dir = temp_dir("silent-connections");
    let secret = dir.join("secret");
    std::fs::write(&secret, SECRET).unwrap();
    let db = dir.join("silent.db");
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg("ulimit -n 64 && exec \"$0\" \"$@\"")
        .arg(binary("strider-coordinator"))
        .args([
            "serve",
            "--db",
            db.to_str().unwrap(),
            "--experiment",
            FIXTURE,
        ])
        .args(["--listen", "127.0.0.1:0", "--handshake-seconds", "1"])
        .args(["--token-file", secret.to_str().unwrap()]);
    let (coordinator, url) = start_serving(cmd);
    let addr = url.trim_start_matches("http://").to_string();

    // Three times the descriptors the process has; the kernel completes each TCP
    // handshake, the coordinator accepts them as descriptors free up.
    let silent: Vec<std::net::TcpStream> = (0..200)
        .map(|_| std::net::TcpStream::connect(&addr).unwrap())
        .collect();

    tokio::runtime::Runtime::new().unwrap().block_on(async {
        let check = async {
            let channel = Channel::from_shared(url.clone())
                .unwrap()
                .connect()
                .await
                .unwrap();
            tonic_health::pb::health_client::HealthClient::new(channel)
                .check(tonic_health::pb::HealthCheckRequest::default())
                .await
                .unwrap()
                .into_inner()
                .status
        };
        let status = tokio::time::timeout(Duration::from_secs(60), check)
            .await
            .expect("health answered while silent connections were open");
        assert_eq!(status, 1, "SERVING");
    });

    // One that opens HTTP/2 (the client preface and an empty SETTINGS frame) and then
    // idles, answering nothing, is closed too.
    let mut idle = std::net::TcpStream::connect(&addr).unwrap();
    std::io::Write::write_all(
        &mut idle,
        b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n\x00\x00\x00\x04\x00\x00\x00\x00\x00",
    )
    .unwrap();

    // Each silent connection is closed by the coordinator (what it wrote first, its
    // HTTP/2 settings, then the end), not left open.
    for (i, mut s) in silent.into_iter().chain([idle]).enumerate() {
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let mut buf = [0u8; 256];
        loop {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(_) => continue,
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => break,
                Err(e) => panic!("silent connection {i} still open: {e}"),
            }
        }
    }

    // A worker that shows the secret keeps its connection past the deadline: one session
    // for the whole experiment (seconds, where the deadline is one).
    let mut worker = Command::new(binary("strider-worker"));
    worker
        .args(["--connect", &url, "--threads", "2"])
        .args(["--token-file", secret.to_str().unwrap()]);
    let worker = Process::spawn("worker", worker);
    let mut coordinator = coordinator;
    assert!(
        coordinator.wait_exit(Duration::from_secs(300)).success(),
        "{}",
        coordinator.log()
    );
    let log = coordinator.log();
    assert_eq!(log.matches("worker connected").count(), 1, "{log}");
    drop(worker);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A worker that connects again names its last session (`Hello.replaces`), which ends at
/// once though its connection is alive: the worker counted once, the old session's leases
/// free. (After a network cut the old connection can look alive for half a minute.)
#[test]
fn a_worker_that_connects_again_ends_its_last_session_at_once() {
    let (dir, db, mut coordinator, url) = serving("reconnected");
    tokio::runtime::Runtime::new().unwrap().block_on(async {
        let channel = channel(&url).await;
        let mut first = open(&channel, hello(1)).await.unwrap();
        let token = match first.rx.message().await.unwrap().unwrap().kind {
            Some(coordinator_message::Kind::Welcome(w)) => w.session,
            other => panic!("expected Welcome, got {other:?}"),
        };
        assert_ne!(token, 0);
        let again = hello_replacing(1, token);
        let mut second = open(&channel, again).await.unwrap();
        assert!(matches!(
            second.rx.message().await.unwrap().unwrap().kind,
            Some(coordinator_message::Kind::Welcome(_))
        ));
        // The first stream ends (its assignments read first), well before any keepalive
        // or lease would end it (20 s, 60 s).
        let ended = tokio::time::timeout(Duration::from_secs(10), async {
            loop {
                match first.rx.message().await {
                    Ok(Some(_)) => continue,
                    Ok(None) => break None,
                    Err(status) => break Some(status),
                }
            }
        })
        .await
        .expect("the first session did not end");
        assert!(ended.is_none(), "{ended:?}");
        let mut client = ClientServiceClient::new(channel.clone());
        let progress = client
            .get_progress(authorised(v1::ProgressRequest {
                protocol_version: 1,
            }))
            .await
            .unwrap()
            .into_inner();
        assert_eq!(progress.workers_connected, 1);
        drop(first.tx);
        drop(second);
    });
    coordinator.signal(libc::SIGTERM);
    assert!(coordinator.wait_exit(Duration::from_secs(60)).success());
    let left = strider_tests::sqlite(&db, "SELECT left_because FROM workers ORDER BY id LIMIT 1");
    assert!(
        left.starts_with("the worker connected again (worker "),
        "{left}\n{}",
        coordinator.log()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A worker on a node whose C library rounds `sin` and `cos` otherwise (glibc's, one ulp
/// up, preloaded: `tests/fixtures/other-trigonometry.c`) has the coordinator's build
/// identity, but its reference trial gives another digest: it is refused and exits saying
/// why. The same binary without the shim is admitted and runs the experiment to its end.
/// (One ulp of trigonometry moves MAX's 5-s trial from 2.7007 to 2.7003 m: a run on mixed
/// nodes would not be the same bits.) LD_PRELOAD is the GNU dynamic loader's.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn a_worker_whose_libm_differs_is_refused_by_its_reference_trial() {
    let shim_dir = temp_dir("reference-trial-shim");
    let Some(shim) = other_trigonometry_shim(&shim_dir) else {
        return skip_without("cc, to build the libm shim");
    };
    let (dir, _db, mut coordinator, url) = serving("reference-trial");
    let worker = || {
        let mut cmd = Command::new(binary("strider-worker"));
        cmd.args(["--connect", &url, "--threads", "1"])
            .args(["--token-file", dir.join("secret").to_str().unwrap()]);
        cmd
    };
    let mut shimmed = worker();
    shimmed.env("LD_PRELOAD", &shim);
    let mut other = Process::spawn("other-trigonometry", shimmed);
    let status = other.wait_exit(Duration::from_secs(120));
    let log = other.log();
    assert!(!status.success(), "{log}");
    assert!(
        log.contains("refused this worker: reference trial mismatch")
            && log.contains("this coordinator's"),
        "{log}"
    );
    let control = Process::spawn("worker", worker());
    assert!(
        coordinator.wait_exit(Duration::from_secs(300)).success(),
        "{}",
        coordinator.log()
    );
    let served = coordinator.log();
    assert_eq!(served.matches("worker connected").count(), 1, "{served}");
    assert!(
        served.contains("worker refused: reference trial mismatch"),
        "{served}"
    );
    drop(control);
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::remove_dir_all(&shim_dir).unwrap();
}
