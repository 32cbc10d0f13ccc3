//! The touch-the-ball machine on a virtual clock: scripted inputs, asserted outputs.

use super::*;
use crate::state_file::Record;
use interfaces::msg::body::ReachKind;
use interfaces::msg::command::CommandSource;

fn t(s: f64) -> Duration {
    Duration::from_secs_f64(s)
}

fn cmd(c: Command) -> GameCommand {
    GameCommand {
        game: Game::Touch,
        command: c,
        source: CommandSource::Voice,
        text: c.phrase().to_string(),
        confidence: 0.9,
        ..Default::default()
    }
}

fn ball(kind: BallEventKind) -> BallEvent {
    BallEvent {
        kind,
        ..Default::default()
    }
}

fn track(p: [f64; 3]) -> BallTrack {
    BallTrack {
        found: true,
        has_centre_m: true,
        centre_m: [0.0, 0.2, 0.6],
        has_centre_world: true,
        centre_world_m: p,
        ..Default::default()
    }
}

fn status(id: u64, state: ReachState) -> ReachStatus {
    ReachStatus {
        id,
        body_part: "left_arm_7".into(),
        state,
        distance_m: 0.01,
        ..Default::default()
    }
}

/// A game with the default settings, started at t = 0.
fn game() -> TouchGame {
    let mut g = TouchGame::new(TouchSettings::default()).unwrap();
    let o = g.start(t(0.0));
    assert_eq!(o.steps[0].active, [state::WAITING]);
    g
}

fn active(g: &TouchGame) -> Vec<String> {
    g.machine().active_leaves()
}

fn reaches(o: &Outcome) -> Vec<&ReachGoal> {
    o.outputs
        .iter()
        .filter_map(|x| match x {
            Output::Reach(r) => Some(r),
            _ => None,
        })
        .collect()
}

fn cancels(o: &Outcome) -> Vec<&ReachGoal> {
    o.outputs
        .iter()
        .filter_map(|x| match x {
            Output::CancelReach(r) => Some(r),
            _ => None,
        })
        .collect()
}

fn homes(o: &Outcome) -> Vec<&JointGoal> {
    o.outputs
        .iter()
        .filter_map(|x| match x {
            Output::Home(j) => Some(j),
            _ => None,
        })
        .collect()
}

/// Played until the ball is tracked (t = 3 s); returns the follow-gaze goal.
fn tracking() -> TouchGame {
    let mut g = game();
    g.command(&cmd(Command::Play), t(1.0));
    g.command(&cmd(Command::ScanBall), t(2.0));
    g.ball_track(&track([0.6, 0.1, 0.78]), t(2.9));
    g.ball_event(&ball(BallEventKind::Detected), t(3.0));
    assert!(active(&g).contains(&state::TRACKING.to_string()));
    g
}

/// Tracking, then "touch it" at t = 4 s; returns the arm goal's id.
fn reaching() -> (TouchGame, u64) {
    let mut g = tracking();
    let o = g.command(&cmd(Command::TouchBall), t(4.0));
    let r = reaches(&o);
    assert_eq!(r.len(), 1, "{o:?}");
    (g, r[0].id)
}

#[test]
fn the_person_greets_and_asks_to_play_and_the_robot_answers() {
    let mut g = game();
    let o = g.command(&cmd(Command::Greet), t(1.0));
    assert_eq!(o.said(), [say::GREETING]);
    assert_eq!(active(&g), [state::WAITING]);
    assert!(
        matches!(&o.outputs[0], Output::Log(l) if l.kind == "heard" && l.text.contains("hello"))
    );
    let o = g.command(&cmd(Command::Play), t(2.0));
    assert_eq!(o.said(), [say::PLAY_ACK]);
    assert_eq!(active(&g), [state::RESTING, state::EYES_IDLE]);
    assert_eq!(o.steps[0].entered[0], state::PLAYING);
    // Greeting again while playing still works; playing again is explained.
    assert_eq!(
        g.command(&cmd(Command::Greet), t(3.0)).said(),
        [say::GREETING]
    );
    assert_eq!(
        g.command(&cmd(Command::Play), t(4.0)).said(),
        [say::ALREADY_PLAYING]
    );
}

#[test]
fn the_robot_looks_at_the_person_while_it_listens_and_at_the_ball_once_it_looks_for_it() {
    let mut g = TouchGame::new(TouchSettings::default()).unwrap();
    let face = |o: &Outcome| -> u64 {
        let r = reaches(o);
        assert_eq!(r.len(), 1, "{o:?}");
        assert_eq!(
            (
                r[0].body_part.as_str(),
                r[0].kind,
                r[0].frame.as_str(),
                r[0].follow
            ),
            ("neck", ReachKind::Gaze, "player", true)
        );
        assert_eq!(r[0].position_m, [0.0, 0.0, 1.55]);
        r[0].id
    };
    // Waiting for her: her face.
    let first = face(&g.start(t(0.0)));
    // "Let's play": still her face, with nothing to look for yet.
    let second = face(&g.command(&cmd(Command::Play), t(1.0)));
    assert!(second > first);
    // Looking for the ball: the scan takes the neck (a new gaze replaces hers).
    let o = g.command(&cmd(Command::ScanBall), t(2.0));
    let (scan, _) = scan_gaze(&o).expect("a scan gaze");
    assert!(scan > second);
    // Without a person frame the robot does not look for her.
    let mut quiet = TouchSettings::default();
    quiet.person_frame.clear();
    let mut g = TouchGame::new(quiet).unwrap();
    assert!(reaches(&g.start(t(0.0))).is_empty());
}

