//! The deployment files pass their standard validators: systemd units
//! (`systemd-analyze verify`), Kubernetes manifests (`kubernetes-validate --strict`, the
//! API schemas), the Slurm script and the PGO build script (`shellcheck`); and the Dockerfile builds the way the
//! README says. A missing validator skips its test, saying so (CI installs them all and
//! sets `STRIDER_REQUIRE_TOOLS`, so there it fails instead).

use std::path::{Path, PathBuf};
use std::process::Command;
use strider_tests::{binary, installed, skip_without, temp_dir, workspace_root};

fn deploy(path: &str) -> PathBuf {
    workspace_root().join("deploy").join(path)
}

/// Runs a validator; any failure or any complaint on stderr fails the test.
fn validate(cmd: &mut Command) {
    let out = cmd.output().expect("the validator runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && stderr.trim().is_empty(),
        "{cmd:?} ({}):\n{}{stderr}",
        out.status,
        String::from_utf8_lossy(&out.stdout)
    );
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else if entry.file_type().unwrap().is_file() {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

#[test]
fn the_systemd_units_pass_systemd_analyze_verify() {
    if !installed("systemd-analyze") {
        return skip_without("systemd-analyze is not installed (apt-get install systemd)");
    }
    // A root with the binaries where the units expect them and the system's own units
    // (the default dependencies), so nothing outside the temporary directory is touched.
    let root = temp_dir("systemd-root");
    std::fs::create_dir_all(root.join("usr/local/bin")).unwrap();
    for b in ["strider-coordinator", "strider-worker"] {
        std::fs::copy(binary(b), root.join("usr/local/bin").join(b)).unwrap();
    }
    for system in ["/usr/lib/systemd/system", "/lib/systemd/system"] {
        if Path::new(system).is_dir() {
            copy_dir(
                Path::new(system),
                &root.join(system.trim_start_matches('/')),
            );
            break;
        }
    }
    let units = root.join("etc/systemd/system");
    std::fs::create_dir_all(&units).unwrap();
    for unit in ["strider-coordinator.service", "strider-worker.service"] {
        std::fs::copy(deploy("systemd").join(unit), units.join(unit)).unwrap();
        validate(
            Command::new("systemd-analyze")
                .arg(format!("--root={}", root.display()))
                .arg("verify")
                .arg(units.join(unit)),
        );
    }
    std::fs::remove_dir_all(&root).unwrap();
}

#[test]
fn the_kubernetes_manifests_match_the_api_schemas() {
    if !installed("kubernetes-validate") {
        return skip_without(
            "kubernetes-validate is not installed (pip install kubernetes-validate)",
        );
    }
    validate(
        Command::new("kubernetes-validate")
            .args(["--strict", "--quiet"])
            .arg(deploy("kubernetes/coordinator.yaml"))
            .arg(deploy("kubernetes/workers.yaml")),
    );
}

#[test]
fn the_shell_scripts_pass_shellcheck() {
    if !installed("shellcheck") {
        return skip_without("shellcheck is not installed (apt-get install shellcheck)");
    }
    for script in ["slurm/strider.sbatch", "build-pgo.sh"] {
        validate(Command::new("shellcheck").arg(deploy(script)));
    }
}

#[test]
fn the_dockerfile_builds_with_the_readmes_commands() {
    let dockerfile = std::fs::read_to_string(deploy("container/Dockerfile")).unwrap();
    let readme = std::fs::read_to_string(workspace_root().join("README.md")).unwrap();
    let builds: Vec<&str> = dockerfile
        .lines()
        .filter_map(|l| l.trim().strip_prefix("RUN "))
        .filter(|c| c.starts_with("cargo "))
        .collect();
    assert!(
        !builds.is_empty(),
        "the Dockerfile builds nothing with cargo"
    );
    for command in builds {
        assert!(
            readme.lines().any(|l| l.trim() == command),
            "the Dockerfile runs `{command}`, which the README does not"
        );
    }
    // The image carries the two binaries the README builds.
    for b in ["strider-coordinator", "strider-worker"] {
        assert!(
            dockerfile.contains(&format!("target/release/{b}")),
            "{b} is not in the image"
        );
    }
}
