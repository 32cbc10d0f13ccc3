//! Scenario tests of the field: physics, behaviours, rules, timeline, packets, determinism.

use spl::{
    FieldPoint, FusionConfig, GameState, NaoBody, NaoCommand, NaoHead, NaoStrategy,
    WorldModelFusion, decode_debug, decode_gamecontroller, encode_command,
};

use crate::{Datagram, RobotId, SimConfig, SimEvent, SplField, V2};

/// A field already in PLAYING, no falls, the opponents standing still unless `opponents_play`.
fn playing(opponents_play: bool) -> SplField {
    let passive_robots = if opponents_play {
        vec![]
    } else {
        vec![RobotId::KEEPER, RobotId::DEFENDER]
    };
    let mut f = SplField::new(SimConfig {
        falls_per_min: 0.0,
        passive_robots,
        ..SimConfig::default()
    });
    f.set_game_state(GameState::Playing);
    f
}

fn send(
    f: &mut SplField,
    body: Option<NaoBody>,
    head: Option<NaoHead>,
    target: Option<(f32, f32)>,
) {
    let cmd = NaoCommand {
        body: body.unwrap_or(NaoBody::Keep),
        head: head.unwrap_or(NaoHead::Keep),
        strategy: NaoStrategy::Default,
        target: target.map_or(FieldPoint::default(), |(x, y)| FieldPoint::new(x, y)),
        ..Default::default()
    };
    f.receive_command(&encode_command(&cmd).unwrap()).unwrap();
}

fn run_until(f: &mut SplField, max_s: f64, mut done: impl FnMut(&SplField) -> bool) -> bool {
    let end = f.time_s() + max_s;
    while f.time_s() < end {
        f.step(0.1);
        if done(f) {
            return true;
        }
    }
    false
}

fn pos(f: &SplField, id: RobotId) -> V2 {
    f.robot(id).unwrap().pos
}

#[test]
fn a_kick_moves_the_ball_and_friction_stops_it() {
    let mut f = playing(false);
    // Robots out of the way; the controlled robot near the ball, facing +x.
    f.place_robot(RobotId::AUTONOMOUS, V2::new(-3000.0, 2500.0), 0.0);
    f.place_robot(RobotId::KEEPER, V2::new(4300.0, 2500.0), 0.0);
    f.place_robot(RobotId::DEFENDER, V2::new(4000.0, -2500.0), 0.0);
    f.place_ball(V2::new(-2000.0, 0.0), V2::ZERO);
    f.place_robot(RobotId::CONTROLLED, V2::new(-2600.0, 0.0), 0.0);
    send(&mut f, Some(NaoBody::Kick), None, None);
    assert!(
        run_until(&mut f, 20.0, |f| f.events().iter().any(|(_, e)| matches!(
            e,
            SimEvent::Kick {
                by: RobotId::CONTROLLED,
                ..
            }
        ))),
        "the robot never kicked"
    );
    let start = f.ball;
    f.step(0.5);
    assert!(
        f.ball_vel.norm() > 2000.0,
        "ball speed {}",
        f.ball_vel.norm()
    );
    // v = 3000 mm/s, a = 400 mm/s²: stops after 7.5 s and about 11 m, unless it leaves the field
    // or enters the goal first; either way it is at rest 8 s later.
    f.step(8.0);
    assert_eq!(f.ball_vel, V2::ZERO);
    let travelled = (f.ball - start).norm();
    assert!(travelled > 2000.0, "ball travelled {travelled} mm");
    assert!(f.controlled().done, "a kick is one-shot");
}

