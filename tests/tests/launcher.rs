#![allow(clippy::unwrap_used, clippy::expect_used)] // a test fails by panicking
//! `robocog launch`: order, restarts, stopping, and failures, with real processes.

use robocog_tests::*;
use std::time::Duration;

fn index_of(lines: &[String], pred: impl Fn(&str) -> bool) -> usize {
    lines.iter().position(|l| pred(l)).expect("line present")
}

#[test]
fn three_components_start_in_order_a_killed_one_restarts_and_sigterm_stops_all() {
    let ns = unique_namespace("order");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[graph]
name = "three"

[[component]]
name = "front"
binary = "@FIXTURE@"
args = ["--role", "talker"]
depends_on = ["middle"]

[[component]]
name = "middle"
binary = "@FIXTURE@"
args = ["--role", "listener"]
depends_on = ["base"]
restart = "on-failure"
backoff_ms = 100

[[component]]
name = "base"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
    );
    let mut launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("front up", Duration::from_secs(30), |l| {
            l.contains("front is up")
        });
    let lines = launch.lines.all();
    let base_up = index_of(&lines, |l| l.contains("base is up"));
    let middle_started = index_of(&lines, |l| l.contains("started middle"));
    let middle_up = index_of(&lines, |l| l.contains("middle is up"));
    let front_started = index_of(&lines, |l| l.contains("started front"));
    assert!(
        base_up < middle_started,
        "middle started before base was up:\n{}",
        lines.join("\n")
    );
    assert!(
        middle_up < front_started,
        "front started before middle was up:\n{}",
        lines.join("\n")
    );

    let pids: Vec<u32> = ["front", "middle", "base"]
        .iter()
        .map(|n| {
            eventually(&format!("{n}'s pid"), Duration::from_secs(10), || {
                component_pid(&launch, n)
            })
        })
        .collect();

    // SIGKILL the middle one: the launcher restarts it (a new process comes up).
    signal(pids[1], "KILL");
    launch
        .lines
        .wait_for("the restart", Duration::from_secs(15), |l| {
            l.contains("middle stopped (killed by signal 9") && l.contains("restart 1/")
        });
    let new_pid = eventually("middle's new pid", Duration::from_secs(20), || {
        component_pid(&launch, "middle").filter(|p| *p != pids[1])
    });
    assert!(alive(new_pid));
    let restart_at = launch.lines.all().len();
    launch.lines.wait_until(
        "messages again after the restart",
        Duration::from_secs(15),
        |lines| {
            lines[restart_at..]
                .iter()
                .any(|l| l.contains("middle |") && l.contains("received: hello"))
        },
    );

    // SIGTERM to the launcher: everything stops, nothing is left.
    launch.sigterm();
    let status = launch.wait_exit(Duration::from_secs(30));
    assert!(status.success(), "launcher exit {status:?}");
    for pid in [pids[0], new_pid, pids[2]] {
        eventually(&format!("pid {pid} gone"), Duration::from_secs(5), || {
            (!alive(pid)).then_some(())
        });
    }
    assert!(launch.lines.count(|l| l.contains("all components stopped")) == 1);
}

#[test]
fn a_child_that_ignores_sigterm_is_killed_after_its_grace_period() {
    let ns = unique_namespace("stubborn");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "stubborn"
binary = "@FIXTURE@"
args = ["--role", "idle", "--ignore-sigterm"]
stop_timeout_s = 1.0
"#,
    );
    let mut launch = Launch::start(&m, &ns, &[]);
    launch.lines.wait_for("up", Duration::from_secs(20), |l| {
        l.contains("stubborn is up")
    });
    let pid = eventually("pid", Duration::from_secs(10), || {
        component_pid(&launch, "stubborn")
    });
    launch.sigterm();
    let status = launch.wait_exit(Duration::from_secs(20));
    assert!(status.success());
    assert!(
        launch
            .lines
            .count(|l| l.contains("stubborn ignored SIGTERM") && l.contains("SIGKILL"))
            == 1
    );
    eventually("stubborn gone", Duration::from_secs(5), || {
        (!alive(pid)).then_some(())
    });
}

#[test]
fn a_required_component_that_keeps_crashing_fails_the_graph() {
    let ns = unique_namespace("crash");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "crasher"
binary = "@FIXTURE@"
args = ["--role", "idle", "--exit-after", "0.3", "--exit-code", "3"]
max_restarts = 2
backoff_ms = 50

[[component]]
name = "bystander"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
    );
    let mut launch = Launch::start(&m, &ns, &[]);
    let status = launch.wait_exit(Duration::from_secs(40));
    assert_eq!(status.code(), Some(1), "{}", launch.lines.all().join("\n"));
    let all = launch.lines.all().join("\n");
    assert!(
        all.contains("crasher stopped (exit code 3); restart 1/2"),
        "{all}"
    );
    assert!(
        all.contains("crasher stopped (exit code 3); restart 2/2"),
        "{all}"
    );
    assert!(
        all.contains("crasher failed for good (exit code 3, after 2 restarts)"),
        "{all}"
    );
}