#[test]
fn after_a_finished_game_the_next_visitor_starts_a_new_one_with_new_goal_ids() {
    let (mut g, first_goal) = reaching();
    g.command(&cmd(Command::Quit), t(5.0));
    assert!(g.is_finished());
    // Anything but a greeting or "let's play" leaves the game over.
    g.command(&cmd(Command::TouchBall), t(6.0));
    assert!(g.is_finished());
    let o = g.command(&cmd(Command::Greet), t(7.0));
    assert!(!g.is_finished());
    assert_eq!(active(&g), [state::WAITING]);
    assert_eq!(o.said(), [say::GREETING]);
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::Log(l) if l.text.contains("new visitor"))),
        "{o:?}"
    );
    // The new game plays as the first did; its goals are numbered after the last game's.
    g.command(&cmd(Command::Play), t(8.0));
    g.command(&cmd(Command::ScanBall), t(9.0));
    g.ball_track(&track([0.6, 0.1, 0.78]), t(9.9));
    g.ball_event(&ball(BallEventKind::Detected), t(10.0));
    let o = g.command(&cmd(Command::TouchBall), t(11.0));
    let r = reaches(&o);
    assert_eq!(r.len(), 1, "{o:?}");
    assert!(r[0].id > first_goal, "{} after {first_goal}", r[0].id);
    // "Let's play" after a finished game starts one too, straight into playing.
    g.command(&cmd(Command::Stop), t(12.0));
    assert!(g.is_finished());
    let o = g.command(&cmd(Command::Play), t(13.0));
    assert_eq!(o.said(), [say::PLAY_ACK]);
    assert!(g.machine().is_active(state::PLAYING));
}

/// A status of the neck's goal `id`.
fn gaze_status(id: u64, state: ReachState) -> ReachStatus {
    ReachStatus {
        id,
        body_part: "neck".into(),
        state,
        ..Default::default()
    }
}

/// The scan gaze of an outcome (one at most), as (goal id, point).
fn scan_gaze(o: &Outcome) -> Option<(u64, [f64; 3])> {
    let r = reaches(o);
    assert!(r.len() <= 1, "{o:?}");
    r.first().map(|g| {
        assert_eq!(
            (g.body_part.as_str(), g.kind, g.frame.as_str(), g.follow),
            ("neck", ReachKind::Gaze, "world", false)
        );
        (g.id, g.position_m)
    })
}

/// Played and asked to scan at t = 2 s; returns the first scan gaze's id.
fn scanning() -> (TouchGame, u64) {
    let mut g = game();
    g.command(&cmd(Command::Play), t(1.0));
    let o = g.command(&cmd(Command::ScanBall), t(2.0));
    let (id, p) = scan_gaze(&o).expect("a scan gaze");
    assert_eq!(p, TouchSettings::default().scan_pattern()[0]);
    (g, id)
}

#[test]
fn scan_sends_the_target_and_looks_first_where_people_hold_a_ball_up() {
    let mut g = game();
    g.command(&cmd(Command::Play), t(1.0));
    let o = g.command(&cmd(Command::ScanBall), t(2.0));
    let target = o
        .outputs
        .iter()
        .find_map(|x| match x {
            Output::SetBallTarget(b) => Some(b.clone()),
            _ => None,
        })
        .expect("a target");
    assert!(target.active);
    assert_eq!(
        (target.hue_deg, target.saturation, target.diameter_m),
        (51.7, 0.85, 0.07)
    );
    assert_eq!(o.said(), [say::LOOKING]);
    // The target goes out before the head turns: the tracker looks during the first turn.
    let target_at = o
        .outputs
        .iter()
        .position(|x| matches!(x, Output::SetBallTarget(_)))
        .unwrap();
    let gaze_at = o
        .outputs
        .iter()
        .position(|x| matches!(x, Output::Reach(_)))
        .unwrap();
    assert!(target_at < gaze_at);
    // First: in front of the touching (left) arm, at chest height, at arm's length.
    let (_, p) = scan_gaze(&o).unwrap();
    assert_eq!(p, [0.50, 0.15, 1.25]);
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
}

#[test]
fn the_head_goes_on_to_the_next_point_once_there_and_held_still_a_moment() {
    let s = TouchSettings::default();
    let points = s.scan_pattern();
    let (mut g, id) = scanning();
    // "Moving" is not "there"; a status of another goal is not this one's.
    g.reach_status(&gaze_status(id, ReachState::Moving), t(2.1));
    g.reach_status(&gaze_status(id + 100, ReachState::Reached), t(2.2));
    // No dwell timer while the head turns: nothing before the neck is there (within the
    // move's time-out, 3 s).
    assert!(scan_gaze(&g.advance(t(4.99))).is_none());
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
    // There at 4.99 s: held still for scan_dwell_s (0.3 s), then the next point, not before.
    let o = g.reach_status(&gaze_status(id, ReachState::Reached), t(4.99));
    assert!(scan_gaze(&o).is_none());
    assert_eq!(active(&g), [state::RESTING, state::HOLDING]);
    assert!(scan_gaze(&g.advance(t(5.289))).is_none());
    let o = g.advance(t(5.29));
    assert_eq!(o.steps[0].event, "timer:dwell");
    let (id2, p) = scan_gaze(&o).unwrap();
    assert_eq!(p, points[1]);
    assert_ne!(id2, id);
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
    // The whole pattern at that pace, then again from its first point.
    let mut now = 5.29;
    let mut id = id2;
    let mut seen = vec![points[0], points[1]];
    for _ in 0..points.len() {
        now += 0.5;
        g.reach_status(&gaze_status(id, ReachState::Reached), t(now));
        now += s.scan_dwell_s;
        let (next, p) = scan_gaze(&g.advance(t(now))).unwrap();
        id = next;
        seen.push(p);
    }
    assert_eq!(seen[..points.len()], points[..]);
    assert_eq!(seen[points.len()..], points[..2]);
}

#[test]
fn a_neck_that_cannot_get_there_or_says_nothing_does_not_stop_the_scan() {
    let s = TouchSettings::default();
    let points = s.scan_pattern();
    let (mut g, id) = scanning();
    // Unreachable: held a moment where it is, then the next point.
    g.reach_status(&gaze_status(id, ReachState::Unreachable), t(2.05));
    assert_eq!(active(&g), [state::RESTING, state::HOLDING]);
    let (id, p) = scan_gaze(&g.advance(t(2.35))).unwrap();
    assert_eq!(p, points[1]);
    // Failed: the same.
    g.reach_status(&gaze_status(id, ReachState::Failed), t(3.0));
    let (_, p) = scan_gaze(&g.advance(t(3.3))).unwrap();
    assert_eq!(p, points[2]);
    // Silence: the next point after scan_move_timeout_s (3 s), exactly.
    assert!(scan_gaze(&g.advance(t(6.299))).is_none());
    let o = g.advance(t(6.3));
    assert_eq!(o.steps[0].event, "timer:scan");
    assert_eq!(scan_gaze(&o).unwrap().1, points[3]);
}

