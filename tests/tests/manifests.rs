#![allow(clippy::unwrap_used)]
//! Every manifest shipped in `launch/` passes `robocog check` (binaries, topics, dependencies);
//! with its default variables every component could start here (`--preflight`: its files and
//! models are where the manifest says). The profiles for real hardware are checked for structure
//! only (`--no-preflight`): this machine has no servos and no Kinect, which
//! `check::the_real_profile_without_its_servo_map_is_reported_before_the_launch` asserts.

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
            let mut v = vec!["--profile".to_string(), p.clone()];
            if p == "real" {
                v.push("--no-preflight".into());
            }
            variants.push(v);
        }
        for extra in variants {
            let mut args = vec!["check".to_string(), path.display().to_string()];
            args.extend(extra.iter().cloned());
            // From the repository root, as the manifests say (their relative paths are the
            // working folder's).
            let out = run_in(
                Some(&launch_dir.join("..")),
                &bin("robocog"),
                &args,
                Duration::from_secs(60),
            );
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
