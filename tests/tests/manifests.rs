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
        let out = run(
            &bin("robocog"),
            &["check".into(), path.display().to_string()],
            Duration::from_secs(60),
        );
        assert!(
            out.status.success(),
            "{} does not pass robocog check:\n{}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        checked += 1;
    }
    assert!(checked > 0, "no manifest in {}", launch_dir.display());
}
