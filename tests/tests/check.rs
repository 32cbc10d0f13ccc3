#![allow(clippy::unwrap_used)]
//! `robocog check` names the file and line of every broken-manifest kind.

use robocog_tests::*;
use std::time::Duration;

fn check(text: &str) -> (i32, String, String) {
    let ns = unique_namespace("check");
    let dir = scratch(&ns);
    let m = write_manifest(&dir, "graph.toml", text);
    let out = run(
        &bin("robocog"),
        &["check".into(), m.display().to_string()],
        Duration::from_secs(30),
    );
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        m.display().to_string(),
    )
}

fn assert_rejected(text: &str, line: usize, phrase: &str) {
    let (code, err, file) = check(text);
    assert_eq!(code, 1, "expected a rejection, got {code}: {err}");
    let at = format!("{file}:{line}: ");
    assert!(
        err.lines().any(|l| l.contains(&at) && l.contains(phrase)),
        "expected `{at}…{phrase}…` in:\n{err}"
    );
}

#[test]
fn a_sound_graph_passes() {
    let (code, err, _) = check(
        r#"
[[component]]
name = "talker"
binary = "@FIXTURE@"
args = ["--role", "talker"]

[[component]]
name = "listener"
binary = "@FIXTURE@"
args = ["--role", "listener"]
depends_on = ["talker"]
"#,
    );
    assert_eq!(code, 0, "{err}");
}

#[test]
fn an_unknown_key_is_an_error_at_its_line() {
    assert_rejected(
        "[[component]]\nname = \"a\"\nbinary = \"@FIXTURE@\"\nargz = [\"--role\", \"idle\"]\n",
        4,
        "unknown field `argz`",
    );
}

#[test]
fn an_unknown_binary_is_named() {
    assert_rejected(
        "\n[[component]]\nname = \"ghost\"\nbinary = \"no_such_robocog_component\"\n",
        3,
        "unknown binary \"no_such_robocog_component\"",
    );
}

#[test]
fn a_dependency_cycle_is_shown() {
    assert_rejected(
        r#"[[component]]
name = "a"
binary = "@FIXTURE@"
args = ["--role", "idle"]
depends_on = ["b"]

[[component]]
name = "b"
binary = "@FIXTURE@"
args = ["--role", "idle"]
depends_on = ["a"]
"#,
        2,
        "dependency cycle: a -> b -> a",
    );
}

#[test]
fn a_duplicate_name_points_at_both() {
    assert_rejected(
        r#"[[component]]
name = "twin"
binary = "@FIXTURE@"
args = ["--role", "idle"]

[[component]]
name = "twin"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
        7,
        "duplicate component name \"twin\" (first at ",
    );
}

#[test]
fn an_input_nobody_publishes_is_an_error() {
    assert_rejected(
        r#"[[component]]
name = "lonely"
binary = "@FIXTURE@"
args = ["--role", "listener"]
"#,
        2,
        "subscribes to \"chatter\" (robocog.Text), which no component of the graph publishes",
    );
}

#[test]
fn an_input_declared_external_is_accepted() {
    let (code, err, _) = check(
        r#"[[component]]
name = "lonely"
binary = "@FIXTURE@"
args = ["--role", "listener"]
external_inputs = ["chatter"]
"#,
    );
    assert_eq!(code, 0, "{err}");
}