#[test]
fn friction_stops_a_rolling_ball_at_the_predicted_distance() {
    let mut f = playing(false);
    for id in RobotId::ALL {
        f.place_robot(
            id,
            V2::new(-4000.0, 2800.0 - f64::from(id.number) * 500.0),
            0.0,
        );
    }
    f.place_robot(RobotId::KEEPER, V2::new(4000.0, 2800.0), 0.0);
    f.place_robot(RobotId::DEFENDER, V2::new(4000.0, 2300.0), 0.0);
    f.place_ball(V2::new(-2000.0, 0.0), V2::new(1600.0, 0.0));
    f.step(5.0);
    // d = v² / 2a = 1600² / 800 = 3200 mm (discretisation: within 1 %).
    assert_eq!(f.ball_vel, V2::ZERO);
    assert!(
        (f.ball.x - 1200.0).abs() < 32.0,
        "ball stopped at {}",
        f.ball.x
    );
}

#[test]
fn go_to_position_reaches_the_target() {
    // Everybody else stands: the teammate would otherwise score, which ends the attempt.
    let mut f = SplField::new(SimConfig {
        falls_per_min: 0.0,
        passive_robots: vec![RobotId::AUTONOMOUS, RobotId::KEEPER, RobotId::DEFENDER],
        ..SimConfig::default()
    });
    f.set_game_state(GameState::Playing);
    send(
        &mut f,
        Some(NaoBody::GoToPosition),
        None,
        Some((1000.0, 1500.0)),
    );
    let reached = run_until(&mut f, 30.0, |f| f.controlled().done);
    assert!(
        reached,
        "not reached, at {:?}",
        pos(&f, RobotId::CONTROLLED)
    );
    let d = (pos(&f, RobotId::CONTROLLED) - V2::new(1000.0, 1500.0)).norm();
    assert!(d < 50.0, "{d} mm from the target");
    // ~3.6 m at 250 mm/s: about 15 s, not instantly.
    assert!(f.time_s() > 12.0);
}

#[test]
fn commands_are_not_obeyed_in_set_and_bad_packets_change_nothing() {
    let mut f = SplField::new(SimConfig {
        falls_per_min: 0.0,
        ..SimConfig::default()
    });
    f.set_game_state(GameState::Set);
    let before = pos(&f, RobotId::CONTROLLED);
    send(
        &mut f,
        Some(NaoBody::GoToPosition),
        None,
        Some((0.0, 2000.0)),
    );
    f.step(2.0);
    assert_eq!(pos(&f, RobotId::CONTROLLED), before, "no motion in SET");
    // A 10-byte packet and a NaN target are refused; the command stays GoToPosition.
    let good = encode_command(&NaoCommand::body(
        NaoBody::Stop,
        NaoStrategy::Default,
        FieldPoint::default(),
    ))
    .unwrap();
    assert!(f.receive_command(&good[..10]).is_err());
    let mut nan = good;
    nan[0] = 1;
    nan[3..7].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(f.receive_command(&nan).is_err());
    assert_eq!(f.controlled().body, Some(NaoBody::GoToPosition));
    // A head-only packet keeps the body.
    send(&mut f, None, Some(NaoHead::Scan), None);
    assert_eq!(f.controlled().body, Some(NaoBody::GoToPosition));
    assert_eq!(f.controlled().head, NaoHead::Scan);
}

#[test]
fn turn_faces_x_y_not_y_x() {
    let mut f = playing(false);
    f.place_robot(RobotId::CONTROLLED, V2::new(0.0, 0.0), 0.0);
    // Target (0, 3000): facing +y (pi/2). The quirk (y, x) would face +x.
    send(&mut f, Some(NaoBody::Turn), None, Some((0.0, 3000.0)));
    assert!(run_until(&mut f, 5.0, |f| f.controlled().done));
    let th = f.robot(RobotId::CONTROLLED).unwrap().theta;
    assert!(
        (th - std::f64::consts::FRAC_PI_2).abs() < 0.06,
        "theta {th}"
    );
}

