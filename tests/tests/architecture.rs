//! The rules of the layout that a change could quietly break: a coordinator for a cluster's
//! head node links no physics engine, the command lines stay thin, the coordinator's
//! folders depend one way (the quality-diversity core knows nothing of storage, the
//! network or the results), no two modules of a crate import each other, no source file
//! grows past 600 lines, and no reference points outside the repository.

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
    for krate in ["proto", "process", "common", "worker", "coordinator"] {
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

/// The coordinator's folders and what each may not import: the quality-diversity core
/// (`qd`) is plain data and logic; storage (`db`) writes what the core emits; the
/// service serves the core and storage; the results read the core's libraries and
/// storage; only the command lines see everything.
const FORBIDDEN: &[(&str, &[&str])] = &[
    ("qd", &["db", "service", "results", "commands"]),
    ("db", &["service", "results", "commands"]),
    ("service", &["results", "commands"]),
    ("results", &["service", "commands"]),
];

#[test]
fn the_coordinators_folders_depend_one_way() {
    let modules = modules("coordinator");
    let names: Vec<&str> = modules.iter().map(|(m, _)| m.as_str()).collect();
    let top = |m: &str| m.split("::").next().unwrap_or("").to_string();
    let mut checked = 0;
    for (me, code) in &modules {
        let Some((_, forbidden)) = FORBIDDEN.iter().find(|(folder, _)| top(me) == *folder) else {
            continue;
        };
        for used in uses(me, code, &names) {
            checked += 1;
            assert!(
                !forbidden.contains(&top(&used).as_str()),
                "coordinator: {me} imports {used}"
            );
        }
        if top(me) == "qd" {
            for outside in ["sqlx", "tonic", "strider_proto"] {
                assert!(!code.contains(outside), "coordinator: {me} uses {outside}");
            }
        }
    }
    // Each folder exists and the scan saw its imports.
    for (folder, _) in FORBIDDEN {
        assert!(
            names.contains(folder),
            "no module {folder} in the coordinator"
        );
    }
    assert!(checked > 20, "only {checked} imports checked");
}

/// Every `.rs` file under `dir` (recursively).
fn rust_files(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("source directory") {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out.sort();
    out
}

/// The workspace's own crates (vendor/ aside), by folder.
const CRATES: [&str; 6] = [
    "proto",
    "process",
    "common",
    "worker",
    "coordinator",
    "tests",
];

#[test]
fn no_source_file_is_over_600_lines() {
    let root = workspace_root();
    let mut counted = 0;
    for krate in CRATES {
        for file in rust_files(&root.join(krate).join("src")) {
            let text = std::fs::read_to_string(&file).unwrap();
            // A file's unit tests (its trailing `#[cfg(test)]` module) are tests, not source.
            let source = text.split("\n#[cfg(test)]").next().unwrap_or("");
            let lines = source.lines().count();
            counted += 1;
            assert!(
                lines <= 600,
                "{} has {lines} lines of source (at most 600)",
                file.strip_prefix(&root).unwrap().display()
            );
        }
    }
    assert!(counted > 50, "only {counted} files counted");
}

#[test]
fn every_reference_points_into_the_repository() {
    let root = workspace_root();
    let mut files: Vec<std::path::PathBuf> = CRATES
        .iter()
        .flat_map(|krate| rust_files(&root.join(krate)))
        .collect();
    files.extend(["README.md", "BENCHMARKS.md"].map(|f| root.join(f)));
    for entry in std::fs::read_dir(root.join("docs")).expect("docs/") {
        files.push(entry.unwrap().path());
    }
    files.push(root.join("proto/strider/v1/strider.proto"));
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap().to_lowercase();
        // Built from pieces, so this file does not match itself.
        for gone in [
            ["spec", " section"].concat(),
            ["spec", "'s "].concat(),
            ["spec", ".md"].concat(),
        ] {
            assert!(
                !text.contains(&gone),
                "{} refers to {gone:?}: a document not in the repository",
                file.strip_prefix(&root).unwrap().display()
            );
        }
    }
    assert!(files.len() > 50);
}
