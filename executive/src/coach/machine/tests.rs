#![allow(clippy::unwrap_used)]
//! The coach machine driven by messages on a virtual clock.

use super::*;
use interfaces::msg::command::CommandSource;
use interfaces::msg::nao::{
    FieldPoint, FieldPose, PlayerPenalty, PlayerRole, TeamRobot, TeamStatus,
};

fn t(s: f64) -> Duration {
    Duration::from_secs_f64(s)
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

fn world(fallen: bool, mate: bool) -> NaoWorldModel {
    let r = |n: u8, x: f32, y: f32| TeamRobot {
        player_number: n,
        role: PlayerRole::from_wire(17 + (n == 2) as u8),
        pose: FieldPose {
            x_mm: x,
            y_mm: y,
            theta_rad: 0.0,
        },
        fallen: n == 2 && fallen,
        age_s: 0.1,
    };
    let mut robots = vec![r(2, -1500.0, -1200.0)];
    if mate {
        robots.push(r(1, -600.0, 0.0));
    }
    NaoWorldModel {
        robots,
        ball_known: true,
        ball: FieldPoint {
            x_mm: 0.0,
            y_mm: 0.0,
        },
        ball_age_s: 0.2,
        ..Default::default()
    }
}

fn voice(c: Command) -> GameCommand {
    GameCommand {
        game: Game::Coach,
        command: c,
        source: CommandSource::Voice,
        text: c.phrase().into(),
        confidence: 0.9,
        ..Default::default()
    }
}

fn go_to(x: f32, y: f32) -> CoachRequest {
    CoachRequest {
        command: NaoCommand {
            body: NaoBody::GoToPosition,
            target: FieldPoint { x_mm: x, y_mm: y },
            source: "panel".into(),
            ..Default::default()
        },
        ..Default::default()
    }
}

fn started() -> CoachGame {
    let mut g = CoachGame::new(CoachSettings::default()).unwrap();
    let o = g.start(t(0.0));
    assert_eq!(o.steps[0].active, [state::WAITING]);
    g.world_model(&world(false, true), t(0.1));
    g
}

fn playing() -> CoachGame {
    let mut g = started();
    let o = g.game_state(&game(GameState::PLAYING), t(0.2));
    assert_eq!(o.steps.last().unwrap().active, [state::PLAYING]);
    g
}

#[test]
fn the_definition_is_valid_and_draws() {
    let d = definition(&CoachSettings::default()).unwrap();
    assert_eq!(
        d.state_paths(),
        [
            state::COACH,
            state::WAITING,
            state::PLAYING,
            state::ROBOT_DOWN,
            state::PENALISED,
            state::LINK_LOST
        ]
    );
    let m = d.mermaid();
    assert!(m.contains("route = robot_down"), "{m}");
}

#[test]
fn a_command_is_answered_before_it_is_sent() {
    let mut g = playing();
    let o = g.request(&go_to(-1000.0, 1000.0), t(1.0));
    let say = o
        .outputs
        .iter()
        .position(|x| matches!(x, Output::Say { .. }))
        .unwrap();
    let cmd = o
        .outputs
        .iter()
        .position(|x| matches!(x, Output::Command(_)))
        .unwrap();
    assert!(say < cmd, "{o:?}");
    assert_eq!(o.said(), ["Going to the position."]);
    assert_eq!(o.commands()[0].body, NaoBody::GoToPosition);
    assert_eq!(o.steps[0].event, "request:go_to_position");
    assert!(!o.steps[0].ignored);
    assert_eq!(
        g.memory().clicked,
        Some(FieldPoint {
            x_mm: -1000.0,
            y_mm: 1000.0
        })
    );
    // "go to position" by voice goes where the panel clicked.
    let o = g.command(&voice(Command::GoToPosition), t(2.0));
    assert_eq!(
        o.commands()[0].target,
        FieldPoint {
            x_mm: -1000.0,
            y_mm: 1000.0
        }
    );
}

#[test]
fn motion_in_set_is_refused_spoken_and_done_when_playing_starts() {
    let mut g = started();
    g.game_state(&game(GameState::SET), t(1.0));
    assert_eq!(g.mode(), state::WAITING);
    let o = g.command(&voice(Command::GoToBallAndDribble), t(1.5));
    assert!(o.commands().is_empty());
    assert_eq!(
        o.said(),
        ["I cannot go to the ball and dribble now: the game is in SET. I will do it when we play."]
    );
    assert!(g.status(t(1.5)).has_pending);
    // Looking is allowed in SET.
    let o = g.command(&voice(Command::LookLeft), t(1.6));
    assert_eq!(
        o.commands()[0].head,
        interfaces::msg::nao::NaoHead::LookLeft
    );
    // PLAYING: the kept request is done, said first.
    let o = g.game_state(&game(GameState::PLAYING), t(3.0));
    assert_eq!(o.steps[0].event, "game:playing");
    assert_eq!(o.steps[0].entered, [state::PLAYING]);
    assert_eq!(o.said(), ["We are playing. Going to the ball to dribble."]);
    assert_eq!(o.commands()[0].body, NaoBody::GoToBallAndDribble);
    assert!(!g.status(t(3.0)).has_pending);
}

#[test]
fn a_pass_without_teammate_becomes_a_dribble() {
    let mut g = playing();
    g.world_model(&world(false, false), t(1.0));
    let o = g.command(&voice(Command::Pass), t(1.1));
    assert_eq!(
        o.said(),
        ["I see no teammate to pass to: I will go to the ball and dribble."]
    );
    assert_eq!(o.commands()[0].body, NaoBody::GoToBallAndDribble);
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::Log(l) if l.kind == "replaced"))
    );
}

