#![allow(clippy::unwrap_used)]
//! The Executive alone on the bus, with the deep representation and the simulated joints it calls:
//! this test plays the person, the tracker and the reach component (it publishes `game/command`,
//! `vision/ball_events` and `body/reach_status`) and asserts what the Executive publishes
//! (`executive/transitions`, `speech/say`, `body/reach`, `vision/ball_target`, `executive/log`)
//! and serves (`executive/configuration`, `executive/propose`).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use executive::touch::{say, state};
use interfaces::msg::body::{ReachGoal, ReachKind, ReachState, ReachStatus};
use interfaces::msg::command::{Command, CommandSource, Game, GameCommand};
use interfaces::msg::dr::{Edge, NodeSpec, ProposeRequest, StructuralChange, Transform};
use interfaces::msg::executive::{ConfigurationRequest, GameLog, StateTransition};
use interfaces::msg::speech::SayRequest;
use interfaces::msg::tracking::{BallEvent, BallEventKind, BallTarget};
use interfaces::{Bus, Message, Subscriber, topics};
use robocog_tests::*;
use std::time::Duration;
use tokio::time::Instant;

const MANIFEST: &str = r#"
[graph]
name = "executive_alone"

[[component]]
name = "deep_representation"
binary = "deep_representation"
args = ["--scene", "touch"]

[[component]]
name = "joint_motor"
binary = "joint_motor"
args = ["--driver", "sim"]

[[component]]
name = "executive"
binary = "executive"
args = ["--game", "touch", "--settings", "@SETTINGS@"]
depends_on = ["deep_representation", "joint_motor"]
external_inputs = ["game/command", "vision/ball_events", "vision/ball", "body/reach_status", "speech/speaking", "vision/camera_status"]
"#;

/// Short delays so the test runs in seconds.
const SETTINGS: &str = r#"
[touch]
courtesy_delay_s = 1.0
scan_dwell_s = 0.4
scan_move_timeout_s = 0.4
homing_s = 0.5
"#;

const WAIT: Duration = Duration::from_secs(10);

/// The next message on `sub` that satisfies `pred`, within `timeout`; panics with `what` and the
/// graph's output otherwise.
async fn next<T: Message>(
    sub: &Subscriber<T>,
    launch: &Launch,
    what: &str,
    timeout: Duration,
    pred: impl Fn(&T) -> bool,
) -> T {
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match sub.recv_timeout(left).await.unwrap() {
            Some(m) if pred(&m) => return m,
            Some(_) => {}
            None => panic!(
                "timed out after {timeout:?} waiting for {what}; output:\n{}",
                launch.lines.all().join("\n")
            ),
        }
    }
}

fn command(c: Command) -> GameCommand {
    GameCommand {
        game: Game::Touch,
        command: c,
        source: CommandSource::Panel,
        text: c.phrase().to_string(),
        confidence: 1.0,
        ..Default::default()
    }
}

fn ball(kind: BallEventKind) -> BallEvent {
    BallEvent {
        kind,
        ..Default::default()
    }
}

/// Adding a free node under `world`.
fn add(name: &str, node_type: &str) -> ProposeRequest {
    ProposeRequest {
        change: StructuralChange::AddNode(Box::new(NodeSpec {
            name: name.into(),
            node_type: node_type.into(),
            parent: "world".into(),
            edge: Edge::Free {
                pose: Transform::from_translation(0.7, 0.3, 0.8),
            },
            ..Default::default()
        })),
        ..Default::default()
    }
}

