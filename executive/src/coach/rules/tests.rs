//! The coach's rules, case by case.
#![allow(clippy::unwrap_used)]
use super::*;
use interfaces::msg::nao::{
    FieldPose, PlayerPenalty, PlayerRole, TeamRobot, TeamStatus, TrackedObstacle,
};

fn cfg() -> RulesConfig {
    RulesConfig::default()
}

fn robot(n: u8, x: f32, y: f32) -> TeamRobot {
    TeamRobot {
        player_number: n,
        role: PlayerRole::from_wire(if n == 2 { 18 } else { 17 }),
        pose: FieldPose {
            x_mm: x,
            y_mm: y,
            theta_rad: 0.0,
        },
        fallen: false,
        age_s: 0.1,
    }
}

fn game(state: u8) -> GameState {
    GameState {
        state,
        our_team_found: true,
        our_team: TeamStatus {
            team_number: 19,
            players: vec![PlayerPenalty::default(); 20],
            ..Default::default()
        },
        ..Default::default()
    }
}

/// PLAYING, link up, controlled robot at (-1500, 0), teammate at (500, 1500), ball at
/// (-1200, 0).
fn playing() -> Situation {
    Situation {
        game: Some(game(GameState::PLAYING)),
        world: Some(NaoWorldModel {
            robots: vec![robot(2, -1500.0, 0.0), robot(1, 500.0, 1500.0)],
            ball_known: true,
            ball: FieldPoint {
                x_mm: -1200.0,
                y_mm: 0.0,
            },
            ..Default::default()
        }),
        link_up: true,
    }
}

fn pt(x: f32, y: f32) -> FieldPoint {
    FieldPoint { x_mm: x, y_mm: y }
}

fn go_to(x: f32, y: f32) -> Ask {
    Ask {
        target: Some(pt(x, y)),
        ..Ask::body(NaoBody::GoToPosition, "panel")
    }
}

#[test]
fn a_command_in_playing_is_executed_with_its_answer_first() {
    let v = decide(&go_to(-1000.0, 1000.0), &playing(), &cfg());
    let Verdict::Execute { command, say } = v else {
        panic!("{v:?}")
    };
    assert_eq!(say, "Going to the position.");
    assert_eq!(command.body, NaoBody::GoToPosition);
    assert_eq!(command.target, pt(-1000.0, 1000.0));
    assert_eq!(command.source, "executive");
    let v = decide(&Ask::body(NaoBody::Pass, "voice"), &playing(), &cfg());
    assert_eq!(v.say(), "Passing to my teammate.");
    assert_eq!(v.command().unwrap().body, NaoBody::Pass);
}

#[test]
fn a_position_outside_the_field_is_refused_with_the_reason() {
    for (x, y) in [(5200.0, 300.0), (0.0, -3100.0), (f32::NAN, 0.0)] {
        let v = decide(&go_to(x, y), &playing(), &cfg());
        let Verdict::Refuse { reason, say, keep } = v else {
            panic!("{v:?}")
        };
        assert_eq!(reason, Refusal::OutsideField);
        assert!(!keep);
        assert!(say.contains("outside the field"), "{say}");
    }
    let v = decide(&go_to(5200.0, 300.0), &playing(), &cfg());
    assert_eq!(
        v.say(),
        "I cannot go to the position at 5.2, 0.3 metres: it is outside the field."
    );
    // On the line is inside.
    assert!(matches!(
        decide(&go_to(4500.0, -3000.0), &playing(), &cfg()),
        Verdict::Execute { .. }
    ));
    // No target at all.
    let mut a = go_to(0.0, 0.0);
    a.target = None;
    assert!(matches!(
        decide(&a, &playing(), &cfg()),
        Verdict::Refuse {
            reason: Refusal::NoTarget,
            ..
        }
    ));
}

