//! Scene graph, transforms with history, predicates, fork, integrity, snapshot and change log.

#![allow(clippy::unwrap_used)] // tests may unwrap (STYLE: no unwrap outside tests)

use nalgebra::{Point3, Vector3};
use robot_model::RobotModel;
use world_model::error::DrError;
use world_model::field::FieldModel;
use world_model::graph::{At, RejectReason, SceneGraph, translation};
use world_model::predicates::{Fact, PredicateConfig, PredicateKind as P, evaluate, fork_report};
use world_model::scenes;
use world_model::types::{
    AttrValue, ChangeEvent, Edge, NodeSpec, NodeType, Stamp, StructuralChange, Transform,
};

fn loki() -> RobotModel {
    RobotModel::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap()
}
fn field() -> FieldModel {
    FieldModel::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/spl_field.toml"
    ))
    .unwrap()
}
fn fact(k: P, args: &[&str]) -> Fact {
    Fact::new(k, args)
}
const S: Stamp = Stamp(1_000_000_000);

#[test]
fn graph_transform_agrees_with_chain_fk_and_points_map_both_ways() {
    let m = loki();
    let mut g = scenes::touch_the_ball(&m, S).unwrap();
    let chain = m.body_part("left_arm_13").unwrap();
    let q = [
        0.3, 0.4, -1.0, 0.5, 0.2, -1.2, 0.7, 0.3, -0.4, 0.1, -0.9, -0.5, -0.3,
    ];
    for (name, v) in chain.joint_names().iter().zip(q) {
        g.set_joint(name, v, S).unwrap();
    }
    let fk = chain.fk(&q).unwrap();
    let t = g
        .transform("base_footprint", "left_fingertip", At::Latest)
        .unwrap();
    assert!((t.to_homogeneous() - fk.to_homogeneous()).abs().max() < 1e-12);
    // The inverse direction and a point round trip.
    let inv = g
        .transform("left_fingertip", "base_footprint", At::Latest)
        .unwrap();
    assert!(
        (inv * t)
            .to_homogeneous()
            .relative_eq(&nalgebra::Matrix4::identity(), 1e-12, 1e-12)
    );
    let p = Point3::new(0.1, -0.2, 0.3);
    let pw = g
        .transform_point("world", "left_fingertip", &p, At::Latest)
        .unwrap();
    let back = g
        .transform_point("left_fingertip", "world", &pw, At::Latest)
        .unwrap();
    assert!((back - p).norm() < 1e-12);
    // Moving the robot in the world moves the hand by the same rigid motion.
    let pose = nalgebra::Isometry3::new(Vector3::new(1.0, 2.0, 0.0), Vector3::new(0.0, 0.0, 0.5));
    g.set_pose("loki", &pose, S).unwrap();
    let tw = g.transform("world", "left_fingertip", At::Latest).unwrap();
    assert!(
        (tw.to_homogeneous() - (pose * fk).to_homogeneous())
            .abs()
            .max()
            < 1e-12
    );
}

