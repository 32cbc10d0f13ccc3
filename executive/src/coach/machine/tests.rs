#![allow(clippy::unwrap_used)]
//! The coach machine driven by messages on a virtual clock.

use super::*;
use crate::state_file::Record;
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

// ----- restarts ---------------------------------------------------------------------------

/// A new game taken up from `g`'s record, as a restarted process does (through the JSON on
/// disk), and told at `now` that the bridge listens.
fn restarted(g: &CoachGame, now: Duration) -> (CoachGame, Outcome) {
    let record = resume::Resume::from_json(&g.resume_record().to_json()).unwrap();
    assert_eq!(record, g.resume_record());
    let mut h = CoachGame::new(CoachSettings::default()).unwrap();
    let mut o = h.resume(&record, now);
    assert_eq!(o.steps[0].active, [state::WAITING], "a fresh machine");
    o.extend(h.bridge(true, now));
    h.delivered();
    (h, o)
}

fn penalised() -> GameState {
    let mut g = game(GameState::PLAYING);
    g.our_team.players[1].penalty = 4;
    g
}

fn logged(o: &Outcome, kind: &str) -> Vec<String> {
    o.outputs
        .iter()
        .filter_map(|x| match x {
            Output::Log(l) if l.kind == kind => Some(l.text.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_restarted_coach_keeps_the_command_under_way_and_does_not_send_it_again() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    let r = g.resume_record();
    assert_eq!(r.mode, state::PLAYING);
    assert_eq!(r.last.as_ref().unwrap().command.body, NaoBody::GoToPosition);
    assert!(!r.last.as_ref().unwrap().done);
    assert_eq!(r.undelivered.as_ref().unwrap().body, NaoBody::GoToPosition);
    g.delivered();
    assert_eq!(g.resume_record().undelivered, None);

    let (mut h, o) = restarted(&g, t(100.0));
    assert_eq!(o.said(), [say::BACK], "one line about the restart");
    assert!(o.commands().is_empty(), "the robot has it: {o:?}");
    let line = &logged(&o, "resumed")[0];
    assert!(
        line.contains("coach/playing") && line.contains("GoToPosition (under way)"),
        "{line}"
    );
    h.world_model(&world(false, true), t(100.1));
    let o = h.game_state(&game(GameState::PLAYING), t(100.2));
    assert_eq!(o.steps[0].active, [state::PLAYING]);
    assert!(o.said().is_empty() && o.commands().is_empty(), "{o:?}");
    // It knows what the robot does: the status shows it, and it is done when the robot is there.
    let s = h.status(t(100.3));
    assert!(s.has_last && !s.last_done);
    assert_eq!(s.last_command.target, FieldPoint::new(-3000.0, 2000.0));
    let mut there = world(false, true);
    there.robots[0].pose.x_mm = -2900.0;
    there.robots[0].pose.y_mm = 1950.0;
    h.world_model(&there, t(110.0));
    assert!(h.status(t(110.0)).last_done);
    // After a fall it resumes the command it took up (done: not sent again).
    let mut down = there.clone();
    down.robots[0].fallen = true;
    assert_eq!(h.world_model(&down, t(111.0)).said(), [say::FELL]);
    let o = h.world_model(&there, t(115.0));
    assert!(o.commands().is_empty(), "{o:?}");
    // A new command goes out at once.
    let o = h.command(&voice(Command::LookLeft), t(116.0));
    assert_eq!(
        o.commands()[0].head,
        interfaces::msg::nao::NaoHead::LookLeft
    );
}

/// A request or a command its sender sends again after the Executive restarted (the old process
/// may have died before acting on it, see `interfaces::outbox`) is carried out once: the stamps
/// acted on go into the record.
#[test]
fn a_request_sent_again_after_a_restart_is_carried_out_once() {
    let mut g = playing();
    let mut walk = go_to(-3000.0, 2000.0);
    walk.header.stamp_ns = 41;
    assert_eq!(g.request(&walk, t(1.0)).commands().len(), 1);
    let mut left = voice(Command::LookLeft);
    left.header.stamp_ns = 42;
    assert_eq!(g.command(&left, t(2.0)).commands().len(), 1);
    g.delivered();
    let (mut h, _) = restarted(&g, t(3.0));
    h.world_model(&world(false, true), t(3.1));
    h.game_state(&game(GameState::PLAYING), t(3.2));
    for o in [h.request(&walk, t(4.0)), h.command(&left, t(4.1))] {
        assert!(o.commands().is_empty() && o.said().is_empty(), "{o:?}");
        assert!(
            logged(&o, "heard")[0].contains("already carried out"),
            "{o:?}"
        );
    }
    // One it never acted on is carried out.
    let mut right = voice(Command::LookRight);
    right.header.stamp_ns = 43;
    assert_eq!(h.command(&right, t(5.0)).commands().len(), 1);
}

#[test]
fn a_request_kept_in_set_is_done_when_playing_starts_after_a_restart() {
    let mut g = started();
    g.game_state(&game(GameState::SET), t(1.0));
    let o = g.command(&voice(Command::AskForBall), t(1.5));
    assert_eq!(
        o.said(),
        ["I cannot ask for the ball now: the game is in SET. I will do it when we play."]
    );
    let r = g.resume_record();
    assert_eq!(r.mode, state::WAITING);
    assert_eq!(r.pending.as_ref().unwrap().body, NaoBody::AskForTheBall);

    let (mut h, o) = restarted(&g, t(50.0));
    assert_eq!(o.said(), [say::BACK]);
    assert!(o.commands().is_empty());
    let o = h.game_state(&game(GameState::SET), t(50.5));
    assert!(o.said().is_empty() && o.commands().is_empty(), "{o:?}");
    assert!(h.status(t(50.5)).has_pending);
    let o = h.game_state(&game(GameState::PLAYING), t(52.0));
    assert_eq!(o.steps[0].entered, [state::PLAYING]);
    assert_eq!(
        o.said(),
        ["We are playing. Asking my teammate for the ball."]
    );
    assert_eq!(o.commands()[0].body, NaoBody::AskForTheBall);
    assert!(!h.status(t(52.0)).has_pending);
}

#[test]
fn a_request_kept_in_set_is_done_when_playing_started_during_the_restart() {
    let mut g = started();
    g.game_state(&game(GameState::SET), t(1.0));
    g.command(&voice(Command::AskForBall), t(1.5));
    let (mut h, _) = restarted(&g, t(50.0));
    let o = h.game_state(&game(GameState::PLAYING), t(50.5));
    assert_eq!(
        o.said(),
        ["We are playing. Asking my teammate for the ball."]
    );
    assert_eq!(o.commands()[0].body, NaoBody::AskForTheBall);
}

#[test]
fn a_restarted_coach_while_penalised_does_not_say_it_again_and_resumes_after() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    g.delivered();
    assert_eq!(g.game_state(&penalised(), t(2.0)).said(), [say::PENALISED]);
    let o = g.command(&voice(Command::SearchBall), t(3.0));
    assert_eq!(
        o.said(),
        ["I cannot search for the ball now: I am penalised. I will do it when I am back."]
    );
    let r = g.resume_record();
    assert_eq!(r.mode, state::PENALISED);
    assert_eq!(r.interrupted, Some(resume::Interruption::Penalised));

    let (mut h, o) = restarted(&g, t(20.0));
    assert_eq!(o.said(), [say::BACK]);
    h.world_model(&world(false, true), t(20.1));
    let o = h.game_state(&penalised(), t(20.2));
    assert_eq!(o.steps[0].entered, [state::PENALISED]);
    assert!(o.said().is_empty(), "said again: {:?}", o.said());
    assert!(logged(&o, "resumed")[0].contains(say::PENALISED));
    // Still penalised: a motion command is refused and kept (the latest replaces it).
    let o = h.command(&voice(Command::Turn), t(21.0));
    assert!(o.said()[0].contains("I am penalised"), "{:?}", o.said());
    assert!(o.commands().is_empty());
    let o = h.game_state(&game(GameState::PLAYING), t(40.0));
    assert_eq!(o.said(), ["My penalty is over. Turning."]);
    assert_eq!(o.commands()[0].body, NaoBody::Turn);
    // A later penalty is news again.
    assert_eq!(h.game_state(&penalised(), t(50.0)).said(), [say::PENALISED]);
}

#[test]
fn a_penalty_over_during_the_restart_resumes_with_the_kept_request() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    g.game_state(&penalised(), t(2.0));
    g.command(&voice(Command::SearchBall), t(3.0));
    let (mut h, _) = restarted(&g, t(20.0));
    let o = h.game_state(&game(GameState::PLAYING), t(20.2));
    assert_eq!(o.said(), ["My penalty is over. Searching for the ball."]);
    assert_eq!(o.commands()[0].body, NaoBody::SearchTheBall);
}

#[test]
fn a_command_under_way_after_a_penalty_resumes_when_it_ends_after_a_restart() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    g.delivered();
    g.game_state(&penalised(), t(2.0));
    let (mut h, _) = restarted(&g, t(20.0));
    assert!(h.game_state(&penalised(), t(20.2)).said().is_empty());
    let o = h.game_state(&game(GameState::PLAYING), t(30.0));
    assert_eq!(
        o.said(),
        ["My penalty is over. Resuming. Going to the position."]
    );
    assert_eq!(o.commands()[0].target, FieldPoint::new(-3000.0, 2000.0));
}

