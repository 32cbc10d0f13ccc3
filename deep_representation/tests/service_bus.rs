//! The DR service over a real bus in one process: a zenoh router on a loopback port, the service
//! and a client, each its own session. Every service, its typed errors, and that a fork leaves the
//! live graph alone.
#![allow(clippy::expect_used)] // a test fails by panicking
#![expect(
    clippy::disallowed_methods,
    reason = "an integration test over a real zenoh router: it waits on the wall for the transport"
)]

use std::time::Duration;

use deep_representation::service::{self, Scene, ServiceConfig};
use interfaces::bus::BusOptions;
use interfaces::msg::dr::*;
use interfaces::{Bus, CallError, ConnectArgs, ErrorCode, Header, ServiceError, topics};

const T: Duration = Duration::from_secs(5);

struct Env {
    _router: zenoh::Session,
    _running: service::Running,
    client: Bus,
}

async fn env(scene: Scene, state_dir: Option<std::path::PathBuf>) -> Env {
    let (router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0")
        .await
        .expect("a router");
    let connect = ConnectArgs::to_router(&endpoint, "dr-service-test");
    let server = Bus::open_with(&connect, "deep_representation", BusOptions::default())
        .await
        .expect("join the bus");
    let client = Bus::open_with(&connect, "client", BusOptions::default())
        .await
        .expect("join the bus");
    let mut config = ServiceConfig::new(scene);
    config.state_dir = state_dir;
    let running = service::start(server, config)
        .await
        .expect("start the service");
    // Wait until the queryables are reachable through the router.
    let probe = GetNodeRequest {
        name: "world".into(),
        ..Default::default()
    };
    for _ in 0..100 {
        if client.call(&topics::DR_GET_NODE, &probe, T).await.is_ok() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    Env {
        _router: router,
        _running: running,
        client,
    }
}

fn remote(r: Result<impl std::fmt::Debug, CallError>) -> ServiceError {
    match r {
        Err(CallError::Remote(e)) => e,
        other => panic!("expected a typed service error, got {other:?}"),
    }
}

fn tf(target: &str, source: &str, stamp_ns: u64) -> TransformRequest {
    TransformRequest {
        target: target.into(),
        source: source.into(),
        stamp_ns,
        ..Default::default()
    }
}

fn stamped(ns: i64) -> Header {
    Header {
        stamp_ns: ns,
        ..Header::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nodes_transforms_and_updates_with_typed_errors() {
    let e = env(Scene::Touch, None).await;
    let c = &e.client;

    let ball = c
        .call(
            &topics::DR_GET_NODE,
            &GetNodeRequest {
                name: "ball".into(),
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    assert_eq!(
        (
            ball.node_type.as_str(),
            ball.parent.as_str(),
            ball.edge.as_str()
        ),
        ("ball", "world", "free")
    );
    assert_eq!(ball.pose.translation_m, [0.8, 0.2, 1.1]);
    // The full description: the free edge at the same pose, the attributes.
    assert_eq!(ball.spec.name, "ball");
    assert_eq!(ball.spec.edge, Edge::Free { pose: ball.pose });
    assert!(
        ball.spec
            .attributes
            .iter()
            .any(|a| a.key == "radius_m" && matches!(a.value, AttrValue::Float(r) if r > 0.0)),
        "{:?}",
        ball.spec
    );
    let world = c
        .call(
            &topics::DR_GET_NODE,
            &GetNodeRequest {
                name: "world".into(),
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    assert!(world.children.contains(&"loki".to_string()));
    assert_eq!(
        world.spec,
        NodeSpec::default(),
        "the root has no description"
    );

    // world_T_ball is the ball's position; ball_T_world its inverse.
    let r = c
        .call(&topics::DR_TRANSFORM, &tf("world", "ball", 0), T)
        .await
        .unwrap();
    assert_eq!(r.transform.translation_m, [0.8, 0.2, 1.1]);
    assert_eq!(r.header.frame_id, "world");
    let inv = c
        .call(&topics::DR_TRANSFORM, &tf("ball", "world", 0), T)
        .await
        .unwrap();
    assert_eq!(inv.transform.translation_m, [-0.8, -0.2, -1.1]);

    // A joint moves at t = 2 s; at t = 1.5 s the elbow is half way (interpolation on the bus).
    let before = c
        .call(
            &topics::DR_TRANSFORM,
            &tf("world", "left_hand_center", 0),
            T,
        )
        .await
        .unwrap();
    for (t, v) in [(1_000_000_000, 0.0), (2_000_000_000, -1.0)] {
        c.call(
            &topics::DR_UPDATE,
            &UpdateRequest {
                header: stamped(t),
                joints: vec![JointUpdate {
                    joint: "left_elbow".into(),
                    value: v,
                }],
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    }
    let now = c
        .call(
            &topics::DR_TRANSFORM,
            &tf("world", "left_hand_center", 0),
            T,
        )
        .await
        .unwrap();
    assert_eq!(now.stamp_ns, 2_000_000_000);
    assert_ne!(now.transform, before.transform);
    let then = c
        .call(
            &topics::DR_TRANSFORM,
            &tf("world", "left_hand_center", 1_000_000_000),
            T,
        )
        .await
        .unwrap();
    let d = |a: &Transform, b: &Transform| {
        (0..3)
            .map(|i| (a.translation_m[i] - b.translation_m[i]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    assert!(d(&then.transform, &before.transform) < 1e-12);

    // Unknown names: NotFound, naming them.
    let err = remote(
        c.call(&topics::DR_TRANSFORM, &tf("world", "teapot", 0), T)
            .await,
    );
    assert_eq!(err.code, ErrorCode::NotFound);
    assert!(err.message.contains("teapot"), "{}", err.message);
    let err = remote(
        c.call(
            &topics::DR_GET_NODE,
            &GetNodeRequest {
                name: "nobody".into(),
                ..Default::default()
            },
            T,
        )
        .await,
    );
    assert_eq!(err.code, ErrorCode::NotFound);
    let err = remote(
        c.call(
            &topics::DR_UPDATE,
            &UpdateRequest {
                joints: vec![JointUpdate {
                    joint: "left_knee".into(),
                    value: 0.1,
                }],
                ..Default::default()
            },
            T,
        )
        .await,
    );
    assert_eq!(err.code, ErrorCode::NotFound);
    assert!(err.message.contains("left_knee"), "{}", err.message);

    // Malformed: a NaN, a zero quaternion, a pose on a joint link, a negative stamp. A bad batch
    // applies nothing: the valid attribute in it is not set.
    let bad_batch = UpdateRequest {
        attributes: vec![Attribute {
            node: "ball".into(),
            key: "color".into(),
            value: AttrValue::Text("blue".into()),
        }],
        joints: vec![JointUpdate {
            joint: "left_elbow".into(),
            value: f64::NAN,
        }],
        ..Default::default()
    };
    let err = remote(c.call(&topics::DR_UPDATE, &bad_batch, T).await);
    assert_eq!(err.code, ErrorCode::BadRequest);
    assert!(err.message.contains("not finite"), "{}", err.message);
    let ball = c
        .call(
            &topics::DR_GET_NODE,
            &GetNodeRequest {
                name: "ball".into(),
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    let colour = ball.attributes.iter().find(|a| a.key == "color").unwrap();
    assert_eq!(colour.value, AttrValue::Text("yellow".into()));
    for poses in [
        vec![PoseUpdate {
            node: "ball".into(),
            pose: Transform {
                translation_m: [0.0; 3],
                rotation_xyzw: [0.0; 4],
            },
        }],
        vec![PoseUpdate {
            node: "left_hand_center".into(),
            pose: Transform::default(),
        }],
    ] {
        let err = remote(
            c.call(
                &topics::DR_UPDATE,
                &UpdateRequest {
                    poses,
                    ..Default::default()
                },
                T,
            )
            .await,
        );
        assert_eq!(err.code, ErrorCode::BadRequest, "{err:?}");
    }
    let err = remote(
        c.call(
            &topics::DR_UPDATE,
            &UpdateRequest {
                header: stamped(-1),
                ..Default::default()
            },
            T,
        )
        .await,
    );
    assert_eq!(err.code, ErrorCode::BadRequest);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn proposals_predicates_forks_pddl_and_snapshots() {
    let e = env(Scene::Touch, None).await;
    let c = &e.client;
    let changes = c.subscriber(&topics::DR_CHANGES).await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;

    // Rejections are replies, with the rule.
    let propose = |change: StructuralChange| ProposeRequest {
        header: Header::default(),
        change,
    };
    let node = |name: &str, node_type: &str, parent: &str| NodeSpec {
        name: name.into(),
        node_type: node_type.into(),
        parent: parent.into(),
        ..Default::default()
    };
    for (change, code) in [
        (
            StructuralChange::AddNode(Box::new(node("cup", "object", "table"))),
            "unknown_parent",
        ),
        (
            StructuralChange::AddNode(Box::new(node("cup", "teacup", "world"))),
            "unknown_type",
        ),
        (
            StructuralChange::RemoveNode {
                name: "left_hand_center".into(),
            },
            "protected",
        ),
        (
            StructuralChange::Reparent {
                name: "loki".into(),
                new_parent: "left_hand_center".into(),
                pose: Transform::default(),
            },
            "cycle",
        ),
    ] {
        let r = c
            .call(&topics::DR_PROPOSE, &propose(change), T)
            .await
            .unwrap();
        assert!(!r.accepted);
        assert_eq!(r.reason_code, code, "{r:?}");
        assert!(!r.reason.is_empty());
    }
    // A description the graph cannot hold (a NaN attribute, an attribute given twice) is a
    // BadRequest, not a rejection.
    let with_attrs = |attributes: Vec<KeyValue>| NodeSpec {
        attributes,
        ..node("cup", "object", "world")
    };
    let radius = |r: f64| KeyValue {
        key: "radius_m".into(),
        value: AttrValue::Float(r),
    };
    for (spec, says) in [
        (with_attrs(vec![radius(f64::NAN)]), "not finite"),
        (with_attrs(vec![radius(0.1), radius(0.2)]), "given twice"),
    ] {
        let err = remote(
            c.call(
                &topics::DR_PROPOSE,
                &propose(StructuralChange::AddNode(Box::new(spec))),
                T,
            )
            .await,
        );
        assert_eq!(err.code, ErrorCode::BadRequest);
        assert!(err.message.contains(says), "{}", err.message);
    }
    // Accepted: a marker fixed to the table, via a full spec.
    let marker = NodeSpec {
        edge: Edge::Fixed {
            origin: Transform::from_translation(2.0, 0.0, 0.0),
        },
        ..node("marker", "landmark", "world")
    };
    let r = c
        .call(
            &topics::DR_PROPOSE,
            &propose(StructuralChange::AddNode(Box::new(marker.clone()))),
            T,
        )
        .await
        .unwrap();
    assert!(r.accepted, "{r:?}");
    let published = changes.recv_timeout(T).await.unwrap().expect("a change");
    assert_eq!(
        (
            published.event.kind(),
            published.event.node(),
            published.seq
        ),
        ("node_added", "marker", r.seq)
    );
    match &published.event {
        ChangeEvent::NodeAdded { spec, .. } => assert_eq!(**spec, marker),
        other => panic!("expected the added node, got {other:?}"),
    }

    // Predicates: one fact, all facts, bad arity, unknown predicate, unknown body part.
    let pred = |p: &str, args: &[&str]| PredicateRequest {
        predicate: p.into(),
        args: args.iter().map(|s| s.to_string()).collect(),
        ..Default::default()
    };
    let r = c
        .call(
            &topics::DR_PREDICATE,
            &pred("closest_to_ball", &["loki"]),
            T,
        )
        .await
        .unwrap();
    assert!(r.holds);
    let r = c
        .call(
            &topics::DR_PREDICATE,
            &pred("reachable", &["ball", "left_arm"]),
            T,
        )
        .await
        .unwrap();
    assert!(!r.holds, "the ball starts out of reach");
    let all = c
        .call(&topics::DR_PREDICATE, &pred("", &[]), T)
        .await
        .unwrap();
    assert!(all.facts.contains(&Fact {
        predicate: "closest_to_ball".into(),
        args: vec!["loki".into()]
    }));
    let err = remote(
        c.call(&topics::DR_PREDICATE, &pred("near", &["ball"]), T)
            .await,
    );
    assert_eq!(err.code, ErrorCode::BadRequest);
    let err = remote(
        c.call(&topics::DR_PREDICATE, &pred("happy", &["loki"]), T)
            .await,
    );
    assert_eq!(err.code, ErrorCode::BadRequest);
    assert!(
        err.message.contains("closest_to_ball"),
        "lists the known ones: {}",
        err.message
    );
    let err = remote(
        c.call(
            &topics::DR_PREDICATE,
            &pred("reachable", &["ball", "tail"]),
            T,
        )
        .await,
    );
    assert_eq!(err.code, ErrorCode::NotFound);

    // Fork: look down, bring the ball close, reach; the live graph does not move.
    let snap_before = c
        .call(&topics::DR_SNAPSHOT, &SnapshotRequest::default(), T)
        .await
        .unwrap();
    let fork = ForkRequest {
        joints: vec![
            JointUpdate {
                joint: "neck_pitch".into(),
                value: 0.6,
            },
            JointUpdate {
                joint: "left_shoulder_pitch".into(),
                value: -1.2,
            },
        ],
        poses: vec![PoseUpdate {
            node: "ball".into(),
            pose: Transform::from_translation(0.42, 0.2, 1.0),
        }],
        changes: vec![StructuralChange::AddNode(Box::new(node(
            "marker", "landmark", "world",
        )))],
        ..Default::default()
    };
    let r = c.call(&topics::DR_FORK, &fork, T).await.unwrap();
    let reachable = Fact {
        predicate: "reachable".into(),
        args: vec!["ball".into(), "left_arm".into()],
    };
    let visible = Fact {
        predicate: "visible".into(),
        args: vec!["ball".into(), "head_rgbd".into()],
    };
    assert!(r.became_true.contains(&reachable), "{r:?}");
    assert!(r.became_true.contains(&visible), "{r:?}");
    let joints: Vec<&str> = r.joints_changed.iter().map(|j| j.joint.as_str()).collect();
    assert_eq!(joints, ["left_shoulder_pitch", "neck_pitch"]);
    assert_eq!(r.moved.len(), 1);
    assert_eq!(r.moved[0].node, "ball");
    assert_eq!(r.rejected.len(), 1, "the duplicate marker: {r:?}");
    assert!(r.rejected[0].starts_with("0: name `marker`"), "{r:?}");
    let snap_after = c
        .call(&topics::DR_SNAPSHOT, &SnapshotRequest::default(), T)
        .await
        .unwrap();
    assert_eq!(
        snap_after.snapshot, snap_before.snapshot,
        "the fork left the live graph alone"
    );
    assert_eq!(snap_after.last_seq, snap_before.last_seq);
    assert!(changes.try_recv().is_none(), "a fork publishes no change");
    let err = remote(
        c.call(
            &topics::DR_FORK,
            &ForkRequest {
                joints: vec![JointUpdate {
                    joint: "wing".into(),
                    value: 0.0,
                }],
                ..Default::default()
            },
            T,
        )
        .await,
    );
    assert_eq!(err.code, ErrorCode::NotFound);

    // PDDL.
    let p = c
        .call(
            &topics::DR_PDDL,
            &PddlRequest {
                problem_name: "touch".into(),
                goal: vec![Fact {
                    predicate: "near".into(),
                    args: vec!["left_hand_center".into(), "ball".into()],
                }],
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    assert!(
        p.problem.starts_with("(define (problem touch)"),
        "{}",
        p.problem
    );
    assert!(p.problem.contains("(:domain robocog)"));
    assert!(
        p.problem.contains("(closest-to-ball loki)"),
        "{}",
        p.problem
    );
    assert!(
        p.problem.contains("(near left_hand_center ball)"),
        "{}",
        p.problem
    );

    // Restore: replace the state with the empty world, then with the saved one.
    let empty = world_model::SceneGraph::new().snapshot();
    let r = c
        .call(
            &topics::DR_RESTORE,
            &SnapshotData {
                snapshot: empty.clone(),
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    assert!(r.snapshot.nodes.is_empty(), "only world: {r:?}");
    let err = remote(
        c.call(&topics::DR_TRANSFORM, &tf("world", "ball", 0), T)
            .await,
    );
    assert_eq!(err.code, ErrorCode::NotFound);
    let r = c.call(&topics::DR_RESTORE, &snap_before, T).await.unwrap();
    assert_eq!(r.snapshot, snap_before.snapshot, "nothing lost on the way");
    let nodes = &r.snapshot.nodes;
    assert!(nodes.iter().any(|n| matches!(n.camera, Camera::Pinhole(_))));
    assert!(nodes.iter().any(|n| matches!(n.edge, Edge::Joint { .. })));
    assert!(nodes.iter().any(|n| !n.collision.is_empty()));
    assert!(!r.snapshot.body_parts.is_empty());
    // A snapshot that is no graph (a node under a parent that is not there), or that holds what
    // a graph cannot (a NaN attribute), is a BadRequest and changes nothing.
    let orphan = Snapshot {
        nodes: vec![node("cup", "object", "table")],
        ..Default::default()
    };
    let nan = Snapshot {
        nodes: vec![with_attrs(vec![radius(f64::NAN)])],
        ..Default::default()
    };
    for (snapshot, says) in [(orphan, "table"), (nan, "not finite")] {
        let err = remote(
            c.call(
                &topics::DR_RESTORE,
                &SnapshotData {
                    snapshot,
                    ..Default::default()
                },
                T,
            )
            .await,
        );
        assert_eq!(err.code, ErrorCode::BadRequest);
        assert!(err.message.contains(says), "{}", err.message);
    }
    // Changes leave after the reply: wait for both, then make sure nothing else came.
    let mut kinds = Vec::new();
    for _ in 0..2 {
        let c = changes
            .recv_timeout(T)
            .await
            .unwrap()
            .expect("a published restore");
        kinds.push(c.event.kind());
    }
    assert_eq!(kinds, ["restored", "restored"]);
    assert!(
        changes
            .recv_timeout(Duration::from_millis(200))
            .await
            .unwrap()
            .is_none()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_coach_scene_and_a_state_folder() {
    let dir = std::env::temp_dir().join(format!("dr-service-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    {
        let e = env(Scene::Coach, Some(dir.clone())).await;
        let r = e
            .client
            .call(
                &topics::DR_PREDICATE,
                &PredicateRequest {
                    predicate: "fallen".into(),
                    args: vec!["opponent_2".into()],
                    ..Default::default()
                },
                T,
            )
            .await
            .unwrap();
        assert!(r.holds);
        let r = e
            .client
            .call(
                &topics::DR_UPDATE,
                &UpdateRequest {
                    attributes: vec![Attribute {
                        node: "opponent_2".into(),
                        key: "fallen".into(),
                        value: AttrValue::Bool(false),
                    }],
                    ..Default::default()
                },
                T,
            )
            .await
            .unwrap();
        assert_eq!(r.last_seq, 1);
    }
    // A second service on the same folder starts from the saved state, not the scene.
    let e = env(Scene::Empty, Some(dir.clone())).await;
    let r = e
        .client
        .call(
            &topics::DR_PREDICATE,
            &PredicateRequest {
                predicate: "fallen".into(),
                args: vec!["opponent_2".into()],
                ..Default::default()
            },
            T,
        )
        .await
        .unwrap();
    assert!(!r.holds, "the update survived");
    let _ = std::fs::remove_dir_all(&dir);
}