#[test]
fn a_component_that_cannot_start_is_not_restarted_and_stops_the_graph_at_once() {
    let ns = unique_namespace("misconfigured");
    let dir = scratch(&ns);
    let missing = dir.join("calibration.toml");
    let text = format!(
        r#"
[[component]]
name = "bystander"
binary = "@FIXTURE@"
args = ["--role", "idle"]

[[component]]
name = "broken"
binary = "@FIXTURE@"
args = ["--role", "idle", "--needs-file", "{}"]
restart = "always"
max_restarts = 5
backoff_ms = 50
depends_on = ["bystander"]
"#,
        missing.display()
    );
    let m = write_manifest(&dir, "graph.toml", &text);
    let mut launch = Launch::start(&m, &ns, &[]);
    let status = launch.wait_exit(Duration::from_secs(40));
    let all = launch.lines.all().join("\n");
    assert_eq!(status.code(), Some(78), "{all}");
    assert!(
        all.contains("broken cannot start (exit code 78") && all.contains("stopping the graph"),
        "{all}"
    );
    assert!(
        all.contains(&format!("no such file {}", missing.display())),
        "the component's own message: {all}"
    );
    assert_eq!(
        launch.lines.count(|l| l.contains("started broken")),
        1,
        "started once, never restarted: {all}"
    );
    assert!(!all.contains("restart 1/5"), "{all}");
    assert!(all.contains("all components stopped"), "{all}");
}

#[test]
fn a_panel_on_an_address_this_machine_does_not_have_is_a_configuration_error() {
    // Found only once it binds (after joining the bus): still no restart, the graph stops.
    let ns = unique_namespace("noaddr");
    let dir = scratch(&ns);
    let m = write_manifest(
        &dir,
        "graph.toml",
        &format!(
            r#"
[[component]]
name = "panel"
binary = "{}"
args = ["--http", "192.0.2.1:8642", "--allow-remote", "--token", "a-long-enough-token"]
external_inputs = ["nao/world_model", "nao/game_state", "nao/link", "nao/local_model",
    "coach/status", "vision/rgbd", "vision/ball", "vision/ball_events", "speech/speaking",
    "speech/utterance", "speech/say", "executive/transitions", "executive/log", "game/command",
    "speech/listening"]
"#,
            bin("command_generator").display()
        ),
    );
    let mut launch = Launch::start(&m, &ns, &[]);
    let status = launch.wait_exit(Duration::from_secs(40));
    let all = launch.lines.all().join("\n");
    assert_eq!(status.code(), Some(78), "{all}");
    assert!(all.contains("not an address of this machine"), "{all}");
    assert!(!all.contains("restart 1/"), "{all}");
}

#[test]
fn the_real_profile_without_its_servo_map_stops_at_once() {
    // No servo map, no servos: joint_motor cannot start, says why, and the launcher stops the
    // graph at once instead of restarting it five times.
    let ns = unique_namespace("realmissing");
    let dir = scratch(&ns);
    let manifest =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/touch_the_ball.toml");
    let servo_map = format!("servo_config={}", dir.join("loki_servos.toml").display());
    let mut launch = Launch::start(
        &manifest,
        &ns,
        &[
            "--profile",
            "real",
            "--set",
            &servo_map,
            "--set",
            "panel=false",
        ],
    );
    let status = launch.wait_exit(Duration::from_secs(60));
    let all = launch.lines.all().join("\n");
    assert_eq!(status.code(), Some(78), "{all}");
    assert!(
        all.contains("joint_motor cannot start (exit code 78"),
        "{all}"
    );
    assert!(all.contains("reading the servo map"), "{all}");
    assert!(
        !all.contains("joint_motor stopped"),
        "never restarted: {all}"
    );
}

#[test]
fn a_component_that_never_comes_up_is_named() {
    let ns = unique_namespace("silent");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "mute"
binary = "@FIXTURE@"
args = ["--role", "silent"]
ready_timeout_s = 1.5
"#,
    );
    let mut launch = Launch::start(&m, &ns, &[]);
    let status = launch.wait_exit(Duration::from_secs(30));
    assert_eq!(status.code(), Some(1));
    assert!(
        launch.lines.count(|l| l.contains("mute never came up")) == 1,
        "{}",
        launch.lines.all().join("\n")
    );
}