#[test]
fn history_answers_at_time_t_with_interpolation_and_clear_errors() {
    let mut g = scenes::touch_the_ball(&loki(), Stamp(0)).unwrap();
    g.set_joint("left_elbow", -1.0, Stamp(100)).unwrap();
    g.set_joint("left_elbow", -2.0, Stamp(200)).unwrap();
    // A late (older) sample is slotted into the history without changing the latest value.
    g.set_joint("left_elbow", -0.5, Stamp(50)).unwrap();
    assert_eq!(g.joint_value("left_elbow").unwrap(), -2.0);
    let m = loki();
    let c = m.chain("left_upper_arm", "left_elbow_link").unwrap();
    let at = |t: u64| {
        g.transform("left_upper_arm", "left_elbow_link", At::Time(Stamp(t)))
            .unwrap()
    };
    let want = |v: f64| c.fk(&[v]).unwrap();
    let close = |a: nalgebra::Isometry3<f64>, b: nalgebra::Isometry3<f64>| {
        (a.to_homogeneous() - b.to_homogeneous()).abs().max() < 1e-12
    };
    assert!(close(at(150), want(-1.5)), "halfway between -1 and -2");
    assert!(
        close(at(75), want(-0.75)),
        "between the late sample and the next"
    );
    assert!(close(at(100), want(-1.0)));
    assert!(
        close(at(10_000), want(-2.0)),
        "after the newest sample: hold"
    );
    // Before the creation of the joint's history: typed error.
    g.set_history_len(3);
    g.set_joint("left_elbow", -2.1, Stamp(300)).unwrap();
    match g.transform("left_upper_arm", "left_elbow_link", At::Time(Stamp(60))) {
        Err(DrError::TimeOutOfHistory {
            frame,
            requested_ns: 60,
            oldest_ns: 100,
        }) => {
            assert_eq!(frame, "left_elbow_link")
        }
        other => panic!("{other:?}"),
    }
    // Free poses interpolate too.
    g.set_pose("ball", &translation(1.0, 0.0, 1.0), Stamp(1000))
        .unwrap();
    g.set_pose("ball", &translation(2.0, 0.0, 1.0), Stamp(2000))
        .unwrap();
    let p = g
        .transform("world", "ball", At::Time(Stamp(1250)))
        .unwrap()
        .translation
        .vector;
    assert!((p - Vector3::new(1.25, 0.0, 1.0)).norm() < 1e-12);
}

#[test]
fn late_camera_measurement_lands_where_the_ball_was() {
    let m = loki();
    let mut g = scenes::touch_the_ball(&m, Stamp(0)).unwrap();
    let neck = m.body_part("neck").unwrap();
    g.set_chain_values(&neck, &[0.0, 0.3, 0.0, 0.0], Stamp(100))
        .unwrap();
    // The image is taken at t=100 with the ball 1 m straight ahead of the camera...
    let cam_t100 = g.transform("world", "head_rgbd", At::Latest).unwrap();
    // ...then the head turns at t=150, and the detection arrives only afterwards.
    g.set_chain_values(&neck, &[0.8, 0.3, 0.0, 0.0], Stamp(150))
        .unwrap();
    assert_eq!(g.chain_values(&neck).unwrap(), vec![0.8, 0.3, 0.0, 0.0]);
    g.set_pose_in("ball", "head_rgbd", &translation(0.0, 0.0, 1.0), Stamp(100))
        .unwrap();
    let got = g
        .transform("world", "ball", At::Latest)
        .unwrap()
        .translation
        .vector;
    let want = (cam_t100 * Point3::new(0.0, 0.0, 1.0)).coords;
    assert!((got - want).norm() < 1e-12, "{got} vs {want}");
    assert!(matches!(
        g.set_chain_values(&neck, &[0.0; 3], Stamp(200)),
        Err(DrError::JointCount {
            expected: 4,
            got: 3
        })
    ));
}

#[test]
fn unknown_names_give_typed_errors() {
    let mut g = scenes::touch_the_ball(&loki(), S).unwrap();
    assert!(
        matches!(g.transform("world", "left_knee", At::Latest), Err(DrError::UnknownFrame(n)) if n == "left_knee")
    );
    assert!(
        matches!(g.set_joint("left_knee", 0.0, S), Err(DrError::UnknownJoint(n)) if n == "left_knee")
    );
    assert!(matches!(
        g.set_joint("left_elbow", f64::NAN, S),
        Err(DrError::NonFiniteValue(_))
    ));
    assert!(matches!(
        g.set_pose("left_hand", &translation(0.0, 0.0, 0.0), S),
        Err(DrError::WrongEdgeKind(..))
    ));
    assert!(matches!(
        g.set_attr("nobody", "x", AttrValue::Bool(true), S),
        Err(DrError::UnknownFrame(_))
    ));
}

// ------------------------------------------------------------------------------- predicates + fork