#[test]
fn a_ball_detected_while_the_head_turns_ends_the_search_at_once() {
    let (mut g, id) = scanning();
    // Half-way through the first turn, no "reached" yet.
    g.reach_status(&gaze_status(id, ReachState::Moving), t(2.1));
    g.ball_track(&track([0.45, 0.3, 1.2]), t(2.39));
    let o = g.ball_event(&ball(BallEventKind::Detected), t(2.4));
    let r = reaches(&o);
    assert_eq!(r.len(), 1);
    assert_eq!(
        (r[0].body_part.as_str(), r[0].kind, r[0].frame.as_str()),
        ("neck", ReachKind::Gaze, "ball")
    );
    assert!(r[0].follow && r[0].active);
    assert_eq!(o.said(), [say::SEE_IT]);
    assert_eq!(active(&g), [state::RESTING, state::TRACKING]);
    // No more scanning once tracking: no timer, and the old goal's "reached" changes nothing.
    assert!(g.next_deadline().is_none());
    let o = g.reach_status(&gaze_status(id, ReachState::Reached), t(2.8));
    assert!(reaches(&o).is_empty());
    assert!(reaches(&g.advance(t(20.0))).is_empty());
    assert_eq!(active(&g), [state::RESTING, state::TRACKING]);
}

#[test]
fn a_ball_detected_while_the_head_holds_still_ends_the_search_too() {
    let (mut g, id) = scanning();
    g.reach_status(&gaze_status(id, ReachState::Reached), t(2.7));
    assert_eq!(active(&g), [state::RESTING, state::HOLDING]);
    let o = g.ball_event(&ball(BallEventKind::Detected), t(2.8));
    assert_eq!(o.said(), [say::SEE_IT]);
    assert_eq!(active(&g), [state::RESTING, state::TRACKING]);
    assert!(g.next_deadline().is_none());
}

#[test]
fn every_search_starts_again_where_people_hold_a_ball_up() {
    let points = TouchSettings::default().scan_pattern();
    let (mut g, id) = scanning();
    // Three points into the first search.
    g.reach_status(&gaze_status(id, ReachState::Reached), t(2.5));
    let (id, _) = scan_gaze(&g.advance(t(2.8))).unwrap();
    g.reach_status(&gaze_status(id, ReachState::Reached), t(3.3));
    let (_, p) = scan_gaze(&g.advance(t(3.6))).unwrap();
    assert_eq!(p, points[2]);
    g.ball_event(&ball(BallEventKind::Detected), t(4.0));
    // Lost: the new search starts at the first point, not the fourth.
    let o = g.ball_event(&ball(BallEventKind::Lost), t(6.0));
    assert_eq!(o.said(), [say::LOST, say::LOOKING]);
    assert_eq!(scan_gaze(&o).unwrap().1, points[0]);
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
}

#[test]
fn a_scan_configured_for_the_right_arm_starts_on_its_side() {
    let s = TouchSettings {
        arm: "right_arm_7".into(),
        ..TouchSettings::default()
    };
    let mut g = TouchGame::new(s).unwrap();
    g.start(t(0.0));
    let o = g.command(&cmd(Command::ScanBall), t(1.0));
    assert_eq!(scan_gaze(&o).unwrap().1, [0.50, -0.15, 1.25]);
}

#[test]
fn scan_before_play_starts_the_game_and_track_is_a_synonym() {
    let mut g = game();
    let o = g.command(&cmd(Command::TrackBall), t(1.0));
    assert_eq!(o.said(), [say::LOOKING]);
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
    assert_eq!(
        g.command(&cmd(Command::ScanBall), t(2.0)).said(),
        [say::ALREADY_LOOKING]
    );
}

#[test]
fn touch_reaches_the_ball_and_goes_home_when_told_it_touched_it() {
    let mut g = tracking();
    let o = g.command(&cmd(Command::TouchBall), t(4.0));
    assert_eq!(o.said(), [say::GOING_TO_TOUCH]);
    let r = reaches(&o);
    assert_eq!(r.len(), 1);
    let goal = r[0].clone();
    // The joints the rest posture took are given back first.
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::Release(j) if j.release && j.client == "executive"))
    );
    assert_eq!(goal.body_part, "left_arm_7");
    assert_eq!(goal.kind, ReachKind::Position);
    assert_eq!(goal.frame, "ball");
    assert_eq!(goal.position_m, [-0.03, 0.0, 0.0]);
    assert_eq!(goal.tolerance_m, 0.02);
    assert!(goal.follow && goal.active);
    assert_eq!(goal.client, "executive");
    assert_eq!(active(&g), [state::MOVING, state::TRACKING]);

    // Moving status: nothing said. Reached: said.
    assert!(
        g.reach_status(&status(goal.id, ReachState::Moving), t(4.5))
            .said()
            .is_empty()
    );
    let o = g.reach_status(&status(goal.id, ReachState::Reached), t(6.0));
    assert_eq!(o.said(), [say::TOUCHING]);
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::Log(l) if l.kind == "reach" && l.distance_m == 0.01))
    );
    assert_eq!(active(&g), [state::TOUCHING, state::TRACKING]);

    let o = g.command(&cmd(Command::YouTouchedIt), t(7.0));
    assert_eq!(o.said(), [say::THANKS]);
    // The reach is cancelled before the joint goal (IK first releases the joints).
    let cancel_at = o
        .outputs
        .iter()
        .position(|x| matches!(x, Output::CancelReach(_)))
        .unwrap();
    let home_at = o
        .outputs
        .iter()
        .position(|x| matches!(x, Output::Home(_)))
        .unwrap();
    assert!(cancel_at < home_at);
    let c = cancels(&o);
    assert_eq!(
        (c[0].body_part.as_str(), c[0].id, c[0].active),
        ("left_arm_7", goal.id, false)
    );
    let h = homes(&o);
    assert_eq!(h.len(), 1);
    assert_eq!(
        (h[0].client.as_str(), h[0].priority, h[0].release),
        ("executive", 10, false)
    );
    let joints: Vec<&str> = h[0].targets.iter().map(|j| j.joint.as_str()).collect();
    assert_eq!(joints, crate::settings::LEFT_ARM_JOINTS);
    assert!(h[0].targets.iter().all(|j| j.max_speed > 0.0));
    let elbow = h[0]
        .targets
        .iter()
        .find(|j| j.joint == "left_elbow")
        .unwrap();
    assert_eq!(elbow.position, -0.15, "joint_motor's rest posture");
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
    // The neck keeps following the ball the whole time.
    assert!(cancels(&o).iter().all(|c| c.body_part != "neck"));

    // Home after homing_s (2 s), then another touch is a fresh reach with a new id.
    g.advance(t(9.0));
    assert_eq!(active(&g), [state::RESTING, state::TRACKING]);
    let o = g.command(&cmd(Command::TouchBall), t(10.0));
    assert!(reaches(&o)[0].id > goal.id);
}

