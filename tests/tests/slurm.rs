//! The shipped Slurm script (`deploy/slurm/strider.sbatch`, unchanged) across the nodes of
//! a private three-node Slurm cluster ([`strider_tests::slurm::Cluster`]: one network, host
//! name and local disk per node, a shared directory, Debian's slurmctld, slurmd and munge).
//!
//! Each test starts its own cluster; they run one at a time (they would only slow each
//! other down on a small machine). Skipped, saying so, where Slurm or namespaces cannot be
//! had; `.ci/run` installs Slurm and sets `STRIDER_REQUIRE_TOOLS=1`, which turns a skip
//! into a failure.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};
use strider_coordinator::db::Db;
use strider_tests::slurm::Cluster;
use strider_tests::{
    assert_same_library, binary, export, library_run_builds, temp_dir, workspace_root, Process,
};

/// Two STATIC runs of 20 generations (about 14 s on 2 cores): long enough to lose a node
/// in the middle.
const EXPERIMENT: &str = "tests/fixtures/service.toml";
/// The nodes' CPUs, all different, so that a worker sized to another node's count shows.
/// node1 (the first node, where the coordinator runs) keeps 2 for it and gives 2 to its
/// worker.
const CPUS: [u32; 3] = [4, 2, 1];
/// Generous: CI machines are slow and busy; each job takes well under this.
const JOB: Duration = Duration::from_secs(600);
/// Slurm notices a node that stopped answering within about half a minute (SlurmdTimeout
/// 5 s, on its own ping cycle).
const NOTICED: Duration = Duration::from_secs(180);

/// One cluster at a time.
fn one_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The library `run` builds for the experiment on this machine, once per test process.
fn expected() -> &'static serde_json::Value {
    static EXPECTED: OnceLock<serde_json::Value> = OnceLock::new();
    EXPECTED.get_or_init(|| library_run_builds(EXPERIMENT))
}

/// A batch job submitted with `sbatch --wait` (which returns when the job ends).
struct Job {
    name: String,
    sbatch: Process,
    output: PathBuf,
}

/// Submits the shipped script with the experiment, from the shared directory, with
/// `TMPDIR` at every node's local directory and the run directory `run_dir`.
fn submit(
    cluster: &Cluster,
    name: &str,
    run_dir: &Path,
    sbatch_args: &[&str],
    env: &[(&str, &str)],
) -> Job {
    let output = cluster.shared().join(format!("{name}.out"));
    let mut cmd = cluster.command("sbatch");
    cmd.arg("--wait")
        .arg(format!("--job-name={name}"))
        .arg(format!("--output={}", output.display()))
        .arg(format!("--chdir={}", cluster.shared().display()))
        .args(sbatch_args)
        .arg(workspace_root().join("deploy/slurm/strider.sbatch"))
        .arg(workspace_root().join(EXPERIMENT))
        .env("STRIDER_RUN_DIR", run_dir)
        .env("TMPDIR", cluster.local_mount())
        .env(
            "STRIDER_BIN_DIR",
            binary("strider-coordinator").parent().unwrap(),
        )
        .env("STRIDER_PROGRESS_EVERY", "1")
        // Lost workers' leases come back within seconds, not the default minute.
        .env("STRIDER_SERVE_ARGS", "--lease-seconds 4")
        .env("STRIDER_WORKER_ARGS", "--max-backoff-seconds 1")
        // A coordinator whose node is lost: its workers cancel the job after 15 s.
        .env("STRIDER_GIVE_UP_AFTER", "15");
    for (k, v) in env {
        cmd.env(k, v);
    }
    Job {
        name: name.into(),
        sbatch: Process::spawn(name, cmd),
        output,
    }
}

impl Job {
    /// What the job has written so far (its script, coordinator and workers).
    fn output(&self) -> String {
        std::fs::read_to_string(&self.output).unwrap_or_default()
    }

