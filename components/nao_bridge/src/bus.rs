//! Conversions between the protocol types of this crate and the bus messages of
//! `interfaces::msg::nao`, at the edge of the component (one place, both directions).

use interfaces::msg::nao as msg;
use spl::types::{
    BodyCommand, FieldPoint, GameControllerState, GlobalWorldModel, HeadCommand, LinkEvent,
    LocalWorldModel, NaoCommand, Pose2, Strategy, TeamInfo,
};

fn point(p: FieldPoint) -> msg::FieldPoint {
    msg::FieldPoint {
        x_mm: p.x_mm,
        y_mm: p.y_mm,
    }
}

fn pose(p: Pose2) -> msg::FieldPose {
    msg::FieldPose {
        x_mm: p.x_mm,
        y_mm: p.y_mm,
        theta_rad: p.theta_rad,
    }
}

/// A bus command to the protocol's typed command (validated when encoded).
pub fn command_from_bus(c: &msg::NaoCommand) -> NaoCommand {
    use msg::{NaoBody as B, NaoHead as H};
    let body = match c.body {
        B::Keep => None,
        B::GoToPosition => Some(BodyCommand::GoToPosition),
        B::Dribble => Some(BodyCommand::Dribble),
        B::GoToBallAndDribble => Some(BodyCommand::GoToBallAndDribble),
        B::Kick => Some(BodyCommand::Kick),
        B::Spazza => Some(BodyCommand::Spazza),
        B::Pass => Some(BodyCommand::Pass),
        B::AskForTheBall => Some(BodyCommand::AskForTheBall),
        B::Turn => Some(BodyCommand::Turn),
        B::SearchTheBall => Some(BodyCommand::SearchTheBall),
        B::Stop => Some(BodyCommand::Stop),
    };
    let head = match c.head {
        H::Keep => None,
        H::LookAtTheBall => Some(HeadCommand::LookAtTheBall),
        H::LookForward => Some(HeadCommand::LookForward),
        H::LookLeft => Some(HeadCommand::LookLeft),
        H::LookRight => Some(HeadCommand::LookRight),
        H::Scan => Some(HeadCommand::Scan),
    };
    let strategy = match c.strategy {
        msg::NaoStrategy::Default => Strategy::Default,
        msg::NaoStrategy::Passages => Strategy::Passages,
    };
    let target = body
        .filter(|b| b.needs_target())
        .map(|_| FieldPoint::new(c.target.x_mm, c.target.y_mm));
    NaoCommand {
        body,
        head,
        strategy,
        target,
    }
}

/// A decoded debug packet to its bus message.
pub fn local_model_to_bus(m: &LocalWorldModel) -> msg::NaoLocalModel {
    msg::NaoLocalModel {
        header: Default::default(),
        player_number: m.player_number,
        team_number: m.team_number,
        fallen: m.fallen,
        pose: pose(m.pose),
        ball_age_s: m.ball_age_s,
        ball: point(m.ball),
        role: m.role.wire_value(),
        obstacles_seen: m.obstacles_seen,
        obstacles: m
            .obstacles
            .iter()
            .map(|o| msg::NaoObstacle {
                kind: o.kind.wire_value(),
                center: point(o.center),
                last_seen_ms: o.last_seen_ms,
            })
            .collect(),
        message_budget: m.message_budget,
        secs_remaining: m.secs_remaining,
        arm_contact: [m.left_arm.contact, m.right_arm.contact],
        arm_push_direction: [m.left_arm.push_direction, m.right_arm.push_direction],
        arm_last_contact_ms: [
            m.left_arm.time_of_last_contact_ms,
            m.right_arm.time_of_last_contact_ms,
        ],
        time_since_whistle_ms: m.time_since_whistle_ms,
        whistle: m.whistle.wire_value(),
        team_ball: point(m.team_ball),
        team_ball_velocity: point(m.team_ball_velocity),
        battery: m.battery,
        cpu_temperature_c: m.cpu_temperature_c,
        referee_gesture: m.referee_gesture,
    }
}

/// The fused model to its bus message.
pub fn world_model_to_bus(w: &GlobalWorldModel) -> msg::NaoWorldModel {
    let mut out = msg::NaoWorldModel {
        robots: w
            .robots
            .iter()
            .map(|r| msg::TeamRobot {
                player_number: r.player_number,
                role: r.role.wire_value(),
                pose: pose(r.pose),
                fallen: r.fallen,
                age_s: r.age_s,
            })
            .collect(),
        obstacles: w
            .obstacles
            .iter()
            .map(|o| msg::TrackedObstacle {
                kind: o.kind.wire_value(),
                center: point(o.center),
                age_s: o.age_s,
                observations: o.observations,
            })
            .collect(),
        confidence: w.confidence,
        ..Default::default()
    };
    if let Some(b) = &w.ball {
        out.ball_known = true;
        out.ball = point(b.position);
        out.ball_velocity = point(b.velocity);
        out.ball_age_s = b.age_s;
        out.ball_sigma_mm = b.sigma_mm;
        out.ball_confidence = b.confidence;
    }
    if let Some(s) = w.autonomous_is_striker {
        out.striker_known = true;
        out.autonomous_is_striker = s;
    }
    out
}

fn team(t: &TeamInfo) -> msg::TeamStatus {
    msg::TeamStatus {
        team_number: t.team_number,
        score: t.score,
        message_budget: t.message_budget,
        players: t
            .players
            .iter()
            .map(|p| msg::PlayerPenalty {
                penalty: p.penalty.wire_value(),
                secs_till_unpenalised: p.secs_till_unpenalised,
            })
            .collect(),
    }
}

/// A GameController packet to the bus message, our team (by number) first.
pub fn game_state_to_bus(g: &GameControllerState, our_team: u8) -> msg::GameState {
    let ours = g.team(our_team);
    let (our, their) = match (ours, g.opponent_of(our_team)) {
        (Some(o), Some(t)) => (team(o), team(t)),
        _ => (team(&g.teams[0]), team(&g.teams[1])),
    };
    msg::GameState {
        header: Default::default(),
        state: g.state.wire_value(),
        set_play: g.set_play.wire_value(),
        game_phase: g.game_phase.wire_value(),
        first_half: g.first_half,
        kicking_team: g.kicking_team.unwrap_or(255),
        secs_remaining: g.secs_remaining,
        secondary_time: g.secondary_time,
        our_team_found: ours.is_some(),
        our_team: our,
        opponent: their,
    }
}

/// A link event of player `player` to its bus message.
pub fn link_event_to_bus(player: u8, e: &LinkEvent, now_s: f64) -> msg::NaoLinkEvent {
    let (change, silent_for_s) = match *e {
        LinkEvent::Established { .. } => (msg::LinkChange::Established, 0.0),
        LinkEvent::RobotNotResponding {
            last_packet_s,
            at_s,
        } => (
            msg::LinkChange::RobotNotResponding,
            last_packet_s.map_or(at_s, |t| now_s - t),
        ),
        LinkEvent::LinkRestored { silent_for_s, .. } => (msg::LinkChange::Restored, silent_for_s),
    };
    msg::NaoLinkEvent {
        header: Default::default(),
        player_number: player,
        change,
        silent_for_s,
    }
}
