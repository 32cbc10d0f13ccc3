#![allow(clippy::unwrap_used)]
//! Loki's body between real processes: `deep_representation --scene touch --follow-joint-states`,
//! `joint_motor --driver sim` and `body_inverse_kinematics`, launched from the shipped
//! `launch/body_sim.toml` on a fresh namespace. The test sends reach goals on `body/reach`, joint
//! goals on `body/joint_goal`, moves the ball with `dr/update`, and checks the outcome on
//! `body/reach_status`, `body/joint_states` and `dr/transform` (the hand as the DR sees it, from
//! the measured joints).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::body::{
    JointGoal, JointGoalReply, JointMode, JointRefusal, JointStates, JointTarget, ReachGoal,
    ReachKind, ReachState, ReachStatus,
};
use interfaces::msg::dr::{PoseUpdate, Transform, TransformRequest, UpdateRequest};
use interfaces::{Bus, Subscriber, topics};
use robocog_tests::*;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::time::Instant;

const CALL: Duration = Duration::from_secs(2);

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

const LEFT_ARM_7: [&str; 7] = [
    "left_shoulder_pitch",
    "left_shoulder_roll",
    "left_shoulder_yaw",
    "left_elbow",
    "left_forearm_roll",
    "left_wrist_pitch",
    "left_wrist_roll",
];

/// The newest `body/joint_states`, kept by a task that drains the subscription (a queue left
/// full would hold the test's whole bus session back).
#[derive(Clone)]
struct States(std::sync::Arc<std::sync::Mutex<Option<(Instant, JointStates)>>>);

impl States {
    async fn start(bus: &Bus) -> States {
        let sub: Subscriber<JointStates> =
            bus.subscriber(&topics::BODY_JOINT_STATES).await.unwrap();
        let me = States(Default::default());
        let slot = me.0.clone();
        tokio::spawn(async move {
            while let Ok(s) = sub.recv().await {
                *slot.lock().unwrap() = Some((Instant::now(), s));
            }
        });
        me
    }
}