    /// Polls the job's output (a file Slurm writes; no event to wait on) until a line
    /// satisfies `pred`.
    fn wait_for_line(&self, what: &str, pred: impl Fn(&str) -> bool) -> String {
        let deadline = Instant::now() + JOB;
        loop {
            if let Some(line) = self.output().lines().find(|l| pred(l)) {
                return line.to_string();
            }
            assert!(
                Instant::now() < deadline,
                "job {}: no line {what}; its output:\n{}\nsbatch said:\n{}",
                self.name,
                self.output(),
                self.sbatch.log()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Waits until the coordinator reports at least `percent` % of the experiment done.
    fn wait_for_done(&self, percent: f64) {
        self.wait_for_line(&format!("with {percent} % done"), |l| {
            percent_done(l).is_some_and(|p| p >= percent)
        });
    }

    /// Waits for the job to end; its exit status and output.
    fn end(mut self, timeout: Duration) -> (std::process::ExitStatus, String) {
        let status = self.sbatch.wait_exit(timeout);
        (status, self.output())
    }

    /// Waits for the job to end; panics with its output unless it succeeded.
    fn finish(self) -> String {
        let name = self.name.clone();
        let log = self.sbatch.log();
        let (status, output) = self.end(JOB);
        assert!(
            status.success(),
            "job {name} failed ({status}); sbatch said:\n{log}\njob output:\n{output}"
        );
        output
    }
}

/// The state Slurm's record of job `name` gives (`COMPLETED`, `CANCELLED`, ...; records
/// are kept for 5 minutes after a job ends).
fn job_state(cluster: &Cluster, name: &str) -> String {
    let out = cluster
        .command("scontrol")
        .args(["--oneliner", "show", "job"])
        .output()
        .expect("scontrol runs");
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .find(|l| l.split(' ').any(|f| f == format!("JobName={name}")))
        .and_then(|l| l.split(' ').find_map(|f| f.strip_prefix("JobState=")))
        .unwrap_or_else(|| panic!("no job {name} in:\n{text}"))
        .to_string()
}

/// The "N % done" of a coordinator progress line.
fn percent_done(line: &str) -> Option<f64> {
    let before = line
        .split(" % done")
        .next()
        .filter(|_| line.contains(" % done"))?;
    before.rsplit(' ').next()?.parse().ok()
}

fn unfinished_runs(db: &Path) -> usize {
    tokio::runtime::Runtime::new().unwrap().block_on(async {
        let runs = Db::open(db, false).await.unwrap().runs().await.unwrap();
        runs.iter().filter(|r| !r.finished).count()
    })
}

/// Starts a cluster in a fresh directory (`None`: skipped, already said why).
fn cluster(name: &str) -> Option<(Cluster, PathBuf)> {
    let dir = temp_dir(name);
    Cluster::start(&dir, &CPUS).map(|c| (c, dir))
}

#[test]
fn three_nodes_in_one_job_build_the_library_run_builds() {
    let _one = one_at_a_time();
    let expected = expected();
    let Some((cluster, dir)) = cluster("slurm-three") else {
        return;
    };
    let run_dir = cluster.shared().join("run");
    let job = submit(&cluster, "three", &run_dir, &["--nodes=3"], &[]);
    // The live database is on the coordinator's node, in its local directory.
    let line = job.wait_for_line("starting the coordinator", |l| {
        l.contains("coordinator on node1")
    });
    let local = cluster.local_mount().display().to_string();
    assert!(line.contains(&format!("--db {local}/strider-")), "{line}");
    job.wait_for_done(10.0);
    let live: Vec<_> = std::fs::read_dir(cluster.node_local("node1"))
        .unwrap()
        .map(|e| e.unwrap().path().join("strider.db"))
        .collect();
    assert!(
        live.len() == 1 && live[0].is_file(),
        "node1's local directory should hold the live database: {live:?}"
    );
    for node in ["node2", "node3"] {
        assert_eq!(
            std::fs::read_dir(cluster.node_local(node)).unwrap().count(),
            0,
            "nothing on {node}'s local disk"
        );
    }
    let output = job.finish();

    // A worker on every node, each sized to its own node; node1's leaves the coordinator
    // its 2 cores.
    for (node, threads) in [("node1", 2), ("node2", 2), ("node3", 1)] {
        assert!(
            output.contains(&format!("worker on {node}: {threads} threads")),
            "{output}"
        );
        assert!(
            output
                .lines()
                .any(|l| l.contains("worker connected") && l.contains(&format!("{node} pid"))),
            "no worker from {node} connected:\n{output}"
        );
    }
    assert!(output.contains("coordinator done"), "{output}");
    assert_eq!(job_state(&cluster, "three"), "COMPLETED");
    // The copy on shared storage is the whole run; the live database is gone with the job.
    let copy = run_dir.join("strider.db");
    assert_eq!(unfinished_runs(&copy), 0, "{output}");
    assert!(
        !live[0].exists(),
        "the live database should be removed after a clean exit"
    );
    assert_same_library(&export(&copy), expected);
    drop(cluster);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_worker_node_lost_mid_run_leaves_the_job_running_and_the_library_unchanged() {
    let _one = one_at_a_time();
    let expected = expected();
    let Some((mut cluster, dir)) = cluster("slurm-lost-worker") else {
        return;
    };
    let run_dir = cluster.shared().join("run");
    let job = submit(&cluster, "lost-worker", &run_dir, &["--nodes=3"], &[]);
    job.wait_for_line("node3's worker connecting", |l| {
        l.contains("worker connected") && l.contains("node3 pid")
    });
    job.wait_for_done(20.0);
    cluster.lose_node("node3");
    let output = job.finish();
    // Slurm saw the node go, and the job went on without it.
    cluster.wait_for_node_state("node3", "down", NOTICED);
    assert!(output.contains("coordinator done"), "{output}");
    let copy = run_dir.join("strider.db");
    assert_eq!(unfinished_runs(&copy), 0, "{output}");
    assert_same_library(&export(&copy), expected);
    drop(cluster);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_coordinator_node_lost_ends_the_job_and_the_next_job_resumes_from_the_shared_copy() {
    let _one = one_at_a_time();
    let expected = expected();
    let Some((mut cluster, dir)) = cluster("slurm-lost-coordinator") else {
        return;
    };
    let run_dir = cluster.shared().join("run");
    let copy = run_dir.join("strider.db");
    let job = submit(
        &cluster,
        "lost-coordinator",
        &run_dir,
        &["--nodes=3"],
        &[("STRIDER_BACKUP_EVERY", "1")],
    );
    job.wait_for_done(30.0);
    assert!(copy.is_file(), "no copy on shared storage yet");
    cluster.lose_node("node1");
    // The workers on node2 and node3 give up on their coordinator and cancel the job
    // (`sbatch --wait` says 0 for a cancelled job; Slurm's record says what happened).
    let (_, output) = job.end(JOB);
    assert_eq!(
        job_state(&cluster, "lost-coordinator"),
        "CANCELLED",
        "{output}"
    );
    assert!(
        unfinished_runs(&copy) > 0,
        "the copy should be of an unfinished run:\n{output}"
    );

    // Submitted again: node1 is down, so the coordinator runs on node2, from the copy.
    let again = submit(&cluster, "again", &run_dir, &["--nodes=2"], &[]);
    let output = again.finish();
    assert!(output.contains("coordinator on node2"), "{output}");
    assert!(output.contains("starting from the copy"), "{output}");
    assert_eq!(unfinished_runs(&copy), 0, "{output}");
    assert_same_library(&export(&copy), expected);
    drop(cluster);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_job_cut_short_is_resumed_by_a_coordinator_job_and_a_separate_two_node_worker_job() {
    let _one = one_at_a_time();
    let expected = expected();
    let Some((cluster, dir)) = cluster("slurm-separate") else {
        return;
    };
    let run_dir = cluster.shared().join("run");
    let copy = run_dir.join("strider.db");

    // A one-minute limit with leasing stopped 58 s before it (after 2 s): cut short.
    let cut = submit(
        &cluster,
        "cut",
        &run_dir,
        &["--nodes=1", "--time=1"],
        &[("STRIDER_STOP_MARGIN", "58")],
    );
    let output = cut.finish();
    assert!(output.contains("leasing stops after"), "{output}");
    assert!(output.contains("out of time"), "{output}");
    assert!(
        unfinished_runs(&copy) > 0,
        "the time limit should have cut the run short:\n{output}"
    );

    // Submitted again as the header says, as a small coordinator job and a worker job on
    // the two other nodes that finds it through the address file.
    let coordinator = submit(
        &cluster,
        "coordinator",
        &run_dir,
        &[
            "--nodes=1",
            "--ntasks-per-node=1",
            "--cpus-per-task=2",
            "--oversubscribe",
        ],
        &[("STRIDER_ROLE", "coordinator")],
    );
    coordinator.wait_for_line("the coordinator serving", |l| {
        l.contains("serving experiment")
    });
    let workers = submit(
        &cluster,
        "workers",
        &run_dir,
        &["--nodes=2"],
        &[("STRIDER_ROLE", "workers")],
    );
    let output = coordinator.finish();
    assert!(output.contains("starting from the copy"), "{output}");
    let worker_output = workers.finish();
    assert!(worker_output.contains("workers done"), "{worker_output}");
    let coordinator_node = output
        .lines()
        .find_map(|l| l.split("coordinator on ").nth(1))
        .and_then(|rest| rest.split(':').next())
        .unwrap_or_else(|| panic!("no coordinator line:\n{output}"))
        .to_string();
    for node in cluster.nodes() {
        let here = worker_output.contains(&format!("worker on {node}:"));
        assert_eq!(
            here,
            node != coordinator_node,
            "workers on the two nodes the coordinator is not on:\n{worker_output}"
        );
    }
    assert_eq!(unfinished_runs(&copy), 0, "{output}");
    assert_same_library(&export(&copy), expected);
    drop(cluster);
    std::fs::remove_dir_all(&dir).unwrap();
}