#[test]
fn the_state_folder_outlives_a_failed_launch_is_moved_aside_or_resumed_and_goes_with_a_clean_one() {
    let ns = unique_namespace("statefolder");
    let dir = scratch(&ns);
    let graph = |exit_code: u8, completes: bool| {
        format!(
            r#"
[graph]
name = "statefolders"

[[component]]
name = "worker"
binary = "@FIXTURE@"
args = ["--role", "idle", "--exit-after", "0.5", "--exit-code", "{exit_code}"]
restart = "never"
completes_graph = {completes}
"#
        )
    };
    let failing = write_manifest(&dir, "failing.toml", &graph(3, false));
    let clean = write_manifest(&dir, "clean.toml", &graph(0, true));
    let run = |m: &std::path::Path, extra: &[&str]| {
        let mut launch = Launch::start(m, &ns, extra);
        let status = launch.wait_exit(Duration::from_secs(30));
        (status, launch.lines.all().join("\n"))
    };
    let folder = |out: &str| -> std::path::PathBuf {
        let line = out
            .lines()
            .find(|l| l.contains("component state in "))
            .unwrap_or_else(|| panic!("no state folder line:\n{out}"));
        let p = line.split("component state in ").nth(1).unwrap();
        std::path::PathBuf::from(p.trim_end_matches(" (resumed)"))
    };

    // A failed launch keeps its folder, and says where.
    let (status, out) = run(&failing, &[]);
    assert_eq!(status.code(), Some(1), "{out}");
    let state = folder(&out);
    assert!(
        state.ends_with(format!("statefolders/{ns}")),
        "{}",
        state.display()
    );
    assert!(state.is_dir(), "{out}");
    assert!(out.contains("the components' state stays in"), "{out}");
    std::fs::write(state.join("marker"), "kept").unwrap();

    // The next launch starts afresh: the earlier state moved aside, not lost.
    let (_, out) = run(&failing, &[]);
    let mut aside = state.as_os_str().to_owned();
    aside.push(".previous");
    let aside = std::path::PathBuf::from(aside);
    assert!(out.contains("moved aside to"), "{out}");
    assert!(aside.join("marker").is_file(), "{out}");
    assert!(!state.join("marker").exists(), "{out}");

    // --resume takes up what the last launch left.
    std::fs::write(state.join("marker"), "kept").unwrap();
    let (_, out) = run(&failing, &["--resume"]);
    assert!(
        out.contains("(resumed)") && !out.contains("moved aside"),
        "{out}"
    );
    assert!(state.join("marker").is_file(), "{out}");

    // A clean end removes it.
    let (status, out) = run(&clean, &["--resume"]);
    assert!(status.success(), "{out}");
    assert!(!state.exists(), "{out}");
    // The graph's folder keeps only what other launches left (here the moved-aside one).
    assert!(aside.is_dir(), "{out}");
}

#[test]
fn a_completing_component_ends_the_graph_with_success() {
    let ns = unique_namespace("complete");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "scenario"
binary = "@FIXTURE@"
args = ["--role", "idle", "--exit-after", "1.0", "--exit-code", "0"]
completes_graph = true

[[component]]
name = "other"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
    );
    let mut launch = Launch::start(&m, &ns, &[]);
    let status = launch.wait_exit(Duration::from_secs(30));
    assert!(status.success(), "{}", launch.lines.all().join("\n"));
    assert!(launch.lines.count(|l| l.contains("scenario completed")) == 1);
}

#[test]
fn a_serving_component_is_up_only_once_its_services_answer() {
    // The echo server takes its time before serving; the dependent starts only after, and a
    // call made as soon as the server is "up" is answered.
    let ns = unique_namespace("ready");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "server"
binary = "@FIXTURE@"
args = ["--role", "echo-server", "--serve-after-ms", "800"]

[[component]]
name = "client"
binary = "@FIXTURE@"
args = ["--role", "idle"]
depends_on = ["server"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    let up = launch
        .lines
        .wait_for("server up", Duration::from_secs(20), |l| {
            l.contains("server is up")
        });
    let ms: u64 = up
        .split('(')
        .nth(1)
        .and_then(|s| s.split(", ").nth(1))
        .and_then(|s| s.trim_end_matches(" ms)").parse().ok())
        .unwrap();
    assert!(
        ms >= 800,
        "up after {ms} ms, before its service was served: {up}"
    );
    let out = launch.robocog(&["topic", "list"], Duration::from_secs(15));
    assert!(out.status.success());
    launch
        .lines
        .wait_for("client up", Duration::from_secs(20), |l| {
            l.contains("client is up")
        });
}
