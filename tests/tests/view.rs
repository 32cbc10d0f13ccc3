#![allow(clippy::unwrap_used)]
//! `robocog view --save`: a running graph into an `.rrd` file, checked with the `rerun` command
//! line of the rerun-sdk Python package at the viewer crate's exact version (`rerun rrd verify`,
//! `rerun rrd print`). `scripts/test` installs it and exports its path as `ROBOCOG_RERUN_CLI`.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::body::{JointState, JointStates};
use interfaces::msg::executive::StateTransition;
use interfaces::{Bus, topics};
use robocog_tests::*;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The `rerun` CLI, from `ROBOCOG_RERUN_CLI`.
fn rerun_cli() -> PathBuf {
    let p = std::env::var_os("ROBOCOG_RERUN_CLI").map(PathBuf::from);
    match p {
        Some(p) if p.is_file() => p,
        _ => panic!(
            "ROBOCOG_RERUN_CLI must name the `rerun` executable of `pip install rerun-sdk==<the \
             rerun crate's version>` (scripts/test installs it: `source scripts/lib.sh; \
             need_rerun_cli`); got {p:?}"
        ),
    }
}

/// What a recording holds: entity -> archetype -> rows (`/world/ball` -> {Points3D: 19}).
type Contents = BTreeMap<String, BTreeMap<String, u64>>;