#[test]
fn the_courtesy_delay_sends_the_arm_home_exactly_after_the_delay() {
    let (mut g, id) = reaching();
    g.reach_status(&status(id, ReachState::Reached), t(10.0));
    assert_eq!(g.next_deadline(), Some(t(15.0)));
    let o = g.advance(t(14.999));
    assert!(o.outputs.is_empty() && o.steps.is_empty());
    assert_eq!(active(&g), [state::TOUCHING, state::TRACKING]);
    let o = g.advance(t(15.0));
    assert_eq!(o.steps.len(), 1);
    assert_eq!(o.steps[0].event, "timer:courtesy");
    assert_eq!(o.said(), [say::COURTESY]);
    assert_eq!(cancels(&o)[0].id, id);
    assert_eq!(homes(&o).len(), 1);
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
}

#[test]
fn the_courtesy_delay_counts_from_the_robots_last_word() {
    let (mut g, id) = reaching();
    g.reach_status(&status(id, ReachState::Reached), t(10.0));
    // Another component talks (the dialog: "I can't hear you for a moment") from 13 s to 19 s:
    // the person, who waits for the robot to finish, has not had her 5 s yet.
    assert!(g.speaking(true, t(13.0)).said().is_empty());
    assert!(g.advance(t(18.5)).said().is_empty());
    let o = g.speaking(false, t(19.0));
    assert!(
        o.said().is_empty(),
        "re-entering touching says nothing: {o:?}"
    );
    assert_eq!(active(&g), [state::TOUCHING, state::TRACKING]);
    assert_eq!(g.next_deadline(), Some(t(24.0)));
    // Her answer in that time is taken.
    let o = g.command(&cmd(Command::YouTouchedIt), t(22.0));
    assert_eq!(o.said(), [say::THANKS]);
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
    // Sentences while not touching change nothing.
    let before = g.next_deadline();
    let o = g.speaking(false, t(22.5));
    assert!(o.steps.is_empty() && o.outputs.is_empty(), "{o:?}");
    assert_eq!(g.next_deadline(), before);
}

#[test]
fn the_courtesy_delay_still_runs_out_after_a_silent_while() {
    let (mut g, id) = reaching();
    g.reach_status(&status(id, ReachState::Reached), t(10.0));
    // "I'm touching the ball." from 10 s to 11.5 s; then the person says nothing.
    g.speaking(true, t(10.0));
    g.speaking(false, t(11.5));
    assert!(g.advance(t(16.4)).said().is_empty());
    assert_eq!(g.advance(t(16.5)).said(), [say::COURTESY]);
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
    // The talk's progress reports map onto talking and silent.
    let ev = |state| SpeakingEvent {
        state,
        ..SpeakingEvent::default()
    };
    assert_eq!(talking(&ev(SpeakingState::Started)), Some(true));
    assert_eq!(talking(&ev(SpeakingState::Interrupted)), Some(false));
    assert_eq!(talking(&ev(SpeakingState::Dropped)), None);
}

#[test]
fn a_configured_courtesy_delay_is_used() {
    let s = TouchSettings {
        courtesy_delay_s: 2.0,
        ..TouchSettings::default()
    };
    let mut g = TouchGame::new(s).unwrap();
    g.start(t(0.0));
    g.command(&cmd(Command::ScanBall), t(1.0));
    g.ball_event(&ball(BallEventKind::Detected), t(2.0));
    let id = reaches(&g.command(&cmd(Command::TouchBall), t(3.0)))[0].id;
    g.reach_status(&status(id, ReachState::Reached), t(4.0));
    assert!(g.advance(t(5.99)).said().is_empty());
    assert_eq!(g.advance(t(6.0)).said(), [say::COURTESY]);
}

#[test]
fn the_ball_moved_while_reaching_is_followed_and_said() {
    let (mut g, id) = reaching();
    g.reach_status(&status(id, ReachState::Reached), t(5.0));
    // A small move (4 cm) is noise.
    assert!(
        g.ball_track(&track([0.6, 0.14, 0.78]), t(6.0))
            .said()
            .is_empty()
    );
    assert_eq!(active(&g), [state::TOUCHING, state::TRACKING]);
    // 15 cm: following; the reach goal itself follows the ball (no new goal needed).
    let o = g.ball_track(&track([0.6, 0.25, 0.78]), t(7.0));
    assert_eq!(o.said(), [say::FOLLOWING]);
    assert!(reaches(&o).is_empty());
    assert_eq!(active(&g), [state::FOLLOWING, state::TRACKING]);
    // While following, the courtesy timer is off.
    assert!(g.advance(t(20.0)).said().is_empty());
    assert_eq!(
        g.reach_status(&status(id, ReachState::Reached), t(21.0))
            .said(),
        [say::TOUCHING]
    );
    assert_eq!(g.next_deadline(), Some(t(26.0)));
    // "Touch it" again: a fresh goal (Fig. 6).
    let o = g.command(&cmd(Command::TouchBall), t(22.0));
    assert_eq!(o.said(), [say::GOING_TO_TOUCH]);
    assert!(reaches(&o)[0].id > id);
    assert_eq!(active(&g), [state::MOVING, state::TRACKING]);
}