#[test]
fn touch_the_ball_start_state_predicates() {
    let g = scenes::touch_the_ball(&loki(), S).unwrap();
    // Reach of the left arm: elbow 0.28 + forearm 0.05 + 0.22 + hand centre 0.06 m.
    let arm = g.body_part("left_arm").unwrap();
    assert!((arm.reach_m - 0.61).abs() < 1e-12);
    assert_eq!(
        (arm.base_frame.as_str(), arm.tip_frame.as_str()),
        ("left_shoulder_pitch_link", "left_hand_center")
    );
    let facts = evaluate(&g, &PredicateConfig::default(), At::Latest).unwrap();
    // Ball at 0.91 m from the left shoulder (reach 0.61 m + 0.035 m): not reachable; below the
    // image (v = 534 px > 480): not visible. Nothing else holds (no field, Loki upright).
    assert!(!facts.contains(&fact(P::Reachable, &["ball", "left_arm"])));
    assert!(
        !facts
            .iter()
            .any(|f| f.kind == P::Visible && f.args[0] == "ball")
    );
    assert!(!facts.iter().any(|f| f.kind == P::Fallen));
    assert!(
        facts.contains(&fact(P::ClosestToBall, &["loki"])),
        "the only robot"
    );
}

#[test]
fn fork_with_virtual_actions_leaves_live_graph_unchanged_and_reports_changes() {
    let m = loki();
    let live = scenes::touch_the_ball(&m, S).unwrap();
    let before = live.snapshot_json();
    let cfg = PredicateConfig::default();

    let mut fork = live.fork();
    assert!(fork.is_fork());
    // Virtual actions: look down, move the ball closer, reach with the left arm to it.
    fork.set_joint("neck_pitch", 0.6, S).unwrap();
    fork.set_pose("ball", &translation(0.42, 0.2, 1.0), S)
        .unwrap();
    fork.set_joint("left_shoulder_pitch", -1.2, S).unwrap();
    let report = fork_report(&live, &fork, &cfg).unwrap();

    // The live graph is byte-for-byte the same.
    assert_eq!(live.snapshot_json(), before);
    assert_eq!(live.joint_value("neck_pitch").unwrap(), 0.0);
    assert_eq!(live.joint_value("left_shoulder_pitch").unwrap(), 0.0);
    let ball = live
        .transform("world", "ball", At::Latest)
        .unwrap()
        .translation
        .vector;
    assert_eq!(ball, Vector3::new(0.8, 0.2, 1.1));

    // And the fork reports what its actions change.
    assert!(
        report
            .facts
            .became_true
            .contains(&fact(P::Visible, &["ball", "head_rgbd"])),
        "{report:?}"
    );
    assert!(
        report
            .facts
            .became_true
            .contains(&fact(P::Reachable, &["ball", "left_arm"])),
        "{report:?}"
    );
    assert!(report.facts.became_false.is_empty(), "{report:?}");
    let joints: Vec<&str> = report.joints_changed.iter().map(|j| j.0.as_str()).collect();
    assert_eq!(joints, ["left_shoulder_pitch", "neck_pitch"]);
    assert_eq!(report.moved.len(), 1);
    assert_eq!(report.moved[0].0, "ball");
    assert!((report.moved[0].1 - (0.38f64.powi(2) + 0.1f64.powi(2)).sqrt()).abs() < 1e-9);
}

#[test]
fn near_with_the_hand_in_a_fork() {
    let m = loki();
    let live = scenes::touch_the_ball(&m, S).unwrap();
    let mut fork = live.fork();
    // Put the ball right at the left hand centre.
    let hand = fork
        .transform("world", "left_hand_center", At::Latest)
        .unwrap();
    fork.set_pose("ball", &hand, S).unwrap();
    let r = fork_report(&live, &fork, &PredicateConfig::default()).unwrap();
    assert!(
        r.facts
            .became_true
            .contains(&fact(P::Near, &["left_hand_center", "ball"])),
        "{r:?}"
    );
    assert!(
        r.facts
            .became_true
            .contains(&fact(P::Reachable, &["ball", "left_arm"]))
    );
}