#[test]
fn motion_outside_playing_is_refused_and_kept_but_head_and_stop_are_allowed() {
    for (state, name) in [(0, "INITIAL"), (1, "READY"), (2, "SET")] {
        let s = Situation {
            game: Some(game(state)),
            ..playing()
        };
        let v = decide(&Ask::body(NaoBody::GoToBallAndDribble, "voice"), &s, &cfg());
        let Verdict::Refuse { reason, say, keep } = v else {
            panic!("{v:?}")
        };
        assert_eq!(reason, Refusal::NotPlaying(state));
        assert!(keep);
        assert_eq!(
            say,
            format!(
                "I cannot go to the ball and dribble now: the game is in {name}. I will do it when we play."
            )
        );
        let head = Ask {
            head: NaoHead::LookLeft,
            ..Ask::body(NaoBody::Keep, "voice")
        };
        assert_eq!(decide(&head, &s, &cfg()).say(), "Looking left.");
        assert!(
            decide(&Ask::body(NaoBody::Stop, "voice"), &s, &cfg())
                .command()
                .is_some()
        );
    }
    // FINISHED: refused and not kept; no GameController yet: refused, kept.
    let s = Situation {
        game: Some(game(GameState::FINISHED)),
        ..playing()
    };
    assert!(matches!(
        decide(&Ask::body(NaoBody::Kick, "voice"), &s, &cfg()),
        Verdict::Refuse { keep: false, .. }
    ));
    let s = Situation {
        game: None,
        ..playing()
    };
    let v = decide(&Ask::body(NaoBody::Kick, "voice"), &s, &cfg());
    assert!(v.say().contains("no game state"), "{v:?}");
    // Not kept when the coach does not want it.
    let c = RulesConfig {
        keep_for_playing: false,
        ..cfg()
    };
    let s = Situation {
        game: Some(game(GameState::SET)),
        ..playing()
    };
    let v = decide(&go_to(0.0, 0.0), &s, &c);
    assert!(matches!(v, Verdict::Refuse { keep: false, .. }), "{v:?}");
    assert_eq!(
        v.say(),
        "I cannot go to the position now: the game is in SET."
    );
}

#[test]
fn a_penalised_robot_does_not_move() {
    let mut s = playing();
    let g = s.game.as_mut().unwrap();
    g.our_team.players[1] = PlayerPenalty {
        penalty: 3,
        secs_till_unpenalised: 30,
    };
    assert!(s.penalised(&cfg()));
    let v = decide(&go_to(0.0, 0.0), &s, &cfg());
    assert_eq!(
        v,
        Verdict::Refuse {
            reason: Refusal::Penalised,
            say: "I cannot go to the position now: I am penalised. I will do it when I am back."
                .into(),
            keep: true
        }
    );
    // Player 1's penalty is not ours.
    let mut s = playing();
    s.game.as_mut().unwrap().our_team.players[0].penalty = 5;
    assert!(!s.penalised(&cfg()));
}

#[test]
fn a_lost_link_or_a_fall_keeps_the_request_for_later() {
    let s = Situation {
        link_up: false,
        ..playing()
    };
    let v = decide(&Ask::body(NaoBody::Pass, "voice"), &s, &cfg());
    assert!(
        matches!(
            v,
            Verdict::Refuse {
                reason: Refusal::LinkDown,
                keep: true,
                ..
            }
        ),
        "{v:?}"
    );
    let mut s = playing();
    s.world.as_mut().unwrap().robots[0].fallen = true;
    let v = decide(&go_to(0.0, 0.0), &s, &cfg());
    assert_eq!(
        v,
        Verdict::Refuse {
            reason: Refusal::Fallen,
            say: "I am on the ground. I will go to the position when I am up.".into(),
            keep: true
        }
    );
}

#[test]
fn a_pass_without_a_visible_teammate_becomes_a_dribble_and_says_so() {
    for change in [
        |w: &mut NaoWorldModel| w.robots[1].fallen = true,
        |w: &mut NaoWorldModel| w.robots[1].age_s = 5.0,
        |w: &mut NaoWorldModel| {
            w.robots.pop();
        },
    ] {
        let mut s = playing();
        change(s.world.as_mut().unwrap());
        let v = decide(&Ask::body(NaoBody::Pass, "voice"), &s, &cfg());
        let Verdict::Replace {
            asked,
            command,
            say,
        } = v
        else {
            panic!("{v:?}")
        };
        assert_eq!(asked, NaoBody::Pass);
        assert_eq!(command.body, NaoBody::GoToBallAndDribble);
        assert_eq!(
            say,
            "I see no teammate to pass to: I will go to the ball and dribble."
        );
    }
}