#[test]
fn search_the_ball_turns_until_it_sees_it() {
    let mut f = playing(false);
    f.place_robot(RobotId::CONTROLLED, V2::new(0.0, 0.0), 0.0);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(-4000.0, 2800.0), 0.0);
    f.place_ball(V2::new(-2000.0, -300.0), V2::ZERO); // behind the robot
    send(
        &mut f,
        Some(NaoBody::SearchTheBall),
        Some(NaoHead::LookForward),
        None,
    );
    assert!(
        run_until(&mut f, 15.0, |f| f.controlled().done),
        "never found the ball"
    );
    let r = f.robot(RobotId::CONTROLLED).unwrap();
    assert!(r.theta.abs() > 1.0, "it turned (theta {})", r.theta);
}

fn completed_passes(f: &SplField) -> Vec<(RobotId, RobotId, f64)> {
    f.events()
        .iter()
        .filter_map(|(_, e)| match e {
            SimEvent::PassCompleted {
                from,
                to,
                distance_mm,
            } => Some((*from, *to, *distance_mm)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_pass_to_the_teammate_is_completed_and_detected() {
    let mut f = playing(false);
    f.place_robot(RobotId::KEEPER, V2::new(4300.0, 2500.0), 0.0);
    f.place_robot(RobotId::DEFENDER, V2::new(4000.0, -2500.0), 0.0);
    f.place_robot(RobotId::CONTROLLED, V2::new(-1500.0, 0.0), 0.0);
    f.place_ball(V2::new(-1200.0, 0.0), V2::ZERO);
    // The teammate 2.5 m away, farther from the ball: supporter, it holds its position.
    f.place_robot(RobotId::AUTONOMOUS, V2::new(300.0, 2000.0), 0.0);
    send(&mut f, Some(NaoBody::Pass), None, None);
    assert!(
        run_until(&mut f, 30.0, |f| !completed_passes(f).is_empty()),
        "no pass completed; events {:?}",
        f.events()
    );
    let passes = completed_passes(&f);
    assert_eq!(passes[0].0, RobotId::CONTROLLED);
    assert_eq!(passes[0].1, RobotId::AUTONOMOUS);
    assert!(passes[0].2 >= 1000.0);
    assert_eq!(f.score(), 1, "a completed pass is 1 point");
}

#[test]
fn a_ball_touched_by_an_opponent_first_is_no_pass() {
    let mut f = playing(false);
    f.place_robot(RobotId::CONTROLLED, V2::new(-1500.0, 0.0), 0.0);
    f.place_ball(V2::new(-1200.0, 0.0), V2::ZERO);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(1800.0, 0.0), 0.0);
    // The defender stands on the line of the pass.
    f.place_robot(RobotId::DEFENDER, V2::new(200.0, 0.0), 0.0);
    f.place_robot(RobotId::KEEPER, V2::new(4300.0, 2500.0), 0.0);
    send(&mut f, Some(NaoBody::Pass), None, None);
    run_until(&mut f, 20.0, |f| {
        f.events().iter().any(|(_, e)| {
            matches!(
                e,
                SimEvent::Touch {
                    by: RobotId::DEFENDER
                }
            )
        })
    });
    f.step(5.0);
    assert!(
        f.events().iter().any(|(_, e)| matches!(
            e,
            SimEvent::Touch {
                by: RobotId::DEFENDER
            }
        )),
        "the defender should intercept"
    );
    assert!(completed_passes(&f).is_empty());
}

#[test]
fn pass_without_an_active_teammate_dribbles() {
    let mut f = playing(false);
    f.place_robot(RobotId::CONTROLLED, V2::new(-1500.0, 0.0), 0.0);
    f.place_ball(V2::new(-1200.0, 0.0), V2::ZERO);
    f.knock_over(RobotId::AUTONOMOUS);
    send(&mut f, Some(NaoBody::Pass), None, None);
    f.step(5.0);
    assert!(
        !f.events()
            .iter()
            .any(|(_, e)| matches!(e, SimEvent::Kick { .. })),
        "no kick without a teammate"
    );
    assert!(
        f.ball.x > -1000.0,
        "the ball was dribbled forward: {:?}",
        f.ball
    );
}

#[test]
fn the_autonomous_teammate_scores_in_a_scripted_situation() {
    let mut f = playing(true);
    // The teammate near the ball 2 m from goal, the controlled robot far behind; the keeper on
    // its line, the defender far away on the wing.
    f.place_ball(V2::new(2500.0, 200.0), V2::ZERO);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(1900.0, 0.0), 0.0);
    f.place_robot(RobotId::CONTROLLED, V2::new(-2000.0, -1000.0), 0.0);
    f.place_robot(RobotId::DEFENDER, V2::new(-1000.0, 2800.0), 0.0);
    let scored = run_until(&mut f, 30.0, |f| f.game_state() == GameState::Finished);
    assert!(scored, "events {:?}", f.events());
    assert!(
        f.events().iter().any(|(_, e)| matches!(
            e,
            SimEvent::Goal {
                side: crate::Side::Us,
                counted: true
            }
        )),
        "events {:?}",
        f.events()
    );
    assert_eq!(f.score(), 2, "a goal is 2 points");
    assert!(f.secs_remaining() == 0.0, "a goal ends the attempt");
}

#[test]
fn the_controlled_robot_may_not_score_directly() {
    let mut f = playing(false);
    f.place_robot(RobotId::KEEPER, V2::new(4300.0, 2500.0), 0.0);
    f.place_robot(RobotId::DEFENDER, V2::new(4000.0, -2500.0), 0.0);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(-3000.0, 2500.0), 0.0);
    f.place_ball(V2::new(2500.0, 0.0), V2::ZERO);
    f.place_robot(RobotId::CONTROLLED, V2::new(2000.0, 0.0), 0.0);
    send(&mut f, Some(NaoBody::Kick), None, None);
    assert!(run_until(&mut f, 20.0, |f| f.game_state() == GameState::Finished));
    assert!(
        f.events()
            .iter()
            .any(|(_, e)| matches!(e, SimEvent::Goal { counted: false, .. }))
    );
    assert_eq!(f.score(), 0);
}

#[test]
fn a_fall_happens_and_the_robot_gets_up() {
    let mut f = SplField::new(SimConfig {
        falls_per_min: 20.0,
        getup_s: 4.0,
        passive_robots: vec![RobotId::KEEPER, RobotId::DEFENDER],
        seed: 3,
        ..SimConfig::default()
    });
    f.set_game_state(GameState::Playing);
    // Keep the controlled robot walking back and forth.
    let mut fell_at = None;
    let mut got_up_at = None;
    for k in 0..60 {
        let y = if k % 2 == 0 { 2000.0 } else { -2000.0 };
        send(
            &mut f,
            Some(NaoBody::GoToPosition),
            None,
            Some((-1500.0, y)),
        );
        f.step(2.0);
        for (t, e) in f.events() {
            match e {
                SimEvent::Fell { robot } if *robot == RobotId::CONTROLLED && fell_at.is_none() => {
                    fell_at = Some(*t)
                }
                SimEvent::GotUp { robot }
                    if *robot == RobotId::CONTROLLED
                        && fell_at.is_some()
                        && got_up_at.is_none() =>
                {
                    got_up_at = Some(*t)
                }
                _ => {}
            }
        }
        if got_up_at.is_some() {
            break;
        }
    }
    let (fell, up) = (fell_at.expect("no fall"), got_up_at.expect("never got up"));
    assert!((up - fell - 4.0).abs() < 0.02, "fell at {fell}, up at {up}");
    // While down it reported fallen in its debug packets and did not move.
    let mut g = SplField::new(SimConfig {
        falls_per_min: 0.0,
        getup_s: 4.0,
        ..SimConfig::default()
    });
    g.set_game_state(GameState::Playing);
    // The ball deep in our half, so that no goal ends the attempt meanwhile.
    g.place_ball(V2::new(-4000.0, 2800.0), V2::ZERO);
    send(
        &mut g,
        Some(NaoBody::GoToPosition),
        None,
        Some((2000.0, 0.0)),
    );
    g.knock_over(RobotId::CONTROLLED);
    let p0 = pos(&g, RobotId::CONTROLLED);
    let out = g.step(1.0);
    assert_eq!(pos(&g, RobotId::CONTROLLED), p0);
    let fallen_flags: Vec<bool> = out
        .iter()
        .filter_map(|d| match d {
            Datagram::Debug { player: 2, bytes } => Some(decode_debug(bytes).unwrap().fallen),
            _ => None,
        })
        .collect();
    assert_eq!(fallen_flags.len(), 10);
    assert!(fallen_flags.iter().all(|f| *f));
    g.step(3.5);
    assert!(!g.robot(RobotId::CONTROLLED).unwrap().is_fallen());
    g.step(2.0);
    assert_ne!(
        pos(&g, RobotId::CONTROLLED),
        p0,
        "walks again after getting up"
    );
}

#[test]
fn game_state_timeline_set_playing_90_s_finished() {
    // Everybody stands still in PLAYING: nobody scores, the attack runs out.
    let config = SimConfig {
        falls_per_min: 0.0,
        passive_robots: RobotId::ALL.to_vec(),
        ..SimConfig::default()
    };
    let (i, r, s) = (config.initial_s, config.ready_s, config.set_s);
    let mut f = SplField::new(config);
    // Keep the ball away from any goal: nobody scores, the attack runs out.
    let mut states = vec![];
    let mut gc_times = vec![];
    let mut secs_at_playing_plus_30 = None;
    while f.time_s() < i + r + s + 95.0 {
        for d in f.step(0.1) {
            if let Datagram::GameController { bytes } = d {
                let st = decode_gamecontroller(&bytes).unwrap();
                gc_times.push(f.time_s());
                if states.last() != Some(&st.state) {
                    states.push(st.state);
                }
                if (f.time_s() - (i + r + s + 30.0)).abs() < 1e-6 {
                    secs_at_playing_plus_30 = Some(st.secs_remaining);
                }
            }
        }
        if f.game_state() == GameState::Finished {
            break;
        }
    }
    f.step(1.0);
    let changes: Vec<(f64, GameState)> = f
        .events()
        .iter()
        .filter_map(|(t, e)| match e {
            SimEvent::StateChanged { state } => Some((*t, *state)),
            _ => None,
        })
        .collect();
    let at = |st: GameState| changes.iter().find(|(_, s)| *s == st).map(|(t, _)| *t);
    assert!((at(GameState::Ready).unwrap() - i).abs() < 1e-6);
    assert!((at(GameState::Set).unwrap() - (i + r)).abs() < 1e-6);
    let playing = at(GameState::Playing).unwrap();
    assert!((playing - (i + r + s)).abs() < 1e-6);
    let finished = at(GameState::Finished).unwrap();
    let goal = f
        .events()
        .iter()
        .any(|(_, e)| matches!(e, SimEvent::Goal { .. }));
    if !goal {
        assert!(
            (finished - playing - 90.0).abs() < 1e-6,
            "attack lasted {}",
            finished - playing
        );
    } else {
        assert!(finished - playing <= 90.0);
    }
    assert_eq!(
        states,
        vec![
            GameState::Initial,
            GameState::Ready,
            GameState::Set,
            GameState::Playing,
            GameState::Finished
        ]
    );
    if !goal {
        assert_eq!(secs_at_playing_plus_30, Some(60));
    }
    // 2 Hz.
    let gaps: Vec<f64> = gc_times.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(gaps.iter().all(|g| (g - 0.5).abs() < 1e-6));
}

#[test]
fn debug_packets_every_100_ms_decode_and_fuse_to_the_true_ball() {
    let mut f = playing(false);
    f.place_robot(RobotId::CONTROLLED, V2::new(-1500.0, 0.0), 0.0);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(0.0, 1500.0), -1.0);
    f.place_ball(V2::new(500.0, 0.0), V2::ZERO);
    let mut fusion = WorldModelFusion::new(FusionConfig::default());
    let mut per_player = [0u32; 3];
    for _ in 0..30 {
        for d in f.step(0.1) {
            if let Datagram::Debug { player, bytes } = d {
                assert_eq!(bytes.len(), 356);
                let m = decode_debug(&bytes).unwrap();
                assert_eq!(m.player_number, player);
                per_player[usize::from(player)] += 1;
                fusion.ingest(&m, f.time_s());
            }
        }
    }
    assert_eq!(per_player[1], 30);
    assert_eq!(per_player[2], 30);
    let w = fusion.snapshot(f.time_s());
    assert!(w.ball_known, "both robots see the ball");
    let err = f64::from(w.ball.x_mm - 500.0).hypot(f64::from(w.ball.y_mm));
    assert!(err < 60.0, "fused ball {err} mm from the truth");
    assert_eq!(w.robots.len(), 2);
    // The opponents were seen by someone.
    assert!(!w.obstacles.is_empty());
}

