//! The codebase's shape, as `cargo metadata` sees it.
//!
//! The rule (ARCHITECTURE.md, "Adding a component"): a process crate (every component, the
//! Executive, the simulators, the deep representation's service, the `robocog` tool) depends only
//! on `interfaces`, the libraries in `libs/` and external crates, in every kind of dependency
//! (normal, dev, build). Libraries depend only on `interfaces`, other libraries and external
//! crates; `interfaces` on no crate of the workspace. So no process links another's code, and
//! what two processes share is a library anyone can find in `libs/`.
#![allow(clippy::expect_used)] // a test fails by panicking

use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// `interfaces`: the messages, the bus and the component runtime.
    Interfaces,
    /// A crate in `libs/`.
    Library,
    /// A crate that builds a process: components, the Executive, simulators, the DR, the tool.
    Process,
    /// The process-level test harness (`tests/`), which may start any process.
    Tests,
}

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// The role of a workspace crate from its folder, or `None` for a folder the rule does not know.
fn role(dir: &Path, root: &Path) -> Option<Role> {
    let rel = dir.strip_prefix(root).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?;
    match first {
        "interfaces" => Some(Role::Interfaces),
        "libs" => Some(Role::Library),
        "components" | "sims" | "executive" | "deep_representation" | "robocog" => {
            Some(Role::Process)
        }
        "tests" => Some(Role::Tests),
        _ => None,
    }
}

fn allowed(from: Role, to: Role) -> bool {
    match from {
        Role::Interfaces => false,
        Role::Library | Role::Process => matches!(to, Role::Interfaces | Role::Library),
        Role::Tests => true,
    }
}

/// Workspace crates: name -> (folder, role).
type Crates = BTreeMap<String, (PathBuf, Option<Role>)>;
/// A dependency on a path crate: (from, to, kind).
type Edge = (String, String, String);

/// The workspace's crates and every dependency edge on a path crate.
fn workspace() -> (Crates, Vec<Edge>) {
    let root = workspace_root();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(&root)
        .output()
        .expect("cargo runs");
    assert!(
        out.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: Value = serde_json::from_slice(&out.stdout).expect("cargo metadata prints JSON");
    let mut crates = BTreeMap::new();
    let packages = meta["packages"].as_array().expect("packages");
    for p in packages {
        let name = p["name"].as_str().expect("name").to_string();
        let manifest = PathBuf::from(p["manifest_path"].as_str().expect("manifest_path"));
        let dir = manifest.parent().expect("manifest folder").to_path_buf();
        let r = role(&dir, &root);
        crates.insert(name, (dir, r));
    }
    let mut edges = Vec::new();
    for p in packages {
        let from = p["name"].as_str().expect("name").to_string();
        for d in p["dependencies"].as_array().expect("dependencies") {
            let Some(path) = d["path"].as_str() else {
                continue;
            };
            let to = crates
                .iter()
                .find(|(_, (dir, _))| dir == Path::new(path))
                .map(|(n, _)| n.clone())
                .unwrap_or_else(|| path.to_string());
            let kind = d["kind"].as_str().unwrap_or("normal").to_string();
            edges.push((from.clone(), to, kind));
        }
    }
    (crates, edges)
}

#[test]
fn every_workspace_crate_lives_in_a_folder_of_known_role() {
    let (crates, _) = workspace();
    let unknown: Vec<_> = crates
        .iter()
        .filter(|(_, (_, r))| r.is_none())
        .map(|(n, (d, _))| format!("{n} ({})", d.display()))
        .collect();
    assert!(
        unknown.is_empty(),
        "crates outside interfaces/, libs/, components/, sims/, executive/, deep_representation/, \
         robocog/, tests/: {unknown:?}"
    );
    // The top level the project was asked for.
    let root = workspace_root();
    for dir in [
        "components",
        "interfaces",
        "executive",
        "deep_representation",
        "launch",
        "tests",
        "libs",
    ] {
        assert!(
            root.join(dir).is_dir(),
            "{dir}/ is missing at the top level"
        );
    }
}

#[test]
fn processes_depend_only_on_interfaces_libraries_and_external_crates() {
    let (crates, edges) = workspace();
    let mut broken = Vec::new();
    for (from, to, kind) in &edges {
        let Some((_, Some(fr))) = crates.get(from) else {
            continue;
        };
        let tr = crates.get(to).and_then(|(_, r)| *r);
        let ok = match tr {
            Some(tr) => allowed(*fr, tr),
            // A path dependency outside the workspace's folders.
            None => false,
        };
        if !ok {
            broken.push(format!(
                "{from} ({fr:?}) -> {to} ({tr:?}), {kind} dependency"
            ));
        }
    }
    assert!(
        broken.is_empty(),
        "dependencies that break the layout rule:\n  {}",
        broken.join("\n  ")
    );
    // The rule is checked against something: processes and libraries exist and use libraries.
    let process_to_lib = edges.iter().any(|(f, t, _)| {
        crates.get(f).and_then(|c| c.1) == Some(Role::Process)
            && crates.get(t).and_then(|c| c.1) == Some(Role::Library)
    });
    assert!(
        process_to_lib,
        "no process uses a library: is the metadata read right?"
    );
}

#[test]
fn the_rule_names_an_edge_between_two_processes() {
    assert!(!allowed(Role::Process, Role::Process));
    assert!(!allowed(Role::Library, Role::Process));
    assert!(!allowed(Role::Interfaces, Role::Library));
    assert!(allowed(Role::Process, Role::Library));
    assert!(allowed(Role::Process, Role::Interfaces));
    let root = Path::new("/r");
    assert_eq!(
        role(Path::new("/r/components/rgbd"), root),
        Some(Role::Process)
    );
    assert_eq!(role(Path::new("/r/libs/camera"), root), Some(Role::Library));
    assert_eq!(role(Path::new("/r/executive"), root), Some(Role::Process));
    assert_eq!(role(Path::new("/r/elsewhere/x"), root), None);
}
