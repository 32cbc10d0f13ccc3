use super::*;
use crate::types::{
    BodyPart, CameraIntrinsics, CollisionShape, JointKind, JointLimits, NodeType, StructuralChange,
    Transform, TransformIso, attr,
};
use crate::{At, SceneGraph, Stamp, scenes};
use interfaces::codec;
use interfaces::msg::Message;

/// Through CDR bytes as the bus carries them, in the message that carries it.
fn wire<T: Message>(msg: &T) -> T {
    let bytes = codec::encode(msg, T::TYPE_NAME).unwrap();
    codec::decode(&bytes, T::TYPE_NAME).unwrap()
}

/// Through JSON as the state folder keeps it.
fn json<T: serde::Serialize + serde::de::DeserializeOwned>(v: &T) -> T {
    serde_json::from_str(&serde_json::to_string(v).unwrap()).unwrap()
}

fn loki() -> crate::RobotModel {
    crate::RobotModel::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap()
}

/// A node with every kind of attribute, a camera, collision shapes of every kind (one with
/// an origin from Euler angles, whose quaternion is not exactly unit) and a continuous joint
/// (infinite limits).
fn rich_spec() -> NodeSpec {
    let iso = |t: [f64; 3], r: [f64; 3]| {
        Transform::from_iso(&nalgebra::Isometry3::new(t.into(), r.into()))
    };
    let mut spec = NodeSpec {
        name: "gripper".into(),
        node_type: "link".into(),
        parent: "wrist".into(),
        edge: Edge::Joint {
            joint: "wrist_roll".into(),
            kind: JointKind::Continuous,
            origin: Transform::planar(0.1, -0.2, 0.3),
            axis: [0.0, 0.0, 1.0],
            limits: JointLimits {
                lower: f64::NEG_INFINITY,
                upper: f64::INFINITY,
                velocity: 2.5,
                effort: f64::INFINITY,
            },
            value: -0.75,
        },
        attributes: Vec::new(),
        camera: Camera::Pinhole(CameraIntrinsics {
            name: "wrist_cam".into(),
            frame: "gripper".into(),
            width: 640,
            height: 480,
            fx: 525.0,
            fy: 524.5,
            cx: 319.5,
            cy: 239.5,
            min_range_m: 0.4,
            max_range_m: 4.0,
        }),
        collision: vec![
            CollisionShape {
                origin: iso([0.01, 0.02, 0.03], [0.3, -0.2, 0.1]),
                shape: Shape::Box {
                    size_m: [0.1, 0.2, 0.3],
                },
            },
            CollisionShape {
                origin: Transform::default(),
                shape: Shape::Cylinder {
                    radius_m: 0.05,
                    length_m: 0.2,
                },
            },
            CollisionShape {
                origin: Transform::from_translation(0.0, 0.0, 0.1),
                shape: Shape::Capsule {
                    radius_m: 0.04,
                    length_m: 0.12,
                },
            },
            CollisionShape {
                origin: Transform::default(),
                shape: Shape::Sphere { radius_m: 0.03 },
            },
            CollisionShape {
                origin: Transform::default(),
                shape: Shape::Mesh {
                    filename: "package://loki/gripper.stl".into(),
                },
            },
        ],
    };
    for (k, v) in [
        (attr::COLOR, AttrValue::Text("yellow".into())),
        (attr::EFFECTOR, AttrValue::Bool(true)),
        (attr::RADIUS_M, AttrValue::Float(0.055)),
        (attr::TEAM, AttrValue::Int(-3)),
        ("velocity_mps", AttrValue::Vec3([0.1, -0.2, 1e-9])),
    ] {
        spec = spec.with_attr(k, v);
    }
    spec
}

#[test]
fn a_node_spec_survives_the_bus_and_the_state_folder() {
    for spec in [
        rich_spec(),
        NodeSpec::free(
            "ball",
            NodeType::Ball,
            "world",
            Transform::planar(1.0, 2.0, 0.5),
        )
        .with_attr(attr::RADIUS_M, AttrValue::Float(0.11)),
        NodeSpec {
            edge: Edge::Fixed {
                origin: Transform::from_translation(2.0, 0.0, 0.0),
            },
            ..NodeSpec::free("marker", NodeType::Landmark, "world", Transform::default())
        },
    ] {
        let msg = m::NodeInfo {
            spec: spec.clone(),
            ..Default::default()
        };
        assert_eq!(wire(&msg).spec, spec);
        assert_eq!(json(&spec), spec);
    }
    // A missing limit is `null` in JSON, the tagged forms are snake_case.
    let text = serde_json::to_string(&rich_spec()).unwrap();
    for part in [
        r#""limits":{"lower":null,"upper":null,"velocity":2.5,"effort":null}"#,
        r#""edge":{"edge":"joint","joint":"wrist_roll","kind":"continuous""#,
        r#"{"key":"team","value":{"type":"int","value":-3}}"#,
        r#""shape":{"type":"sphere","radius_m":0.03}"#,
        r#""camera":{"pinhole":{"name":"wrist_cam""#,
    ] {
        assert!(text.contains(part), "{part} not in {text}");
    }
    // What the graph describes: the attributes sorted by key, each once.
    let mut g = SceneGraph::new();
    g.propose(
        StructuralChange::add(NodeSpec {
            parent: "world".into(),
            edge: Edge::Free {
                pose: Transform::default(),
            },
            node_type: "object".into(),
            ..rich_spec()
        }),
        Stamp(1),
    )
    .unwrap();
    let keys: Vec<String> = g
        .node_spec("gripper")
        .unwrap()
        .attributes
        .into_iter()
        .map(|a| a.key)
        .collect();
    let mut sorted = keys.clone();
    sorted.sort();
    assert_eq!(keys, sorted);
}