/// `launch/body_sim.toml` up, with a test bus joined to it and the first joint states seen.
async fn body_sim(tag: &str) -> (Launch, Bus, States) {
    let ns = unique_namespace(tag);
    let launch = Launch::start(&repo().join("launch/body_sim.toml"), &ns, &[]);
    launch
        .lines
        .wait_for("body_inverse_kinematics up", Duration::from_secs(30), |l| {
            l.contains("body_inverse_kinematics is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-body")
        .await
        .unwrap();
    let states = States::start(&bus).await;
    latest(&states).await;
    (launch, bus, states)
}

fn reach(id: u64, part: &str, frame: &str, p: [f64; 3]) -> ReachGoal {
    ReachGoal {
        id,
        client: "test".into(),
        active: true,
        body_part: part.into(),
        kind: ReachKind::Position,
        frame: frame.into(),
        position_m: p,
        ..Default::default()
    }
}

/// Waits for a status of goal `id` in `state`, at most `timeout`; returns it with every status
/// of that goal seen before it. Panics on time-out or on a `Failed` status.
async fn wait_state(
    sub: &Subscriber<ReachStatus>,
    launch: &Launch,
    id: u64,
    state: ReachState,
    timeout: Duration,
) -> (ReachStatus, Vec<ReachStatus>) {
    let deadline = Instant::now() + timeout;
    let mut seen = Vec::new();
    loop {
        tokio::select! {
            s = sub.recv() => {
                let s = s.unwrap();
                if s.id != id {
                    continue;
                }
                if s.state == state {
                    return (s, seen);
                }
                assert_ne!(s.state, ReachState::Failed, "goal {id} failed: {s:?}");
                seen.push(s);
            }
            _ = tokio::time::sleep_until(deadline) => panic!(
                "goal {id}: no {state:?} within {timeout:?} (seen {:?}); output:\n{}",
                seen.iter().map(|s| s.state).collect::<Vec<_>>(),
                launch.lines.all().join("\n")
            ),
        }
    }
}

/// The DR's `world_T_frame` translation (latest).
async fn world_position(bus: &Bus, frame: &str) -> [f64; 3] {
    let req = TransformRequest {
        target: "world".into(),
        source: frame.into(),
        ..Default::default()
    };
    let rep = bus.call(&topics::DR_TRANSFORM, &req, CALL).await.unwrap();
    rep.transform.translation_m
}

/// Joint states newer than now, waiting at most 2 s for them.
async fn latest(states: &States) -> JointStates {
    let asked = Instant::now();
    eventually_async("fresh joint states", Duration::from_secs(2), || async {
        states
            .0
            .lock()
            .unwrap()
            .as_ref()
            .filter(|(at, _)| *at > asked)
            .map(|(_, s)| s.clone())
    })
    .await
}

fn positions(s: &JointStates, joints: &[&str]) -> Vec<f64> {
    joints.iter().map(|j| s.get(j).unwrap().position).collect()
}

async fn joint_goal(bus: &Bus, client: &str, priority: u8, joint: &str, q: f64) -> JointGoalReply {
    let goal = JointGoal {
        client: client.into(),
        priority,
        targets: vec![JointTarget {
            joint: joint.into(),
            mode: JointMode::Position,
            position: q,
            max_speed: 0.5,
            velocity: 0.0,
        }],
        ..Default::default()
    };
    bus.call(&topics::BODY_JOINT_GOAL, &goal, CALL)
        .await
        .unwrap()
}

async fn move_ball(bus: &Bus, p: [f64; 3]) {
    let update = UpdateRequest {
        poses: vec![PoseUpdate {
            node: "ball".into(),
            pose: Transform {
                translation_m: p,
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
        }],
        ..Default::default()
    };
    bus.call(&topics::DR_UPDATE, &update, CALL).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reachable_target_is_reached_an_unreachable_one_does_not_move_and_cancel_frees_the_arm() {
    let (launch, bus, states) = body_sim("body-reach").await;
    let goals = bus.publisher(&topics::BODY_REACH).await.unwrap();
    let status = bus.subscriber(&topics::BODY_REACH_STATUS).await.unwrap();
    // The joints start at the rest posture: the left hand hangs beside the body.
    let rest = latest(&states).await;
    assert_eq!(rest.driver, "sim");
    assert!((rest.get("neck_pitch").unwrap().position - 0.3).abs() < 1e-6);
    let hand0 = world_position(&bus, "left_hand_center").await;
    assert!(hand0[2] < 0.8, "the hand hangs down at rest: {hand0:?}");

    // (a) A reachable world target: Moving, then Reached, and the DR's hand is there.
    let target = [0.45, 0.30, 1.00];
    let sent = Instant::now();
    goals
        .publish(&mut reach(1, "left_arm_7", "world", target))
        .await
        .unwrap();
    let (reached, before) = wait_state(
        &status,
        &launch,
        1,
        ReachState::Reached,
        Duration::from_secs(15),
    )
    .await;
    let took = sent.elapsed();
    assert_eq!(
        before.iter().map(|s| s.state).collect::<Vec<_>>(),
        [ReachState::Moving],
        "{before:?}"
    );
    assert!(before[0].residual_m < 0.001, "{:?}", before[0]);
    assert!(
        reached.distance_m >= 0.0 && reached.distance_m <= 0.01,
        "{reached:?}"
    );
    assert!(dist(reached.target_world_m, target) < 1e-9, "{reached:?}");
    assert!(dist(reached.tip_world_m, target) <= 0.01, "{reached:?}");
    // The DR follows the measured joints (at 50 Hz): its hand is within 1 cm of the target.
    let hand = eventually_async(
        "the DR's hand at the target",
        Duration::from_secs(3),
        || async {
            let h = world_position(&bus, "left_hand_center").await;
            (dist(h, target) <= 0.01).then_some(h)
        },
    )
    .await;
    eprintln!(
        "left_arm_7 to {target:?}: Reached after {:.2} s, tip {:.1} mm from the target (status), DR hand {:.1} mm",
        took.as_secs_f64(),
        reached.distance_m * 1e3,
        dist(hand, target) * 1e3
    );
    // The arm is owned by the component's client for the part.
    let s = latest(&states).await;
    assert_eq!(
        s.get("left_elbow").unwrap().owner,
        "body_inverse_kinematics/left_arm_7"
    );

    // (b) 2 m away: Unreachable with the residual, the old goal Cancelled, nothing moves.
    let held = positions(&latest(&states).await, &LEFT_ARM_7);
    let far = [2.45, 0.30, 1.00];
    goals
        .publish(&mut reach(2, "left_arm_7", "world", far))
        .await
        .unwrap();
    let (cancelled, _) = wait_state(
        &status,
        &launch,
        1,
        ReachState::Cancelled,
        Duration::from_secs(5),
    )
    .await;
    assert!(cancelled.detail.contains("replaced"), "{cancelled:?}");
    let (unreachable, _) = wait_state(
        &status,
        &launch,
        2,
        ReachState::Unreachable,
        Duration::from_secs(5),
    )
    .await;
    assert!(unreachable.residual_m > 1.0, "{unreachable:?}");
    assert!(unreachable.detail.contains("residual"), "{unreachable:?}");
    tokio::time::sleep(Duration::from_millis(800)).await;
    let after = positions(&latest(&states).await, &LEFT_ARM_7);
    for (j, (a, b)) in LEFT_ARM_7.iter().zip(held.iter().zip(&after)) {
        assert!((a - b).abs() < 1e-3, "{j} moved from {a} to {b}");
    }
    eprintln!(
        "unreachable 2 m target: residual {:.3} m ({})",
        unreachable.residual_m, unreachable.detail
    );

    // Cancel frees the arm: another client at the same priority (the Executive's "home") takes it.
    goals
        .publish(&mut reach(3, "left_arm_7", "world", target))
        .await
        .unwrap();
    wait_state(
        &status,
        &launch,
        3,
        ReachState::Reached,
        Duration::from_secs(15),
    )
    .await;
    let r = joint_goal(&bus, "executive", 0, "left_elbow", -0.2).await;
    assert_eq!(
        (r.accepted, r.refusal, r.owner.as_str()),
        (
            false,
            JointRefusal::Owned,
            "body_inverse_kinematics/left_arm_7"
        ),
        "{r:?}"
    );
    let mut cancel = reach(3, "left_arm_7", "world", target);
    cancel.active = false;
    goals.publish(&mut cancel).await.unwrap();
    wait_state(
        &status,
        &launch,
        3,
        ReachState::Cancelled,
        Duration::from_secs(5),
    )
    .await;
    let r = eventually_async(
        "the executive takes the elbow",
        Duration::from_secs(3),
        || async {
            let r = joint_goal(&bus, "executive", 0, "left_elbow", -0.2).await;
            r.accepted.then_some(r)
        },
    )
    .await;
    assert!(r.detail.is_empty(), "{r:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn joint_goals_beyond_a_limit_or_on_owned_joints_are_refused_by_name() {
    let (launch, bus, states) = body_sim("body-joints").await;
    // (c) Beyond a limit: refused, naming the joint, the limit and the value; nothing moves.
    let r = joint_goal(&bus, "a", 0, "right_elbow", 0.3).await;
    assert!(!r.accepted);
    assert_eq!(r.refusal, JointRefusal::AboveUpperLimit);
    assert_eq!(
        (r.joint.as_str(), r.limit, r.requested),
        ("right_elbow", 0.0, 0.3)
    );
    assert!(
        r.detail.contains("right_elbow") && r.detail.contains("upper"),
        "{r:?}"
    );
    let r = joint_goal(&bus, "a", 0, "neck_pitch", -0.9).await;
    assert_eq!(
        (r.refusal, r.joint.as_str(), r.limit),
        (JointRefusal::BelowLowerLimit, "neck_pitch", -0.5)
    );
    let r = joint_goal(&bus, "a", 0, "no_such_joint", 0.0).await;
    assert_eq!(
        (r.refusal, r.joint.as_str()),
        (JointRefusal::UnknownJoint, "no_such_joint")
    );

    // (d) Ownership: first come first served at equal priority; a higher priority preempts.
    let r = joint_goal(&bus, "a", 0, "right_elbow", -0.5).await;
    assert!(r.accepted, "{r:?}");
    let r = joint_goal(&bus, "b", 0, "right_elbow", -0.6).await;
    assert_eq!(
        (r.accepted, r.refusal, r.joint.as_str(), r.owner.as_str()),
        (false, JointRefusal::Owned, "right_elbow", "a")
    );
    let r = joint_goal(&bus, "c", 5, "right_elbow", -0.7).await;
    assert!(r.accepted && r.preempted == ["right_elbow"], "{r:?}");
    // The state names the owner (within its 1 s lease), and the elbow goes to c's goal.
    let s = latest(&states).await;
    assert_eq!(s.get("right_elbow").unwrap().owner, "c");
    assert_eq!(s.get("left_elbow").unwrap().owner, "");
    eventually_async("the elbow at c's -0.7", Duration::from_secs(5), || async {
        let s = latest(&states).await;
        ((s.get("right_elbow").unwrap().position + 0.7).abs() < 1e-3).then_some(())
    })
    .await;
    assert!(joint_goal(&bus, "c", 5, "right_elbow", -0.6).await.accepted);
    // Releasing gives it back to everyone.
    let release = JointGoal {
        client: "c".into(),
        release: true,
        ..Default::default()
    };
    let r: JointGoalReply = bus
        .call(&topics::BODY_JOINT_GOAL, &release, CALL)
        .await
        .unwrap();
    assert!(r.accepted, "{r:?}");
    assert!(joint_goal(&bus, "b", 0, "right_elbow", -0.6).await.accepted);

    // Reach goals that cannot run fail with a detail naming what is wrong.
    let goals = bus.publisher(&topics::BODY_REACH).await.unwrap();
    let status = bus.subscriber(&topics::BODY_REACH_STATUS).await.unwrap();
    goals
        .publish(&mut reach(7, "tail", "world", [0.4, 0.3, 1.1]))
        .await
        .unwrap();
    goals
        .publish(&mut reach(8, "left_arm_7", "nowhere", [0.0; 3]))
        .await
        .unwrap();
    // The right elbow is b's: a right-arm reach at the same priority is refused by joint_motor.
    goals
        .publish(&mut reach(9, "right_arm_7", "world", [0.45, -0.3, 1.15]))
        .await
        .unwrap();
    let mut failed = std::collections::HashMap::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while failed.len() < 3 {
        tokio::select! {
            s = status.recv() => {
                let s = s.unwrap();
                if s.state == ReachState::Failed {
                    failed.insert(s.id, s.detail);
                }
            }
            _ = tokio::time::sleep_until(deadline) => panic!(
                "failures so far {failed:?}; output:\n{}", launch.lines.all().join("\n")
            ),
        }
    }
    assert!(
        failed[&7].contains("unknown body part `tail`"),
        "{failed:?}"
    );
    assert!(
        failed[&8].contains("unknown frame") && failed[&8].contains("nowhere"),
        "{failed:?}"
    );
    assert!(
        failed[&9].contains("refused")
            && failed[&9].contains("right_elbow")
            && failed[&9].contains("`b`"),
        "{failed:?}"
    );

    // Counted: joint_motor's refusals by reason; the DR's joint states naming unknown joints.
    let diagnostics = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    let stray = bus.publisher(&topics::BODY_JOINT_STATES).await.unwrap();
    let mut stray_msg = JointStates {
        driver: "test".into(),
        joints: vec![interfaces::msg::body::JointState {
            name: "tail_wag".into(),
            ..Default::default()
        }],
        ..Default::default()
    };
    // The DR applies the newest joint state at most every 20 ms and joint_motor publishes every
    // 10 ms: the stray message goes out every 2 ms so that it is the newest one now and then.
    let stray_task = tokio::spawn(async move {
        loop {
            if stray.publish(&mut stray_msg).await.is_err() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
    });
    let (mut dr_unknown, mut refused_upper) = (0, 0);
    let deadline = Instant::now() + Duration::from_secs(10);
    while dr_unknown == 0 || refused_upper == 0 {
        tokio::select! {
            d = diagnostics.recv() => {
                let d = d.unwrap();
                match d.component.as_str() {
                    "deep_representation" => dr_unknown = d.get("dr/unknown_joints"),
                    "joint_motor" => refused_upper = d.get("refused/above_upper_limit"),
                    _ => {}
                }
            }
            _ = tokio::time::sleep_until(deadline) => panic!(
                "counters: dr/unknown_joints {dr_unknown}, refused/above_upper_limit {refused_upper}"
            ),
        }
    }
    stray_task.abort();
    assert_eq!(refused_upper, 1);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_followed_ball_is_reached_again_where_it_moves_and_the_head_looks_at_it() {
    let (launch, bus, _states) = body_sim("body-follow").await;
    let goals = bus.publisher(&topics::BODY_REACH).await.unwrap();
    let status = bus.subscriber(&topics::BODY_REACH_STATUS).await.unwrap();
    let p1 = [0.45, 0.30, 1.00];
    let p2 = [0.50, 0.20, 1.10];
    move_ball(&bus, p1).await;
    let mut goal = reach(10, "left_arm_7", "ball", [0.0; 3]);
    goal.follow = true;
    goals.publish(&mut goal).await.unwrap();
    let mut gaze = reach(11, "neck", "ball", [0.0; 3]);
    gaze.kind = ReachKind::Gaze;
    gaze.follow = true;
    goals.publish(&mut gaze).await.unwrap();
    let (r1, _) = wait_state(
        &status,
        &launch,
        10,
        ReachState::Reached,
        Duration::from_secs(15),
    )
    .await;
    assert!(
        dist(r1.target_world_m, p1) < 1e-6 && r1.distance_m <= 0.01,
        "{r1:?}"
    );
    // (e) The ball moves 15 cm: the arm follows and reaches it again.
    move_ball(&bus, p2).await;
    let (r2, before) = wait_state(
        &status,
        &launch,
        10,
        ReachState::Reached,
        Duration::from_secs(15),
    )
    .await;
    assert!(
        before.iter().any(|s| s.state == ReachState::Moving),
        "a Moving before the second Reached: {before:?}"
    );
    assert!(dist(r2.target_world_m, p2) < 1e-6, "{r2:?}");
    assert!(dist(r2.tip_world_m, p2) <= 0.01, "{r2:?}");
    let hand = eventually_async(
        "the DR's hand at the new ball",
        Duration::from_secs(3),
        || async {
            let h = world_position(&bus, "left_hand_center").await;
            (dist(h, p2) <= 0.01).then_some(h)
        },
    )
    .await;
    // The head camera looks at the ball: it is on the optical axis, within 1 cm.
    let cam = TransformRequest {
        target: "head_rgbd_optical_frame".into(),
        source: "ball".into(),
        ..Default::default()
    };
    let ball_in_cam = eventually_async(
        "the ball on the camera's axis",
        Duration::from_secs(5),
        || async {
            let t = bus
                .call(&topics::DR_TRANSFORM, &cam, CALL)
                .await
                .unwrap()
                .transform
                .translation_m;
            (t[2] > 0.0 && t[0].hypot(t[1]) < 0.01).then_some(t)
        },
    )
    .await;
    eprintln!(
        "followed ball: reached again at {p2:?}, DR hand {:.1} mm away; ball in the camera frame {ball_in_cam:?}",
        dist(hand, p2) * 1e3
    );
}

/// The angle (rad) between the optical axis of `frame` and the direction to the ball, in the DR.
async fn off_axis(bus: &Bus, frame: &str) -> f64 {
    let req = TransformRequest {
        target: frame.into(),
        source: "ball".into(),
        ..Default::default()
    };
    let t = bus
        .call(&topics::DR_TRANSFORM, &req, CALL)
        .await
        .unwrap()
        .transform
        .translation_m;
    t[0].hypot(t[1]).atan2(t[2])
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_gaze_turns_the_eyes_first_then_the_head_while_the_eyes_come_back_to_the_middle() {
    let (launch, bus, states) = body_sim("body-eyes").await;
    let goals = bus.publisher(&topics::BODY_REACH).await.unwrap();
    let status = bus.subscriber(&topics::BODY_REACH_STATUS).await.unwrap();
    // A ball up and to the left: the head, at rest, looks ahead and down.
    move_ball(&bus, [0.9, 0.45, 1.3]).await;
    assert!(off_axis(&bus, "head_rgbd_optical_frame").await > 0.4);
    let mut gaze = reach(21, "neck", "ball", [0.0; 3]);
    gaze.kind = ReachKind::Gaze;
    goals.publish(&mut gaze).await.unwrap();
    // While the head is still on its way (the camera more than 10° off), the left eye already
    // looks at the ball (within 3°): eyes first.
    let eyes_first = eventually_async(
        "the left eye on the ball while the head is still turning",
        Duration::from_secs(10),
        || async {
            let eye = off_axis(&bus, "left_eye_optical_frame").await;
            let head = off_axis(&bus, "head_rgbd_optical_frame").await;
            (eye < 3f64.to_radians() && head > 10f64.to_radians()).then_some((eye, head))
        },
    )
    .await;
    wait_state(
        &status,
        &launch,
        21,
        ReachState::Reached,
        Duration::from_secs(15),
    )
    .await;
    // The head there, both eyes still on the ball and back near their middle (what is left is
    // the parallax between the camera and the eyes).
    let pans = eventually_async(
        "the eyes on the ball, near their middle",
        Duration::from_secs(5),
        || async {
            let s = latest(&states).await;
            let pans = positions(&s, &["eyes_tilt", "left_eye_pan", "right_eye_pan"]);
            let left = off_axis(&bus, "left_eye_optical_frame").await;
            let right = off_axis(&bus, "right_eye_optical_frame").await;
            (pans.iter().all(|q| q.abs() < 0.15)
                && left < 3f64.to_radians()
                && right < 3f64.to_radians())
            .then_some(pans)
        },
    )
    .await;
    // The gaze cancelled: the eyes go to the middle and the joints are free.
    gaze.active = false;
    goals.publish(&mut gaze).await.unwrap();
    let s = eventually_async("the eyes centred", Duration::from_secs(5), || async {
        let s = latest(&states).await;
        let eyes = positions(&s, &["eyes_tilt", "left_eye_pan", "right_eye_pan"]);
        (eyes.iter().all(|q| q.abs() < 1e-3) && s.get("left_eye_pan").unwrap().owner.is_empty())
            .then_some(s)
    })
    .await;
    assert_eq!(s.driver, "sim");
    eprintln!(
        "eyes first: the left eye {:.1}° off the ball while the camera was {:.1}° off; reached with the eyes at {pans:.3?} rad",
        eyes_first.0.to_degrees(),
        eyes_first.1.to_degrees()
    );
}

/// Polls the async `f` every 50 ms until it returns `Some`, at most `timeout`.
async fn eventually_async<T, F, Fut>(what: &str, timeout: Duration, mut f: F) -> T
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Option<T>>,
{
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = f().await {
            return v;
        }
        assert!(
            Instant::now() < deadline,
            "timed out after {timeout:?} waiting for {what}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}