#[test]
fn commands_are_held_while_no_bridge_listens_and_sent_once_one_does() {
    let mut g = playing();
    assert!(g.bridge_listening());
    let o = g.bridge(false, t(1.0));
    assert!(logged(&o, "anomaly")[0].contains("no bridge listens"));
    let o = g.request(&go_to(-3000.0, 2000.0), t(1.5));
    assert_eq!(o.said(), ["Going to the position."], "answered at once");
    assert!(o.commands().is_empty());
    assert!(logged(&o, "held")[0].contains("GoToPosition"));
    let o = g.command(&voice(Command::LookLeft), t(1.6));
    assert!(o.commands().is_empty());
    // What the robot gets when the bridge is back: both, as one command.
    let o = g.bridge(true, t(3.0));
    let c = o.commands();
    assert_eq!(c.len(), 1, "{o:?}");
    assert_eq!(
        (c[0].body, c[0].head, c[0].target),
        (
            NaoBody::GoToPosition,
            interfaces::msg::nao::NaoHead::LookLeft,
            FieldPoint::new(-3000.0, 2000.0)
        )
    );
    g.delivered();
    assert!(g.bridge(true, t(3.5)).commands().is_empty(), "sent once");
    assert_eq!(g.undelivered(), None);
}

#[test]
fn a_held_command_is_sent_by_a_restarted_coach() {
    let mut g = playing();
    g.bridge(false, t(1.0));
    g.request(&go_to(-3000.0, 2000.0), t(1.5));
    let record = g.resume_record();
    let mut h = CoachGame::new(CoachSettings::default()).unwrap();
    let o = h.resume(&record, t(10.0));
    assert!(o.commands().is_empty());
    // Held until the process knows a bridge listens.
    assert!(!h.bridge_listening());
    let o = h.bridge(true, t(10.1));
    assert_eq!(o.commands()[0].body, NaoBody::GoToPosition);
}

