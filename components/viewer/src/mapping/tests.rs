//! The mapping of each message type, on hand-built messages.

#![allow(clippy::unwrap_used)]
use super::*;
use interfaces::msg::vision::Intrinsics;

const S: i64 = 1_000_000_000;

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

fn mapper() -> Mapper {
    Mapper::new(Some(loki()), Some(field()), MapperOptions::default())
}

fn enc<T: Message>(m: &T) -> Vec<u8> {
    codec::encode(m, T::TYPE_NAME).unwrap()
}

fn stamped<T: Message>(mut m: T, stamp_ns: i64) -> T {
    m.header_mut().stamp_ns = stamp_ns;
    m
}

fn map<T: Message>(mp: &mut Mapper, topic: &str, m: &T, at: i64) -> Vec<Logged> {
    mp.map(topic, T::TYPE_NAME, &enc(m), at).unwrap().items
}

fn find<'a>(items: &'a [Logged], path_end: &str, archetype: &str) -> Option<&'a Logged> {
    items.iter().find(|i| {
        i.path.ends_with(path_end)
            && i.archetypes()
                .iter()
                .any(|a| a.ends_with(&format!(".{archetype}")))
    })
}

#[test]
fn joint_states_move_the_links_and_the_collision_geometry_is_drawn_once() {
    let mut mp = mapper();
    let js = body::JointStates {
        joints: vec![body::JointState {
            name: "neck_yaw".into(),
            position: 0.4,
            ..Default::default()
        }],
        ..Default::default()
    };
    let first = map(&mut mp, "body/joint_states", &js, S);
    let head = find(&first, "/neck_roll_link/head", "Transform3D").expect("head link");
    assert!(
        head.path.starts_with("world/robot/base_footprint/"),
        "{}",
        head.path
    );
    let statics = first.iter().filter(|i| i.is_static).count();
    assert!(
        first.iter().any(|i| i.is_static
            && i.path.contains("/collision/")
            && i.archetypes()
                .iter()
                .any(|a| a.ends_with("Boxes3D") || a.ends_with("Cylinders3D"))),
        "collision geometry"
    );
    assert!(statics > 10, "{statics} static items");
    let second = map(&mut mp, "body/joint_states", &js, 2 * S);
    assert!(second.iter().all(|i| !i.is_static));
    // Only the joints in the message (and a known URDF joint) are logged after the first.
    assert_eq!(second.len(), 1, "{second:?}");
    // Unknown joints are skipped, not fatal.
    let odd = body::JointStates {
        joints: vec![body::JointState {
            name: "no_such_joint".into(),
            ..Default::default()
        }],
        ..Default::default()
    };
    assert!(map(&mut mp, "body/joint_states", &odd, 3 * S).is_empty());
}

fn frame(w: u32, h: u32) -> vision::RgbdFrame {
    let mut f = vision::RgbdFrame::blank(
        w,
        h,
        Intrinsics {
            fx: 100.0,
            fy: 100.0,
            cx: 2.0,
            cy: 1.5,
        },
    );
    f.header.frame_id = "head_rgbd_optical_frame".into();
    f
}

#[test]
fn camera_frames_become_a_pinhole_with_rgb_and_depth_thinned_to_the_image_rate() {
    let mut mp = mapper();
    let cam = mp.head_camera_path();
    assert!(
        cam.ends_with("/head/head_rgbd_link/head_rgbd_optical_frame/camera"),
        "{cam}"
    );
    let items = map(&mut mp, "vision/rgbd", &frame(4, 3), S);
    assert!(find(&items, &cam, "Pinhole").is_some(), "{items:?}");
    assert!(find(&items, &format!("{cam}/rgb"), "Image").is_some());
    assert!(find(&items, &format!("{cam}/depth"), "DepthImage").is_some());
    // 10 Hz: a frame 50 ms later is thinned, one 100 ms later is logged (pinhole unchanged).
    assert!(map(&mut mp, "vision/rgbd", &frame(4, 3), S + S / 20).is_empty());
    let later = map(&mut mp, "vision/rgbd", &frame(4, 3), S + S / 10);
    assert!(find(&later, &cam, "Pinhole").is_none());
    assert!(find(&later, &format!("{cam}/rgb"), "Image").is_some());
    let figs = mp.figures(2 * S);
    let figs = mp
        .figures(3 * S)
        .into_iter()
        .chain(figs)
        .collect::<Vec<_>>();
    assert!(
        figs.iter()
            .any(|f| f.topic == "vision/rgbd" && f.thinned == 1)
    );
}