fn remove(name: &str) -> ProposeRequest {
    ProposeRequest {
        change: StructuralChange::RemoveNode { name: name.into() },
        ..Default::default()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_executive_plays_touch_the_ball_from_bus_inputs() {
    let ns = unique_namespace("executive");
    let dir = scratch(&ns);
    let settings = dir.join("executive.toml");
    std::fs::write(&settings, SETTINGS).unwrap();
    let manifest = write_manifest(
        &dir,
        "executive.toml.launch",
        &MANIFEST.replace("@SETTINGS@", &settings.display().to_string()),
    );
    let launch = Launch::start(&manifest, &ns, &[]);
    let bus = Bus::open(&launch.connect_args(), "test-executive")
        .await
        .unwrap();
    let transitions = bus
        .subscriber(&topics::EXECUTIVE_TRANSITIONS)
        .await
        .unwrap();
    let says = bus.subscriber(&topics::SPEECH_SAY).await.unwrap();
    let reaches = bus.subscriber(&topics::BODY_REACH).await.unwrap();
    let targets = bus.subscriber(&topics::VISION_BALL_TARGET).await.unwrap();
    let logs = bus.subscriber(&topics::EXECUTIVE_LOG).await.unwrap();
    let commands = bus.publisher(&topics::GAME_COMMAND).await.unwrap();
    let ball_events = bus.publisher(&topics::VISION_BALL_EVENTS).await.unwrap();
    let statuses = bus.publisher(&topics::BODY_REACH_STATUS).await.unwrap();

    // Up: the configuration service answers with the initial state and the diagram.
    let deadline = Instant::now() + Duration::from_secs(30);
    let conf = loop {
        let req = ConfigurationRequest::default();
        match bus
            .call(
                &topics::EXECUTIVE_CONFIGURATION,
                &req,
                Duration::from_secs(1),
            )
            .await
        {
            Ok(c) => break c,
            Err(e) if Instant::now() > deadline => panic!(
                "executive/configuration never answered: {e}; output:\n{}",
                launch.lines.all().join("\n")
            ),
            Err(_) => tokio::time::sleep(Duration::from_millis(200)).await,
        }
    };
    assert_eq!(conf.machine, "touch_the_ball");
    assert_eq!(conf.active, [state::WAITING]);
    assert!(
        conf.mermaid.starts_with("stateDiagram-v2"),
        "{}",
        conf.mermaid
    );

    // Greet until heard (the first publications may precede the route to the executive).
    let deadline = Instant::now() + WAIT;
    loop {
        commands
            .publish(&mut command(Command::Greet))
            .await
            .unwrap();
        if let Some(s) = says.recv_timeout(Duration::from_millis(500)).await.unwrap() {
            assert_eq!(s.text, say::GREETING);
            break;
        }
        assert!(Instant::now() < deadline, "the greeting was never answered");
    }

    commands.publish(&mut command(Command::Play)).await.unwrap();
    let t: StateTransition = next(&transitions, &launch, "play", WAIT, |t| {
        t.event == "command:play"
    })
    .await;
    assert_eq!(t.exited, [state::WAITING]);
    assert_eq!(t.active, [state::RESTING, state::EYES_IDLE]);
    next(&says, &launch, "the play ack", WAIT, |s: &SayRequest| {
        s.text == say::PLAY_ACK
    })
    .await;
    // Nothing to look for yet: the robot looks at her face while it listens.
    let face: ReachGoal = next(&reaches, &launch, "the gaze at her face", WAIT, |g| {
        g.frame == "player"
    })
    .await;
    assert_eq!(
        (face.body_part.as_str(), face.kind, face.follow),
        ("neck", ReachKind::Gaze, true)
    );

    // Scan: the target for the tracker, then the neck searches where a person shows a ball.
    commands
        .publish(&mut command(Command::ScanBall))
        .await
        .unwrap();
    let target: BallTarget = next(&targets, &launch, "the ball target", WAIT, |_| true).await;
    assert!(target.active);
    assert_eq!(
        (target.hue_deg, target.saturation, target.diameter_m),
        (51.7, 0.85, 0.07)
    );
    let first: ReachGoal = next(&reaches, &launch, "a scan gaze", WAIT, |g| {
        g.frame != "player"
    })
    .await;
    assert_eq!(
        (first.body_part.as_str(), first.kind, first.frame.as_str()),
        ("neck", ReachKind::Gaze, "world")
    );
    // No neck here to say "reached": the next scan point after the move's time-out (0.4 s).
    let second = next(&reaches, &launch, "the second scan gaze", WAIT, |_| true).await;
    assert_eq!(second.frame, "world");
    assert_ne!(second.position_m, first.position_m);

    // Detected: the neck follows the ball.
    ball_events
        .publish(&mut ball(BallEventKind::Detected))
        .await
        .unwrap();
    let gaze = next(&reaches, &launch, "the follow gaze", WAIT, |g| {
        g.frame == "ball"
    })
    .await;
    assert_eq!(
        (gaze.body_part.as_str(), gaze.kind, gaze.follow),
        ("neck", ReachKind::Gaze, true)
    );
    next(&says, &launch, "I see the ball", WAIT, |s| {
        s.text == say::SEE_IT
    })
    .await;

    // Touch: the hand's goal at the ball.
    commands
        .publish(&mut command(Command::TouchBall))
        .await
        .unwrap();
    let arm = next(&reaches, &launch, "the arm goal", WAIT, |g| {
        g.body_part == "left_arm_7"
    })
    .await;
    assert_eq!(
        (arm.kind, arm.frame.as_str(), arm.follow, arm.tolerance_m),
        (ReachKind::Position, "ball", true, 0.02)
    );
    next(&says, &launch, "going to touch", WAIT, |s| {
        s.text == say::GOING_TO_TOUCH
    })
    .await;

    // Reached, then the courtesy delay (1 s on the bus clock) sends the arm home.
    let mut reached = ReachStatus {
        id: arm.id,
        body_part: "left_arm_7".into(),
        state: ReachState::Reached,
        distance_m: 0.012,
        ..Default::default()
    };
    statuses.publish(&mut reached).await.unwrap();
    let sent = Instant::now();
    let t = next(&transitions, &launch, "touching", WAIT, |t| {
        t.event == "reach:reached"
    })
    .await;
    assert!(t.active.contains(&state::TOUCHING.to_string()), "{t:?}");
    next(&says, &launch, "touching", WAIT, |s| {
        s.text == say::TOUCHING
    })
    .await;
    let t = next(&transitions, &launch, "the courtesy timer", WAIT, |t| {
        t.event == "timer:courtesy"
    })
    .await;
    let waited = sent.elapsed();
    assert!(
        waited >= Duration::from_millis(900) && waited < Duration::from_secs(3),
        "courtesy after {waited:?}"
    );
    assert!(t.active.contains(&state::HOMING.to_string()), "{t:?}");
    next(&says, &launch, "the courtesy words", WAIT, |s| {
        s.text == say::COURTESY
    })
    .await;
    let cancel = next(&reaches, &launch, "the arm's cancel", WAIT, |g| {
        g.body_part == "left_arm_7" && !g.active
    })
    .await;
    assert_eq!(cancel.id, arm.id);
    // joint_motor took the rest posture.
    let l: GameLog = next(&logs, &launch, "the rest posture accepted", WAIT, |l| {
        l.text.contains("rest posture of 7 joints was accepted")
    })
    .await;
    assert_eq!(l.kind, "reach");

    // The ball is lost: said, and searched again.
    ball_events
        .publish(&mut ball(BallEventKind::Lost))
        .await
        .unwrap();
    next(&says, &launch, "I lost the ball", WAIT, |s| {
        s.text == say::LOST
    })
    .await;
    let t = next(&transitions, &launch, "searching again", WAIT, |t| {
        t.event == "ball:lost"
    })
    .await;
    assert!(t.active.contains(&state::LOOKING.to_string()), "{t:?}");

    // Structural changes pass through the Executive.
    let refused = bus
        .call(&topics::EXECUTIVE_PROPOSE, &remove("ball"), WAIT)
        .await
        .unwrap();
    assert!(!refused.accepted);
    assert_eq!(refused.reason_code, "game_protected");
    let dup = bus
        .call(&topics::EXECUTIVE_PROPOSE, &add("ball", "ball"), WAIT)
        .await
        .unwrap();
    assert_eq!(
        (dup.accepted, dup.reason_code.as_str()),
        (false, "duplicate_name"),
        "{dup:?}"
    );
    let cup = bus
        .call(&topics::EXECUTIVE_PROPOSE, &add("cup", "object"), WAIT)
        .await
        .unwrap();
    assert!(cup.accepted, "{cup:?}");
    let again = bus
        .call(&topics::EXECUTIVE_PROPOSE, &add("cup", "object"), WAIT)
        .await
        .unwrap();
    assert_eq!(again.reason_code, "duplicate_name");

    // Quit: goodbye, the final state.
    commands.publish(&mut command(Command::Quit)).await.unwrap();
    next(&says, &launch, "goodbye", WAIT, |s| s.text == say::GOODBYE).await;
    let t = next(&transitions, &launch, "finished", WAIT, |t| {
        t.event == "command:quit"
    })
    .await;
    assert_eq!(t.active, [state::FINISHED]);
    let off = next(&targets, &launch, "the target cleared", WAIT, |t| !t.active).await;
    assert!(!off.active);
    let conf = bus
        .call(
            &topics::EXECUTIVE_CONFIGURATION,
            &ConfigurationRequest::default(),
            WAIT,
        )
        .await
        .unwrap();
    assert_eq!(conf.active, [state::FINISHED]);
    assert!(conf.step >= 10, "{conf:?}");
    // The readable game log is on the console too.
    launch
        .lines
        .wait_for("the said line on the console", WAIT, |l| {
            l.contains("[said]") && l.contains(say::GOODBYE)
        });
    launch
        .lines
        .wait_for("the heard line on the console", WAIT, |l| {
            l.contains("[heard]") && l.contains("quit the game")
        });
}

#[test]
fn print_diagram_draws_the_machine() {
    let out = run(
        &bin("executive"),
        &["--print-diagram".to_string()],
        Duration::from_secs(10),
    );
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.starts_with("stateDiagram-v2"), "{text}");
    for s in [
        "waiting",
        "searching",
        "tracking",
        "touching",
        "homing",
        "finished",
    ] {
        assert!(text.contains(s), "{s} missing:\n{text}");
    }
    let bad = run(
        &bin("executive"),
        &[
            "--print-diagram".into(),
            "--settings".into(),
            "/nonexistent.toml".into(),
        ],
        Duration::from_secs(10),
    );
    assert!(!bad.status.success());
}

#[test]
fn with_exit_when_finished_quit_ends_the_graph_with_success() {
    let ns = unique_namespace("executive-exit");
    let dir = scratch(&ns);
    let settings = dir.join("executive.toml");
    std::fs::write(&settings, SETTINGS).unwrap();
    let text = MANIFEST
        .replace("@SETTINGS@", &settings.display().to_string())
        .replace(
            "args = [\"--game\", \"touch\",",
            "completes_graph = true\nargs = [\"--exit-when-finished\", \"--game\", \"touch\",",
        );
    assert!(text.contains("--exit-when-finished"));
    let manifest = write_manifest(&dir, "exit.toml.launch", &text);
    let mut launch = Launch::start(&manifest, &ns, &[]);
    let rt = tokio::runtime::Runtime::new().unwrap();
    rt.block_on(async {
        let bus = Bus::open(&launch.connect_args(), "test-executive-exit")
            .await
            .unwrap();
        let says = bus.subscriber(&topics::SPEECH_SAY).await.unwrap();
        let commands = bus.publisher(&topics::GAME_COMMAND).await.unwrap();
        // Quit until heard (the executive may not be up yet).
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            commands.publish(&mut command(Command::Quit)).await.unwrap();
            if let Some(s) = says.recv_timeout(Duration::from_millis(500)).await.unwrap() {
                assert_eq!(s.text, say::GOODBYE);
                break;
            }
            assert!(
                Instant::now() < deadline,
                "quit was never answered; output:\n{}",
                launch.lines.all().join("\n")
            );
        }
    });
    let status = launch.wait_exit(Duration::from_secs(20));
    assert!(
        status.success(),
        "{status:?}; output:\n{}",
        launch.lines.all().join("\n")
    );
    launch.lines.wait_for("the last game log line", WAIT, |l| {
        l.contains("the game is over")
    });
}