#[test]
fn same_seed_same_run_other_seed_other_run() {
    let run = |seed: u64| {
        let mut f = SplField::new(SimConfig {
            seed,
            falls_per_min: 2.0,
            ..SimConfig::default()
        });
        let mut bytes = Vec::new();
        for k in 0..400 {
            if k == 120 {
                send(
                    &mut f,
                    Some(NaoBody::GoToBallAndDribble),
                    Some(NaoHead::LookAtTheBall),
                    None,
                );
            }
            for d in f.step(0.1) {
                match d {
                    Datagram::Debug { bytes: b, .. } | Datagram::GameController { bytes: b } => {
                        bytes.extend(b)
                    }
                }
            }
        }
        (bytes, f.events().len())
    };
    let a = run(11);
    assert_eq!(a, run(11));
    assert_ne!(a.0, run(12).0);
}

#[test]
fn ask_for_the_ball_makes_the_teammate_pass() {
    let mut f = playing(false);
    f.place_robot(RobotId::KEEPER, V2::new(4300.0, 2500.0), 0.0);
    f.place_robot(RobotId::DEFENDER, V2::new(4000.0, -2500.0), 0.0);
    f.place_ball(V2::new(-500.0, 1000.0), V2::ZERO);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(-900.0, 1000.0), 0.0);
    f.place_robot(RobotId::CONTROLLED, V2::new(1500.0, -1000.0), 0.0);
    send(&mut f, Some(NaoBody::AskForTheBall), None, None);
    assert!(f.controlled().ball_requested);
    assert!(
        run_until(&mut f, 30.0, |f| !completed_passes(f).is_empty()),
        "events {:?}",
        f.events()
    );
    let p = completed_passes(&f)[0];
    assert_eq!((p.0, p.1), (RobotId::AUTONOMOUS, RobotId::CONTROLLED));
    assert!(!f.controlled().ball_requested, "request served");
}

