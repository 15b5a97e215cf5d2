//! The service across hosts: the coordinator and two workers each in their own network
//! namespace, joined by virtual links (veth pairs). One worker's link is cut mid-run
//! and later restored. Needs root (CAP_NET_ADMIN) and `ip`; skipped, saying so, without
//! (and failing instead where `STRIDER_REQUIRE_TOOLS` is set, as in CI).

use std::path::Path;
use std::process::Command;
use std::time::Duration;
use strider_tests::coordinator::{integrity, wait_serving};
use strider_tests::{
    assert_same_library, binary, export, free_port, ip, ip_ok, library_run_builds, secret_file,
    skip_without, temp_dir, workspace_root, Process,
};

const FIXTURE: &str = "tests/fixtures/service.toml";
const SECRET: &str = "network-test-secret-0123456789";
const START: Duration = Duration::from_secs(60);
const FINISH: Duration = Duration::from_secs(300);

/// Three namespaces, `c` (the coordinator) linked to `w1` and `w2`; removed when dropped
/// (with their links and anything still inside).
struct Network {
    prefix: String,
}

impl Network {
    /// Builds the network, or `None` (after saying why) where namespaces cannot be made.
    fn build() -> Option<Network> {
        let prefix = format!("strider{}", std::process::id());
        let probe = ip(&["netns", "add", &format!("{prefix}c")]);
        if !probe.status.success() {
            skip_without(&format!(
                "cannot create network namespaces (needs root and iproute2): {}",
                String::from_utf8_lossy(&probe.stderr).trim()
            ));
            return None;
        }
        let net = Network { prefix };
        let c = net.ns("c");
        ip_ok(&["-n", &c, "link", "set", "lo", "up"]);
        for w in [1, 2] {
            let ns = net.ns(&format!("w{w}"));
            ip_ok(&["netns", "add", &ns]);
            ip_ok(&["-n", &ns, "link", "set", "lo", "up"]);
            // The coordinator's end of the link is `c<w>`, the worker's `w<w>`.
            ip_ok(&[
                "-n",
                &c,
                "link",
                "add",
                &format!("c{w}"),
                "type",
                "veth",
                "peer",
                "name",
                &format!("w{w}"),
                "netns",
                &ns,
            ]);
            ip_ok(&[
                "-n",
                &c,
                "addr",
                "add",
                &format!("10.77.{w}.1/24"),
                "dev",
                &format!("c{w}"),
            ]);
            ip_ok(&[
                "-n",
                &ns,
                "addr",
                "add",
                &format!("10.77.{w}.2/24"),
                "dev",
                &format!("w{w}"),
            ]);
            ip_ok(&["-n", &c, "link", "set", &format!("c{w}"), "up"]);
            ip_ok(&["-n", &ns, "link", "set", &format!("w{w}"), "up"]);
        }
        Some(net)
    }

    fn ns(&self, name: &str) -> String {
        format!("{}{name}", self.prefix)
    }

    /// `program args...` inside namespace `name`.
    fn command(&self, name: &str, program: &Path) -> Command {
        let mut cmd = Command::new("ip");
        cmd.args(["netns", "exec", &self.ns(name)]).arg(program);
        cmd
    }

    /// Takes worker `w`'s link down (`false`) or up (`true`), at the coordinator's end:
    /// packets are dropped, nobody is told.
    fn link(&self, w: u32, up: bool) {
        ip_ok(&[
            "-n",
            &self.ns("c"),
            "link",
            "set",
            &format!("c{w}"),
            if up { "up" } else { "down" },
        ]);
    }
}

impl Drop for Network {
    fn drop(&mut self) {
        for n in ["w1", "w2", "c"] {
            let _ = ip(&["netns", "del", &self.ns(n)]);
        }
    }
}

#[test]
fn a_worker_cut_off_and_reconnected_changes_nothing() {
    let Some(net) = Network::build() else {
        return;
    };
    let expected = library_run_builds(FIXTURE);
    let dir = temp_dir("network");
    let db = dir.join("network.db");
    let secret = secret_file(&dir, SECRET);
    let port = free_port();

    let mut cmd = net.command("c", &binary("strider-coordinator"));
    cmd.args(["serve", "--db", db.to_str().unwrap(), "--experiment"])
        .arg(workspace_root().join(FIXTURE))
        .args(["--listen", &format!("0.0.0.0:{port}")])
        .args(["--token-file", secret.to_str().unwrap()])
        .args(["--lease-seconds", "3", "--progress-every", "0.2"]);
    let mut coordinator = Process::spawn("coordinator", cmd);
    wait_serving(&coordinator);

    let worker = |w: u32| {
        let mut cmd = net.command(&format!("w{w}"), &binary("strider-worker"));
        cmd.args(["--connect", &format!("http://10.77.{w}.1:{port}")])
            .args(["--threads", "1", "--name", &format!("w{w}")])
            .args(["--token-file", secret.to_str().unwrap()])
            .args(["--max-backoff-seconds", "0.5"]);
        Process::spawn(&format!("w{w}"), cmd)
    };
    // w1 works alone for a while, so it holds leases when its link goes.
    let mut w1 = worker(1);
    coordinator.wait_for_line("at generation 2", |l| l.contains("generation 2/20"), FINISH);
    net.link(1, false);
    let mut w2 = worker(2);
    coordinator.wait_for_line(
        "w2 connecting over its own link",
        |l| l.contains("worker connected") && l.contains("w2"),
        START,
    );
    // w1's leases run out and go to w2; the run goes on without w1.
    coordinator.wait_for_line(
        "about expired leases",
        |l| l.contains("leases expired"),
        START,
    );
    coordinator.wait_for_line("at generation 5", |l| l.contains("generation 5/20"), FINISH);
    // The link comes back: w1's late results (if its stream survived) change nothing,
    // and it works again until the end.
    net.link(1, true);
    let status = coordinator.wait_exit(FINISH);
    assert!(
        status.success(),
        "coordinator failed:\n{}",
        coordinator.log()
    );
    for w in [&mut w1, &mut w2] {
        let status = w.wait_exit(START);
        assert!(status.success(), "{}", w.log());
        assert!(
            w.log().contains("the experiment is finished"),
            "{}",
            w.log()
        );
    }
    assert_same_library(&export(&db), &expected);
    assert_eq!(integrity(&db), "ok");
    drop(net);
    std::fs::remove_dir_all(&dir).unwrap();
}
