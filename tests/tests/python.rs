//! Components in Python (libs/python, the `robocog` package): on the bus, in the launcher, with
//! the same types, counters and restart policies as Rust ones.
//!
//! The Python is `ROBOCOG_PYTHON`, the venv `scripts/test` makes with the package installed
//! (its extension built from this workspace). The Python side of the tests is in `tests/python/`.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::diag::Diagnostics;
use interfaces::msg::std_msgs::Text;
use interfaces::{Bus, CallError, ErrorCode, Service, Topic, topics};
use robocog_tests::{Launch, Log, component_pid, run, scratch, signal, unique_namespace};
use std::path::{Path, PathBuf};
use std::time::Duration;

const PY_IN: Topic<Text> = Topic::new("py/in");
const PY_OUT: Topic<Text> = Topic::new("py/out");
const PY_UPPER: Service<Text, Text> = Service::new("py/upper");

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn python() -> PathBuf {
    match std::env::var_os("ROBOCOG_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => panic!(
            "ROBOCOG_PYTHON is not set: run the suite with scripts/test, which makes the venv with the robocog Python package"
        ),
    }
}

/// A graph of the Python fixture (tests/python/py_fixture.py) with `args`, and `extra` TOML.
fn manifest(ns: &str, args: &str, extra: &str) -> PathBuf {
    // The interpreter must be the venv's: the launcher reads ROBOCOG_PYTHON, which the
    // suite's environment sets.
    let _ = python();
    let dir = scratch(ns);
    let text = format!(
        r#"
[graph]
name = "python"

[[component]]
name = "py_fixture"
python = "py_fixture:Fixture"
args = [{args}]
env = {{ PYTHONPATH = "{pythonpath}" }}
restart = "on-failure"
backoff_ms = 100
external_inputs = ["py/in", "vision/rgbd"]
{extra}
"#,
        pythonpath = repo().join("tests/python").display()
    );
    robocog_tests::write_manifest(&dir, "python.toml", &text)
}