#[test]
fn spazza_clears_the_ball_away_from_our_goal() {
    let mut f = playing(false);
    f.place_robot(RobotId::AUTONOMOUS, V2::new(2000.0, 2500.0), 0.0);
    f.place_ball(V2::new(-3500.0, -500.0), V2::ZERO);
    f.place_robot(
        RobotId::CONTROLLED,
        V2::new(-3000.0, 0.0),
        std::f64::consts::PI,
    );
    send(&mut f, Some(NaoBody::Spazza), None, None);
    assert!(run_until(&mut f, 30.0, |f| f.controlled().done));
    f.step(10.0);
    let from_goal = (f.ball - V2::new(-4500.0, 0.0)).norm();
    assert!(from_goal > 4000.0, "ball only {from_goal} mm from our goal");
}

#[test]
fn head_commands_move_the_head() {
    let mut f = playing(false);
    f.place_robot(RobotId::CONTROLLED, V2::new(0.0, -2000.0), 0.0);
    for (head, yaw) in [
        (NaoHead::LookLeft, 1.0),
        (NaoHead::LookRight, -1.0),
        (NaoHead::LookForward, 0.0),
    ] {
        send(&mut f, None, Some(head), None);
        f.step(1.0);
        let r = f.robot(RobotId::CONTROLLED).unwrap();
        assert!((r.head_yaw - yaw).abs() < 1e-9, "{head:?}: {}", r.head_yaw);
    }
    // Scan sweeps: the yaw takes both signs within a period.
    send(&mut f, None, Some(NaoHead::Scan), None);
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for _ in 0..40 {
        f.step(0.1);
        let y = f.robot(RobotId::CONTROLLED).unwrap().head_yaw;
        lo = lo.min(y);
        hi = hi.max(y);
    }
    assert!(lo < -1.0 && hi > 1.0, "scan range {lo}..{hi}");
}

