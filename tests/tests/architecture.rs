//! The rules of the layout that a change could quietly break: a coordinator for a cluster's
//! head node links no physics engine, the command lines stay thin, and the
//! quality-diversity core (library, breeding, scheduler, the changes it emits) knows
//! nothing of storage or the network, and no two modules of a crate import each other.

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

/// Every module of a crate's `src/`, by its path (`service::session`), with the source
/// text of its file, comments left out.
fn modules(crate_dir: &str) -> Vec<(String, String)> {
    fn walk(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("source directory") {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let src = workspace_root().join(crate_dir).join("src");
    let mut files = Vec::new();
    walk(&src, &mut files);
    files
        .into_iter()
        .filter_map(|file| {
            let rel = file.strip_prefix(&src).unwrap().with_extension("");
            let mut parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if parts.last().is_some_and(|p| p == "mod") {
                parts.pop();
            }
            if matches!(parts.as_slice(), [root] if root == "lib" || root == "main") {
                return None;
            }
            if parts.first().is_some_and(|p| p == "bin") {
                return None;
            }
            let code: String = std::fs::read_to_string(&file)
                .unwrap()
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .collect::<Vec<_>>()
                .join("\n");
            Some((parts.join("::"), code))
        })
        .collect()
}

/// The modules that `code` (the module `me`) names through `crate::` or `super::`.
fn uses(me: &str, code: &str, all: &[&str]) -> Vec<String> {
    // `super` of `a::b`, in a/b.rs or in a/b/mod.rs, is `a`.
    let parent = me.rsplit_once("::").map_or("", |(p, _)| p);
    let mut found = Vec::new();
    for (prefix, base) in [("crate::", ""), ("super::", parent)] {
        let mut rest = code;
        while let Some(at) = rest.find(prefix) {
            let before = rest[..at].chars().next_back();
            rest = &rest[at + prefix.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
                continue;
            }
            let path: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let full: Vec<&str> = if base.is_empty() {
                path.split("::").collect()
            } else {
                base.split("::").chain(path.split("::")).collect()
            };
            // The longest prefix of the path that is a module.
            if let Some(module) = (1..=full.len())
                .rev()
                .map(|n| full[..n].join("::"))
                .find(|m| all.contains(&m.as_str()))
            {
                found.push(module);
            }
        }
    }
    found
}

#[test]
fn no_two_modules_import_each_other() {
    let is_within = |inner: &str, outer: &str| inner.starts_with(&format!("{outer}::"));
    let mut checked = 0;
    for krate in ["proto", "common", "worker", "coordinator"] {
        let modules = modules(krate);
        let names: Vec<&str> = modules.iter().map(|(m, _)| m.as_str()).collect();
        let graph: Vec<(&str, Vec<String>)> = modules
            .iter()
            .map(|(m, code)| (m.as_str(), uses(m, code, &names)))
            .collect();
        for (a, a_uses) in &graph {
            for b in a_uses {
                // A module and the modules inside it are one piece: a parent names its
                // children, a child its parent's items.
                if b == a || is_within(a, b) || is_within(b, a) {
                    continue;
                }
                checked += 1;
                let b_uses = &graph.iter().find(|(m, _)| m == b).unwrap().1;
                assert!(
                    !b_uses.iter().any(|m| m == a || is_within(m, a)),
                    "{krate}: {a} and {b} import each other"
                );
            }
        }
    }
    // The scan found the imports it is meant to judge (the service uses the scheduler).
    assert!(checked > 20, "only {checked} imports between modules found");
}