#[test]
fn a_kick_towards_our_goal_is_refused_and_nothing_is_sent() {
    let mut g = playing();
    let r = CoachRequest {
        command: NaoCommand {
            body: NaoBody::Kick,
            ..Default::default()
        },
        aimed: true,
        aim: FieldPoint {
            x_mm: -4500.0,
            y_mm: 0.0,
        },
        ..Default::default()
    };
    let o = g.request(&r, t(1.0));
    assert!(o.commands().is_empty());
    assert_eq!(o.said(), ["I will not kick towards our own goal."]);
    assert!(!g.status(t(1.0)).has_pending);
}

#[test]
fn after_a_fall_the_last_command_resumes() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    let o = g.world_model(&world(true, true), t(2.0));
    assert_eq!(o.steps[0].event, "robot:fell");
    assert_eq!(o.steps[0].active, [state::ROBOT_DOWN]);
    assert_eq!(o.said(), [say::FELL]);
    // Still down after 20 s: said once.
    let o = g.advance(t(22.5));
    assert_eq!(o.said(), [say::STILL_DOWN]);
    assert!(g.advance(t(60.0)).said().is_empty());
    let o = g.world_model(&world(false, true), t(61.0));
    assert_eq!(o.steps[0].event, "robot:up");
    assert_eq!(o.steps[0].active, [state::PLAYING]);
    assert_eq!(
        o.said(),
        ["I am up again. Resuming. Going to the position."]
    );
    assert_eq!(
        o.commands()[0].target,
        FieldPoint {
            x_mm: -3000.0,
            y_mm: 2000.0
        }
    );
}

#[test]
fn a_command_given_while_down_is_the_one_done_when_up() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    g.world_model(&world(true, true), t(2.0));
    let o = g.command(&voice(Command::SearchBall), t(3.0));
    assert_eq!(
        o.said(),
        ["I am on the ground. I will search for the ball when I am up."]
    );
    assert!(o.commands().is_empty());
    let o = g.world_model(&world(false, true), t(8.0));
    assert_eq!(o.said(), ["I am up again. Searching for the ball."]);
    assert_eq!(o.commands()[0].body, NaoBody::SearchTheBall);
}