#[test]
fn a_ball_out_of_the_arms_reach_turns_the_base_then_one_out_of_both_is_explained() {
    let (mut g, id) = reaching();
    // The arm alone cannot: its goal is cancelled, the robot says it turns, and the arm and the
    // base reach together.
    let o = g.reach_status(&status(id, ReachState::Unreachable), t(5.0));
    assert_eq!(o.said(), [say::TURNING]);
    let c = cancels(&o);
    assert_eq!((c[0].id, c[0].body_part.as_str()), (id, "left_arm_7"));
    let r = reaches(&o);
    assert_eq!(r.len(), 1, "{o:?}");
    assert_eq!(r[0].body_part, "left_arm_9");
    assert!(r[0].follow && r[0].id > id);
    assert!(homes(&o).is_empty());
    assert_eq!(active(&g), [state::MOVING, state::TRACKING]);
    let with_base = r[0].id;
    // The old goal's status is no longer this reach's business.
    let o = g.reach_status(&status(id, ReachState::Unreachable), t(5.5));
    assert!(o.steps.is_empty() && o.said().is_empty(), "{o:?}");
    // Out of reach of both: explained once, and the arm and the base go home.
    let o = g.reach_status(&status(with_base, ReachState::Unreachable), t(6.0));
    assert_eq!(o.said(), [say::CANT_REACH]);
    assert!(matches!(
        o.outputs.iter().find(|x| matches!(x, Output::Say { .. })),
        Some(Output::Say {
            priority: Priority::High,
            ..
        })
    ));
    let c = cancels(&o);
    assert_eq!(
        (c[0].id, c[0].body_part.as_str()),
        (with_base, "left_arm_9")
    );
    let home = homes(&o);
    assert_eq!(home.len(), 1);
    let joints: Vec<&str> = home[0].targets.iter().map(|t| t.joint.as_str()).collect();
    assert!(
        joints.contains(&"left_elbow") && joints.contains(&"base_yaw"),
        "{joints:?}"
    );
    assert!(joints.contains(&"base_forward"), "{joints:?}");
    // The base goes back slower than the arm.
    let speed = |j: &str| {
        home[0]
            .targets
            .iter()
            .find(|t| t.joint == j)
            .unwrap()
            .max_speed
    };
    assert!(speed("base_forward") < speed("left_elbow"));
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
    // A failed status of an old goal is not this reach's business.
    let o = g.reach_status(&status(with_base, ReachState::Failed), t(6.5));
    assert!(o.steps.is_empty() && o.said().is_empty());
    // The next touch starts with the arm alone again, and its rest leaves the base alone.
    let o = g.command(&cmd(Command::TouchBall), t(7.0));
    let r = reaches(&o);
    assert_eq!(r[0].body_part, "left_arm_7");
    let o = g.command(&cmd(Command::YouTouchedIt), t(8.0));
    let home = homes(&o);
    assert!(home[0].targets.iter().all(|t| !t.joint.starts_with("base")));
}

#[test]
fn without_the_base_an_unreachable_ball_is_explained_at_once() {
    let settings = TouchSettings {
        arm_with_base: String::new(),
        ..TouchSettings::default()
    };
    let mut g = TouchGame::new(settings).unwrap();
    g.start(t(0.0));
    g.command(&cmd(Command::Play), t(1.0));
    g.command(&cmd(Command::ScanBall), t(2.0));
    g.ball_track(&track([0.6, 0.1, 0.78]), t(2.9));
    g.ball_event(&ball(BallEventKind::Detected), t(3.0));
    let o = g.command(&cmd(Command::TouchBall), t(4.0));
    let id = reaches(&o)[0].id;
    let o = g.reach_status(&status(id, ReachState::Unreachable), t(5.0));
    assert_eq!(o.said(), [say::CANT_REACH]);
    assert_eq!(cancels(&o)[0].id, id);
    assert!(reaches(&o).is_empty());
    assert_eq!(homes(&o).len(), 1);
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
}

#[test]
fn a_lost_ball_is_said_and_searched_again_and_the_arm_goes_home() {
    let (mut g, _) = reaching();
    let o = g.ball_event(&ball(BallEventKind::Lost), t(5.0));
    assert_eq!(o.said(), [say::LOST, say::LOOKING]);
    // Both regions stepped on the one event.
    assert_eq!(o.steps.len(), 1);
    assert_eq!(o.steps[0].active, [state::HOMING, state::LOOKING]);
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::SetBallTarget(b) if b.active))
    );
    let r = reaches(&o);
    assert_eq!(
        (r[0].body_part.as_str(), r[0].frame.as_str()),
        ("neck", "world")
    );
    // Found again.
    g.ball_event(&ball(BallEventKind::Detected), t(6.0));
    assert_eq!(active(&g), [state::HOMING, state::TRACKING]);
}

#[test]
fn out_of_view_then_lost_then_found_again() {
    let mut g = tracking();
    let o = g.ball_event(&ball(BallEventKind::OutOfView), t(5.0));
    assert_eq!(o.said(), [say::OUT_OF_SIGHT]);
    assert_eq!(cancels(&o)[0].body_part, "neck");
    assert_eq!(active(&g), [state::RESTING, state::OUT_OF_SIGHT]);
    // Touch now: not seen.
    assert_eq!(
        g.command(&cmd(Command::TouchBall), t(5.5)).said(),
        [say::NOT_SEEN]
    );
    let o = g.ball_event(&ball(BallEventKind::Lost), t(6.0));
    assert_eq!(o.said(), [say::LOST, say::LOOKING]);
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
    let o = g.ball_event(&ball(BallEventKind::Detected), t(9.0));
    assert_eq!(o.said(), [say::SEE_IT]);
}

