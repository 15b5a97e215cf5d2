//! The shipped Slurm script (`deploy/slurm/strider.sbatch`) on a private single-node
//! Slurm cluster: munged, slurmctld and slurmd from Debian's packages, configured in a
//! temporary directory and stopped afterwards.
//!
//! Skipped, saying so, when Slurm is not installed; `.ci/run` installs it and sets
//! `STRIDER_REQUIRE_TOOLS=1`, which turns a missing Slurm into a failure.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};
use strider_coordinator::db::Db;
use strider_tests::{
    assert_same_library, binary, export, free_port, installed, skip_without, temp_dir,
    workspace_root, Process,
};

const EXPERIMENT: &str = "tests/fixtures/service.toml";
/// Generous: CI machines are slow and busy; the whole experiment takes well under this.
const JOB: Duration = Duration::from_secs(600);
const START: Duration = Duration::from_secs(60);

/// A running private Slurm cluster of one node; stopped (jobs cancelled, daemons ended)
/// when dropped.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    // Dropped last to first: slurmd, slurmctld, then munged.
    munged: Option<Process>,
    slurmctld: Option<Process>,
    slurmd: Option<Process>,
}

impl Cluster {
    /// Starts the cluster, or `None` (after saying so) when Slurm is not installed.
    fn start(dir: &Path) -> Option<Cluster> {
        let needed = [
            "munged",
            "slurmctld",
            "slurmd",
            "sbatch",
            "squeue",
            "scancel",
        ];
        let missing: Vec<_> = needed.iter().filter(|p| !installed(p)).collect();
        if !missing.is_empty() {
            skip_without(&format!(
                "Slurm is not installed ({missing:?} missing; apt-get install slurmctld slurmd munge)"
            ));
            return None;
        }
        let munge = dir.join("munge");
        let spool = dir.join("spool");
        let state = dir.join("state");
        for d in [&munge, &spool, &state] {
            std::fs::create_dir_all(d).unwrap();
        }
        let key = munge.join("munge.key");
        std::fs::write(&key, random_bytes(1024)).unwrap();
        set_mode(&key, 0o400);
        set_mode(&munge, 0o755);
        let socket = munge.join("munge.socket");
        let mut cmd = Command::new("munged");
        cmd.args(["--foreground", "--force"])
            .arg(format!("--socket={}", socket.display()))
            .arg(format!("--key-file={}", key.display()))
            .arg(format!("--pid-file={}", munge.join("munged.pid").display()))
            .arg(format!("--seed-file={}", munge.join("seed").display()))
            .arg(format!("--log-file={}", munge.join("munged.log").display()));
        let munged = Process::spawn("munged", cmd);
        munged.wait_for_line(
            "creating its socket",
            |l| l.contains("Created socket"),
            START,
        );

        let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .unwrap()
            .trim()
            .to_string();
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        let conf = dir.join("slurm.conf");
        let d = dir.display();
        std::fs::write(
            &conf,
            format!(
                "ClusterName=strider-test
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={ctld}
SlurmdPort={slurmd}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={socket}
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/slurmctld.log
SlurmdLogFile={d}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
KillWait=10
InactiveLimit=0
NodeName=strider-test NodeHostname={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
",
                ctld = free_port(),
                slurmd = free_port(),
                socket = socket.display(),
            ),
        )
        .unwrap();
        let mut cluster = Cluster {
            dir: dir.to_path_buf(),
            conf,
            munged: Some(munged),
            slurmctld: None,
            slurmd: None,
        };
        let mut ctld = cluster.command("slurmctld");
        ctld.args(["-D", "-i"]);
        cluster.slurmctld = Some(Process::spawn("slurmctld", ctld));
        let mut slurmd = cluster.command("slurmd");
        slurmd.args(["-D", "-N", "strider-test"]);
        cluster.slurmd = Some(Process::spawn("slurmd", slurmd));
        cluster.wait_for_idle_node();
        Some(cluster)
    }

    /// A Slurm command that talks to this cluster.
    fn command(&self, program: &str) -> Command {
        let mut cmd = Command::new(program);
        cmd.env("SLURM_CONF", &self.conf).current_dir(&self.dir);
        cmd
    }

    /// Polls `sinfo` until the node has registered and is idle (Slurm offers no event).
    fn wait_for_idle_node(&self) {
        let deadline = Instant::now() + START;
        loop {
            let out = self.command("sinfo").args(["-h", "-o", "%T"]).output();
            if let Ok(out) = out {
                if String::from_utf8_lossy(&out.stdout).trim() == "idle" {
                    return;
                }
            }
            assert!(
                Instant::now() < deadline,
                "the Slurm node never became idle; slurmctld log:\n{}\nslurmd log:\n{}",
                self.daemon_log("slurmctld.log"),
                self.daemon_log("slurmd.log")
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    fn daemon_log(&self, name: &str) -> String {
        std::fs::read_to_string(self.dir.join(name)).unwrap_or_default()
    }

    /// Submits the shipped script with `sbatch --wait` (returns when the job ends).
    fn submit(&self, name: &str, sbatch_args: &[&str], env: &[(&str, &str)]) -> Process {
        let mut cmd = self.command("sbatch");
        cmd.arg("--wait")
            .arg(format!("--job-name={name}"))
            .arg(format!(
                "--output={}",
                self.dir.join(format!("{name}.out")).display()
            ))
            .args(sbatch_args)
            .arg(workspace_root().join("deploy/slurm/strider.sbatch"))
            .arg(workspace_root().join(EXPERIMENT));
        for (k, v) in env {
            cmd.env(k, v);
        }
        cmd.env(
            "STRIDER_BIN_DIR",
            binary("strider-coordinator").parent().unwrap(),
        )
        .env("STRIDER_PROGRESS_EVERY", "1");
        Process::spawn(name, cmd)
    }

    /// Waits for a submitted job; panics with its output unless it succeeded.
    fn finish(&self, mut job: Process, name: &str) -> String {
        let status = job.wait_exit(JOB);
        let output = std::fs::read_to_string(self.dir.join(format!("{name}.out")))
            .unwrap_or_else(|e| format!("(no job output: {e})"));
        assert!(
            status.success(),
            "job {name} failed ({status}); sbatch said:\n{}\njob output:\n{output}",
            job.log()
        );
        output
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Cancel every job first, so slurmstepd ends our processes, then the daemons.
        let _ = self.command("scancel").arg("--user=root").status();
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            match self.command("squeue").args(["-h", "-o", "%i"]).output() {
                Ok(o) if o.status.success() && o.stdout.is_empty() => break,
                Ok(o) if o.status.success() => {}
                _ => break,
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        for p in [&self.slurmd, &self.slurmctld, &self.munged]
            .into_iter()
            .flatten()
        {
            // SAFETY: kill(2) on our own child.
            unsafe { libc::kill(p.pid() as i32, libc::SIGTERM) };
        }
        for p in [&mut self.slurmd, &mut self.slurmctld, &mut self.munged] {
            if let Some(mut p) = p.take() {
                let _ = p.wait_exit(Duration::from_secs(30));
            }
        }
    }
}

fn random_bytes(n: usize) -> Vec<u8> {
    use std::io::Read;
    let mut buf = vec![0; n];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut buf))
        .expect("reading /dev/urandom");
    buf
}

fn set_mode(path: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode)).unwrap();
}

fn unfinished_runs(db: &Path) -> usize {
    tokio::runtime::Runtime::new().unwrap().block_on(async {
        let runs = Db::open(db, false).await.unwrap().runs().await.unwrap();
        runs.iter().filter(|r| !r.finished).count()
    })
}

#[test]
fn the_batch_script_runs_an_experiment_and_a_job_cut_short_is_resumed_by_the_next() {
    let dir = temp_dir("slurm");
    let Some(cluster) = Cluster::start(&dir) else {
        return;
    };

    // One allocation, uninterrupted: coordinator and a worker on the node.
    let whole = dir.join("whole");
    let whole_dir = whole.to_str().unwrap();
    let job = cluster.submit("whole", &["--nodes=1"], &[("STRIDER_RUN_DIR", whole_dir)]);
    let output = cluster.finish(job, "whole");
    assert!(output.contains("coordinator done"), "{output}");
    assert_eq!(unfinished_runs(&whole.join("strider.db")), 0, "{output}");
    let expected = export(&whole.join("strider.db"));

    // The same, with a one-minute limit and leasing stopped 58 s before it (after 2 s of
    // the run's 3): cut short.
    let cut = dir.join("cut");
    let cut_dir = cut.to_str().unwrap();
    let job = cluster.submit(
        "cut",
        &["--nodes=1", "--time=1"],
        &[("STRIDER_RUN_DIR", cut_dir), ("STRIDER_STOP_MARGIN", "58")],
    );
    let output = cluster.finish(job, "cut");
    assert!(output.contains("leasing stops after"), "{output}");
    assert!(output.contains("out of time"), "{output}");
    assert!(
        unfinished_runs(&cut.join("strider.db")) > 0,
        "the time limit should have cut the run short:\n{output}"
    );

    // Submitted again, as separate coordinator and worker jobs, with the live database on
    // "node-local" disk: it starts from the run directory's database, goes on to the end,
    // and leaves its copy there.
    let local_db = dir.join("node-local").join("strider.db");
    let coordinator = cluster.submit(
        "coordinator",
        &["--nodes=1", "--oversubscribe", "--cpus-per-task=1"],
        &[
            ("STRIDER_RUN_DIR", cut_dir),
            ("STRIDER_ROLE", "coordinator"),
            ("STRIDER_DB", local_db.to_str().unwrap()),
        ],
    );
    let workers = cluster.submit(
        "workers",
        &["--nodes=1", "--oversubscribe", "--cpus-per-task=1"],
        &[("STRIDER_RUN_DIR", cut_dir), ("STRIDER_ROLE", "workers")],
    );
    let output = cluster.finish(coordinator, "coordinator");
    assert!(output.contains("starting from the copy"), "{output}");
    cluster.finish(workers, "workers");
    assert_eq!(unfinished_runs(&local_db), 0, "{output}");
    assert_eq!(unfinished_runs(&cut.join("strider.db")), 0, "{output}");
    assert_same_library(&export(&cut.join("strider.db")), &expected);

    drop(cluster);
    std::fs::remove_dir_all(&dir).unwrap();
}