/// A replay graph leaves the robot out: the Executive's calls to `body/joint_goal` (and here to
/// the DR) go to servers outside the graph, declared like external topics.
#[test]
fn a_called_service_declared_external_is_accepted() {
    let executive = |external: &str| {
        format!(
            r#"[[component]]
name = "executive"
binary = "executive"
args = ["--game", "touch"]
external_inputs = ["game/command", "vision/ball_events", "vision/ball", "body/reach_status", "speech/speaking", "vision/camera_status"{external}]
"#
        )
    };
    assert_rejected(
        &executive(r#", "dr/propose", "dr/get_node""#),
        2,
        "calls service \"body/joint_goal\", which no component of the graph serves",
    );
    let (code, err, _) = check(&executive(
        r#", "dr/propose", "dr/get_node", "body/joint_goal""#,
    ));
    assert_eq!(code, 0, "{err}");
}

#[test]
fn two_claims_of_one_port_are_an_error() {
    assert_rejected(
        r#"[[component]]
name = "bridge_a"
binary = "@FIXTURE@"
args = ["--role", "idle"]
hardware = ["udp:65305"]

[[component]]
name = "bridge_b"
binary = "@FIXTURE@"
args = ["--role", "idle"]
hardware = ["udp:65305"]
"#,
        11,
        "hardware \"udp:65305\" is claimed by both \"bridge_a\"",
    );
}

#[test]
fn an_unknown_dependency_and_an_unknown_variable_are_errors() {
    assert_rejected(
        r#"[[component]]
name = "a"
binary = "@FIXTURE@"
args = ["--role", "${role}"]
depends_on = ["nobody"]
"#,
        5,
        "depends on \"nobody\", which is not in the graph",
    );
    assert_rejected(
        r#"[[component]]
name = "a"
binary = "@FIXTURE@"
args = ["--role", "${role}"]
"#,
        2,
        "unknown variable ${role}",
    );
}

#[test]
fn profiles_and_set_choose_the_arguments() {
    let ns = unique_namespace("profiles");
    let dir = scratch(&ns);
    let m = write_manifest(
        &dir,
        "graph.toml",
        r#"
[vars]
role = "nonsense"

[profiles.good]
role = "idle"

[[component]]
name = "a"
binary = "@FIXTURE@"
args = ["--role", "${role}"]
"#,
    );
    let m = m.display().to_string();
    let robocog = bin("robocog");
    let t = Duration::from_secs(30);
    // With the default variable, the binary cannot describe itself: a warning, not an error.
    let plain = run(&robocog, &["check".into(), m.clone()], t);
    assert!(String::from_utf8_lossy(&plain.stderr).contains("cannot describe"));
    let profiled = run(
        &robocog,
        &["check".into(), m.clone(), "--profile".into(), "good".into()],
        t,
    );
    assert!(profiled.status.success());
    assert!(!String::from_utf8_lossy(&profiled.stderr).contains("cannot describe"));
    let set = run(
        &robocog,
        &[
            "check".into(),
            m.clone(),
            "--set".into(),
            "role=talker".into(),
        ],
        t,
    );
    assert!(set.status.success());
    let bad = run(
        &robocog,
        &["check".into(), m, "--profile".into(), "nope".into()],
        t,
    );
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown profile \"nope\""));
}

/// An include that names a device (it would never end) or a huge file is refused unread, at the
/// include's line.
#[test]
fn an_include_of_a_device_is_refused_unread() {
    assert_rejected(
        "include = [\"/dev/zero\"]\n[graph]\nname = \"g\"\n",
        1,
        "not a regular file",
    );
}