/// Reported at the border while the head turned, but still held by the tracker and well inside
/// the image once the head stopped: the eyes follow it again (no deadlock in out_of_sight).
#[test]
fn a_ball_still_held_well_inside_the_image_is_followed_again() {
    let mut g = tracking();
    g.ball_event(&ball(BallEventKind::OutOfView), t(5.0));
    assert_eq!(active(&g), [state::RESTING, state::OUT_OF_SIGHT]);
    let mut near_border = track([0.5, 0.2, 1.2]);
    near_border.state = BallTrackState::Tracking;
    near_border.centre_m = [0.4, 0.0, 0.6];
    g.ball_track(&near_border, t(5.2));
    assert_eq!(
        active(&g),
        [state::RESTING, state::OUT_OF_SIGHT],
        "34 degrees off"
    );
    let mut inside = near_border.clone();
    inside.centre_m = [0.1, 0.05, 0.6];
    let o = g.ball_track(&inside, t(5.4));
    assert_eq!(active(&g), [state::RESTING, state::TRACKING]);
    assert!(
        reaches(&o).iter().any(|r| r.body_part == "neck"),
        "the neck follows the ball again"
    );
}

/// Reported at the border while the head turned, and held at the border by the head that
/// stopped there (34 degrees off its axis): after a second held, the eyes follow it again and
/// bring it inside (no deadlock in out_of_sight). A break in the track starts the second again.
#[test]
fn a_ball_held_at_the_border_for_a_second_is_followed_again() {
    let mut g = tracking();
    g.ball_event(&ball(BallEventKind::OutOfView), t(5.0));
    let mut near_border = track([0.5, 0.2, 1.2]);
    near_border.state = BallTrackState::Tracking;
    near_border.centre_m = [0.4, 0.0, 0.6];
    g.ball_track(&near_border, t(5.1));
    g.ball_track(&near_border, t(5.9));
    let mut gone = near_border.clone();
    gone.found = false;
    g.ball_track(&gone, t(6.0));
    g.ball_track(&near_border, t(6.1));
    g.ball_track(&near_border, t(7.0));
    assert_eq!(
        active(&g),
        [state::RESTING, state::OUT_OF_SIGHT],
        "held 0.9 s since the break"
    );
    let o = g.ball_track(&near_border, t(7.1));
    assert_eq!(active(&g), [state::RESTING, state::TRACKING]);
    assert!(
        reaches(&o).iter().any(|r| r.body_part == "neck"),
        "the neck follows the ball again"
    );
}

#[test]
fn commands_that_make_no_sense_now_are_explained() {
    let mut g = game();
    let o = g.command(&cmd(Command::TouchBall), t(1.0));
    assert_eq!(o.said(), [say::NOT_SEEN]);
    assert!(reaches(&o).is_empty());
    assert_eq!(
        g.command(&cmd(Command::YouTouchedIt), t(2.0)).said(),
        [say::NOT_TOUCHING]
    );
    g.command(&cmd(Command::Play), t(3.0));
    assert_eq!(
        g.command(&cmd(Command::TouchBall), t(4.0)).said(),
        [say::NOT_SEEN]
    );
    g.command(&cmd(Command::ScanBall), t(5.0));
    assert_eq!(
        g.command(&cmd(Command::TouchBall), t(6.0)).said(),
        [say::NOT_SEEN]
    );
    assert_eq!(
        g.command(&cmd(Command::YouTouchedIt), t(7.0)).said(),
        [say::NOT_TOUCHING]
    );
    // Another game's command, and nothing understood.
    assert_eq!(
        g.command(&cmd(Command::Kick), t(8.0)).said(),
        [say::NOT_THIS_GAME]
    );
    assert_eq!(
        g.command(&cmd(Command::None), t(9.0)).said(),
        [say::PLEASE_REPEAT]
    );
    // Yes/No belong to the dialog: logged as heard, nothing else.
    g.advance(t(10.0));
    let o = g.command(&cmd(Command::Yes), t(10.0));
    assert!(o.steps.is_empty() && o.said().is_empty());
    assert_eq!(o.outputs.len(), 1);
    assert_eq!(active(&g), [state::RESTING, state::LOOKING]);
}

type Script = fn(&mut TouchGame);

#[test]
fn stop_or_quit_from_any_state_rests_says_goodbye_and_finishes() {
    let scripts: Vec<(&str, Script)> = vec![
        ("waiting", |_| {}),
        ("playing", |g| {
            g.command(&cmd(Command::Play), t(1.0));
        }),
        ("searching", |g| {
            g.command(&cmd(Command::ScanBall), t(1.0));
        }),
        ("touching", |g| {
            g.command(&cmd(Command::ScanBall), t(1.0));
            g.ball_event(&ball(BallEventKind::Detected), t(2.0));
            let id = reaches(&g.command(&cmd(Command::TouchBall), t(3.0)))[0].id;
            g.reach_status(&status(id, ReachState::Reached), t(4.0));
        }),
        ("out_of_sight", |g| {
            g.command(&cmd(Command::ScanBall), t(1.0));
            g.ball_event(&ball(BallEventKind::Detected), t(2.0));
            g.ball_event(&ball(BallEventKind::OutOfView), t(3.0));
        }),
        ("homing", |g| {
            g.command(&cmd(Command::ScanBall), t(1.0));
            g.ball_event(&ball(BallEventKind::Detected), t(2.0));
            g.command(&cmd(Command::TouchBall), t(3.0));
            g.command(&cmd(Command::YouTouchedIt), t(4.0));
        }),
    ];
    for (name, script) in scripts {
        for end in [Command::Stop, Command::Quit] {
            let mut g = game();
            script(&mut g);
            let was_playing = g.machine().is_active(state::PLAYING);
            let o = g.command(&cmd(end), t(5.0));
            assert!(g.is_finished(), "{name} {end:?}");
            assert_eq!(active(&g), [state::FINISHED], "{name}");
            assert_eq!(o.said(), [say::GOODBYE], "{name}");
            assert!(o.outputs.iter().any(|x| matches!(
                x,
                Output::Say {
                    priority: Priority::Urgent,
                    ..
                }
            )));
            assert_eq!(o.outputs.last(), Some(&Output::Finish), "{name}");
            let parts: Vec<&str> = cancels(&o).iter().map(|c| c.body_part.as_str()).collect();
            assert_eq!(parts, ["left_arm_7", "neck"], "{name}");
            let h = homes(&o);
            assert_eq!(h.len(), 2, "{name}: arm and head");
            assert!(h[1].targets.iter().any(|j| j.joint == "neck_pitch"));
            assert_eq!(
                o.outputs
                    .iter()
                    .any(|x| matches!(x, Output::SetBallTarget(b) if !b.active)),
                was_playing,
                "{name}: the tracker's target is cleared when the game played"
            );
            assert!(g.next_deadline().is_none(), "{name}: no timer left");
            // Nothing happens after the end but the next visitor's game (see
            // after_a_finished_game_the_next_visitor_starts_a_new_one_with_new_goal_ids).
            let o = g.command(&cmd(Command::TouchBall), t(6.0));
            assert!(o.said().is_empty() && o.steps[0].ignored);
            assert!(g.is_finished());
        }
    }
}