#[test]
fn a_proposal_survives_the_bus() {
    for p in [
        StructuralChange::add(rich_spec()),
        StructuralChange::RemoveNode { name: "cup".into() },
        StructuralChange::Reparent {
            name: "ball".into(),
            new_parent: "left_hand_center".into(),
            pose: Transform::planar(0.0, 0.1, -0.2),
        },
    ] {
        let msg = m::ProposeRequest {
            change: p.clone(),
            ..Default::default()
        };
        assert_eq!(wire(&msg).change, p);
    }
}

#[test]
fn every_change_event_survives_the_bus() {
    let mut g = scenes::touch_the_ball(&loki(), Stamp(1)).unwrap();
    g.enable_log();
    g.propose(StructuralChange::add(rich_spec_under("torso")), Stamp(2))
        .unwrap();
    g.propose(
        StructuralChange::Reparent {
            name: "ball".into(),
            new_parent: "left_hand_center".into(),
            pose: Transform::from_translation(0.0, 0.0, 0.05),
        },
        Stamp(3),
    )
    .unwrap();
    g.set_joint("left_elbow", -1.0, Stamp(4)).unwrap();
    g.set_pose(
        "player",
        &Transform::planar(2.0, 0.5, 3.0).to_iso(),
        Stamp(5),
    )
    .unwrap();
    g.set_attr(
        "ball",
        "velocity_mps",
        AttrValue::Vec3([0.0, 1.0, 0.0]),
        Stamp(6),
    )
    .unwrap();
    g.declare_body_part(
        BodyPart {
            name: "gripper_arm".into(),
            robot: "loki".into(),
            base_frame: "torso".into(),
            tip_frame: "gripper".into(),
            reach_m: 0.3,
        },
        Stamp(7),
    )
    .unwrap();
    g.propose(
        StructuralChange::add(NodeSpec::free(
            "cup",
            NodeType::Object,
            "world",
            Transform::default(),
        )),
        Stamp(8),
    )
    .unwrap();
    g.propose(
        StructuralChange::RemoveNode { name: "cup".into() },
        Stamp(9),
    )
    .unwrap();
    let events = g.take_log();
    let kinds: Vec<&str> = events.iter().map(|e| e.kind()).collect();
    assert_eq!(
        kinds,
        [
            "node_added",
            "reparented",
            "joint_set",
            "pose_set",
            "attribute_set",
            "body_part_declared",
            "node_added",
            "node_removed"
        ]
    );
    for (seq, e) in events.iter().enumerate() {
        let msg = m::DrChange {
            seq: seq as u64,
            event: e.clone(),
            ..Default::default()
        };
        assert_eq!(wire(&msg).event, *e);
        assert_eq!(json(e), *e);
    }
    assert_eq!(
        serde_json::to_string(&events[2]).unwrap(),
        r#"{"event":"joint_set","stamp_ns":4,"joint":"left_elbow","value":-1.0}"#
    );
    let typo = r#"{"event":"joint_set","stamp_ns":5,"joint":"a","value":1.0,"vaule":2}"#;
    assert!(
        serde_json::from_str::<ChangeEvent>(typo).is_err(),
        "unknown fields rejected"
    );
    assert_eq!(
        check_event(&ChangeEvent::Restored),
        Err(InvalidSpec::Restored)
    );
}

fn rich_spec_under(parent: &str) -> NodeSpec {
    NodeSpec {
        parent: parent.into(),
        ..rich_spec()
    }
}

