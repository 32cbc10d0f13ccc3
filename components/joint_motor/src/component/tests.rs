//! The component's unit tests.

use super::*;

fn loki() -> RobotModel {
    RobotModel::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap()
}

#[test]
fn the_example_servo_map_drives_lokis_neck_and_arms() {
    // As `open` offers them: the URDF's joints and the Stewart neck's legs.
    let (specs, plan) = loki_neck();
    let offered = specs.into_iter().chain(plan.legs.iter().cloned()).collect();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(EXAMPLE_SERVO_MAP);
    let (driven, cfg) = load_servo_map(&path, offered).unwrap();
    let names: Vec<&str> = driven.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(driven.len(), 18, "{names:?}");
    for j in [
        "neck_rotation",
        "neck_leg_2",
        "left_elbow",
        "right_wrist_roll",
    ] {
        assert!(names.contains(&j), "{j} is not driven: {names:?}");
    }
    assert!(
        !names.iter().any(|n| plan.is_axis(n)),
        "the neck goes through its legs"
    );
    assert_eq!((cfg.port.as_str(), cfg.baud), ("/dev/ttyUSB0", 1_000_000));
    // A missing map names the example.
    let err = load_servo_map(std::path::Path::new("/nonexistent/servos.toml"), vec![]).unwrap_err();
    assert!(format!("{err:#}").contains(EXAMPLE_SERVO_MAP), "{err:#}");
}

#[test]
fn every_movable_urdf_joint_becomes_a_spec_with_its_limits() {
    let model = loki();
    let specs = specs_from_model(&model, 0.25).unwrap();
    assert_eq!(specs.len(), model.movable_joint_names().len());
    let elbow = specs.iter().find(|s| s.name == "left_elbow").unwrap();
    assert_eq!(
        (elbow.lower, elbow.upper, elbow.max_velocity),
        (-2.4, 0.0, 1.8)
    );
    assert!((elbow.max_acceleration - 7.2).abs() < 1e-12);
    assert!(specs_from_model(&model, 0.0).is_err());
}

fn config(args: &[&str]) -> Config {
    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        config: Config,
    }
    let mut all = vec!["joint_motor"];
    all.extend_from_slice(args);
    <Cli as clap::Parser>::parse_from(all).config
}

