//! The codebase's shape, as `cargo metadata` sees it.
//!
//! The rules (ARCHITECTURE.md, "Cross-cutting rules"): a process crate (every component, the
//! Executive, the simulators, the deep representation's service, the `robocog` tool) depends only
//! on `interfaces`, the libraries in `libs/` and external crates, in every kind of dependency
//! (normal, dev, build). Libraries depend only on `interfaces`, other libraries and external
//! crates; `interfaces` on no crate of the workspace. So no process links another's code, and
//! what two processes share is a library anyone can find in `libs/`. Beside it: only the crates
//! in [`UNSAFE_ALLOWED`] lift the workspace's `unsafe_code = "deny"`, and no source file that is
//! not a test passes [`MAX_SOURCE_LINES`] lines.
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

/// The crates allowed `unsafe` code (`#![allow(unsafe_code)]` over the workspace's
/// `unsafe_code = "deny"`), each with its reason. A crate that adds `unsafe` joins this list in
/// the same change, where a reviewer sees it.
const UNSAFE_ALLOWED: &[(&str, &str)] = &[
    (
        "freenect",
        "loads libfreenect at run time and calls its C API",
    ),
    ("pocketsphinx-sys-min", "PocketSphinx's C API"),
    (
        "robocog-python",
        "the buffer protocol: a received frame's bytes lent to NumPy without a copy",
    ),
    (
        "robocog",
        "the launcher's pre_exec hook: prctl(PR_SET_PDEATHSIG) in the forked child",
    ),
    (
        "robocog-fuzz",
        "a counting global allocator in the corpora test",
    ),
];

/// The most lines a source file that is not a test may have: past it, split it by what its
/// parts are responsible for.
const MAX_SOURCE_LINES: usize = 800;