/// `rerun rrd verify <file>` passes; the entities of `rerun rrd print <file>`, each with the
/// archetypes of its data columns and their row counts.
fn verify_and_print(rrd: &Path) -> Contents {
    let cli = rerun_cli();
    let out = Command::new(&cli)
        .args(["rrd", "verify"])
        .arg(rrd)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rerun rrd verify {} failed:\n{}{}",
        rrd.display(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new(&cli)
        .args(["rrd", "print"])
        .arg(rrd)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "rerun rrd print {} failed:\n{}",
        rrd.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    entities(&String::from_utf8_lossy(&out.stdout))
}

/// Parse the chunk lines of `rerun rrd print`:
/// `Chunk(<id>) with 1 rows (988 B) - /a/c - data columns: [Image:buffer Image:format]`.
fn entities(print: &str) -> Contents {
    let mut map = Contents::new();
    for line in print.lines().filter(|l| l.starts_with("Chunk(")) {
        let mut parts = line.splitn(3, " - ");
        let (Some(head), Some(entity), Some(columns)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let rows: u64 = head
            .split(" with ")
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .and_then(|n| n.parse().ok())
            .unwrap_or(0);
        let columns = columns
            .trim()
            .trim_start_matches("data columns: [")
            .trim_end_matches(']');
        let archetypes: BTreeSet<&str> = columns
            .split_whitespace()
            .filter_map(|c| c.split_once(':').map(|(a, _)| a))
            .collect();
        let e = map.entry(entity.trim().to_string()).or_default();
        for a in archetypes {
            *e.entry(a.to_string()).or_default() += rows;
        }
    }
    map
}

/// Rows of `archetype` at `entity` (0 when absent).
fn rows(entities: &Contents, entity: &str, archetype: &str) -> u64 {
    let path = format!("/{}", entity.trim_start_matches('/'));
    entities
        .get(&path)
        .and_then(|a| a.get(archetype))
        .copied()
        .unwrap_or(0)
}

fn assert_has(entities: &Contents, entity: &str, archetype: &str) {
    let path = format!("/{}", entity.trim_start_matches('/'));
    assert!(
        rows(entities, entity, archetype) > 0,
        "no {archetype} at {path} in the recording; it has:\n{}",
        entities
            .iter()
            .map(|(e, a)| format!("{e}: {a:?}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
}

/// Start `robocog view --save <rrd>` (plus `extra`) on the graph; its log goes to `log`.
fn start_view(
    launch: &Launch,
    ns: &str,
    rrd: &Path,
    extra: &[&str],
    log: &Path,
) -> std::process::Child {
    let rrd = rrd.display().to_string();
    let mut args = vec!["view", "--save", rrd.as_str()];
    args.extend_from_slice(extra);
    start_tool(launch, ns, &args, log)
}

/// Joint states of the head's joints (the rest of the arm at 0).
fn joint_states(t: f64) -> JointStates {
    let joint = |name: &str, position: f64| JointState {
        name: name.into(),
        position,
        ..Default::default()
    };
    JointStates {
        driver: "test".into(),
        joints: vec![joint("neck_yaw", 0.3 * t.sin()), joint("left_elbow", -0.5)],
        ..Default::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_touch_graph_is_saved_with_camera_robot_ball_logs_and_rates() {
    let ns = unique_namespace("view-eyes");
    let dir = scratch(&ns);
    let rrd = dir.join("eyes.rrd");
    let log = dir.join("view.log");
    let launch = Launch::start(&repo().join("launch/eyes_sim.toml"), &ns, &[]);
    let mut view = start_view(&launch, &ns, &rrd, &["--game", "touch"], &log);
    let t = Duration::from_secs(60);
    log_wait(&log, "the viewer on the bus", t, |l| {
        l.contains("logging namespace")
    });
    log_wait(&log, "camera frames", t, |l| {
        l.contains("new topic") && l.contains("vision/rgbd")
    });
    log_wait(&log, "tracks", t, |l| {
        l.contains("new topic") && l.contains("vision/ball")
    });

    // What the eyes graph does not publish: joint states, a transition, a mangled transition,
    // and a type this build does not know.
    let bus = Bus::open(&launch.connect_args(), "test-view")
        .await
        .unwrap();
    let js = bus.publisher(&topics::BODY_JOINT_STATES).await.unwrap();
    let tr = bus.publisher(&topics::EXECUTIVE_TRANSITIONS).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    for i in 0..20 {
        js.publish(&mut joint_states(i as f64 * 0.1)).await.unwrap();
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    tr.put_encoded(vec![0x00, 0x01, 0x00, 0x00, 1, 2, 3])
        .await
        .unwrap();
    let mut transition = StateTransition {
        machine: "touch".into(),
        event: "ball_detected".into(),
        exited: vec!["game/playing/search".into()],
        entered: vec!["game/playing/track".into()],
        active: vec!["game/playing/track".into()],
        step: 7,
        ..Default::default()
    };
    tr.publish(&mut transition).await.unwrap();
    let mystery = bus
        .raw_publisher("mystery/topic", "robocog.NoSuchType", "test-mystery")
        .await
        .unwrap();
    mystery
        .put(vec![0x00, 0x01, 0x00, 0x00, 0, 0, 0, 0])
        .await
        .unwrap();
    log_wait(&log, "the unknown type listed", t, |l| {
        l.contains("mystery/topic") && l.contains("robocog.NoSuchType")
    });
    // Two seconds of rates.
    tokio::time::sleep(Duration::from_millis(2500)).await;

    let status = sigterm_and_wait(&mut view, &log);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "the viewer failed: {status:?}\n{text}");
    let summary = text
        .lines()
        .find(|l| l.contains("logged ") && l.contains(" samples of "))
        .unwrap_or_else(|| panic!("no summary line:\n{text}"));
    assert!(summary.contains("undecodable 1;"), "{summary}");
    assert!(
        summary.contains("mystery/topic (robocog.NoSuchType)"),
        "{summary}"
    );

    let print = verify_and_print(&rrd);
    // The camera hangs under its optical-frame link, deep in the robot's link tree.
    let camera = print
        .keys()
        .find(|e| {
            e.starts_with("/world/robot/base_footprint/")
                && e.ends_with("/head_rgbd_optical_frame/camera")
        })
        .unwrap_or_else(|| panic!("no head camera entity; entities: {:?}", print.keys()))
        .clone();
    let optical = camera.trim_end_matches("/camera").to_string();
    assert_has(&print, &camera, "Pinhole");
    assert_has(&print, &format!("{camera}/rgb"), "Image");
    assert_has(&print, &format!("{camera}/depth"), "DepthImage");
    assert_has(&print, &format!("{camera}/ball_window"), "Boxes2D");
    assert_has(&print, &optical, "Transform3D");
    // No deep representation in this graph: the ball is in the camera frame.
    assert_has(&print, &format!("{optical}/ball"), "Points3D");
    assert_has(
        &print,
        &format!("{optical}/ball/trajectory"),
        "LineStrips3D",
    );
    // The joint states move the links (the neck's yaw), with the collision geometry drawn.
    let head = print
        .keys()
        .find(|e| e.ends_with("/neck_roll_link/head"))
        .unwrap_or_else(|| panic!("no head link; entities: {:?}", print.keys()))
        .clone();
    // Every one of the 20 joint states moved the head (plus the rest pose drawn first).
    assert!(
        rows(&print, &head, "Transform3D") >= 20,
        "{:?}",
        print.get(&head)
    );
    assert!(
        print.iter().any(|(e, a)| e.contains("/collision/")
            && (a.contains_key("Boxes3D") || a.contains_key("Cylinders3D"))),
        "no collision geometry"
    );
    assert_has(&print, "log/executive/touch", "TextLog");
    assert_has(&print, "stats/rate_hz/vision/rgbd", "Scalars");
    assert_has(&print, "stats/latency_ms/vision/ball", "Scalars");
    drop(launch);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_nao_field_is_saved_in_2d_and_3d() {
    let ns = unique_namespace("view-nao");
    let dir = scratch(&ns);
    let rrd = dir.join("nao.rrd");
    let log = dir.join("view.log");
    let free = || {
        std::net::UdpSocket::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port()
    };
    let sets = [
        format!("debug_port={}", free()),
        format!("gc_port={}", free()),
        format!("command_port={}", free()),
    ];
    let mut extra = Vec::new();
    for s in &sets {
        extra.push("--set");
        extra.push(s.as_str());
    }
    let launch = Launch::start(&repo().join("launch/nao_field.toml"), &ns, &extra);
    let mut view = start_view(&launch, &ns, &rrd, &[], &log);
    let t = Duration::from_secs(60);
    log_wait(&log, "the coach layout chosen from the topics", t, |l| {
        l.contains("layout: Coach")
    });
    log_wait(&log, "the team world model", t, |l| {
        l.contains("new topic") && l.contains("nao/world_model")
    });
    log_wait(&log, "the simulated field's truth", t, |l| {
        l.contains("new topic") && l.contains("sim/field_truth")
    });
    tokio::time::sleep(Duration::from_secs(3)).await;
    let status = sigterm_and_wait(&mut view, &log);
    assert!(
        status.success(),
        "the viewer failed: {status:?}\n{}",
        std::fs::read_to_string(&log).unwrap()
    );
    let print = verify_and_print(&rrd);
    assert_has(&print, "field2d/lines", "LineStrips2D");
    assert_has(&print, "field3d/lines", "LineStrips3D");
    assert_has(&print, "field2d/robots", "Points2D");
    assert_has(&print, "field3d/robots", "Points3D");
    assert_has(&print, "field3d/robots/heading", "Arrows3D");
    assert_has(&print, "field2d/truth/ball", "Points2D");
    assert_has(&print, "stats/rate_hz/nao/world_model", "Scalars");
    drop(launch);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_deep_representation_is_mirrored_with_its_nodes_and_changes() {
    use interfaces::msg::dr::{PoseUpdate, Transform, UpdateRequest};
    let ns = unique_namespace("view-dr");
    let dir = scratch(&ns);
    let rrd = dir.join("dr.rrd");
    let log = dir.join("view.log");
    let state = format!("state_dir={}", dir.join("dr-state").display());
    let launch = Launch::start(&repo().join("launch/dr_only.toml"), &ns, &["--set", &state]);
    launch
        .lines
        .wait_for("the DR up", Duration::from_secs(60), |l| {
            l.contains("deep_representation is up")
        });
    let mut view = start_view(&launch, &ns, &rrd, &[], &log);
    let t = Duration::from_secs(60);
    log_wait(&log, "the DR snapshot", t, |l| {
        l.contains("DR snapshot for the viewer's copy")
    });
    // The ball moves in the DR: a pose_set change the viewer's copy applies.
    let bus = Bus::open(&launch.connect_args(), "test-view-dr")
        .await
        .unwrap();
    let request = UpdateRequest {
        poses: vec![PoseUpdate {
            node: "ball".into(),
            pose: Transform {
                translation_m: [0.6, 0.1, 0.9],
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
        }],
        ..Default::default()
    };
    let reply = bus
        .call(&topics::DR_UPDATE, &request, Duration::from_secs(10))
        .await
        .unwrap();
    assert_eq!(reply.applied, 1);
    log_wait(&log, "the change received", t, |l| {
        l.contains("new topic") && l.contains("dr/changes")
    });
    tokio::time::sleep(Duration::from_secs(1)).await;
    let status = sigterm_and_wait(&mut view, &log);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "the viewer failed: {status:?}\n{text}");
    assert!(
        !text.contains("not applied to the viewer's copy"),
        "the copy missed the change:\n{text}"
    );
    let print = verify_and_print(&rrd);
    // Drawn from the snapshot, then again after the change.
    assert!(
        rows(&print, "dr/nodes/ball", "Transform3D") >= 2,
        "{:?}",
        print.get("/dr/nodes/ball")
    );
    assert_has(&print, "dr/nodes/ball", "Points3D");
    assert_has(&print, "dr/edges", "LineStrips3D");
    // The snapshot and the pose change as text.
    assert!(
        rows(&print, "log/dr", "TextLog") >= 2,
        "{:?}",
        print.get("/log/dr")
    );
    drop(launch);
}