#[test]
fn coach_game_predicates() {
    let g = scenes::coach_game(&field(), S).unwrap();
    let facts = evaluate(&g, &PredicateConfig::default(), At::Latest).unwrap();
    for t in ["ball", "nao_1", "nao_2", "opponent_1", "opponent_2"] {
        assert!(facts.contains(&fact(P::InField, &[t])), "{t}");
    }
    assert!(
        !facts.contains(&fact(P::InField, &["coach"])),
        "coach stands behind the line"
    );
    assert!(facts.contains(&fact(P::ClosestToBall, &["nao_2"])));
    assert!(facts.contains(&fact(P::ClosestToBall, &["opponent_1"])));
    assert!(!facts.contains(&fact(P::ClosestToBall, &["nao_1"])));
    assert!(facts.contains(&fact(P::Fallen, &["opponent_2"])));
    assert!(!facts.contains(&fact(P::Fallen, &["nao_2"])));
    // A robot lying on its side is fallen from geometry alone.
    let mut fork = g.fork();
    let lying =
        nalgebra::Isometry3::new(Vector3::new(-1.0, -0.5, 0.1), Vector3::new(1.5, 0.0, 0.0));
    fork.set_pose("nao_2", &lying, S).unwrap();
    let r = fork_report(&g, &fork, &PredicateConfig::default()).unwrap();
    assert!(
        r.facts.became_true.contains(&fact(P::Fallen, &["nao_2"])),
        "{r:?}"
    );
    // Ball kicked out over the touch line (wholly past the 25 mm half line): not in the field.
    let mut out = g.fork();
    out.set_pose("ball", &translation(0.5, -3.0 - 0.025 - 0.051, 0.05), S)
        .unwrap();
    let r = fork_report(&g, &out, &PredicateConfig::default()).unwrap();
    assert!(
        r.facts.became_false.contains(&fact(P::InField, &["ball"])),
        "{r:?}"
    );
    let mut on_line = g.fork();
    on_line
        .set_pose("ball", &translation(0.5, -3.0 - 0.025 - 0.049, 0.05), S)
        .unwrap();
    assert!(
        fork_report(&g, &on_line, &PredicateConfig::default())
            .unwrap()
            .facts
            .became_false
            .is_empty()
    );
}

// ------------------------------------------------------------------------------- integrity

fn ball_spec(name: &str, parent: &str) -> NodeSpec {
    NodeSpec::free(
        name,
        NodeType::Ball,
        parent,
        Transform::from_translation(1.0, 0.0, 0.5),
    )
}
fn reason(g: &mut SceneGraph, p: StructuralChange) -> RejectReason {
    g.propose(p, S).unwrap_err().reason
}

#[test]
fn integrity_unique_names() {
    let mut g = scenes::touch_the_ball(&loki(), S).unwrap();
    let r = reason(
        &mut g,
        StructuralChange::AddNode(Box::new(ball_spec("ball", "world"))),
    );
    assert_eq!(r, RejectReason::DuplicateName("ball".into()));
    assert!(r.to_string().contains("already used"));
    // A robot link name is taken too.
    let r = reason(
        &mut g,
        StructuralChange::AddNode(Box::new(ball_spec("left_hand", "world"))),
    );
    assert_eq!(r, RejectReason::DuplicateName("left_hand".into()));
    // Loading a second robot with the same link names is rejected, atomically.
    let n = g.len();
    let e = g
        .add_robot(&loki(), "loki_2", "world", &translation(3.0, 0.0, 0.0), S)
        .unwrap_err();
    assert!(
        matches!(&e, DrError::Rejected(r) if matches!(r.reason, RejectReason::DuplicateName(_))),
        "{e}"
    );
    assert_eq!(g.len(), n, "nothing half-added");
}

#[test]
fn integrity_parent_exists() {
    let mut g = SceneGraph::new();
    let r = reason(
        &mut g,
        StructuralChange::AddNode(Box::new(ball_spec("ball", "table"))),
    );
    assert_eq!(r, RejectReason::UnknownParent("table".into()));
    let r = reason(
        &mut g,
        StructuralChange::Reparent {
            name: "nothing".into(),
            new_parent: "world".into(),
            pose: Transform::default(),
        },
    );
    assert_eq!(r, RejectReason::UnknownNode("nothing".into()));
}