/// The `.rs` files of a crate's folder, without those of crates nested in it (a folder with a
/// `Cargo.toml` of its own) and without build outputs and node modules.
fn rust_files(dir: &Path, crate_root: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            let name = e.file_name();
            if name == "target" || name == "node_modules" || name.to_string_lossy().starts_with('.')
            {
                continue;
            }
            if p != crate_root && p.join("Cargo.toml").exists() {
                continue;
            }
            rust_files(&p, crate_root, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// Whether an attribute (its text, joined across lines) lifts the workspace's
/// `unsafe_code = "deny"`.
fn allows_unsafe(attribute: &str) -> bool {
    let l: String = attribute.chars().filter(|c| !c.is_whitespace()).collect();
    (l.starts_with("#[") || l.starts_with("#!["))
        && ["allow(", "warn(", "expect("]
            .iter()
            .any(|lvl| l.contains(&format!("{lvl}unsafe_code")))
}

/// The first line of each attribute in `text` that lifts the unsafe rule. An attribute is read
/// from its `#[` or `#![` to the line that closes it, so one written over several lines counts;
/// code and string literals do not.
fn unsafe_attribute_lines(text: &str) -> Vec<usize> {
    let lines: Vec<&str> = text.lines().collect();
    let mut found = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let t = lines[i].trim_start();
        if t.starts_with("#[") || t.starts_with("#![") {
            let start = i;
            let mut attribute = lines[i].to_string();
            while !lines[i].trim_end().ends_with(']') && i + 1 < lines.len() {
                i += 1;
                attribute.push_str(lines[i]);
            }
            if allows_unsafe(&attribute) {
                found.push(start + 1);
            }
        }
        i += 1;
    }
    found
}

/// The files of `dir` (a crate) whose attributes lift the unsafe rule, with the first such line.
fn unsafe_allowances(dir: &Path) -> Vec<(PathBuf, usize)> {
    let mut files = Vec::new();
    rust_files(dir, dir, &mut files);
    files
        .into_iter()
        .filter_map(|f| {
            let text = std::fs::read_to_string(&f).ok()?;
            let first = *unsafe_attribute_lines(&text).first()?;
            Some((f, first))
        })
        .collect()
}

#[test]
fn only_the_listed_crates_allow_unsafe_code() {
    let (crates, _) = workspace();
    let mut unlisted = Vec::new();
    let mut used = Vec::new();
    for (name, (dir, _)) in &crates {
        let found = unsafe_allowances(dir);
        if found.is_empty() {
            continue;
        }
        if UNSAFE_ALLOWED.iter().any(|(n, _)| n == name) {
            used.push(name.clone());
        } else {
            for (f, line) in found {
                unlisted.push(format!("{name}: {}:{line}", f.display()));
            }
        }
    }
    assert!(
        unlisted.is_empty(),
        "crates that allow unsafe code without being in UNSAFE_ALLOWED (tests/tests/layout.rs):\n  {}",
        unlisted.join("\n  ")
    );
    // The list names no crate that no longer needs it (or that was renamed).
    let stale: Vec<_> = UNSAFE_ALLOWED
        .iter()
        .filter(|(n, _)| !used.iter().any(|u| u == n))
        .map(|(n, why)| format!("{n} ({why})"))
        .collect();
    assert!(
        stale.is_empty(),
        "UNSAFE_ALLOWED names crates that allow no unsafe code: {stale:?}"
    );
    // And the lint it lifts is in force in every crate: each takes the workspace's lints.
    let root = workspace_root();
    let workspace_toml = std::fs::read_to_string(root.join("Cargo.toml")).expect("Cargo.toml");
    assert!(
        workspace_toml.contains("unsafe_code = \"deny\""),
        "the workspace no longer denies unsafe code"
    );
    for (name, (dir, _)) in &crates {
        let toml = std::fs::read_to_string(dir.join("Cargo.toml")).expect("a crate's Cargo.toml");
        let lints = toml.split("[lints]").nth(1).unwrap_or("");
        assert!(
            lints.trim_start().starts_with("workspace = true"),
            "{name}'s Cargo.toml does not take the workspace's lints ([lints] workspace = true)"
        );
    }
}

#[test]
fn the_unsafe_scan_finds_an_allowance_and_ignores_comments_and_strings() {
    assert!(allows_unsafe("#![allow(unsafe_code)]"));
    assert!(allows_unsafe("#[allow( unsafe_code )]"));
    assert!(allows_unsafe("#[expect(unsafe_code, reason = \"ffi\")]"));
    assert!(!allows_unsafe(
        "// #![allow(unsafe_code)] is for the listed crates"
    ));
    assert!(!allows_unsafe("unsafe_code = \"deny\""));
    assert!(!allows_unsafe(
        "assert!(allows_unsafe(\"#![allow(unsafe_code)]\"));"
    ));
    let text = "//! x\n#![allow(unsafe_code)]\nfn f() {}\n#[expect(\n    unsafe_code,\n    reason = \"ffi\"\n)]\nfn g() {}\nconst S: &str = \"#[allow(unsafe_code)]\";\n";
    assert_eq!(unsafe_attribute_lines(text), vec![2, 4]);
    let dir = std::env::temp_dir().join(format!("robocog-layout-{}", std::process::id()));
    let src = dir.join("src");
    std::fs::create_dir_all(&src).expect("temp folder");
    std::fs::write(src.join("lib.rs"), text).expect("write");
    let found = unsafe_allowances(&dir);
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].1, 2);
}

/// Whether a file is test code: in a `tests/` folder of its crate, a `tests.rs` module, or in the
/// test crates under the top-level `tests/`.
fn is_test_file(file: &Path, crate_dir: &Path, role: Option<Role>) -> bool {
    role == Some(Role::Tests)
        || file.file_stem().is_some_and(|s| s == "tests")
        || file
            .strip_prefix(crate_dir)
            .is_ok_and(|rel| rel.components().any(|c| c.as_os_str() == "tests"))
}

#[test]
fn no_source_file_is_over_800_lines() {
    let (crates, _) = workspace();
    let mut long = Vec::new();
    let mut seen = 0;
    for (dir, role) in crates.values() {
        let mut files = Vec::new();
        rust_files(dir, dir, &mut files);
        for f in files {
            if is_test_file(&f, dir, *role) {
                continue;
            }
            seen += 1;
            let n = std::fs::read_to_string(&f).map_or(0, |t| t.lines().count());
            if n > MAX_SOURCE_LINES {
                long.push(format!("{} ({n} lines)", f.display()));
            }
        }
    }
    assert!(
        seen > 100,
        "only {seen} source files found: is the walk right?"
    );
    assert!(
        long.is_empty(),
        "source files over {MAX_SOURCE_LINES} lines (split them by responsibility):\n  {}",
        long.join("\n  ")
    );
}
