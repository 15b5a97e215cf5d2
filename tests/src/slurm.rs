//! A private multi-node Slurm cluster on one machine, for tests that run the shipped
//! batch script across nodes.
//!
//! The controller (`slurmctld`, host `ctl`) lives in a "hub" network namespace that holds a
//! bridge; every node is a `slurmd` in its own network namespace (linked to the bridge by
//! a veth pair, address 10.78.0.1N), its own UTS namespace (host name `nodeN`) and its own
//! mount namespace, in which:
//! - `/etc/hosts` names the controller and every node (as a site's DNS would), and
//! - [`Cluster::local_mount`] is the node's own directory ([`Cluster::node_local`]): the
//!   same path on every node, different disks, like `/tmp` or `/scratch` on a real site.
//!
//! [`Cluster::shared`] is seen by every node alike: the shared file system. One `munged`
//! serves them all (its socket is a path, which namespaces do not separate). Everything
//! is stopped and removed when the cluster is dropped, and every wait is bounded.
//!
//! Needs root, iproute2, util-linux (`nsenter`, `unshare`), munge and Slurm's daemons
//! (Debian's slurmctld, slurmd, munge, slurm-client); [`Cluster::start`] says what is
//! missing and returns `None` (failing instead under `STRIDER_REQUIRE_TOOLS`).

use crate::{installed, ip, ip_ok, skip_without, Process};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// How long daemons get to start and nodes to register.
const START: Duration = Duration::from_secs(60);
/// How long Slurm gets to end the jobs and the daemons to exit on teardown.
const STOP: Duration = Duration::from_secs(30);

/// A running private cluster; see the module documentation.
pub struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    /// Prefix of this cluster's network namespaces (unique per process and cluster).
    prefix: String,
    /// CPUs each node declares, node `i + 1` at index `i`.
    cpus: Vec<u32>,
    // Stopped in reverse order of start: slurmds, slurmctld, then munged.
    munged: Option<Process>,
    slurmctld: Option<Process>,
    slurmds: Vec<Option<Process>>,
}

impl Cluster {
    /// Starts a cluster of `cpus.len()` nodes, node N declaring `cpus[N-1]` CPUs (more than
    /// the machine has is fine: the declared counts are what jobs get), and waits until
    /// every node is idle. `None`, after saying why, where it cannot be had.
    pub fn start(dir: &Path, cpus: &[u32]) -> Option<Cluster> {
        assert!(!cpus.is_empty() && cpus.len() < 90, "1 to 89 nodes");
        let needed = [
            "munged",
            "slurmctld",
            "slurmd",
            "sbatch",
            "squeue",
            "scancel",
            "sinfo",
            "scontrol",
            "ip",
            "nsenter",
            "unshare",
        ];
        let missing: Vec<_> = needed.iter().filter(|p| !installed(p)).collect();
        if !missing.is_empty() {
            skip_without(&format!(
                "a private Slurm cluster needs {missing:?} (apt-get install slurmctld slurmd \
                 munge slurm-client iproute2)"
            ));
            return None;
        }
        static CLUSTERS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = CLUSTERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let prefix = format!("sl{}x{n}", std::process::id());
        let hub = format!("{prefix}hub");
        let probe = ip(&["netns", "add", &hub]);
        if !probe.status.success() {
            skip_without(&format!(
                "cannot create network namespaces for a Slurm cluster (needs root): {}",
                String::from_utf8_lossy(&probe.stderr).trim()
            ));
            return None;
        }
        let mut cluster = Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
            prefix,
            cpus: cpus.to_vec(),
            munged: None,
            slurmctld: None,
            slurmds: Vec::new(),
        };
        cluster.build_network();
        for d in ["munge", "state", "shared", "local"] {
            std::fs::create_dir_all(dir.join(d)).unwrap();
        }
        for node in cluster.nodes() {
            std::fs::create_dir_all(dir.join(&node).join("local")).unwrap();
            std::fs::create_dir_all(dir.join(&node).join("spool")).unwrap();
        }
        let mut hosts = String::from("127.0.0.1 localhost\n10.78.0.1 ctl\n");
        for (i, node) in cluster.nodes().iter().enumerate() {
            hosts += &format!("10.78.0.{} {node}\n", 11 + i);
        }
        std::fs::write(dir.join("hosts"), hosts).unwrap();
        cluster.munged = Some(start_munged(&dir.join("munge")));
        cluster.write_conf();

