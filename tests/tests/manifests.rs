#![allow(clippy::unwrap_used)]
//! Every manifest shipped in `launch/` passes `robocog check` (binaries, topics, dependencies).

use robocog_tests::*;
use std::time::Duration;

#[test]
fn every_shipped_manifest_is_sound() {
    let launch_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch");
    let mut checked = 0;
    for entry in std::fs::read_dir(&launch_dir).expect("launch/ exists") {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        // The default graph and every profile (a profile swaps drivers: what it switches off
        // must not leave a subscription without a publisher).
        let text = std::fs::read_to_string(&path).unwrap();
        let profiles: Vec<String> = text
            .lines()
            .filter_map(|l| l.trim().strip_prefix("[profiles."))
            .filter_map(|l| l.strip_suffix(']'))
            .map(str::to_string)
            .collect();
        let mut variants = vec![vec![]];
        for p in &profiles {
            variants.push(vec!["--profile".to_string(), p.clone()]);
        }
        for extra in variants {
            let mut args = vec!["check".to_string(), path.display().to_string()];
            args.extend(extra.iter().cloned());
            let out = run(&bin("robocog"), &args, Duration::from_secs(60));
            assert!(
                out.status.success(),
                "{} {extra:?} does not pass robocog check:\n{}",
                path.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            checked += 1;
        }
    }
    assert!(checked > 0, "no manifest in {}", launch_dir.display());
}