#[test]
fn every_step_reports_its_event_and_a_state_log_line() {
    let mut g = game();
    let o = g.command(&cmd(Command::ScanBall), t(1.0));
    let s = &o.steps[0];
    assert_eq!(s.event, "command:scan_ball");
    assert_eq!(s.exited, [state::WAITING]);
    assert_eq!(
        s.entered,
        [
            state::PLAYING,
            state::EYES,
            state::SEARCHING,
            state::LOOKING,
            state::ARM,
            state::RESTING
        ]
    );
    let states: Vec<&LogLine> = o
        .outputs
        .iter()
        .filter_map(|x| match x {
            Output::Log(l) if l.kind == "state" => Some(l),
            _ => None,
        })
        .collect();
    assert_eq!(states.len(), 1);
    assert_eq!(
        states[0].text,
        "command:scan_ball: waiting -> eyes/searching/looking + arm/resting; now arm/resting + eyes/searching/looking"
    );
}

#[test]
fn the_diagram_names_every_state() {
    let def = definition(&TouchSettings::default()).unwrap();
    let m = def.mermaid();
    for p in def.state_paths() {
        let name = p.rsplit('/').next().unwrap();
        assert!(m.contains(name), "{name} missing");
    }
    assert!(m.contains("after 5s (courtesy)"), "{m}");
    assert!(m.contains("[ball seen]"), "{m}");
}

#[test]
fn what_is_heard_is_logged_after_the_timers_that_fell_due_before_it() {
    let (mut g, id) = reaching();
    g.reach_status(&status(id, ReachState::Reached), t(5.0));
    let o = g.command(&cmd(Command::Quit), t(30.0));
    // courtesy (10 s), homed (12 s), then the command.
    let events: Vec<&str> = o.steps.iter().map(|s| s.event.as_str()).collect();
    assert_eq!(events, ["timer:courtesy", "timer:homed", "command:quit"]);
    let kinds: Vec<&str> = o
        .outputs
        .iter()
        .filter_map(|x| match x {
            Output::Log(l) => Some(l.kind),
            _ => None,
        })
        .collect();
    let heard = kinds.iter().position(|k| *k == "heard").unwrap();
    assert_eq!(kinds[heard + 1], "state");
    assert_eq!(kinds.iter().filter(|k| **k == "state").count(), 3);
}

/// The reach goals of `o` that are not the neck's.
fn arm_reaches(o: &Outcome) -> Vec<&ReachGoal> {
    reaches(o)
        .into_iter()
        .filter(|r| r.body_part != "neck")
        .collect()
}

/// The game `g` left, taken up by a fresh game at `now` (a restarted Executive): the record
/// through its JSON, as on disk.
fn restarted(g: &TouchGame, now: f64) -> (TouchGame, Outcome) {
    let record = g
        .resume_record()
        .expect("a game that is not over leaves a record");
    let record = resume::Resume::from_json(&record.to_json()).unwrap();
    let mut fresh = TouchGame::new(TouchSettings::default()).unwrap();
    let o = fresh.resume(&record, t(now));
    (fresh, o)
}

fn targets(o: &Outcome) -> Vec<&BallTarget> {
    o.outputs
        .iter()
        .filter_map(|x| match x {
            Output::SetBallTarget(b) => Some(b),
            _ => None,
        })
        .collect()
}

/// A command its sender sends again after the Executive restarted (the old process may have died
/// before acting on it, see `interfaces::outbox`) is carried out once: the stamps of the commands
/// acted on go into the record.
#[test]
fn a_command_sent_again_after_a_restart_is_carried_out_once() {
    let mut g = game();
    let mut play = cmd(Command::Play);
    play.header.stamp_ns = 17;
    assert_eq!(g.command(&play, t(1.0)).said(), [say::PLAY_ACK]);
    assert!(g.command(&play, t(1.5)).said().is_empty(), "twice");
    let (mut fresh, _) = restarted(&g, 2.0);
    let o = fresh.command(&play, t(3.0));
    assert!(o.said().is_empty(), "{:?}", o.said());
    assert!(
        o.outputs
            .iter()
            .any(|x| matches!(x, Output::Log(l) if l.text.contains("already carried out")))
    );
    // One it never acted on (it died first) is carried out.
    let mut scan = cmd(Command::ScanBall);
    scan.header.stamp_ns = 18;
    assert_eq!(fresh.command(&scan, t(4.0)).said(), [say::LOOKING]);
}

#[test]
fn a_restarted_executive_takes_up_a_waiting_game_silently() {
    let g = game();
    let (fresh, o) = restarted(&g, 1.0);
    assert_eq!(active(&fresh), [state::WAITING]);
    assert!(o.said().is_empty(), "{:?}", o.said());
    // And the first command works as in a new game.
    let mut fresh = fresh;
    let o = fresh.command(&cmd(Command::Play), t(2.0));
    assert_eq!(o.said(), [say::PLAY_ACK]);
}

#[test]
fn a_restarted_executive_takes_up_an_idle_game_with_one_line() {
    let mut g = game();
    g.command(&cmd(Command::Play), t(1.0));
    let (mut fresh, o) = restarted(&g, 2.0);
    assert_eq!(o.said(), [resume::BACK]);
    assert!(active(&fresh).contains(&state::EYES_IDLE.to_string()));
    assert!(active(&fresh).contains(&state::RESTING.to_string()));
    // "scan the ball" after the restart is carried out, not refused.
    let o = fresh.command(&cmd(Command::ScanBall), t(3.0));
    assert_eq!(o.said(), [say::LOOKING]);
    assert_eq!(targets(&o).len(), 1);
}