#[test]
fn random_command_bytes_never_panic_and_never_apply_when_refused() {
    let mut rng = crate::rng::SimRng::new(99);
    let mut f = playing(false);
    let (mut ok, mut refused) = (0, 0);
    for _ in 0..20_000 {
        let len = (rng.next_u64() % 16) as usize;
        let mut b: Vec<u8> = (0..len).map(|_| rng.next_u64() as u8).collect();
        if len == 11 {
            // Bias towards valid-looking packets so both paths are exercised.
            b[0] %= 12;
            b[1] %= 7;
            b[2] %= 3;
        }
        let before = f.controlled().clone();
        match f.receive_command(&b) {
            Ok(_) => ok += 1,
            Err(_) => {
                refused += 1;
                assert_eq!(f.controlled(), &before);
            }
        }
    }
    assert!(ok > 100 && refused > 1000, "ok {ok}, refused {refused}");
}

#[test]
fn the_autonomous_striker_scores_past_playing_opponents() {
    // No coach: the controlled robot stands; the teammate plays alone against the keeper and
    // the defender, both playing. It shoots only through a free lane (else dribbles round the
    // defender), so it scores in some attempts on its own; with the coach's help in others.
    // (Shooting regardless of the lane, as before, it scored in 1 of these 10.)
    let mut goals = 0;
    let mut times = Vec::new();
    for seed in 1..=10 {
        let mut f = SplField::new(SimConfig {
            seed,
            falls_per_min: 0.0,
            ..SimConfig::default()
        });
        f.set_game_state(GameState::Playing);
        f.step(90.0);
        if let Some((t, _)) = f.events().iter().find(|(_, e)| {
            matches!(
                e,
                SimEvent::Goal {
                    side: crate::types::Side::Us,
                    counted: true
                }
            )
        }) {
            goals += 1;
            times.push(*t);
        }
    }
    println!("goals in {goals} of 10 attempts, at {times:?}");
    assert!(goals >= 4, "goals in {goals} of 10 attempts");
}