#[test]
fn integrity_no_cycles() {
    let mut g = SceneGraph::new();
    g.propose(
        StructuralChange::AddNode(Box::new(NodeSpec::free(
            "table",
            NodeType::Object,
            "world",
            Transform::default(),
        ))),
        S,
    )
    .unwrap();
    g.propose(
        StructuralChange::AddNode(Box::new(ball_spec("ball", "table"))),
        S,
    )
    .unwrap();
    let r = reason(
        &mut g,
        StructuralChange::Reparent {
            name: "table".into(),
            new_parent: "ball".into(),
            pose: Transform::default(),
        },
    );
    assert_eq!(
        r,
        RejectReason::Cycle {
            node: "table".into(),
            new_parent: "ball".into()
        }
    );
    let r = reason(
        &mut g,
        StructuralChange::Reparent {
            name: "table".into(),
            new_parent: "table".into(),
            pose: Transform::default(),
        },
    );
    assert!(matches!(r, RejectReason::Cycle { .. }));
    // A legal reparent keeps transforms consistent.
    g.propose(
        StructuralChange::Reparent {
            name: "ball".into(),
            new_parent: "world".into(),
            pose: Transform::from_translation(0.0, 1.0, 0.0),
        },
        S,
    )
    .unwrap();
    assert_eq!(
        g.transform("world", "ball", At::Latest)
            .unwrap()
            .translation
            .vector,
        Vector3::new(0.0, 1.0, 0.0)
    );
}

#[test]
fn integrity_types_known() {
    let mut g = SceneGraph::new();
    let mut spec = ball_spec("unicorn", "world");
    spec.node_type = "unicorn".into();
    let r = reason(&mut g, StructuralChange::AddNode(Box::new(spec)));
    assert!(
        matches!(&r, RejectReason::UnknownType(t, known) if t == "unicorn" && known.contains("ball")),
        "{r}"
    );
    let mut spec = ball_spec("world2", "world");
    spec.node_type = "world".into();
    assert!(
        matches!(
            reason(&mut g, StructuralChange::AddNode(Box::new(spec))),
            RejectReason::UnknownType(..)
        ),
        "world is unique"
    );
}

#[test]
fn integrity_removals_and_geometry() {
    let mut g = scenes::touch_the_ball(&loki(), S).unwrap();
    assert_eq!(
        reason(
            &mut g,
            StructuralChange::RemoveNode {
                name: "world".into()
            }
        ),
        RejectReason::Protected("world".into(), "the root")
    );
    assert!(matches!(
        reason(
            &mut g,
            StructuralChange::RemoveNode {
                name: "left_hand".into()
            }
        ),
        RejectReason::Protected(..)
    ));
    assert!(matches!(
        reason(
            &mut g,
            StructuralChange::RemoveNode {
                name: "loki".into()
            }
        ),
        RejectReason::HasChildren(..)
    ));
    let mut bad = ball_spec("ghost", "world");
    bad.edge = Edge::Free {
        pose: Transform::from_translation(f64::NAN, 0.0, 0.0),
    };
    assert!(matches!(
        reason(&mut g, StructuralChange::AddNode(Box::new(bad))),
        RejectReason::InvalidGeometry(_)
    ));
    assert!(matches!(
        reason(
            &mut g,
            StructuralChange::AddNode(Box::new(ball_spec("two words", "world")))
        ),
        RejectReason::InvalidName(_)
    ));
    g.propose(
        StructuralChange::RemoveNode {
            name: "ball".into(),
        },
        S,
    )
    .unwrap();
    assert!(!g.contains("ball"));
    assert!(matches!(
        g.transform("world", "ball", At::Latest),
        Err(DrError::UnknownFrame(_))
    ));
}

// ------------------------------------------------------------------------------- snapshot + log

