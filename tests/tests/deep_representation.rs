#![allow(clippy::unwrap_used)]
//! The `deep_representation` service as a real process under `robocog launch`: changes through
//! the bus, a SIGKILL, a restart by the launcher, and the same answers afterwards.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::dr::*;
use interfaces::{Bus, CallError, ErrorCode, Header, topics};
use robocog_tests::*;
use std::path::Path;
use std::time::{Duration, Instant};

const T: Duration = Duration::from_secs(5);

fn manifest(dir: &Path, state: &Path) -> std::path::PathBuf {
    let urdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/loki.urdf");
    write_manifest(
        dir,
        "dr.toml",
        &format!(
            r#"
[graph]
name = "dr_restart"

[[component]]
name = "deep_representation"
binary = "{bin}"
args = ["--scene", "touch", "--state-dir", "{state}", "--urdf", "{urdf}", "--compact-every", "2"]
restart = "on-failure"
backoff_ms = 100
"#,
            bin = bin("deep_representation").display(),
            state = state.display(),
            urdf = urdf.display(),
        ),
    )
}

/// Call until the service answers (it may be restarting), at most `within`.
async fn call_until_up<Q: interfaces::Message, R: interfaces::Message>(
    bus: &Bus,
    svc: &interfaces::Service<Q, R>,
    req: &Q,
    within: Duration,
) -> R {
    let deadline = Instant::now() + within;
    loop {
        match bus.call(svc, req, Duration::from_secs(2)).await {
            Ok(r) => return r,
            Err(_) if Instant::now() < deadline => {
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
            Err(e) => panic!("{} did not answer within {within:?}: {e}", svc.name()),
        }
    }
}

fn at(stamp_ns: i64) -> Header {
    Header {
        stamp_ns,
        ..Header::default()
    }
}

async fn ball_colour(bus: &Bus) -> Option<AttrValue> {
    let ball = call_until_up(
        bus,
        &topics::DR_GET_NODE,
        &GetNodeRequest {
            name: "ball".into(),
            ..Default::default()
        },
        T * 4,
    )
    .await;
    ball.attributes
        .into_iter()
        .find(|a| a.key == "color")
        .map(|a| a.value)
}

async fn cup_in_world(bus: &Bus) -> TransformReply {
    let req = TransformRequest {
        target: "world".into(),
        source: "cup".into(),
        ..Default::default()
    };
    call_until_up(bus, &topics::DR_TRANSFORM, &req, T * 4).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn changes_survive_a_sigkill_and_the_restart_answers_the_same() {
    let ns = unique_namespace("dr");
    let dir = scratch(&ns);
    let state = dir.join("state");
    let m = manifest(&dir, &state);
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("the DR up", Duration::from_secs(30), |l| {
            l.contains("deep_representation is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-client")
        .await
        .unwrap();
    let changes = bus.subscriber(&topics::DR_CHANGES).await.unwrap();
    // The start scene answers (and the subscription has settled).
    let before = call_until_up(
        &bus,
        &topics::DR_GET_NODE,
        &GetNodeRequest {
            name: "ball".into(),
            ..Default::default()
        },
        T * 4,
    )
    .await;
    assert_eq!(before.node_type, "ball");
    assert_eq!(before.parent, "world");
    tokio::time::sleep(Duration::from_millis(300)).await;

    // Perception writes straight in: the ball's colour and pose.
    let update = UpdateRequest {
        header: at(2_000_000_000),
        attributes: vec![Attribute {
            node: "ball".into(),
            key: "color".into(),
            value: AttrValue::Text("red".into()),
        }],
        poses: vec![PoseUpdate {
            node: "ball".into(),
            pose: Transform::from_translation(0.7, 0.1, 1.0),
        }],
        joints: vec![],
    };
    let rep = bus.call(&topics::DR_UPDATE, &update, T).await.unwrap();
    assert_eq!(rep.applied, 2);

    // A structural change: a cup on the table, accepted; the same again is rejected, typed.
    let cup = StructuralChange::AddNode(Box::new(NodeSpec {
        name: "cup".into(),
        node_type: "object".into(),
        parent: "world".into(),
        edge: Edge::Free {
            pose: Transform::from_translation(0.5, -0.25, 0.8),
        },
        attributes: vec![KeyValue {
            key: "radius_m".into(),
            value: AttrValue::Float(0.04),
        }],
        ..Default::default()
    }));
    let req = ProposeRequest {
        header: at(2_100_000_000),
        change: cup.clone(),
    };
    let rep = bus.call(&topics::DR_PROPOSE, &req, T).await.unwrap();
    assert!(rep.accepted, "{rep:?}");
    let again = bus.call(&topics::DR_PROPOSE, &req, T).await.unwrap();
    assert!(!again.accepted);
    assert_eq!(again.reason_code, "duplicate_name");
    assert!(again.reason.contains("cup"), "{}", again.reason);

    // Bad input is a typed error.
    let unknown = TransformRequest {
        target: "world".into(),
        source: "teapot".into(),
        ..Default::default()
    };
    match bus.call(&topics::DR_TRANSFORM, &unknown, T).await {
        Err(CallError::Remote(e)) => {
            assert_eq!(e.code, ErrorCode::NotFound);
            assert!(e.message.contains("teapot"), "{}", e.message);
        }
        other => panic!("expected NotFound, got {other:?}"),
    }

    // Every change was published, in order.
    let mut seen = Vec::new();
    while seen.len() < 3 {
        match changes.recv_timeout(T).await.unwrap() {
            Some(c) => seen.push(c),
            None => panic!("only {} changes published: {seen:?}", seen.len()),
        }
    }
    let kinds: Vec<&str> = seen.iter().map(|c| c.event.kind()).collect();
    assert_eq!(
        kinds,
        ["pose_set", "attribute_set", "node_added"],
        "{seen:?}"
    );
    assert!(
        seen.windows(2).all(|w| w[1].seq == w[0].seq + 1),
        "{seen:?}"
    );
    assert_eq!(seen[2].event.node(), "cup");

    let colour = ball_colour(&bus).await;
    assert_eq!(colour, Some(AttrValue::Text("red".into())));
    let cup_before = cup_in_world(&bus).await;
    assert_eq!(cup_before.transform.translation_m, [0.5, -0.25, 0.8]);
    let ball_before = call_until_up(
        &bus,
        &topics::DR_TRANSFORM,
        &TransformRequest {
            target: "cup".into(),
            source: "ball".into(),
            ..Default::default()
        },
        T,
    )
    .await;

    // SIGKILL: no clean stop, no final snapshot. The launcher restarts it.
    let pid = eventually("the DR's pid", Duration::from_secs(15), || {
        component_pid(&launch, "deep_representation")
    });
    signal(pid, "KILL");
    launch
        .lines
        .wait_for("the restart", Duration::from_secs(20), |l| {
            l.contains("deep_representation stopped (killed by signal 9")
                && l.contains("restart 1/")
        });
    let new_pid = eventually("the DR's new pid", Duration::from_secs(30), || {
        component_pid(&launch, "deep_representation").filter(|p| *p != pid)
    });
    assert!(alive(new_pid));
    launch
        .lines
        .wait_for("the recovery line", Duration::from_secs(20), |l| {
            l.contains("recovered the state from")
        });

    // The same queries answer the same.
    assert_eq!(ball_colour(&bus).await, Some(AttrValue::Text("red".into())));
    let cup_after = cup_in_world(&bus).await;
    assert_eq!(cup_after.transform, cup_before.transform);
    let ball_after = call_until_up(
        &bus,
        &topics::DR_TRANSFORM,
        &TransformRequest {
            target: "cup".into(),
            source: "ball".into(),
            ..Default::default()
        },
        T,
    )
    .await;
    assert_eq!(ball_after.transform, ball_before.transform);
    let cup_node = call_until_up(
        &bus,
        &topics::DR_GET_NODE,
        &GetNodeRequest {
            name: "cup".into(),
            ..Default::default()
        },
        T,
    )
    .await;
    assert_eq!(cup_node.node_type, "object");
    assert_eq!(cup_node.attributes[0].value, AttrValue::Float(0.04));
    // Sequence numbers continue where they stopped.
    let rep = bus
        .call(
            &topics::DR_UPDATE,
            &UpdateRequest {
                header: at(3_000_000_000),
                attributes: vec![Attribute {
                    node: "cup".into(),
                    key: "color".into(),
                    value: AttrValue::Text("white".into()),
                }],
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    assert_eq!(rep.last_seq, seen[2].seq + 1);
    // The state folder holds the snapshot pair and the log.
    for f in ["snapshot.json", "snapshot.prev.json", "changes.log"] {
        assert!(
            state.join(f).is_file(),
            "{f} missing in {}",
            state.display()
        );
    }
    assert_eq!(
        launch.lines.count(|l| l.contains("corrupt")),
        0,
        "{}",
        launch.lines.all().join("\n")
    );
}