#[test]
fn bad_samples_are_typed_errors_not_panics() {
    let mut mp = mapper();
    let e = mp
        .map("mystery", "robocog.NoSuchType", &[0, 1, 0, 0], S)
        .unwrap_err();
    assert!(matches!(e, MapError::UnknownType { .. }), "{e}");
    let e = mp
        .map(
            "executive/transitions",
            executive::StateTransition::TYPE_NAME,
            &[0, 1, 0, 0, 9],
            S,
        )
        .unwrap_err();
    assert!(matches!(e, MapError::Undecodable { .. }), "{e}");
    let mut f = frame(4, 3);
    f.rgb.pop();
    let e = mp
        .map("vision/rgbd", vision::RgbdFrame::TYPE_NAME, &enc(&f), S)
        .unwrap_err();
    assert!(matches!(e, MapError::Invalid { .. }), "{e}");
    assert!(e.to_string().contains("4x3"), "{e}");
}

#[test]
fn the_ball_in_the_world_has_a_trajectory_and_the_window_is_on_the_image() {
    let mut mp = mapper();
    let track = |x: f64| tracking::BallTrack {
        header: Header::new("head_rgbd_optical_frame"),
        found: true,
        window: tracking::PixelWindow {
            x: 10,
            y: 20,
            width: 30,
            height: 30,
        },
        has_centre_m: true,
        has_centre_world: true,
        centre_world_m: [x, 0.0, 0.8],
        diameter_m: 0.1,
        state: tracking::BallTrackState::Tracking,
        ..Default::default()
    };
    let a = map(&mut mp, "vision/ball", &track(0.5), S);
    assert!(find(&a, "world/ball", "Points3D").is_some());
    assert!(
        find(
            &a,
            &format!("{}/ball_window", mp.head_camera_path()),
            "Boxes2D"
        )
        .is_some()
    );
    assert!(find(&a, "world/ball/trajectory", "LineStrips3D").is_none());
    let b = map(&mut mp, "vision/ball", &track(0.6), 2 * S);
    assert!(find(&b, "world/ball/trajectory", "LineStrips3D").is_some());
    // Lost: the window is cleared.
    let lost = tracking::BallTrack {
        header: Header::new("head_rgbd_optical_frame"),
        ..Default::default()
    };
    let c = map(&mut mp, "vision/ball", &lost, 3 * S);
    assert!(find(&c, "/ball_window", "Clear").is_some(), "{c:?}");
}

#[test]
fn reach_outcomes_leave_marks_and_warnings() {
    let mut mp = mapper();
    let st = body::ReachStatus {
        body_part: "left_arm".into(),
        state: body::ReachState::Unreachable,
        target_world_m: [1.5, 0.0, 0.9],
        ..Default::default()
    };
    let items = map(&mut mp, "body/reach_status", &st, S);
    assert!(find(&items, "world/reach/left_arm/unreachable", "Points3D").is_some());
    assert!(find(&items, "log/reach", "TextLog").is_some());
    let reached = body::ReachStatus {
        state: body::ReachState::Reached,
        ..st
    };
    let items = map(&mut mp, "body/reach_status", &reached, 2 * S);
    assert!(find(&items, "world/reach/left_arm/reached", "Points3D").is_some());
}

#[test]
fn the_nao_world_is_drawn_in_2d_and_3d_with_the_field_lines_once() {
    let mut mp = mapper();
    let wm = nao::NaoWorldModel {
        robots: vec![nao::TeamRobot {
            player_number: 2,
            pose: nao::FieldPose {
                x_mm: 1000.0,
                y_mm: -500.0,
                theta_rad: 0.5,
            },
            ..Default::default()
        }],
        ball_known: true,
        ..Default::default()
    };
    let a = map(&mut mp, "nao/world_model", &wm, S);
    for (p, arch) in [
        ("field2d/lines", "LineStrips2D"),
        ("field3d/lines", "LineStrips3D"),
        ("field2d/robots", "Points2D"),
        ("field3d/robots", "Points3D"),
        ("field2d/robots/heading", "Arrows2D"),
        ("field3d/ball", "Points3D"),
    ] {
        assert!(find(&a, p, arch).is_some(), "{p} {arch}: {a:?}");
    }
    let b = map(&mut mp, "nao/world_model", &wm, 2 * S);
    assert!(find(&b, "field2d/lines", "LineStrips2D").is_none());
}