#[test]
fn a_finished_command_is_not_resumed() {
    let mut g = playing();
    g.request(&go_to(-1500.0, -1100.0), t(1.0));
    // The robot is there (within 300 mm): done.
    g.world_model(&world(false, true), t(1.5));
    assert!(g.status(t(1.5)).last_done);
    g.world_model(&world(true, true), t(2.0));
    let o = g.world_model(&world(false, true), t(8.0));
    assert!(o.commands().is_empty(), "{o:?}");
}

#[test]
fn a_penalty_and_a_lost_link_interrupt_and_resume() {
    let mut g = playing();
    g.command(&voice(Command::GoToBallAndDribble), t(1.0));
    let mut pen = game(GameState::PLAYING);
    pen.our_team.players[1].penalty = 4;
    let o = g.game_state(&pen, t(2.0));
    assert_eq!(o.steps[0].event, "penalty:on");
    assert_eq!(o.steps[0].active, [state::PENALISED]);
    assert_eq!(o.said(), [say::PENALISED]);
    let o = g.game_state(&game(GameState::PLAYING), t(30.0));
    assert_eq!(o.steps[0].event, "penalty:off");
    assert_eq!(
        o.said(),
        ["My penalty is over. Resuming. Going to the ball to dribble."]
    );

    let lost = NaoLinkEvent {
        player_number: 2,
        change: LinkChange::RobotNotResponding,
        ..Default::default()
    };
    let o = g.link(&lost, t(31.0));
    assert_eq!(o.steps[0].active, [state::LINK_LOST]);
    assert_eq!(o.said(), [say::LINK_LOST]);
    // A request while lost is kept and sent when the link is back.
    let o = g.command(&voice(Command::Pass), t(32.0));
    assert!(o.commands().is_empty());
    // The teammate's link is not ours.
    let other = NaoLinkEvent {
        player_number: 1,
        change: LinkChange::Restored,
        ..Default::default()
    };
    assert!(
        g.link(&other, t(33.0))
            .steps
            .iter()
            .all(|s| s.ignored || s.entered.is_empty())
    );
    let o = g.advance(t(41.5));
    assert_eq!(o.said(), [say::STILL_LOST]);
    let back = NaoLinkEvent {
        player_number: 2,
        change: LinkChange::Restored,
        ..Default::default()
    };
    let o = g.link(&back, t(45.0));
    assert_eq!(o.steps[0].event, "link:restored");
    assert_eq!(
        o.said(),
        ["The robot is responding again. Passing to my teammate."]
    );
    assert_eq!(o.commands()[0].body, NaoBody::Pass);
}

#[test]
fn the_other_games_commands_and_answers_are_ignored() {
    let mut g = playing();
    let mut c = voice(Command::TouchBall);
    c.game = Game::Touch;
    let o = g.command(&c, t(1.0));
    assert!(o.commands().is_empty() && o.said().is_empty());
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::Log(l) if l.kind == "anomaly"))
    );
    let o = g.command(&voice(Command::Yes), t(1.1));
    assert!(o.commands().is_empty() && o.said().is_empty());
    assert!(
        !o.outputs
            .iter()
            .any(|x| matches!(x, Output::Log(l) if l.kind == "anomaly"))
    );
}

#[test]
fn status_shows_memory_and_last_seen_times() {
    let mut g = playing();
    let mut w = world(false, true);
    w.ball_age_s = 1.0;
    g.world_model(&w, t(10.0));
    let s = g.status(t(12.0));
    assert_eq!(s.state, state::PLAYING);
    assert!((s.ball_last_seen_s - 3.0).abs() < 1e-9, "{s:?}");
    assert_eq!(s.obstacle_last_seen_s, -1.0);
    assert!(s.link_up && !s.fallen && !s.penalised && s.game_known);
}