#[test]
fn a_restarted_executive_looks_for_the_ball_again_when_it_was_searching_or_tracking() {
    let mut searching = game();
    searching.command(&cmd(Command::Play), t(1.0));
    searching.command(&cmd(Command::ScanBall), t(2.0));
    for (what, g) in [("searching", searching), ("tracking", tracking())] {
        let (mut fresh, o) = restarted(&g, 10.0);
        assert_eq!(o.said(), [resume::BACK], "{what}");
        assert!(
            active(&fresh)
                .iter()
                .any(|s| s.starts_with(state::SEARCHING)),
            "{what}: {:?}",
            active(&fresh)
        );
        // The tracker gets its target again (it finds the ball again from scratch).
        assert!(targets(&o).iter().any(|b| b.active), "{what}: {o:?}");
        fresh.ball_track(&track([0.6, 0.1, 0.78]), t(10.5));
        let o = fresh.ball_event(&ball(BallEventKind::Detected), t(10.6));
        assert!(
            active(&fresh).contains(&state::TRACKING.to_string()),
            "{what}"
        );
        assert_eq!(o.said(), [say::SEE_IT], "{what}");
        // "touch the ball" now works: the game knows the ball.
        let o = fresh.command(&cmd(Command::TouchBall), t(11.0));
        assert_eq!(reaches(&o).len(), 1, "{what}: {o:?}");
    }
}

#[test]
fn a_restarted_executive_reaches_again_once_it_sees_the_ball_when_the_arm_was_at_it() {
    let (mut g, arm_goal) = reaching();
    // Moving, and touching (reached).
    let (moving, _) = reaching();
    g.reach_status(&status(arm_goal, ReachState::Reached), t(5.0));
    assert!(active(&g).contains(&state::TOUCHING.to_string()));
    for (what, g) in [("moving", moving), ("touching", g)] {
        let old_ids = g.resume_record().unwrap().last_goal_id;
        let (mut fresh, o) = restarted(&g, 6.0);
        assert_eq!(o.said(), [resume::BACK], "{what}");
        assert!(
            reaches(&o).iter().all(|r| r.body_part == "neck"),
            "{what}: no arm goal before the ball is seen"
        );
        fresh.ball_track(&track([0.6, 0.1, 0.78]), t(6.4));
        let o = fresh.ball_event(&ball(BallEventKind::Detected), t(6.5));
        let arm = arm_reaches(&o);
        assert_eq!(
            arm.len(),
            1,
            "{what}: the touch is carried out again: {o:?}"
        );
        assert!(
            arm[0].id > old_ids,
            "{what}: goal ids go on ({} vs {old_ids})",
            arm[0].id
        );
        assert!(
            active(&fresh).contains(&state::MOVING.to_string()),
            "{what}"
        );
        // Only "I see the ball" on the way: the reach is not announced again.
        assert_eq!(o.said(), [say::SEE_IT], "{what}");
        // The old process's goal's status means nothing to the new one.
        let o = fresh.reach_status(&status(arm_goal, ReachState::Unreachable), t(7.0));
        assert!(o.said().is_empty(), "{what}: {:?}", o.said());
        assert!(
            active(&fresh).contains(&state::MOVING.to_string()),
            "{what}"
        );
    }
}

#[test]
fn a_restarted_executive_reaches_again_with_the_base_when_the_reach_had_turned_it() {
    let (mut g, id) = reaching();
    let o = g.reach_status(&status(id, ReachState::Unreachable), t(5.0));
    assert_eq!(reaches(&o)[0].body_part, "left_arm_9");
    let (mut fresh, _) = restarted(&g, 6.0);
    fresh.ball_track(&track([0.6, 0.1, 0.78]), t(6.4));
    let o = fresh.ball_event(&ball(BallEventKind::Detected), t(6.5));
    let arm = arm_reaches(&o);
    assert_eq!(arm.len(), 1, "{o:?}");
    assert_eq!(arm[0].body_part, "left_arm_9", "the base goes on turning");
    // And it goes home with the arm.
    let o = fresh.command(&cmd(Command::YouTouchedIt), t(8.0));
    let home = homes(&o);
    assert!(
        home[0].targets.iter().any(|t| t.joint == "base_yaw"),
        "{home:?}"
    );
    // A record of an older release, without the field, reads as an arm-only reach.
    let mut json: serde_json::Value =
        serde_json::from_str(&g.resume_record().unwrap().to_json()).unwrap();
    json.as_object_mut().unwrap().remove("with_base");
    let old = resume::Resume::from_json(&json.to_string()).unwrap();
    assert!(!old.with_base);
}

#[test]
fn a_restarted_executive_leaves_a_homing_arm_at_rest_and_a_finished_game_leaves_no_record() {
    let (mut g, arm_goal) = reaching();
    g.reach_status(&status(arm_goal, ReachState::Reached), t(5.0));
    g.command(&cmd(Command::YouTouchedIt), t(5.5));
    assert!(active(&g).contains(&state::HOMING.to_string()));
    let (mut fresh, o) = restarted(&g, 6.0);
    assert_eq!(o.said(), [resume::BACK]);
    assert!(active(&fresh).contains(&state::RESTING.to_string()));
    fresh.ball_event(&ball(BallEventKind::Detected), t(6.5));
    assert!(
        active(&fresh).contains(&state::RESTING.to_string()),
        "no reach of its own"
    );
    fresh.command(&cmd(Command::Quit), t(7.0));
    assert!(fresh.is_finished());
    assert_eq!(fresh.resume_record(), None);
}

#[test]
fn a_record_of_another_machine_or_garbage_is_refused() {
    assert!(resume::Resume::from_json("{").is_err());
    let mut r = game().resume_record().unwrap();
    r.machine = "nao_coach".into();
    let e = resume::Resume::from_json(&r.to_json()).unwrap_err();
    assert!(e.contains("nao_coach"), "{e}");
}