#[test]
fn a_command_the_process_died_sending_is_sent_again() {
    let mut g = playing();
    let o = g.request(&go_to(-3000.0, 2000.0), t(1.0));
    assert_eq!(o.commands().len(), 1);
    // Killed before it confirmed the command went out: sent again, once.
    let (_, o) = restarted(&g, t(10.0));
    assert_eq!(o.said(), [say::BACK]);
    assert_eq!(o.commands().len(), 1);
    assert_eq!(o.commands()[0].body, NaoBody::GoToPosition);
}

#[test]
fn a_link_lost_before_a_restart_is_back_with_the_first_fresh_packet() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    g.delivered();
    let lost = NaoLinkEvent {
        player_number: 2,
        change: LinkChange::RobotNotResponding,
        ..Default::default()
    };
    g.link(&lost, t(2.0));
    assert!(!g.resume_record().link_up);
    let (mut h, _) = restarted(&g, t(10.0));
    assert!(!h.status(t(10.0)).link_up);
    // Still silent (only the teammate reports): still lost.
    let mut stale = world(false, true);
    stale.robots[0].age_s = 3.0;
    let o = h.world_model(&stale, t(10.1));
    assert!(o.said().is_empty() && !h.status(t(10.1)).link_up, "{o:?}");
    let o = h.game_state(&game(GameState::PLAYING), t(10.2));
    assert_eq!(o.steps[0].active, [state::LINK_LOST]);
    assert!(o.said().is_empty(), "said again: {:?}", o.said());
    // A fresh packet: back, and the walk resumes.
    let o = h.world_model(&world(false, true), t(11.0));
    assert!(logged(&o, "anomaly")[0].contains("up again"), "{o:?}");
    assert_eq!(
        o.said(),
        ["The robot is responding again. Resuming. Going to the position."]
    );
    assert_eq!(o.commands()[0].body, NaoBody::GoToPosition);

    // Up before the restart: a late world model (a slow machine) does not make it lost; only
    // `nao/link` does, as without a restart.
    let g = playing();
    let (mut h, _) = restarted(&g, t(10.0));
    h.world_model(&stale, t(10.1));
    assert!(h.status(t(10.1)).link_up);
    let o = h.link(&lost, t(10.5));
    assert_eq!(o.said(), [say::LINK_LOST]);
}

