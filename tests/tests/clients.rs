//! Reading a coordinator's progress and library: the `status` command, and a client that
//! Python's standard gRPC toolchain generates from `proto/` alone.

use std::path::Path;
use std::process::Command;
use std::time::Duration;
use strider_tests::coordinator::{serve_command, start_serving};
use strider_tests::{binary, export, run, temp_dir, workspace_root, Process};

const FIXTURE: &str = "tests/fixtures/service.toml";
const SECRET: &str = "clients-secret-0123456789abcdef";
const LONG: Duration = Duration::from_secs(300);
/// Debian's interpreter, where python3-grpcio and python3-grpc-tools install.
const PYTHON: &str = "/usr/bin/python3";

fn status(url: &str, secret: &Path) -> serde_json::Value {
    let out = run(
        "strider-coordinator",
        &[
            "status",
            "--connect",
            url,
            "--token-file",
            secret.to_str().unwrap(),
            "--json",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn status_and_a_generated_python_client_read_progress_and_elites() {
    let dir = temp_dir("clients");
    let secret = dir.join("secret");
    std::fs::write(&secret, SECRET).unwrap();
    let db = dir.join("clients.db");
    let mut cmd = serve_command(FIXTURE, &db, "127.0.0.1:0", &secret);
    cmd.args(["--keep-serving", "--progress-every", "0.1"]);
    let (coordinator, url) = start_serving(cmd);
    let mut w = Command::new(binary("strider-worker"));
    w.args([
        "--connect",
        &url,
        "--threads",
        "2",
        "--token-file",
        secret.to_str().unwrap(),
    ]);
    let _worker = Process::spawn("worker", w);

    // While it runs.
    coordinator.wait_for_line("generation 3", |l| l.contains("generation 3/20"), LONG);
    let running = status(&url, &secret);
    assert_eq!(running["experiment"], "service");
    assert_eq!(running["workers_connected"], 1);
    let runs = running["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    assert!(runs.iter().any(|r| r["generation"].as_u64().unwrap() >= 3));
    assert!(runs.iter().all(|r| r["trials_done"].as_u64().unwrap() > 0));
    assert!(runs.iter().any(|r| r["finished"] == false));

    // Once finished (it keeps serving clients).
    coordinator.wait_for_line("finished", |l| l.contains("every run is finished"), LONG);
    let done = status(&url, &secret);
    let exported = export(&db);
    for (r, e) in done["runs"]
        .as_array()
        .unwrap()
        .iter()
        .zip(exported["runs"].as_array().unwrap())
    {
        assert_eq!(r["finished"], true);
        assert_eq!(r["generation"], 20);
        let best = e["elites"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x["fitness"].as_f64().unwrap())
            .fold(0.0, f64::max);
        assert_eq!(r["best_fitness"].as_f64().unwrap(), best);
    }

    // A wrong secret is refused by name.
    let wrong = dir.join("wrong");
    std::fs::write(&wrong, "not-the-secret-at-all-000").unwrap();
    let out = run(
        "strider-coordinator",
        &[
            "status",
            "--connect",
            &url,
            "--token-file",
            wrong.to_str().unwrap(),
        ],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("wrong secret"));

    // The generated client.
    let has_grpc = Command::new(PYTHON)
        .args(["-c", "import grpc, grpc_tools"])
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        has_grpc,
        "{PYTHON} lacks grpcio and grpc-tools: apt-get install python3-grpcio python3-grpc-tools (.ci/run does)"
    );
    let stubs = dir.join("stubs");
    std::fs::create_dir_all(&stubs).unwrap();
    let generated = Command::new(PYTHON)
        .args(["-m", "grpc_tools.protoc", "-I", "proto"])
        .arg(format!("--python_out={}", stubs.display()))
        .arg(format!("--grpc_python_out={}", stubs.display()))
        .arg("strider/v1/strider.proto")
        .current_dir(workspace_root())
        .output()
        .unwrap();
    assert!(
        generated.status.success(),
        "{}",
        String::from_utf8_lossy(&generated.stderr)
    );
    let out = Command::new(PYTHON)
        .arg(workspace_root().join("tests/clients/python_client.py"))
        .arg(&stubs)
        .arg(&url)
        .arg(SECRET)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let py: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(py["experiment"], "service");
    assert_eq!(py["without_secret"], "UNAUTHENTICATED");
    // Paging two at a time with the tokens it is given reads the same elites; a token it
    // was never given, or one issued for another page size, is refused.
    assert_eq!(py["paged"], py["elites"]);
    assert_eq!(py["forged_token"], "INVALID_ARGUMENT");
    assert_eq!(py["reused_token"], "INVALID_ARGUMENT");
    let run0 = &exported["runs"][0]["elites"];
    assert_eq!(
        py["elites"].as_array().unwrap().len(),
        run0.as_array().unwrap().len()
    );
    let best = run0
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["fitness"].as_f64().unwrap())
        .fold(0.0, f64::max);
    assert_eq!(
        py["elites"][0]["fitness"].as_f64().unwrap(),
        best,
        "best first"
    );
    assert_eq!(py["elite"]["fitness"].as_f64().unwrap(), best);
    assert_eq!(py["elite"]["morphology"], 43);
    assert_eq!(py["elite"]["controller"], 7);
    assert_eq!(py["elite"]["kind"], "valid");

    // Server reflection as grpcio-reflection's client speaks it: the services listed
    // (health among them), and the file that defines the worker service.
    reflection_lists_the_services(&url);
    drop(coordinator);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A Python with grpcio-reflection (`.ci/run` installs it with pip), if any.
fn python_with_reflection() -> Option<&'static str> {
    ["python3", PYTHON].into_iter().find(|py| {
        Command::new(py)
            .args(["-c", "import grpc_reflection.v1alpha.reflection_pb2_grpc"])
            .output()
            .is_ok_and(|o| o.status.success())
    })
}

fn reflection_lists_the_services(url: &str) {
    let Some(python) = python_with_reflection() else {
        strider_tests::skip_without("grpcio-reflection (python3 -m pip install grpcio-reflection)");
        return;
    };
    let out = Command::new(python)
        .arg(workspace_root().join("tests/clients/python_reflection.py"))
        .arg(url.trim_start_matches("http://"))
        .arg(SECRET)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let seen: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let services: Vec<&str> = seen["services"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap())
        .collect();
    for wanted in [
        "grpc.health.v1.Health",
        "strider.v1.ClientService",
        "strider.v1.WorkerService",
    ] {
        assert!(services.contains(&wanted), "{wanted} not in {seen}");
    }
    assert_eq!(seen["file"][0], "strider/v1/strider.proto", "{seen}");
    let in_file = seen["file_services"].to_string();
    assert!(
        in_file.contains("WorkerService") && in_file.contains("ClientService"),
        "{seen}"
    );
    assert!(
        seen["file_messages"].to_string().contains("\"Progress\""),
        "{seen}"
    );
}