#[test]
fn a_scripted_penalty_is_reported_by_the_gamecontroller_and_stops_the_robot() {
    let mut f = SplField::new(SimConfig {
        falls_per_min: 0.0,
        penalty_at_s: Some(2.0),
        penalty_s: 5.0,
        passive_robots: vec![RobotId::KEEPER, RobotId::DEFENDER],
        ..SimConfig::default()
    });
    f.set_game_state(GameState::Playing);
    send(
        &mut f,
        Some(NaoBody::GoToPosition),
        None,
        Some((-1500.0, 2500.0)),
    );
    let penalty_of_player_2 = |out: &[Datagram]| {
        out.iter()
            .filter_map(|d| match d {
                Datagram::GameController { bytes } => {
                    let s = spl::decode_gamecontroller(bytes).unwrap();
                    let p = s.teams[0].players[1];
                    Some((p.penalty, p.secs_till_unpenalised))
                }
                _ => None,
            })
            .next_back()
    };
    let out = f.step(1.9);
    assert_eq!(
        penalty_of_player_2(&out).map(|p| p.0),
        Some(spl::Penalty::None)
    );
    let moving = pos(&f, RobotId::CONTROLLED);
    let out = f.step(1.0);
    let (penalty, secs) = penalty_of_player_2(&out).unwrap();
    assert_eq!(penalty, spl::Penalty::Pushing);
    assert!((4..=5).contains(&secs), "{secs} s left");
    assert!(f.robot(RobotId::CONTROLLED).unwrap().is_penalised());
    // Penalised: it stands, whatever it is told.
    let p0 = pos(&f, RobotId::CONTROLLED);
    assert_ne!(p0, moving, "it walked before the penalty");
    send(
        &mut f,
        Some(NaoBody::GoToPosition),
        None,
        Some((2000.0, 0.0)),
    );
    f.step(3.0);
    assert_eq!(pos(&f, RobotId::CONTROLLED), p0);
    // Over: the GameController clears it and the robot walks again.
    let out = f.step(1.5);
    assert_eq!(
        penalty_of_player_2(&out).map(|p| p.0),
        Some(spl::Penalty::None)
    );
    f.step(1.0);
    assert_ne!(pos(&f, RobotId::CONTROLLED), p0);
    let kinds: Vec<_> = f
        .events()
        .iter()
        .filter(|(_, e)| matches!(e, SimEvent::Penalised { .. } | SimEvent::Unpenalised { .. }))
        .map(|(t, _)| (*t * 10.0).round() / 10.0)
        .collect();
    assert_eq!(kinds, [2.0, 7.0]);
}