#[test]
fn the_dynamixel_driver_opens_the_port_flag_and_drives_only_the_mapped_joints() {
    use crate::servo_sim::{Faults, ServoChain};
    let (chain, path) = ServoChain::spawn_on_pty_path(&[1, 2], Faults::default(), 3).unwrap();
    let dir = std::env::temp_dir().join(format!("joint_motor-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let map = dir.join("servos.toml");
    std::fs::write(
        &map,
        "port = \"/dev/not-this-one\"\nbaud = 57600\n[joints.neck_yaw]\nid = 1\n[joints.neck_pitch]\nid = 2\n",
    )
    .unwrap();
    let specs = specs_from_model(&loki(), 0.25).unwrap();
    let c = config(&[
        "--driver",
        "dynamixel",
        "--servo-config",
        map.to_str().unwrap(),
        "--port",
        path.to_str().unwrap(),
    ]);
    let driver = open(&c, specs.clone(), None).unwrap();
    assert_eq!(driver.name(), "dynamixel");
    let names: Vec<&str> = driver.joints().iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["neck_pitch", "neck_yaw"]);
    assert_eq!(chain.torque(1), Some(true), "servo 1 was set up");
    // Without --servo-config: a clear error.
    let c = config(&["--driver", "dynamixel"]);
    let e = open(&c, specs, None).err().unwrap().to_string();
    assert!(e.contains("--servo-config"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn loki_neck() -> (Vec<JointSpec>, NeckPlan) {
    let specs = specs_from_model(&loki(), 0.25).unwrap();
    let plan = NeckPlan::from_model(&loki(), &specs, 0.25)
        .unwrap()
        .unwrap();
    (specs, plan)
}

#[test]
fn the_simulated_neck_is_a_stewart_platform_at_the_start_posture() {
    let (specs, plan) = loki_neck();
    let c = config(&[]);
    let mut driver = open(&c, specs.clone(), Some(&plan)).unwrap();
    let names: Vec<&str> = driver.joints().iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names.len(),
        specs.len(),
        "the legs are not joints of the bus"
    );
    assert!(
        !names.iter().any(|n| n.starts_with("neck_leg")),
        "{names:?}"
    );
    assert!(names.contains(&"neck_pitch") && names.contains(&"neck_rotation"));
    // The rest posture's pitch, read back through the legs' forward kinematics.
    let states = driver.read_state(0.0).unwrap();
    let pitch = states.iter().find(|s| s.name == "neck_pitch").unwrap();
    assert!((pitch.position - 0.30).abs() < 1e-6, "{pitch:?}");
    let mut motor = JointMotor::new(driver, 1.0).unwrap();
    let goal = JointGoal {
        client: "gaze".into(),
        priority: 0,
        targets: vec![JointTarget {
            joint: "neck_yaw".into(),
            command: JointCommand::Position {
                position: -0.5,
                max_speed: 1.0,
            },
        }],
    };
    motor.submit(&goal, 0.0).unwrap();
    let s = motor.states(3.0).unwrap();
    assert!((s.get("neck_yaw").unwrap().position + 0.5).abs() < 1e-5);
    assert!((s.get("neck_pitch").unwrap().position - 0.30).abs() < 1e-5);
    assert_eq!(motor.driver().counters(), [("neck/clamped", 0)]);
}

#[test]
fn the_dynamixel_driver_moves_the_neck_through_its_legs() {
    use crate::dynamixel::reg;
    use crate::servo_sim::{Faults, ServoChain};
    let (chain, path) = ServoChain::spawn_on_pty_path(&[1, 2, 3, 4], Faults::default(), 5).unwrap();
    let dir = std::env::temp_dir().join(format!("joint_motor-legs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let leg = |k: usize, id: u8| {
        format!("[joints.neck_leg_{k}]\nid = {id}\nm_per_rad = 0.04\noffset_rad = -2.9\n")
    };
    let legs = format!("{}{}{}", leg(0, 2), leg(1, 3), leg(2, 4));
    let map = dir.join("servos.toml");
    std::fs::write(
        &map,
        format!(
            "port = \"{}\"\nbaud = 57600\n[joints.neck_rotation]\nid = 1\n{legs}",
            path.display()
        ),
    )
    .unwrap();
    let (specs, plan) = loki_neck();
    let c = config(&[
        "--driver",
        "dynamixel",
        "--servo-config",
        map.to_str().unwrap(),
    ]);
    let mut driver = open(&c, specs.clone(), Some(&plan)).unwrap();
    let names: Vec<&str> = driver.joints().iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        ["neck_rotation", "neck_pitch", "neck_roll", "neck_yaw"]
    );
    let target = |joint: &str, position: f64| JointTarget {
        joint: joint.into(),
        command: JointCommand::Position {
            position,
            max_speed: 1.0,
        },
    };
    driver
        .command(&[target("neck_pitch", 0.2), target("neck_yaw", 0.3)], 0.0)
        .unwrap();
    // A read on the same line answers after the servos have taken the goals.
    driver.read_state(0.1).unwrap();
    // Each leg's servo was sent the length of that pose, through its lead screw.
    let lengths = plan
        .geometry
        .inverse(NeckAngles {
            pitch: 0.2,
            roll: 0.0,
            yaw: 0.3,
        })
        .unwrap();
    for (k, id) in [2u8, 3, 4].into_iter().enumerate() {
        let want = crate::dynamixel::units::rad_to_ticks(lengths[k] / 0.04 - 2.9);
        assert_eq!(
            chain.register(id, reg::GOAL_POSITION),
            Some(want),
            "leg {k}"
        );
    }
    // Mapping the legs and the joints they stand for at once is refused.
    std::fs::write(
        &map,
        format!(
            "port = \"{}\"\nbaud = 57600\n[joints.neck_pitch]\nid = 1\n{legs}",
            path.display()
        ),
    )
    .unwrap();
    let e = open(&c, specs, Some(&plan)).err().unwrap().to_string();
    assert!(e.contains("not both"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn goals_are_refused_typed_and_releases_free_joints() {
    let specs = specs_from_model(&loki(), 0.25).unwrap();
    let motor = Mutex::new(
        JointMotor::new(
            Box::new(SimDriver::new(specs, SimParams::default()).unwrap()),
            1.0,
        )
        .unwrap(),
    );
    let goal = |client: &str, priority: u8, position: f64| m::JointGoal {
        client: client.into(),
        priority,
        targets: vec![m::JointTarget {
            joint: "left_elbow".into(),
            mode: m::JointMode::Position,
            position,
            max_speed: 1.0,
            velocity: 0.0,
        }],
        ..Default::default()
    };
    let r = handle_goal(&motor, &goal("a", 0, 0.3), || 0.0);
    assert_eq!(r.refusal, m::JointRefusal::AboveUpperLimit);
    assert_eq!(
        (r.joint.as_str(), r.limit, r.requested),
        ("left_elbow", 0.0, 0.3)
    );
    assert!(handle_goal(&motor, &goal("a", 0, -0.5), || 0.1).accepted);
    let r = handle_goal(&motor, &goal("b", 0, -0.6), || 0.2);
    assert_eq!((r.refusal, r.owner.as_str()), (m::JointRefusal::Owned, "a"));
    let r = handle_goal(&motor, &goal("c", 1, -0.6), || 0.3);
    assert!(r.accepted && r.preempted == ["left_elbow"], "{r:?}");
    let mut release = goal("c", 0, 0.0);
    release.release = true;
    release.targets.clear();
    assert!(handle_goal(&motor, &release, || 0.4).accepted);
    assert!(handle_goal(&motor, &goal("b", 0, -0.6), || 0.5).accepted);
}