#[test]
fn the_operated_robot_does_not_shoot_at_goal_a_kick_becomes_a_pass() {
    let v = decide(&Ask::body(NaoBody::Kick, "voice"), &playing(), &cfg());
    let Verdict::Replace {
        asked,
        command,
        say,
    } = v
    else {
        panic!("{v:?}")
    };
    assert_eq!((asked, command.body), (NaoBody::Kick, NaoBody::Pass));
    assert_eq!(
        say,
        "I may not shoot at the goal myself. Passing to my teammate."
    );
    // Without a teammate: a dribble.
    let mut s = playing();
    s.world.as_mut().unwrap().robots.pop();
    let v = decide(&Ask::body(NaoBody::Kick, "voice"), &s, &cfg());
    assert_eq!(v.command().unwrap().body, NaoBody::GoToBallAndDribble);
    assert!(
        v.say()
            .starts_with("I may not shoot at the goal myself. I see no teammate")
    );
    // Outside the challenge, a kick is a kick.
    let c = RulesConfig {
        challenge_rule: false,
        ..cfg()
    };
    let v = decide(&Ask::body(NaoBody::Kick, "voice"), &playing(), &c);
    assert_eq!(
        v,
        Verdict::Execute {
            command: Ask::body(NaoBody::Kick, "voice").command(),
            say: "Kicking at the goal.".into()
        }
    );
}

#[test]
fn never_towards_our_own_goal() {
    // Aimed at our goal from the ball at (-1200, 0): refused, whatever the rules.
    for challenge_rule in [true, false] {
        let c = RulesConfig {
            challenge_rule,
            ..cfg()
        };
        for body in [NaoBody::Kick, NaoBody::Spazza] {
            let ask = Ask {
                aim: Some(pt(-4500.0, 300.0)),
                ..Ask::body(body, "panel")
            };
            let v = decide(&ask, &playing(), &c);
            assert!(
                matches!(
                    v,
                    Verdict::Refuse {
                        reason: Refusal::OwnGoal,
                        keep: false,
                        ..
                    }
                ),
                "{body:?} {v:?}"
            );
            assert!(v.say().contains("towards our own goal"), "{v:?}");
        }
    }
    // Without any world model, an aim at our goal mouth is still refused.
    let blind = Situation {
        world: None,
        ..playing()
    };
    let c = RulesConfig {
        challenge_rule: false,
        ..cfg()
    };
    let ask = Ask {
        aim: Some(pt(-4400.0, 100.0)),
        ..Ask::body(NaoBody::Kick, "panel")
    };
    assert!(matches!(
        decide(&ask, &blind, &c),
        Verdict::Refuse {
            reason: Refusal::OwnGoal,
            ..
        }
    ));
    // A pass to a teammate standing between the ball and our goal.
    let mut s = playing();
    let w = s.world.as_mut().unwrap();
    w.robots[1].pose.x_mm = -3500.0;
    w.robots[1].pose.y_mm = -200.0;
    let v = decide(&Ask::body(NaoBody::Pass, "voice"), &s, &cfg());
    assert!(matches!(
        v,
        Verdict::Refuse {
            reason: Refusal::OwnGoal,
            ..
        }
    ));
    // A back pass in midfield stops at the teammate: allowed.
    let mut s = playing();
    let w = s.world.as_mut().unwrap();
    w.robots[1].pose.x_mm = -2000.0;
    w.robots[1].pose.y_mm = 0.0;
    assert!(matches!(
        decide(&Ask::body(NaoBody::Pass, "voice"), &s, &cfg()),
        Verdict::Execute { .. }
    ));
    // Aimed sideways or forwards is fine.
    let c = RulesConfig {
        challenge_rule: false,
        ..cfg()
    };
    let ask = Ask {
        aim: Some(pt(-2000.0, 2900.0)),
        ..Ask::body(NaoBody::Spazza, "panel")
    };
    assert!(matches!(
        decide(&ask, &playing(), &c),
        Verdict::Execute { .. }
    ));
    // The geometry: backwards but wide of the goal is not towards it.
    assert!(towards_own_goal(pt(0.0, 0.0), pt(-1000.0, 0.0), 250.0));
    assert!(!towards_own_goal(pt(0.0, 0.0), pt(-1000.0, 1000.0), 250.0));
    assert!(!towards_own_goal(pt(0.0, 0.0), pt(1000.0, 0.0), 250.0));
    assert!(!towards_own_goal(pt(0.0, 0.0), pt(0.0, 0.0), 250.0));
}