async fn wait_answer(log: &Log<Text>, from: usize, want: &str) -> Text {
    log.wait_from(
        &format!("{want:?} on py/out"),
        from,
        Duration::from_secs(20),
        |m| m.text == want,
    )
    .await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_python_component_is_on_the_bus_like_a_rust_one() {
    let ns = unique_namespace("py-bus");
    let m = manifest(&ns, "", "");
    let check = run(
        &robocog_tests::bin("robocog"),
        &["check".into(), m.display().to_string()],
        Duration::from_secs(60),
    );
    assert!(
        check.status.success(),
        "robocog check (which asks the Python component --describe) failed:\n{}{}",
        String::from_utf8_lossy(&check.stdout),
        String::from_utf8_lossy(&check.stderr)
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("py_fixture up", Duration::from_secs(30), |l| {
            l.contains("py_fixture is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-py").await.unwrap();
    let answers = Log::follow(&bus, &PY_OUT).await;
    let diagnostics = Log::follow(&bus, &topics::DIAGNOSTICS).await;
    let input = bus.publisher(&PY_IN).await.unwrap();
    let say = |text: &str| Text {
        text: text.into(),
        ..Default::default()
    };

    // It shows in the graph as a component, with its publisher and subscriber.
    let list = launch.robocog(&["component", "list"], Duration::from_secs(20));
    let list = String::from_utf8_lossy(&list.stdout).to_string();
    assert!(list.contains("py_fixture"), "component list:\n{list}");
    let info = launch.robocog(&["topic", "info", "py/in"], Duration::from_secs(20));
    let info = String::from_utf8_lossy(&info.stdout).to_string();
    assert!(info.contains("py_fixture"), "topic info py/in:\n{info}");

    // Messages both ways (said again until the subscription has reached the router), and a
    // service with its typed refusal.
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while !answers.all().iter().any(|m| m.text == "HELLO") {
        assert!(
            std::time::Instant::now() < deadline,
            "no answer to hello in 30 s"
        );
        input.publish(&mut say("hello")).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    let rep = bus
        .call(&PY_UPPER, &say("abc"), Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(rep.text, "ABC");
    match bus.call(&PY_UPPER, &say(""), Duration::from_secs(5)).await {
        Err(CallError::Remote(e)) => {
            assert_eq!(e.code, ErrorCode::BadRequest);
            assert!(e.message.contains("nothing to upper-case"), "{e:?}");
        }
        other => panic!("expected a BadRequest, got {other:?}"),
    }

    // A payload that is no Text is a counted drop; an exception in a callback is logged with its
    // traceback and counted; the component goes on.
    let raw = bus
        .raw_publisher("py/in", "robocog.Text", "test-py")
        .await
        .unwrap();
    raw.put(vec![0, 1, 0, 0, 0xff]).await.unwrap();
    input.publish(&mut say("boom")).await.unwrap();
    input.publish(&mut say("after")).await.unwrap();
    wait_answer(&answers, 0, "AFTER").await;
    launch
        .lines
        .wait_for("the traceback", Duration::from_secs(10), |l| {
            l.contains("RuntimeError: boom, as asked")
        });
    let counted = |d: &Diagnostics, name: &str| {
        d.component == "py_fixture" && d.counters.iter().any(|c| c.name == name && c.value >= 1)
    };
    diagnostics
        .wait_from("decode_errors/py/in", 0, Duration::from_secs(20), |d| {
            counted(d, "decode_errors/py/in")
        })
        .await;
    diagnostics
        .wait_from(
            "callback_errors/subscription/py/in",
            0,
            Duration::from_secs(20),
            |d| counted(d, "callback_errors/subscription/py/in"),
        )
        .await;

    // Killed, it is restarted by its policy and answers again.
    let pid = component_pid(&launch, "py_fixture").expect("py_fixture's pid");
    signal(pid, "KILL");
    let from = answers.len();
    let deadline = std::time::Instant::now() + Duration::from_secs(40);
    loop {
        input.publish(&mut say("again")).await.unwrap();
        if answers.all().iter().skip(from).any(|m| m.text == "AGAIN") {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "no answer 40 s after py_fixture was killed; the launcher said:\n{}",
            launch.lines.all().join("\n")
        );
        tokio::time::sleep(Duration::from_millis(300)).await;
    }
    assert_ne!(
        component_pid(&launch, "py_fixture"),
        Some(pid),
        "the answer came from the killed process"
    );
    // Its state folder is the one it had: it counts its second start there.
    let from = answers.len();
    input.publish(&mut say("starts")).await.unwrap();
    wait_answer(&answers, from, "STARTS 2").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_reach_python_as_numpy_views_of_the_shared_memory_sample() {
    let ns = unique_namespace("py-frames");
    let m = manifest(
        &ns,
        r#""--frames""#,
        r#"
[[component]]
name = "rgbd"
binary = "rgbd"
args = ["--driver", "sim", "--scenario", "still", "--camera-pose", "0,0,1.5,0,30,0", "--fps", "10"]
depends_on = ["py_fixture"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    let bus = Bus::open(&launch.connect_args(), "test-py").await.unwrap();
    let answers = Log::follow(&bus, &PY_OUT).await;
    let report = answers
        .wait_from("a frame report", 0, Duration::from_secs(60), |m| {
            m.text.starts_with('{')
        })
        .await;
    let r: serde_json::Value = serde_json::from_str(&report.text).unwrap();
    assert_eq!(r["rgb_shape"], serde_json::json!([480, 640, 3]), "{r}");
    assert_eq!(r["depth_shape"], serde_json::json!([480, 640]), "{r}");
    assert_eq!(r["owns_pixels"], false, "the arrays copied the pixels: {r}");
    assert_eq!(r["writeable"], false, "a received frame is read-only: {r}");
    assert_eq!(r["same_sample"], true, "{r}");
    assert_eq!(
        r["shm"], true,
        "the frame did not come through shared memory: {r}"
    );
    assert!(r["depth_max_mm"].as_u64().unwrap() > 0, "no depth: {r}");
    assert!(r["stamp_ns"].as_i64().unwrap() > 0, "{r}");
}

#[test]
fn every_message_type_round_trips_through_python() {
    let out = run(
        &python(),
        &[repo()
            .join("tests/python/roundtrip.py")
            .display()
            .to_string()],
        Duration::from_secs(60),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let types = interfaces::msg::REGISTRY.len();
    let ok = stdout
        .lines()
        .filter(|l| l.starts_with("ok robocog."))
        .count();
    assert_eq!(ok, types, "{stdout}");
}

#[test]
fn a_python_component_refuses_bad_flags_and_configurations_by_exit_code() {
    let pythonpath = repo().join("tests/python");
    let go = |args: &[&str]| {
        let out = std::process::Command::new(python())
            .args(["-m", "robocog", "run", "py_fixture:Fixture"])
            .args(args)
            .env("PYTHONPATH", &pythonpath)
            .output()
            .unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).to_string()
                + &String::from_utf8_lossy(&out.stderr),
        )
    };
    let (code, out) = go(&["--prefix", "a/b"]);
    assert_eq!(code, Some(78), "{out}");
    assert!(out.contains("--prefix 'a/b': no slashes"), "{out}");
    let (code, out) = go(&["--preflight"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("py_fixture: ready to start"), "{out}");
    let (code, out) = go(&["--no-such-flag"]);
    assert_eq!(code, Some(64), "{out}");
    assert!(out.contains("--no-such-flag"), "{out}");
    let (code, out) = go(&["--describe"]);
    assert_eq!(code, Some(0), "{out}");
    let d: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(d["serves"][0]["type_name"], "robocog.Text", "{d}");
    let out = std::process::Command::new(python())
        .args(["-m", "robocog", "run", "no_such_module"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(78));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("cannot load the component no_such_module")
    );
}

/// The Python tracker's own tests (its machine on rendered frames, the DR geometry), with
/// Python's unittest.
#[test]
fn the_python_trackers_own_tests_pass() {
    let dir = repo().join("components/ball_tracker_py");
    let out = robocog_tests::run_in(
        Some(&dir),
        &python(),
        &[
            "-m".into(),
            "unittest".into(),
            "discover".into(),
            "-s".into(),
            "tests".into(),
        ],
        Duration::from_secs(120),
    );
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
