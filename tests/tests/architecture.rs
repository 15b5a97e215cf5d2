//! The rules of the layout that a change could quietly break: a coordinator for a cluster's
//! head node links no physics engine, the command lines stay thin, and the
//! quality-diversity core (library, breeding, scheduler, the changes it emits) knows
//! nothing of storage or the network.

use std::process::Command;
use strider_tests::workspace_root;

/// The normal and build dependencies of the coordinator, as `cargo tree` prints them.
fn coordinator_tree(default_features: bool) -> String {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.args(["tree", "-p", "strider-coordinator", "-e", "normal,build"])
        .args(["--prefix", "none", "--locked", "--offline"])
        .current_dir(workspace_root());
    if !default_features {
        cmd.arg("--no-default-features");
    }
    let out = cmd.output().expect("cargo runs");
    assert!(
        out.status.success(),
        "cargo tree: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

fn names(tree: &str) -> Vec<&str> {
    tree.lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect()
}

#[test]
fn a_coordinator_built_without_the_simulator_links_no_physics_engine() {
    let head_node = coordinator_tree(false);
    let head_node = names(&head_node);
    assert!(head_node.contains(&"tonic"), "{head_node:?}");
    for crate_name in ["rapier3d", "strider-worker", "parry3d"] {
        assert!(
            !head_node.contains(&crate_name),
            "{crate_name} in {head_node:?}"
        );
    }
    // The default build embeds the evaluator for `run`.
    let default = coordinator_tree(true);
    assert!(names(&default).contains(&"rapier3d"));
}

fn source(path: &str) -> String {
    std::fs::read_to_string(workspace_root().join(path)).expect(path)
}

#[test]
fn both_main_files_only_parse_and_map_outcomes_to_exit_statuses() {
    for main in ["coordinator/src/main.rs", "worker/src/main.rs"] {
        let lines = source(main).lines().count();
        assert!(lines < 150, "{main} has {lines} lines");
    }
}

#[test]
fn the_quality_diversity_core_imports_nothing_from_storage_or_the_service() {
    for core in [
        "coordinator/src/scheduler.rs",
        "coordinator/src/library.rs",
        "coordinator/src/evolution.rs",
        "coordinator/src/changes.rs",
    ] {
        let text = source(core);
        for outside in ["crate::db", "crate::service", "sqlx", "tonic"] {
            assert!(!text.contains(outside), "{core} uses {outside}");
        }
    }
}