        let ctld = cluster.in_namespace(
            "hub",
            "ctl",
            &[],
            &[
                "slurmctld",
                "-D",
                "-i",
                "-f",
                cluster.conf.to_str().unwrap(),
            ],
        );
        cluster.slurmctld = Some(Process::spawn("slurmctld", ctld));
        for node in cluster.nodes() {
            let binds = [
                (dir.join("hosts"), PathBuf::from("/etc/hosts")),
                (dir.join(&node).join("local"), cluster.local_mount()),
            ];
            let slurmd = cluster.in_namespace(
                &node,
                &node,
                &binds,
                &[
                    "slurmd",
                    "-D",
                    "-N",
                    &node,
                    "-f",
                    cluster.conf.to_str().unwrap(),
                ],
            );
            cluster.slurmds.push(Some(Process::spawn(&node, slurmd)));
        }
        cluster.wait_for_idle_nodes();
        Some(cluster)
    }

    /// The node names, `node1` to `nodeN`.
    pub fn nodes(&self) -> Vec<String> {
        (1..=self.cpus.len()).map(|i| format!("node{i}")).collect()
    }

    /// The directory every node sees alike (the shared file system).
    pub fn shared(&self) -> PathBuf {
        self.dir.join("shared")
    }

    /// The path at which every node sees its own local directory (give it to jobs as
    /// `TMPDIR`); from outside the nodes it is an empty directory.
    pub fn local_mount(&self) -> PathBuf {
        self.dir.join("local")
    }

    /// Node `node`'s local directory, as the test (outside every node) sees it.
    pub fn node_local(&self, node: &str) -> PathBuf {
        self.dir.join(node).join("local")
    }

    fn ns(&self, name: &str) -> String {
        format!("{}{name}", self.prefix)
    }

    /// The hub (with the bridge and the controller) and one namespace per node.
    fn build_network(&self) {
        let hub = self.ns("hub");
        ip_ok(&["-n", &hub, "link", "set", "lo", "up"]);
        ip_ok(&["-n", &hub, "link", "add", "br0", "type", "bridge"]);
        ip_ok(&["-n", &hub, "addr", "add", "10.78.0.1/24", "dev", "br0"]);
        ip_ok(&["-n", &hub, "link", "set", "br0", "up"]);
        for (i, node) in self.nodes().iter().enumerate() {
            let ns = self.ns(node);
            ip_ok(&["netns", "add", &ns]);
            ip_ok(&["-n", &ns, "link", "set", "lo", "up"]);
            // The hub's end of the link is named after the node, the node's is eth0.
            ip_ok(&[
                "-n", &hub, "link", "add", node, "type", "veth", "peer", "name", "eth0", "netns",
                &ns,
            ]);
            ip_ok(&["-n", &hub, "link", "set", node, "master", "br0"]);
            ip_ok(&["-n", &hub, "link", "set", node, "up"]);
            let addr = format!("10.78.0.{}/24", 11 + i);
            ip_ok(&["-n", &ns, "addr", "add", &addr, "dev", "eth0"]);
            ip_ok(&["-n", &ns, "link", "set", "eth0", "up"]);
        }
    }

    fn write_conf(&self) {
        let d = self.dir.display();
        let mut nodes = String::new();
        for (i, (node, cpus)) in self.nodes().iter().zip(&self.cpus).enumerate() {
            nodes += &format!(
                "NodeName={node} NodeAddr=10.78.0.{} CPUs={cpus} State=UNKNOWN\n",
                11 + i
            );
        }
        // SlurmdTimeout: a lost node is noticed within about half a minute (Slurm pings
        // on its own cycle). JobRequeue=0: a job whose batch node is lost ends, and is
        // submitted again by hand (a site's default requeues it by itself, the same way).
        // config_overrides: nodes declare the CPUs the test gives them, not the machine's.
        let conf = format!(
            "ClusterName=strider-test
SlurmctldHost=ctl(10.78.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={d}/munge/munge.socket
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/%n/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/%n/slurmd.pid
SlurmctldLogFile={d}/slurmctld.log
SlurmdLogFile={d}/%n/slurmd.log
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
SlurmdTimeout=5
JobRequeue=0
KillWait=10
InactiveLimit=0
SlurmdParameters=config_overrides
{nodes}PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
"
        );
        std::fs::write(&self.conf, conf).unwrap();
    }

    /// `program` in namespace `ns` (its network), with host name `host` and the bind
    /// mounts `binds` (source, target) private to it. `nsenter` rather than `ip netns
    /// exec`, which remounts /sys and so hides the cgroup hierarchy slurmd needs.
    fn in_namespace(
        &self,
        ns: &str,
        host: &str,
        binds: &[(PathBuf, PathBuf)],
        program: &[&str],
    ) -> Command {
        let mut script = format!("hostname {host}");
        for (from, to) in binds {
            script += &format!(" && mount --bind '{}' '{}'", from.display(), to.display());
        }
        script += " && exec \"$@\"";
        let mut cmd = Command::new("nsenter");
        cmd.arg(format!("--net=/run/netns/{}", self.ns(ns)))
            .args(["unshare", "--uts", "--mount", "--propagation", "private"])
            .args(["sh", "-c", &script, "sh"])
            .args(program)
            .env("SLURM_CONF", &self.conf);
        cmd
    }

    /// A Slurm client command (`sbatch`, `squeue`, ...) run beside the controller.
    pub fn command(&self, program: &str) -> Command {
        let mut cmd = Command::new("nsenter");
        cmd.arg(format!("--net=/run/netns/{}", self.ns("hub")))
            .arg(program)
            .env("SLURM_CONF", &self.conf);
        cmd
    }

    /// Each node's state as `sinfo` gives it (`idle`, `alloc`, `down*`, ...).
    pub fn node_states(&self) -> Vec<(String, String)> {
        let out = self
            .command("sinfo")
            .args(["-h", "-N", "-o", "%N %T"])
            .output();
        let Ok(out) = out else { return Vec::new() };
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter_map(|l| {
                let (n, s) = l.split_once(' ')?;
                Some((n.to_string(), s.trim().to_string()))
            })
            .collect()
    }

    /// Polls `sinfo` until every node has registered and is idle (Slurm offers no event).
    fn wait_for_idle_nodes(&self) {
        let deadline = Instant::now() + START;
        loop {
            let states = self.node_states();
            if states.len() == self.cpus.len() && states.iter().all(|(_, s)| s == "idle") {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "the Slurm nodes never all became idle ({states:?}); {}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// The daemons' logs, for a failure message.
    pub fn logs(&self) -> String {
        let mut out = format!(
            "slurmctld log:\n{}",
            std::fs::read_to_string(self.dir.join("slurmctld.log")).unwrap_or_default()
        );
        for node in self.nodes() {
            let log = std::fs::read_to_string(self.dir.join(&node).join("slurmd.log"))
                .unwrap_or_default();
            out += &format!("\n{node} slurmd log:\n{log}");
        }
        out
    }

    /// Loses node `node` as a power cut would: every process on it (slurmd, the job's
    /// steps and whatever they run) is killed at once and its link goes down, so that
    /// nothing it held is handed back and nobody is told.
    pub fn lose_node(&mut self, node: &str) {
        let i = self
            .nodes()
            .iter()
            .position(|n| n == node)
            .unwrap_or_else(|| panic!("no node {node}"));
        ip_ok(&["-n", &self.ns("hub"), "link", "set", node, "down"]);
        let deadline = Instant::now() + STOP;
        loop {
            let pids = self.pids_on(node);
            if pids.is_empty() {
                break;
            }
            for pid in pids {
                // SAFETY: kill(2); a pid that has just exited is at worst refused.
                unsafe { libc::kill(pid, libc::SIGKILL) };
            }
            assert!(
                Instant::now() < deadline,
                "processes on {node} survive SIGKILL"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        if let Some(mut slurmd) = self.slurmds[i].take() {
            let _ = slurmd.wait_exit(STOP);
        }
    }

    /// The processes in node `node`'s network namespace.
    fn pids_on(&self, node: &str) -> Vec<i32> {
        let out = ip(&["netns", "pids", &self.ns(node)]);
        String::from_utf8_lossy(&out.stdout)
            .split_whitespace()
            .filter_map(|p| p.parse().ok())
            .collect()
    }

    /// Polls `sinfo` until node `node`'s state starts with `state` (`down`, ...).
    pub fn wait_for_node_state(&self, node: &str, state: &str, timeout: Duration) {
        let deadline = Instant::now() + timeout;
        loop {
            let states = self.node_states();
            if states
                .iter()
                .any(|(n, s)| n == node && s.starts_with(state))
            {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "{node} never became {state} ({states:?}); {}",
                self.logs()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}

/// munged on a fresh key, its socket in `dir`.
fn start_munged(dir: &Path) -> Process {
    let key = dir.join("munge.key");
    std::fs::write(&key, random_bytes(1024)).unwrap();
    set_mode(&key, 0o400);
    set_mode(dir, 0o755);
    let mut cmd = Command::new("munged");
    cmd.args(["--foreground", "--force"])
        .arg(format!("--socket={}", dir.join("munge.socket").display()))
        .arg(format!("--key-file={}", key.display()))
        .arg(format!("--pid-file={}", dir.join("munged.pid").display()))
        .arg(format!("--seed-file={}", dir.join("seed").display()))
        .arg(format!("--log-file={}", dir.join("munged.log").display()));
    let munged = Process::spawn("munged", cmd);
    munged.wait_for_line(
        "creating its socket",
        |l| l.contains("Created socket"),
        START,
    );
    munged
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Cancel every job first, so slurmstepd ends our processes, then the daemons.
        if self.slurmctld.is_some() {
            let _ = self.command("scancel").arg("--user=root").output();
            let deadline = Instant::now() + STOP;
            while Instant::now() < deadline {
                match self.command("squeue").args(["-h", "-o", "%i"]).output() {
                    Ok(o) if o.status.success() && o.stdout.is_empty() => break,
                    Ok(o) if o.status.success() => {}
                    _ => break,
                }
                std::thread::sleep(Duration::from_millis(200));
            }
        }
        let daemons = self.slurmds.iter().flatten().chain(&self.slurmctld);
        for p in daemons.chain(&self.munged) {
            // SAFETY: kill(2) on our own child.
            unsafe { libc::kill(p.pid() as i32, libc::SIGTERM) };
        }
        let daemons = self.slurmds.iter_mut().chain([&mut self.slurmctld]);
        for p in daemons.chain([&mut self.munged]) {
            if let Some(mut p) = p.take() {
                let _ = p.wait_exit(STOP);
            }
        }
        // Whatever a node still runs (a step Slurm lost track of) ends with it.
        for node in self.nodes() {
            for pid in self.pids_on(&node) {
                // SAFETY: kill(2) on a process in a namespace this cluster made.
                unsafe { libc::kill(pid, libc::SIGKILL) };
            }
            let _ = ip(&["netns", "del", &self.ns(&node)]);
        }
        let _ = ip(&["netns", "del", &self.ns("hub")]);
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
