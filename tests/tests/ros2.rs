#![allow(clippy::unwrap_used, clippy::expect_used)] // tests: a panic is how a test fails
//! Recordings that ROS 2's tools open: a touch game and a coach game are recorded, and every
//! message of every channel is decoded by ROS 2 decoders from PyPI (`mcap-ros2-support` from the
//! schema in the file alone, `rosbags`, with ROS 2 Jazzy's own standard messages, serializing it
//! back to the same bytes), and compared with what robocog itself decodes (the JSON `robocog
//! topic echo --ros` prints: robocog's typed value in its wire form).
//!
//! The decoders live in a Python venv that `scripts/test` makes (ROBOCOG_ROS2_PYTHON).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use robocog_tests::{
    Launch, read_recording, run, scratch, sigterm_and_wait, start_recorder, unique_namespace,
};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The Python of the venv holding the ROS 2 decoders.
fn python() -> PathBuf {
    match std::env::var_os("ROBOCOG_ROS2_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => panic!(
            "ROBOCOG_ROS2_PYTHON is not set: run the suite with scripts/test, which installs the ROS 2 decoders (mcap-ros2-support, rosbags) into a venv"
        ),
    }
}

/// Record `manifest` with `sets` until `until` returns, then stop the recorder and the graph.
fn record(
    tag: &str,
    manifest: &str,
    sets: &[&str],
    until: impl FnOnce(&mut Launch),
) -> (PathBuf, PathBuf) {
    let ns = unique_namespace(tag);
    let dir = scratch(&ns);
    let file = dir.join(format!("{tag}.mcap"));
    let mut args: Vec<&str> = Vec::new();
    for s in sets {
        args.extend(["--set", s]);
    }
    let mut live = Launch::start(&repo().join(manifest), &ns, &args);
    let log = dir.join("record.log");
    let mut rec = start_recorder(&live, &ns, &file, &log, Duration::from_secs(30));
    until(&mut live);
    let status = sigterm_and_wait(&mut rec, &log);
    assert!(
        status.success(),
        "the recorder failed:\n{}",
        std::fs::read_to_string(&log).unwrap_or_default()
    );
    (dir, file)
}

/// FNV-1a, 64 bits: how the decoder script summarizes long byte sequences.
fn fnv1a64(bytes: impl Iterator<Item = u8>) -> String {
    let mut h: u64 = 0xcbf29ce484222325;
    for b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x100000001b3);
    }
    format!("{h:016x}")
}

/// Long sequences of small integers summarized as the script does.
fn summarize(v: &Value) -> Value {
    match v {
        Value::Array(items)
            if items.len() > 64
                && items
                    .iter()
                    .all(|x| x.as_u64().is_some_and(|n| n < 256) && !x.is_f64()) =>
        {
            serde_json::json!({
                "bytes": items.len(),
                "fnv1a64": fnv1a64(items.iter().map(|x| x.as_u64().unwrap_or(0) as u8)),
            })
        }
        Value::Array(items) => Value::Array(items.iter().map(summarize).collect()),
        Value::Object(m) => {
            Value::Object(m.iter().map(|(k, x)| (k.clone(), summarize(x))).collect())
        }
        other => other.clone(),
    }
}

/// Equal, floats to the precision of a `float32`; the first difference otherwise.
fn differ(path: &str, ours: &Value, theirs: &Value) -> Option<String> {
    match (ours, theirs) {
        (Value::Object(a), Value::Object(b)) => {
            if a.len() != b.len() {
                return Some(format!("{path}: fields {a:?} vs {b:?}"));
            }
            a.iter().find_map(|(k, x)| match b.get(k) {
                Some(y) => differ(&format!("{path}.{k}"), x, y),
                None => Some(format!("{path}.{k}: missing from the ROS 2 decoding")),
            })
        }
        (Value::Array(a), Value::Array(b)) => {
            if a.len() != b.len() {
                return Some(format!("{path}: {} vs {} elements", a.len(), b.len()));
            }
            a.iter()
                .zip(b)
                .enumerate()
                .find_map(|(i, (x, y))| differ(&format!("{path}[{i}]"), x, y))
        }
        (Value::Number(a), Value::Number(b)) => {
            if a == b {
                return None;
            }
            let (x, y) = (
                a.as_f64().unwrap_or(f64::NAN),
                b.as_f64().unwrap_or(f64::NAN),
            );
            ((x - y).abs() > 1e-6 * x.abs().max(1.0)).then(|| format!("{path}: {a} vs {b}"))
        }
        _ => (ours != theirs).then(|| format!("{path}: {ours} vs {theirs}")),
    }
}

