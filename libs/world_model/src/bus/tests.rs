use super::*;
use crate::types::{NodeType, attr};
use crate::{At, SceneGraph, scenes};
use interfaces::codec;
use interfaces::msg::Message;

/// Through CDR bytes as the bus carries them, in the message that carries it.
fn wire<T: Message>(msg: &T) -> T {
    let bytes = codec::encode(msg, T::TYPE_NAME).unwrap();
    codec::decode(&bytes, T::TYPE_NAME).unwrap()
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
    let mut spec = NodeSpec {
        name: "gripper".into(),
        node_type: "link".into(),
        parent: "wrist".into(),
        edge: EdgeSpec::Joint {
            joint: "wrist_roll".into(),
            kind: JointKind::Continuous,
            origin: Pose::planar(0.1, -0.2, 0.3),
            axis: [0.0, 0.0, 1.0],
            limits: LimitsSpec {
                lower: f64::NEG_INFINITY,
                upper: f64::INFINITY,
                velocity: 2.5,
                effort: f64::INFINITY,
            },
            value: -0.75,
        },
        attrs: BTreeMap::new(),
        camera: Some(CameraIntrinsics {
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
                origin: Isometry3::new(
                    nalgebra::Vector3::new(0.01, 0.02, 0.03),
                    nalgebra::Vector3::new(0.3, -0.2, 0.1),
                ),
                shape: Shape::Box {
                    size_m: [0.1, 0.2, 0.3],
                },
            },
            CollisionShape {
                origin: Isometry3::identity(),
                shape: Shape::Cylinder {
                    radius_m: 0.05,
                    length_m: 0.2,
                },
            },
            CollisionShape {
                origin: Isometry3::translation(0.0, 0.0, 0.1),
                shape: Shape::Capsule {
                    radius_m: 0.04,
                    length_m: 0.12,
                },
            },
            CollisionShape {
                origin: Isometry3::identity(),
                shape: Shape::Sphere { radius_m: 0.03 },
            },
            CollisionShape {
                origin: Isometry3::identity(),
                shape: Shape::Mesh {
                    filename: "package://loki/gripper.stl".into(),
                },
            },
        ],
    };
    for (k, v) in [
        (attr::EFFECTOR, AttrValue::Bool(true)),
        (attr::TEAM, AttrValue::Int(-3)),
        (attr::RADIUS_M, AttrValue::Float(0.055)),
        (attr::COLOR, AttrValue::Text("yellow".into())),
        ("velocity_mps", AttrValue::Vec3([0.1, -0.2, 1e-9])),
    ] {
        spec.attrs.insert(k.into(), v);
    }
    spec
}

#[test]
fn a_node_spec_survives_the_bus() {
    for spec in [
        rich_spec(),
        NodeSpec::free("ball", NodeType::Ball, "world", Pose::planar(1.0, 2.0, 0.5))
            .with_attr(attr::RADIUS_M, AttrValue::Float(0.11)),
        NodeSpec {
            edge: EdgeSpec::Fixed {
                origin: Pose::from_translation(2.0, 0.0, 0.0),
            },
            ..NodeSpec::free("marker", NodeType::Landmark, "world", Pose::default())
        },
    ] {
        let msg = m::NodeInfo {
            spec: (&spec).into(),
            ..Default::default()
        };
        let back = NodeSpec::try_from(&wire(&msg).spec).unwrap();
        assert_eq!(back, spec);
    }
    // The attributes go sorted by key.
    let keys: Vec<String> = m::NodeSpec::from(&rich_spec())
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
        Proposal::add(rich_spec()),
        Proposal::RemoveNode { name: "cup".into() },
        Proposal::Reparent {
            name: "ball".into(),
            new_parent: "left_hand_center".into(),
            pose: Pose::planar(0.0, 0.1, -0.2),
        },
    ] {
        let msg = m::ProposeRequest {
            change: (&p).into(),
            ..Default::default()
        };
        assert_eq!(Proposal::try_from(&wire(&msg).change).unwrap(), p);
    }
}