#[test]
fn the_next_attack_sets_the_field_up_again_and_time_goes_on() {
    let mut f = playing(false);
    send(
        &mut f,
        Some(NaoBody::GoToPosition),
        None,
        Some((1000.0, 1000.0)),
    );
    f.knock_over(RobotId::AUTONOMOUS);
    f.penalise(RobotId::CONTROLLED, 60.0);
    f.place_ball(V2::new(2000.0, 500.0), V2::new(100.0, 0.0));
    f.set_game_state(GameState::Finished);
    f.step(1.0);
    let (t, ready) = (f.time_s(), SplField::new(SimConfig::default()));
    f.next_attack();
    assert_eq!(f.game_state(), GameState::Initial);
    assert_eq!(f.time_s(), t, "the field's time goes on");
    assert_eq!((f.ball, f.ball_vel), (V2::ZERO, V2::ZERO));
    assert_eq!(f.score(), 0);
    assert_eq!(f.controlled().body, None, "no command from the last attack");
    for id in RobotId::ALL {
        let (r, r0) = (f.robot(id).unwrap(), ready.robot(id).unwrap());
        assert_eq!(
            (r.pos, r.theta),
            (r0.pos, r0.theta),
            "{id:?} on its ready pose"
        );
        assert!(
            !r.is_fallen() && !r.is_penalised(),
            "{id:?} stands, unpenalised"
        );
    }
    // The timeline runs again: READY, SET, then PLAYING.
    assert!(run_until(&mut f, 30.0, |f| f.game_state() == GameState::Playing));
    // The events of both attacks are handed out once.
    let events = f.take_events();
    assert!(events.iter().any(|(_, e)| matches!(
        e,
        SimEvent::StateChanged {
            state: GameState::Finished
        }
    )));
    assert!(events.iter().any(|(_, e)| matches!(
        e,
        SimEvent::StateChanged {
            state: GameState::Playing
        }
    )));
    assert!(f.take_events().is_empty());
}