/// Decode `file` with the ROS 2 decoders and check every message against robocog's decoding.
/// Returns, per topic, how many messages were decoded.
fn check_with_ros2_decoders(dir: &Path, file: &Path) -> BTreeMap<String, usize> {
    let script = repo().join("tests/ros2/decode.py");
    let out = run(
        &python(),
        &[script.display().to_string(), file.display().to_string()],
        Duration::from_secs(600),
    );
    assert!(
        out.status.success(),
        "the ROS 2 decoders failed on {}:\n{}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(dir.join("ros2-decoded.jsonl"), &out.stdout).unwrap();
    let theirs: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let (_, ours, _) = read_recording(file);
    assert_eq!(
        theirs.len(),
        ours.len(),
        "the ROS 2 reader saw another number of messages"
    );
    let defs = ros_msgs::definitions();
    let mut decoded: BTreeMap<String, usize> = BTreeMap::new();
    for (i, (o, t)) in ours.iter().zip(&theirs).enumerate() {
        assert_eq!(t["topic"], o.topic.as_str(), "message {i}");
        match defs.ros_name(&o.type_name) {
            Ok(name) => {
                assert_eq!(t["schema"], name.as_str(), "message {i} on {}", o.topic);
                assert!(
                    t.get("error").is_none(),
                    "a ROS 2 decoder refused message {i} on {} ({}): {}",
                    o.topic,
                    o.type_name,
                    t["error"]
                );
                assert_eq!(
                    t["same_bytes"], true,
                    "rosbags did not serialize message {i} on {} back to its bytes",
                    o.topic
                );
                let mine = summarize(&defs.ros_json(&o.type_name, &o.data).unwrap());
                if let Some(d) = differ(&o.topic, &mine, &t["decoded"]) {
                    panic!(
                        "message {i} on {} ({}) reads differently in ROS 2: {d}",
                        o.topic, o.type_name
                    );
                }
                *decoded.entry(format!("{} ({name})", o.topic)).or_default() += 1;
            }
            Err(why) => panic!(
                "message {i} on {} ({}) has no ROS 2 definition: {why}",
                o.topic, o.type_name
            ),
        }
    }
    for (topic, n) in &decoded {
        eprintln!("{n:>6} decoded by ROS 2 decoders: {topic}");
    }
    decoded
}

#[test]
fn a_recorded_touch_game_reads_the_same_in_ros2_decoders() {
    let (dir, file) = record(
        "ros2touch",
        "launch/touch_the_ball.toml",
        &["panel=false", "camera_fps=5"],
        |live| {
            let status = live.wait_exit(Duration::from_secs(300));
            assert!(
                status.success(),
                "the touch game failed ({status}):\n{}",
                live.lines.all().join("\n")
            );
        },
    );
    let decoded = check_with_ros2_decoders(&dir, &file);
    for topic in [
        "vision/rgbd",
        "vision/ball",
        "body/joint_states",
        "game/command",
        "speech/utterance",
        "audio/in",
        "executive/transitions",
    ] {
        assert!(
            decoded.keys().any(|k| k.starts_with(&format!("{topic} ("))),
            "nothing on {topic} was decoded: {decoded:#?}"
        );
    }
    let _ = std::fs::remove_file(&file);
}

#[test]
fn a_recorded_coach_game_reads_the_same_in_ros2_decoders() {
    let (dir, file) = record("ros2coach", "launch/nao_coach.toml", &[], |live| {
        live.lines
            .wait_for("the coach game under way", Duration::from_secs(60), |l| {
                l.contains("nao_bridge") && l.contains("robot")
            });
        std::thread::sleep(Duration::from_secs(10));
        live.sigterm();
        live.wait_exit(Duration::from_secs(30));
    });
    let decoded = check_with_ros2_decoders(&dir, &file);
    assert!(
        decoded.len() >= 4,
        "too few of the coach game's topics decoded: {decoded:#?}"
    );
    let _ = std::fs::remove_file(&file);
}

#[test]
fn type_hashes_agree_with_an_independent_implementation() {
    let defs = ros_msgs::definitions();
    let dir = scratch(&unique_namespace("rihs01"));
    let types: Vec<Value> = defs
        .types()
        .filter_map(|(ty, r)| {
            let name = r.ok()?;
            Some(serde_json::json!({
                "ros2": name,
                "definition": defs.full_definition(ty).unwrap(),
            }))
        })
        .collect();
    assert_eq!(
        types.len(),
        interfaces::msg::REGISTRY.len(),
        "every message type has a definition"
    );
    // The standard messages robocog's definitions use: their hashes must be ROS 2's own (rosbags'
    // type store of Jazzy), or a ROS 2 node would see another type.
    let standard: Vec<&str> = defs.standard_messages().collect();
    for want in [
        "std_msgs/msg/Header",
        "builtin_interfaces/msg/Time",
        "geometry_msgs/msg/Point",
        "geometry_msgs/msg/Transform",
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CameraInfo",
        "sensor_msgs/msg/JointState",
    ] {
        assert!(standard.contains(&want), "{want} is not used: {standard:?}");
    }
    let input = dir.join("types.json");
    std::fs::write(
        &input,
        serde_json::to_vec(&serde_json::json!({"robocog": types, "standard": standard})).unwrap(),
    )
    .unwrap();
    let out = run(
        &python(),
        &[
            repo().join("tests/ros2/hashes.py").display().to_string(),
            input.display().to_string(),
        ],
        Duration::from_secs(120),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let theirs: BTreeMap<String, String> = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(theirs.len(), types.len() + standard.len());
    for name in &standard {
        assert_eq!(
            defs.message_rihs01(name).unwrap(),
            theirs[*name],
            "the RIHS01 hash of the standard {name}"
        );
    }
    for (ty, r) in defs.types() {
        let Ok(name) = r else { continue };
        assert_eq!(
            defs.rihs01(ty).unwrap(),
            theirs[&name],
            "the RIHS01 hash of {name} ({ty})"
        );
    }
}

/// A graph with the bridge, as a ROS 2 node on rmw_zenoh meets it: a zenoh client from PyPI
/// (`tests/ros2/rmw_zenoh_client.py`) following rmw_zenoh's formats lists robocog's talker from
/// the ROS 2 graph's tokens, reads its topic with a ROS 2 decoder, and publishes as a ROS 2
/// publisher into a robocog subscriber; what it sends wrong is counted by the bridge, which runs
/// on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ros2_node_on_rmw_zenoh_sees_robocog_topics_and_feeds_a_robocog_subscriber() {
    use interfaces::msg::std_msgs::Text;
    use interfaces::{Bus, topics};
    let ns = unique_namespace("rmwzenoh");
    let dir = scratch(&ns);
    let manifest = robocog_tests::write_manifest(
        &dir,
        "bridge.toml",
        r#"
[graph]
name = "bridge_test"

[[component]]
name = "talker"
binary = "@FIXTURE@"
args = ["--role", "talker", "--rate", "20"]

[[component]]
name = "ros2_bridge"
binary = "ros2_bridge"
args = ["--domain", "7"]
"#,
    );
    let mut live = Launch::start(&manifest, &ns, &[]);
    live.lines
        .wait_for("the bridge up", Duration::from_secs(30), |l| {
            l.contains("chatter (robocog.Text) bridged out as /chatter")
        });
    let defs = ros_msgs::definitions();
    let ros_name = defs.ros_name("robocog.Text").unwrap();
    let hash = defs.rihs01("robocog.Text").unwrap();
    let definition = dir.join("Text.msg");
    std::fs::write(&definition, defs.full_definition("robocog.Text").unwrap()).unwrap();

    // What robocog receives from the ROS 2 side, and the bridge's counters.
    let bus = Bus::open(&live.connect_args(), "test-ros2").await.unwrap();
    let said = bus.subscriber_named::<Text>("ros_said", 64).await.unwrap();
    let diags = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();

    let script = repo().join("tests/ros2/rmw_zenoh_client.py");
    let args: Vec<String> = vec![
        script.display().to_string(),
        "--connect".into(),
        live.endpoint.clone(),
        "--domain".into(),
        "7".into(),
        "--ros-name".into(),
        ros_name.clone(),
        "--hash".into(),
        hash.clone(),
        "--definition".into(),
        definition.display().to_string(),
        "--listen".into(),
        "/chatter".into(),
        "--publish".into(),
        "/ros_said".into(),
        "--ready-token".into(),
        interfaces::liveliness::publisher_key(&ns, "ros2_bridge", "robocog.Text", "ros_said"),
    ];
    let client =
        tokio::task::spawn_blocking(move || run(&python(), &args, Duration::from_secs(120)));
    let mut from_ros = Vec::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(90);
    while from_ros.len() < 3 && std::time::Instant::now() < deadline {
        if let Some(t) = said.recv_timeout(Duration::from_millis(500)).await.unwrap() {
            from_ros.push(t.text);
        }
    }
    let out = client.await.unwrap();
    assert!(
        out.status.success(),
        "the rmw_zenoh client failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!("the rmw_zenoh client's report: {report:#}");

    // 1. The ROS 2 graph holds the talker as a node and its publisher, with robocog's hash.
    let tokens: Vec<&str> = report["tokens"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(
        tokens
            .iter()
            .any(|t| t.starts_with("@ros2_lv/7/") && t.ends_with("/NN/%/%/talker")),
        "no node token for the talker: {tokens:#?}"
    );
    let mp = format!("/MP/%/%/talker/%chatter/robocog_msgs::msg::dds_::Text_/{hash}/::,10:,:,:,,");
    assert!(
        tokens.iter().any(|t| t.ends_with(&mp)),
        "no publisher token {mp}: {tokens:#?}"
    );

    // 2. Its samples read as ROS 2 reads them: the text, an attachment, sequence numbers.
    let received = report["received"].as_array().unwrap();
    assert_eq!(received.len(), 3, "{report:#}");
    let mut last_seq = 0;
    for r in received {
        assert!(r["text"].as_str().unwrap().starts_with("hello "), "{r}");
        assert_eq!(r["attachment_len"], 33, "{r}");
        let seq = r["seq"].as_i64().unwrap();
        assert!(seq > last_seq, "sequence numbers go up: {received:#?}");
        last_seq = seq;
        let age_ns = interfaces::header::system_now_ns() - r["source_ns"].as_i64().unwrap();
        assert!((0..120_000_000_000).contains(&age_ns), "{r}");
        assert_eq!(r["gid"].as_str().unwrap().len(), 32, "{r}");
    }

    // 3. The ROS 2 publisher fed the robocog subscriber, every good sample once.
    assert_eq!(
        from_ros,
        ["from ros 1", "from ros 2", "from ros 3"],
        "{report:#}\n{}",
        live.lines.all().join("\n")
    );

    // 4. What it sent wrong was counted, and dropped.
    let want = [
        ("ros2_bad_attachment/ros_said", 2),
        ("ros2_undecodable/ros_said", 1),
        ("ros2_bad_hash/ros_said", 1),
        ("ros2_unknown_type/ros_other", 1),
        ("ros2_in/ros_said", 3),
    ];
    let deadline = std::time::Instant::now() + Duration::from_secs(15);
    let mut last = None;
    while std::time::Instant::now() < deadline {
        if let Some(d) = diags
            .recv_timeout(Duration::from_millis(500))
            .await
            .unwrap()
            && d.component == "ros2_bridge"
        {
            let done = want.iter().all(|(k, n)| d.get(k) == *n);
            last = Some(d);
            if done {
                break;
            }
        }
    }
    let d = last.expect("no diagnostics from the bridge");
    for (k, n) in want {
        assert_eq!(d.get(k), n, "{k}: {d:#?}");
    }
    assert!(d.get("ros2_out/chatter") >= 3, "{d:#?}");
    assert!(
        said.recv_timeout(Duration::from_millis(300))
            .await
            .unwrap()
            .is_none(),
        "a refused sample reached robocog"
    );
    // The bridge ran on.
    assert_eq!(
        live.lines.count(|l| l.contains("ros2_bridge exited")),
        0,
        "{}",
        live.lines.all().join("\n")
    );
    live.sigterm();
    live.wait_exit(Duration::from_secs(30));
}

/// `robocog interface` with what it cannot do: a type it does not know, a folder it cannot
/// write; and a tagged union of the DR shown with its `kind`. (What ROS 2 cannot describe at all
/// is refused with the reason: `ros_msgs`' unit tests; no type of this build is.)
#[test]
fn interface_refuses_unknown_types_and_unwritable_folders_and_shows_tagged_unions() {
    let robocog = robocog_tests::bin("robocog");
    let out = run(
        &robocog,
        &["interface".into(), "show".into(), "robocog.Nope".into()],
        Duration::from_secs(30),
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no message type \"robocog.Nope\""), "{err}");
    let out = run(
        &robocog,
        &[
            "interface".into(),
            "show".into(),
            "robocog.dr.DrChange".into(),
        ],
        Duration::from_secs(30),
    );
    assert!(out.status.success());
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(
        shown.contains("uint32 CHANGE_EVENT_KIND_RESTORED=7")
            && shown.contains("MSG: std_msgs/Header"),
        "{shown}"
    );
    let out = run(
        &robocog,
        &[
            "interface".into(),
            "export".into(),
            "/proc/robocog-cannot-write-here".into(),
        ],
        Duration::from_secs(30),
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("cannot write the package under /proc/robocog-cannot-write-here"),
        "{err}"
    );
}