#[test]
fn every_change_event_survives_the_bus() {
    let mut g = scenes::touch_the_ball(&loki(), Stamp(1)).unwrap();
    g.enable_log();
    g.propose(Proposal::add(rich_spec_under("torso")), Stamp(2))
        .unwrap();
    g.propose(
        Proposal::Reparent {
            name: "ball".into(),
            new_parent: "left_hand_center".into(),
            pose: Pose::from_translation(0.0, 0.0, 0.05),
        },
        Stamp(3),
    )
    .unwrap();
    g.set_joint("left_elbow", -1.0, Stamp(4)).unwrap();
    g.set_pose("player", &Pose::planar(2.0, 0.5, 3.0).to_iso(), Stamp(5))
        .unwrap();
    g.set_attr(
        "ball",
        "velocity_mps",
        AttrValue::Vec3([0.0, 1.0, 0.0]),
        Stamp(6),
    )
    .unwrap();
    g.declare_body_part(
        BodyPartSpec {
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
        Proposal::add(NodeSpec::free(
            "cup",
            NodeType::Object,
            "world",
            Pose::default(),
        )),
        Stamp(8),
    )
    .unwrap();
    g.propose(Proposal::RemoveNode { name: "cup".into() }, Stamp(9))
        .unwrap();
    let events = g.take_log();
    let kinds: Vec<&str> = events
        .iter()
        .map(|e| m::ChangeEvent::from(e).kind())
        .collect();
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
            event: e.into(),
            ..Default::default()
        };
        let got = wire(&msg);
        assert_eq!(got.event.node(), msg.event.node());
        assert_eq!(ChangeEvent::try_from(&got.event).unwrap(), *e);
    }
    assert_eq!(
        ChangeEvent::try_from(&m::ChangeEvent::Restored),
        Err(FromBusError::Restored)
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
    g.propose(Proposal::add(rich_spec_under("torso")), Stamp(2))
        .unwrap();
    g.set_joint("left_elbow", -1.2, Stamp(3)).unwrap();
    g.set_pose("ball", &Pose::planar(0.5, 0.1, 0.2).to_iso(), Stamp(4))
        .unwrap();
    g.set_attr("ball", attr::COLOR, AttrValue::Text("red".into()), Stamp(5))
        .unwrap();
    let snap = g.snapshot();
    assert!(snap.nodes.iter().any(|n| n.camera.is_some()));
    assert!(snap.nodes.iter().any(|n| !n.collision.is_empty()));
    assert!(!snap.body_parts.is_empty());

    let msg = m::SnapshotData {
        snapshot: (&snap).into(),
        last_seq: 42,
        ..Default::default()
    };
    let got = wire(&msg);
    assert_eq!(got, msg);
    let back = Snapshot::try_from(&got.snapshot).unwrap();
    assert_eq!(back, snap);
    // Restored, the graph is the same one: same snapshot, same transforms and values.
    let r = SceneGraph::restore(&back).unwrap();
    assert_eq!(r.snapshot(), snap);
    assert_eq!(r.snapshot_json(), g.snapshot_json());
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
        snapshot: (&coach).into(),
        ..Default::default()
    };
    assert_eq!(Snapshot::try_from(&wire(&msg).snapshot).unwrap(), coach);
}

#[test]
fn what_the_library_cannot_hold_is_a_clear_error() {
    let mut spec = m::NodeSpec::from(&rich_spec());
    spec.attributes.push(m::KeyValue {
        key: attr::COLOR.into(),
        value: m::AttrValue::Text("blue".into()),
    });
    let e = NodeSpec::try_from(&spec).unwrap_err();
    assert_eq!(
        e,
        FromBusError::DuplicateAttribute {
            node: "gripper".into(),
            key: "color".into()
        }
    );
    assert_eq!(
        e.to_string(),
        "node `gripper`: attribute `color` is given twice"
    );

    let nan_attr = m::NodeSpec {
        name: "cup".into(),
        attributes: vec![m::KeyValue {
            key: attr::RADIUS_M.into(),
            value: m::AttrValue::Float(f64::NAN),
        }],
        ..Default::default()
    };
    let e = NodeSpec::try_from(&nan_attr).unwrap_err();
    assert!(e.to_string().contains("`radius_m`"), "{e}");

    let mut nan_limit = m::NodeSpec::from(&rich_spec());
    if let m::Edge::Joint { limits, .. } = &mut nan_limit.edge {
        limits.velocity = f64::NAN;
    }
    let e = NodeSpec::try_from(&nan_limit).unwrap_err();
    assert!(e.to_string().contains("wrist_roll"), "{e}");

    let mut bad_camera = m::NodeSpec::from(&rich_spec());
    if let m::Camera::Pinhole(c) = &mut bad_camera.camera {
        c.max_range_m = f64::INFINITY;
    }
    assert!(NodeSpec::try_from(&bad_camera).is_err());

    let mut bad_shape = m::NodeSpec::from(&rich_spec());
    bad_shape.collision[3].shape = m::Shape::Sphere { radius_m: f64::NAN };
    assert!(NodeSpec::try_from(&bad_shape).is_err());
    let mut zero_rotation = m::NodeSpec::from(&rich_spec());
    zero_rotation.collision[0].origin.rotation_xyzw = [0.0; 4];
    assert!(NodeSpec::try_from(&zero_rotation).is_err());

    let nan_event = m::ChangeEvent::AttributeSet {
        stamp_ns: 1,
        node: "ball".into(),
        key: "velocity_mps".into(),
        value: m::AttrValue::Vec3([0.0, f64::INFINITY, 0.0]),
    };
    assert!(ChangeEvent::try_from(&nan_event).is_err());
    let snap = m::Snapshot {
        nodes: vec![nan_attr],
        ..Default::default()
    };
    assert!(Snapshot::try_from(&snap).is_err());
}