#[test]
fn errors_in_an_included_file_name_that_file() {
    let ns = unique_namespace("include");
    let dir = scratch(&ns);
    let inc = write_manifest(
        &dir,
        "part.toml",
        "[[component]]\nname = \"x\"\nbinary = \"@FIXTURE@\"\nrestart = \"sometimes\"\n",
    );
    let top = write_manifest(&dir, "top.toml", "include = [\"part.toml\"]\n");
    let out = run(
        &bin("robocog"),
        &["check".into(), top.display().to_string()],
        Duration::from_secs(30),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(err.contains(&format!("{}:4: ", inc.display())), "{err}");
}

#[test]
fn a_profile_can_disable_a_simulator_and_a_dependency_on_it_is_an_error() {
    let ns = unique_namespace("enabled");
    let dir = scratch(&ns);
    let m = write_manifest(
        &dir,
        "graph.toml",
        r#"
[vars]
simulate = "true"

[profiles.real]
simulate = "false"

[[component]]
name = "sim"
binary = "@FIXTURE@"
args = ["--role", "talker"]
enabled = "${simulate}"

[[component]]
name = "user"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
    );
    let t = Duration::from_secs(30);
    let robocog = bin("robocog");
    let m = m.display().to_string();
    let out = run(&robocog, &["check".into(), m.clone()], t);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("2 components"));
    let out = run(
        &robocog,
        &["check".into(), m.clone(), "--profile".into(), "real".into()],
        t,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 components"));
    let out = run(
        &robocog,
        &["check".into(), m, "--set".into(), "simulate=maybe".into()],
        t,
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("enabled must be \"true\", \"false\" or a comparison")
            && err.contains("got \"maybe\""),
        "{err}"
    );

    assert_rejected(
        r#"[[component]]
name = "sim"
binary = "@FIXTURE@"
args = ["--role", "idle"]
enabled = "false"

[[component]]
name = "user"
binary = "@FIXTURE@"
args = ["--role", "idle"]
depends_on = ["sim"]
"#,
        8,
        "depends on \"sim\", which is disabled",
    );
}

#[test]
fn a_component_that_cannot_start_is_reported_before_the_launch() {
    let ns = unique_namespace("preflight");
    let dir = scratch(&ns);
    let missing = dir.join("calibration.toml");
    let text = format!(
        r#"
[[component]]
name = "fine"
binary = "@FIXTURE@"
args = ["--role", "idle"]

[[component]]
name = "broken"
binary = "@FIXTURE@"
args = ["--role", "idle", "--needs-file", "{}"]
"#,
        missing.display()
    );
    let m = write_manifest(&dir, "graph.toml", &text)
        .display()
        .to_string();
    let t = Duration::from_secs(60);
    let out = run(&bin("robocog"), &["check".into(), m.clone()], t);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    // At the component's line, in the component's own words.
    let at = format!("{m}:8: ");
    assert!(
        err.lines().any(|l| l.contains(&at)
            && l.contains("component \"broken\" cannot start (exit 78) no such file")),
        "{err}"
    );
    assert!(
        err.contains(&format!("no such file {}", missing.display())),
        "{err}"
    );
    assert!(!err.contains("\"fine\""), "{err}");
    // Structure only: sound.
    let out = run(
        &bin("robocog"),
        &["check".into(), m.clone(), "--no-preflight".into()],
        t,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Once the file is there, it could start.
    std::fs::write(&missing, "").unwrap();
    let out = run(&bin("robocog"), &["check".into(), m], t);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn the_real_profile_without_its_servo_map_is_reported_before_the_launch() {
    // This machine has no servo map in /etc/robocog and no servos: Loki's real profile must
    // say so before anything starts, naming the example map to start from.
    let ns = unique_namespace("realcheck");
    let dir = scratch(&ns);
    let manifest =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/touch_the_ball.toml");
    let servo_map = format!("servo_config={}", dir.join("loki_servos.toml").display());
    let out = run(
        &bin("robocog"),
        &[
            "check".into(),
            manifest.display().to_string(),
            "--profile".into(),
            "real".into(),
            "--set".into(),
            servo_map,
        ],
        Duration::from_secs(90),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let line = err
        .lines()
        .find(|l| l.contains("component \"joint_motor\" cannot start (exit 78)"))
        .unwrap_or_else(|| panic!("joint_motor's missing servo map is not reported:\n{err}"));
    assert!(
        line.contains("reading the servo map") && line.contains("models/loki_servos.example.toml"),
        "{line}"
    );
}

/// `loki_world --check` lists a scenario's steps and exits 0 without a bus (no router runs
/// here); a scenario that does not exist is a configuration error naming it.
#[test]
fn a_scenario_is_checked_without_a_bus() {
    let out = run(
        &bin("loki_world"),
        &["--scenario".into(), "still".into(), "--check".into()],
        Duration::from_secs(30),
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("steps)") && text.contains("  1. "), "{text}");
    let bad = run(
        &bin("loki_world"),
        &[
            "--scenario".into(),
            "no_such_scenario".into(),
            "--check".into(),
        ],
        Duration::from_secs(30),
    );
    assert_eq!(bad.status.code(), Some(78));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("no_such_scenario"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}

/// `robocog check --binaries` lists the programs a graph starts (what `scripts/run` builds):
/// enabled components only, each once, and a `--set` that enables one adds it; a broken
/// manifest is still an error.
#[test]
fn binaries_lists_the_programs_the_graph_starts() {
    let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../launch/touch_the_ball.toml")
        .display()
        .to_string();
    let programs = |extra: &[&str]| {
        let mut args = vec!["check".to_string(), "--binaries".into(), manifest.clone()];
        args.extend(extra.iter().map(|s| s.to_string()));
        let out = run(&bin("robocog"), &args, Duration::from_secs(30));
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    let plain = programs(&[]);
    for p in [
        "executive",
        "joint_motor",
        "rgbd",
        "speech_recognition",
        "loki_world",
    ] {
        assert!(plain.iter().any(|l| l == p), "{p} missing: {plain:?}");
    }
    assert!(!plain.iter().any(|l| l == "viewer"), "{plain:?}");
    let mut sorted = plain.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted, plain, "once each, sorted");
    let viewed = programs(&["--set", "view=true"]);
    assert!(viewed.iter().any(|l| l == "viewer"), "{viewed:?}");

    let ns = unique_namespace("check-binaries");
    let bad = write_manifest(
        &scratch(&ns),
        "graph.toml",
        "[graph]\nname = \"x\"\nbogus = 1\n",
    );
    let out = run(
        &bin("robocog"),
        &[
            "check".into(),
            "--binaries".into(),
            bad.display().to_string(),
        ],
        Duration::from_secs(30),
    );
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("bogus"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