#[test]
fn text_topics_become_text_logs_and_rates_and_latencies_are_measured() {
    let mut mp = mapper();
    let tr = executive::StateTransition {
        machine: "touch".into(),
        event: "ball_seen".into(),
        ..Default::default()
    };
    mp.figures(S);
    for i in 0..10 {
        // Stamped 20 ms before receipt.
        let at = S + i * S / 10;
        let items = map(
            &mut mp,
            "executive/transitions",
            &stamped(tr.clone(), at - S / 50),
            at,
        );
        assert!(find(&items, "log/executive/touch", "TextLog").is_some());
    }
    let figs = mp.figures(2 * S);
    let f = figs
        .iter()
        .find(|f| f.topic == "executive/transitions")
        .unwrap();
    assert!((f.rate_hz - 10.0).abs() < 1e-9, "{f:?}");
    assert!((f.latency_ms.unwrap() - 20.0).abs() < 1e-6, "{f:?}");
    let items = mp.stats(3 * S, &BTreeMap::from([("vision/rgbd".to_string(), 4)]));
    assert!(find(&items, "stats/rate_hz/executive/transitions", "Scalars").is_some());
    assert!(find(&items, "stats/dropped/vision/rgbd", "Scalars").is_some());
}

#[test]
fn where_the_recognizer_listens_is_drawn_with_hers_and_someone_elses_apart() {
    let mut mp = mapper();
    let listening =
        |talker_deg: f64, elsewhere: bool| interfaces::msg::speech::ListeningDirection {
            header: interfaces::Header {
                frame_id: "circular_4".into(),
                ..Default::default()
            },
            beam_azimuth_rad: 0.0,
            listening_to: "player".into(),
            located: true,
            talker_azimuth_rad: talker_deg.to_radians(),
            elsewhere,
        };
    let items = map(
        &mut mp,
        "speech/listening",
        &stamped(listening(60.0, true), S),
        S,
    );
    assert!(find(&items, "hearing/circular_4/beam_azimuth_deg", "Scalars").is_some());
    assert!(
        find(
            &items,
            "hearing/circular_4/someone_else_azimuth_deg",
            "Scalars"
        )
        .is_some()
    );
    assert!(find(&items, "hearing/circular_4/her_azimuth_deg", "Scalars").is_none());
    let items = map(
        &mut mp,
        "speech/listening",
        &stamped(listening(2.0, false), 2 * S),
        2 * S,
    );
    assert!(find(&items, "hearing/circular_4/her_azimuth_deg", "Scalars").is_some());
    // Nothing located: the beam alone.
    let quiet = interfaces::msg::speech::ListeningDirection {
        located: false,
        ..listening(0.0, false)
    };
    let items = map(&mut mp, "speech/listening", &stamped(quiet, 3 * S), 3 * S);
    assert_eq!(items.len(), 1, "{}", items.len());
}

#[test]
fn the_dr_copy_follows_the_changes_and_asks_for_a_snapshot_after_a_gap() {
    use world_model::types::Stamp;
    let mut mp = mapper();
    assert!(mp.wants_dr_snapshot());
    let mut g = world_model::scenes::touch_the_ball(&loki(), Stamp(1)).unwrap();
    let snap = dr::SnapshotData {
        snapshot: g.snapshot(),
        last_seq: 10,
        ..Default::default()
    };
    map(&mut mp, "dr/snapshot", &snap, S);
    assert!(!mp.wants_dr_snapshot());
    let drawn = mp.dr_draw(S);
    let ball = find(&drawn, "dr/nodes/ball", "Transform3D").expect("the ball node");
    assert!(ball.path == "dr/nodes/ball");
    assert!(find(&drawn, "dr/edges", "LineStrips3D").is_some());
    // Nothing changed: nothing to draw.
    assert!(mp.dr_draw(2 * S).is_empty());
    // The ball moves in the DR: change #11 is applied and drawn.
    g.enable_log();
    let pose = Isometry3::translation(0.7, 0.1, 0.9);
    g.set_pose("ball", &pose, Stamp(2)).unwrap();
    let ev = g.take_log().pop().unwrap();
    let change = |seq| dr::DrChange {
        seq,
        event: ev.clone(),
        ..Default::default()
    };
    map(&mut mp, "dr/changes", &change(11), 3 * S);
    assert!(!mp.wants_dr_snapshot());
    let moved = mp.dr_draw(3 * S);
    assert!(find(&moved, "dr/nodes/ball", "Transform3D").is_some());
    // Only what moved is drawn again (the ball, and the edges).
    assert!(
        find(&moved, "dr/nodes/torso", "Transform3D").is_none(),
        "{moved:?}"
    );
    // A gap (#13 after #11): the copy asks for a new snapshot.
    map(&mut mp, "dr/changes", &change(13), 4 * S);
    assert!(mp.wants_dr_snapshot());
}
