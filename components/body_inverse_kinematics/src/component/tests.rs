//! The component's unit tests.

use super::*;

#[test]
fn gaze_error_is_the_distance_to_the_optical_axis() {
    let cam = Isometry3::identity();
    let on_axis = Isometry3::translation(0.0, 0.0, 2.0);
    assert!(tip_error(ReachKind::Gaze, &cam, &on_axis).0 < 1e-12);
    let off = Isometry3::translation(0.05, 0.0, 1.0);
    let (d, a) = tip_error(ReachKind::Gaze, &cam, &off);
    assert!((d - 0.05).abs() < 1e-12 && (a - 0.05f64.atan()).abs() < 1e-9);
    let behind = Isometry3::translation(0.0, 0.3, -0.4);
    assert!((tip_error(ReachKind::Gaze, &cam, &behind).0 - 0.5).abs() < 1e-12);
    let (d, r) = tip_error(
        ReachKind::Position,
        &cam,
        &Isometry3::translation(0.3, 0.4, 0.0),
    );
    assert!((d - 0.5).abs() < 1e-12 && r == 0.0);
}

#[test]
fn goal_poses_and_transform_messages_convert() {
    let mut g = ReachGoal {
        position_m: [0.1, 0.2, 0.3],
        ..Default::default()
    };
    assert_eq!(
        goal_pose(&g).unwrap().translation.vector,
        Vector3::new(0.1, 0.2, 0.3)
    );
    g.kind = ReachKind::Pose;
    assert!(goal_pose(&g).is_err(), "a zero quaternion is no rotation");
    g.orientation_xyzw = [0.0, 0.0, 1.0, 1.0];
    let p = goal_pose(&g).unwrap();
    assert!((p.rotation.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    g.position_m[0] = f64::NAN;
    assert!(goal_pose(&g).is_err());
    let t = Transform {
        translation_m: [1.0, 0.0, 0.0],
        rotation_xyzw: [0.0, 0.0, 0.0, 0.0],
    };
    assert_eq!(iso_from_msg(&t), Isometry3::translation(1.0, 0.0, 0.0));
    assert!(matches!(
        ik_target(ReachKind::Gaze, &Isometry3::translation(1.0, 2.0, 3.0)),
        IkTarget::Gaze {
            point_m: [1.0, 2.0, 3.0]
        }
    ));
}

#[test]
fn chain_values_come_from_the_measured_joints() {
    let body = BodyIk::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap();
    let chain = body.model().body_part("neck").unwrap();
    let mut measured: HashMap<String, f64> =
        chain.joints.iter().map(|j| (j.name.clone(), 0.1)).collect();
    assert_eq!(chain_q(&chain, &measured).unwrap(), vec![0.1; chain.dof()]);
    measured.remove("neck_pitch");
    assert_eq!(chain_q(&chain, &measured).unwrap_err(), "neck_pitch");
}

/// `--joint-range JOINT=LOWER:UPPER`: spaces around the parts are forgiven; a value without its
/// joint, its `=`, its `:` or a number is refused with the form it expects. (Whether the range
/// fits the joint, NaN included, is `robot_model::narrow_limits`' to say, at start.)
#[test]
fn a_joint_range_flag_is_parsed_or_refused_with_the_form_it_expects() {
    assert_eq!(
        parse_joint_range("base_forward=0:0.2"),
        Ok(("base_forward".to_string(), 0.0, 0.2))
    );
    assert_eq!(
        parse_joint_range(" base_yaw = -0.5 : 0.5 "),
        Ok(("base_yaw".to_string(), -0.5, 0.5))
    );
    for bad in [
        "base_forward",
        "base_forward=0.2",
        "=0:0.2",
        "base_forward=a:0.2",
        "base_forward=0:",
        "",
    ] {
        let e = parse_joint_range(bad).unwrap_err();
        assert!(
            e.contains("JOINT=LOWER:UPPER") && e.contains(&format!("`{bad}`")),
            "{bad:?}: {e}"
        );
    }
}