#[test]
fn a_snapshot_survives_the_bus_and_restores_the_same_graph() {
    let mut g = scenes::touch_the_ball(&loki(), Stamp(1)).unwrap();
    g.propose(StructuralChange::add(rich_spec_under("torso")), Stamp(2))
        .unwrap();
    g.set_joint("left_elbow", -1.2, Stamp(3)).unwrap();
    g.set_pose("ball", &Transform::planar(0.5, 0.1, 0.2).to_iso(), Stamp(4))
        .unwrap();
    g.set_attr("ball", attr::COLOR, AttrValue::Text("red".into()), Stamp(5))
        .unwrap();
    let snap = g.snapshot();
    assert!(snap.nodes.iter().any(|n| n.camera.intrinsics().is_some()));
    assert!(snap.nodes.iter().any(|n| !n.collision.is_empty()));
    assert!(!snap.body_parts.is_empty());

    let msg = m::SnapshotData {
        snapshot: snap.clone(),
        last_seq: 42,
        ..Default::default()
    };
    let back = wire(&msg).snapshot;
    assert_eq!(back, snap);
    // Restored, the graph is the same one: same snapshot, same transforms and values; so is
    // the graph restored from its JSON.
    let r = SceneGraph::restore(&back).unwrap();
    assert_eq!(r.snapshot(), snap);
    assert_eq!(r.snapshot_json(), g.snapshot_json());
    let from_json = SceneGraph::restore_json(&g.snapshot_json()).unwrap();
    assert_eq!(from_json.snapshot(), snap);
    let (a, b) = (
        g.transform("world", "gripper", At::Latest).unwrap(),
        r.transform("world", "gripper", At::Latest).unwrap(),
    );
    assert_eq!(a, b);

    // The coach scene too (field, landmarks, robots with teams).
    let field = crate::field::FieldModel::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/spl_field.toml"
    ))
    .unwrap();
    let coach = scenes::coach_game(&field, Stamp(9)).unwrap().snapshot();
    let msg = m::SnapshotData {
        snapshot: coach.clone(),
        ..Default::default()
    };
    assert_eq!(wire(&msg).snapshot, coach);
    assert_eq!(json(&coach), coach);
}

#[test]
fn what_the_graph_cannot_hold_is_a_clear_error() {
    let spec = rich_spec();
    let mut twice = spec.clone();
    twice.attributes.push(m::KeyValue {
        key: attr::COLOR.into(),
        value: AttrValue::Text("blue".into()),
    });
    let e = check_node(&twice).unwrap_err();
    assert_eq!(
        e,
        InvalidSpec::DuplicateAttribute {
            node: "gripper".into(),
            key: "color".into()
        }
    );
    assert_eq!(
        e.to_string(),
        "node `gripper`: attribute `color` is given twice"
    );
    // The graph refuses it too, with its own reason code.
    let mut g = scenes::touch_the_ball(&loki(), Stamp(1)).unwrap();
    let r = g
        .propose(
            StructuralChange::add(NodeSpec {
                parent: "torso".into(),
                ..twice
            }),
            Stamp(2),
        )
        .unwrap_err();
    assert_eq!(reason_code(&r.reason), "invalid_spec");
    assert!(g.node_spec("gripper").is_err(), "nothing half-added");

    let nan_attr = NodeSpec::free("cup", NodeType::Object, "world", Transform::default())
        .with_attr(attr::RADIUS_M, AttrValue::Float(f64::NAN));
    let e = check_node(&nan_attr).unwrap_err();
    assert!(e.to_string().contains("`radius_m`"), "{e}");

    let mut nan_limit = spec.clone();
    if let Edge::Joint { limits, .. } = &mut nan_limit.edge {
        limits.velocity = f64::NAN;
    }
    let e = check_node(&nan_limit).unwrap_err();
    assert!(e.to_string().contains("wrist_roll"), "{e}");

    let mut bad_camera = spec.clone();
    if let Camera::Pinhole(c) = &mut bad_camera.camera {
        c.max_range_m = f64::INFINITY;
    }
    assert!(check_node(&bad_camera).is_err());

    let mut bad_shape = spec.clone();
    bad_shape.collision[3].shape = Shape::Sphere { radius_m: f64::NAN };
    assert!(check_node(&bad_shape).is_err());
    let mut zero_rotation = spec.clone();
    zero_rotation.collision[0].origin.rotation_xyzw = [0.0; 4];
    assert!(check_node(&zero_rotation).is_err());
    assert!(check_change(&StructuralChange::add(zero_rotation)).is_err());

    let nan_event = ChangeEvent::AttributeSet {
        stamp_ns: 1,
        node: "ball".into(),
        key: "velocity_mps".into(),
        value: AttrValue::Vec3([0.0, f64::INFINITY, 0.0]),
    };
    assert!(check_event(&nan_event).is_err());
    assert!(g.apply(&nan_event).is_err());
    let snap = Snapshot {
        nodes: vec![nan_attr],
        ..Default::default()
    };
    assert!(check_snapshot(&snap).is_err());
    assert!(SceneGraph::restore(&snap).is_err());
}