#[test]
fn settings_parse_with_defaults_and_refuse_unknown_keys() {
    let c: RulesConfig = toml::from_str("challenge_rule = false\nstill_down_s = 5.0").unwrap();
    assert!(!c.challenge_rule);
    assert_eq!(c.still_down_s, 5.0);
    assert_eq!(c.controlled_player, 2);
    assert!(toml::from_str::<RulesConfig>("challenge_rules = false").is_err());
}

#[test]
fn voice_commands_become_requests() {
    let c = cfg();
    let s = playing();
    let w = s.world.as_ref();
    let a = Ask::from_voice(Command::GoToPosition, None, w, &c).unwrap();
    assert_eq!(a.target, Some(pt(-1500.0, -1200.0)));
    let a = Ask::from_voice(Command::GoToPosition, Some(pt(100.0, 200.0)), w, &c).unwrap();
    assert_eq!(a.target, Some(pt(100.0, 200.0)));
    let a = Ask::from_voice(Command::Turn, None, w, &c).unwrap();
    let t = a.target.unwrap();
    assert!(
        (t.x_mm + 2500.0).abs() < 1e-3 && t.y_mm.abs() < 1e-3,
        "{t:?}"
    );
    assert_eq!(
        Ask::from_voice(Command::Turn, None, None, &c)
            .unwrap()
            .target,
        None
    );
    assert_eq!(
        Ask::from_voice(Command::ClearBall, None, w, &c)
            .unwrap()
            .body,
        NaoBody::Spazza
    );
    assert_eq!(
        Ask::from_voice(Command::LookRight, None, w, &c)
            .unwrap()
            .head,
        NaoHead::LookRight
    );
    for not_robot in [Command::Yes, Command::No, Command::None, Command::TouchBall] {
        assert_eq!(Ask::from_voice(not_robot, None, w, &c), None);
    }
}

#[test]
fn memory_resumes_an_unfinished_command_and_tracks_last_seen_times() {
    let c = cfg();
    let mut m = Memory::default();
    let ask = go_to(-1000.0, 1000.0);
    let cmd = ask.command();
    m.sent(&ask, &cmd, 10.0);
    let mut w = playing().world.unwrap();
    w.ball_age_s = 1.5;
    w.obstacles = vec![
        TrackedObstacle {
            age_s: 3.0,
            ..Default::default()
        },
        TrackedObstacle {
            age_s: 0.5,
            ..Default::default()
        },
    ];
    m.observe(&w, 20.0, &c);
    assert_eq!(m.ball_age(21.0), Some(2.5));
    assert_eq!(m.obstacle_age(21.0), Some(1.5));
    assert_eq!(m.obstacles_tracked, 2);
    assert_eq!(m.to_resume(), Some(ask.clone()));
    // A head command keeps the body command.
    let head = Ask {
        head: NaoHead::LookLeft,
        ..Ask::body(NaoBody::Keep, "voice")
    };
    m.sent(&head, &head.command(), 21.0);
    let r = m.to_resume().unwrap();
    assert_eq!((r.body, r.head), (NaoBody::GoToPosition, NaoHead::LookLeft));
    // Arrived: done, nothing to resume.
    w.robots[0].pose.x_mm = -1100.0;
    w.robots[0].pose.y_mm = 900.0;
    m.observe(&w, 30.0, &c);
    assert!(m.last_done);
    assert_eq!(m.to_resume(), None);
    // A pass is done once the ball rolls fast.
    let pass = Ask::body(NaoBody::Pass, "voice");
    m.sent(&pass, &pass.command(), 31.0);
    assert!(!m.last_done);
    w.ball_velocity = pt(1500.0, 200.0);
    m.observe(&w, 32.0, &c);
    assert!(m.last_done);
    // A dribble never is.
    let d = Ask::body(NaoBody::GoToBallAndDribble, "voice");
    m.sent(&d, &d.command(), 33.0);
    m.observe(&w, 34.0, &c);
    assert_eq!(m.to_resume(), Some(d));
}