#[test]
fn snapshot_plus_log_recovers_the_graph() {
    let m = loki();
    let mut g = scenes::touch_the_ball(&m, Stamp(0)).unwrap();
    let snap = g.snapshot_json();
    g.enable_log();
    g.set_joint("left_elbow", -1.1, Stamp(10)).unwrap();
    g.set_pose("ball", &translation(0.5, 0.1, 1.0), Stamp(11))
        .unwrap();
    g.set_attr("loki", "fallen", AttrValue::Bool(false), Stamp(12))
        .unwrap();
    g.propose(
        StructuralChange::AddNode(Box::new(ball_spec("ball_2", "world"))),
        Stamp(13),
    )
    .unwrap();
    g.propose(
        StructuralChange::Reparent {
            name: "ball_2".into(),
            new_parent: "left_hand".into(),
            pose: Transform::default(),
        },
        Stamp(14),
    )
    .unwrap();
    g.propose(
        StructuralChange::RemoveNode {
            name: "player".into(),
        },
        Stamp(15),
    )
    .unwrap();
    assert!(
        g.propose(
            StructuralChange::AddNode(Box::new(ball_spec("ball", "nowhere"))),
            Stamp(16)
        )
        .is_err()
    );
    let log = g.take_log();
    assert_eq!(log.len(), 6, "rejected proposals are not logged");
    // The log persists as JSON lines.
    let lines: Vec<String> = log
        .iter()
        .map(|e| serde_json::to_string(e).unwrap())
        .collect();
    let mut r = SceneGraph::restore_json(&snap).unwrap();
    for l in &lines {
        let e: ChangeEvent = serde_json::from_str(l).unwrap();
        r.apply(&e).unwrap();
    }
    assert_eq!(r.snapshot_json(), g.snapshot_json());
    // The restored graph works: same FK through the restored joint edges.
    let t1 = g.transform("world", "left_fingertip", At::Latest).unwrap();
    let t2 = r.transform("world", "left_fingertip", At::Latest).unwrap();
    assert!((t1.to_homogeneous() - t2.to_homogeneous()).abs().max() < 1e-12);
    assert_eq!(r.body_part("left_arm"), g.body_part("left_arm"));
    assert_eq!(
        r.node("head_rgbd").unwrap().camera,
        g.node("head_rgbd").unwrap().camera
    );
    // Replaying a log event that no longer fits is an error, not a panic.
    assert!(matches!(
        r.apply(&ChangeEvent::NodeRemoved {
            stamp_ns: S.0,
            name: "player".into()
        }),
        Err(DrError::BadEvent(_))
    ));
}

#[test]
fn corrupt_snapshots_give_clear_errors() {
    let g = scenes::coach_game(&field(), S).unwrap();
    let good = g.snapshot_json();
    let msg = |t: &str| match SceneGraph::restore_json(t) {
        Err(DrError::CorruptSnapshot(m)) => m,
        other => panic!("expected CorruptSnapshot, got {other:?}"),
    };
    assert!(
        msg(&good[..good.len() / 2]).contains("line"),
        "truncated file names a position"
    );
    assert!(msg("").contains("not a valid snapshot"));
    assert!(msg(&good.replace("robocog-dr-snapshot", "something-else")).contains("format"));
    assert!(msg(&good.replace("\"version\": 2", "\"version\": 99")).contains("version 99"));
    assert!(msg(&good.replace("\"version\": 2", "\"version\": 1")).contains("older robocog"));
    assert!(
        msg(&good.replace("\"parent\": \"field\"", "\"parent\": \"pitch\""))
            .contains("parent `pitch` does not exist")
    );
    assert!(
        msg(&good.replace("\"node_type\": \"ball\"", "\"node_type\": \"balloon\""))
            .contains("balloon")
    );
    assert!(msg(&good.replace("\"node_type\"", "\"nodetype\"")).contains("nodetype"));
    // And the good one restores.
    let r = SceneGraph::restore_json(&good).unwrap();
    assert_eq!(r.snapshot_json(), good);
}