#[test]
fn a_coach_that_was_waiting_with_nothing_asked_starts_silently() {
    let g = started();
    let (_, o) = restarted(&g, t(5.0));
    assert!(o.said().is_empty(), "{:?}", o.said());
    assert!(!logged(&o, "resumed").is_empty());
}

#[test]
fn a_record_of_another_machine_or_mode_is_refused() {
    let r = playing().resume_record();
    let json = r.to_json();
    assert!(resume::Resume::from_json(&json).is_ok());
    let e = resume::Resume::from_json(&json.replace("\"coach\"", "\"touch\"")).unwrap_err();
    assert!(e.contains("machine"), "{e}");
    let e = resume::Resume::from_json(&json.replace("coach/playing", "coach/napping")).unwrap_err();
    assert!(e.contains("no mode"), "{e}");
    assert!(resume::Resume::from_json("{}").is_err());
}

#[test]
fn a_command_published_just_before_the_bridge_went_is_sent_to_the_next_one() {
    let mut g = playing();
    let o = g.request(&go_to(-3000.0, 2000.0), t(1.0));
    assert_eq!(o.commands().len(), 1);
    g.delivered();
    // Long before the bridge went: the robot has it.
    let o = g.command(&voice(Command::LookLeft), t(5.0));
    assert_eq!(o.commands().len(), 1);
    g.delivered();
    // The bridge's going is seen 0.1 s after the last command: that one is sent again.
    g.bridge(false, t(5.1));
    let o = g.bridge(true, t(7.0));
    let c = o.commands();
    assert_eq!(c.len(), 1, "{o:?}");
    assert_eq!(
        (c[0].body, c[0].head),
        (NaoBody::Keep, interfaces::msg::nao::NaoHead::LookLeft)
    );
    g.delivered();
    // Seen 2 s after: nothing is sent again.
    g.command(&voice(Command::LookRight), t(10.0));
    g.delivered();
    g.bridge(false, t(12.0));
    assert!(g.bridge(true, t(13.0)).commands().is_empty());
}

#[test]
fn an_attack_that_ends_with_the_robot_down_resumes_nothing_in_the_next() {
    let mut g = playing();
    g.request(&go_to(-3000.0, 2000.0), t(1.0));
    g.world_model(&world(true, true), t(2.0));
    // The attack ends while the robot is down; it gets up in FINISHED, falls again in INITIAL.
    g.game_state(&game(GameState::FINISHED), t(3.0));
    g.world_model(&world(false, true), t(4.0));
    g.game_state(&game(GameState::INITIAL), t(10.0));
    g.world_model(&world(true, true), t(11.0));
    g.world_model(&world(false, true), t(12.0));
    // The next attack: nothing of the last one is sent again, nothing is said of it.
    let o = g.game_state(&game(GameState::PLAYING), t(20.0));
    assert_eq!(o.steps.last().unwrap().active, [state::PLAYING]);
    assert!(o.commands().is_empty(), "{:?}", o.commands());
    assert!(
        o.said().iter().all(|s| !s.contains("Resuming")),
        "{:?}",
        o.said()
    );
    // Within an attack, a fall still resumes the command (the interruption is the game's).
    g.request(&go_to(-2000.0, 1000.0), t(21.0));
    g.world_model(&world(true, true), t(22.0));
    let o = g.world_model(&world(false, true), t(30.0));
    assert_eq!(
        o.said(),
        ["I am up again. Resuming. Going to the position."]
    );
}
