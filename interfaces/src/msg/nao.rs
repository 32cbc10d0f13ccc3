//! The Nao coach game on the bus: operator commands, the robots' local world models, the fused
//! team world model, the GameController state and the link's health.
//!
//! Field frame: millimetres, origin at the centre spot, x towards the opponent goal, y to the
//! left; angles in radians counter-clockwise from +x. Enum-like bytes keep the robot's own
//! numbering (documented per field) so nothing is lost between the wire and the bus.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// A point on the field (mm).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldPoint {
    pub x_mm: f32,
    pub y_mm: f32,
}

/// A pose on the field.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldPose {
    pub x_mm: f32,
    pub y_mm: f32,
    pub theta_rad: f32,
}

/// Body commands; `Keep` leaves the robot's current body command.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum NaoBody {
    #[default]
    Keep,
    GoToPosition,
    Dribble,
    GoToBallAndDribble,
    Kick,
    /// Clear the ball away.
    Spazza,
    Pass,
    AskForTheBall,
    Turn,
    SearchTheBall,
    Stop,
}

/// Head commands; `Keep` leaves the robot's current head command.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum NaoHead {
    #[default]
    Keep,
    LookAtTheBall,
    LookForward,
    LookLeft,
    LookRight,
    Scan,
}

/// The robot's strategy (always replaced by a command).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum NaoStrategy {
    #[default]
    Default,
    Passages,
}

/// An operator command for the controlled robot (topic `nao/command`). At least one of body and
/// head must be set; GoToPosition and Turn need `target`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NaoCommand {
    pub header: Header,
    pub body: NaoBody,
    pub head: NaoHead,
    pub strategy: NaoStrategy,
    /// Target (global, mm) for GoToPosition and Turn; ignored otherwise.
    pub target: FieldPoint,
    /// Who asked: `panel`, `voice`, `executive`, `cli`...
    pub source: String,
}

/// One obstacle of a robot's local model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct NaoObstacle {
    /// 0 goalpost, 1 unknown, 2 some robot, 3 opponent, 4 teammate, 5-7 fallen variants of 2-4.
    pub kind: u8,
    pub center: FieldPoint,
    /// Robot clock (ms).
    pub last_seen_ms: u32,
}

/// One robot's local world model, from its debug packet (topic `nao/local_model`).
/// `header.stamp_ns` is when the bridge received it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NaoLocalModel {
    pub header: Header,
    pub player_number: u8,
    pub team_number: u8,
    pub fallen: bool,
    pub pose: FieldPose,
    /// Seconds since the robot last saw the ball.
    pub ball_age_s: f32,
    pub ball: FieldPoint,
    /// 17 autonomous, 18 controlled, others per B-Human's PlayerRole.
    pub role: u8,
    /// How many obstacles the robot sees (only the first 20 are sent).
    pub obstacles_seen: u8,
    pub obstacles: Vec<NaoObstacle>,
    pub message_budget: u16,
    pub secs_remaining: u16,
    /// Left, right.
    pub arm_contact: [bool; 2],
    pub arm_push_direction: [u8; 2],
    pub arm_last_contact_ms: [u32; 2],
    pub time_since_whistle_ms: u32,
    /// 0 don't know, 1 not detected, 2 detected.
    pub whistle: u8,
    pub team_ball: FieldPoint,
    /// mm/s.
    pub team_ball_velocity: FieldPoint,
    pub battery: f32,
    pub cpu_temperature_c: f32,
    /// 0: none.
    pub referee_gesture: u8,
}

/// One of our robots in the fused model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TeamRobot {
    pub player_number: u8,
    pub role: u8,
    pub pose: FieldPose,
    pub fallen: bool,
    /// Seconds since its last packet.
    pub age_s: f64,
}

/// A tracked obstacle of the fused model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedObstacle {
    pub kind: u8,
    pub center: FieldPoint,
    /// Seconds since last seen by any robot.
    pub age_s: f64,
    pub observations: u32,
}

/// The fused team world model (topic `nao/world_model`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NaoWorldModel {
    pub header: Header,
    pub robots: Vec<TeamRobot>,
    /// Whether the ball fields hold an estimate (the ball has been seen).
    pub ball_known: bool,
    pub ball: FieldPoint,
    /// mm/s.
    pub ball_velocity: FieldPoint,
    /// Seconds since any robot last saw the ball.
    pub ball_age_s: f64,
    pub ball_sigma_mm: f64,
    pub ball_confidence: f64,
    pub obstacles: Vec<TrackedObstacle>,
    /// Whether `autonomous_is_striker` is known (both robots and a ball).
    pub striker_known: bool,
    pub autonomous_is_striker: bool,
    /// Overall confidence in [0, 1].
    pub confidence: f64,
}

/// A player's penalty: code per the GameController (0 none, 1 illegal ball contact, ...).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PlayerPenalty {
    pub penalty: u8,
    pub secs_till_unpenalised: u8,
}

/// One team's block of the game state.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TeamStatus {
    pub team_number: u8,
    pub score: u8,
    pub message_budget: u16,
    /// Players 1..=20 (index 0 is player 1).
    pub players: Vec<PlayerPenalty>,
}

/// The GameController's state (topic `nao/game_state`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GameState {
    pub header: Header,
    /// 0 INITIAL, 1 READY, 2 SET, 3 PLAYING, 4 FINISHED, 5 STANDBY.
    pub state: u8,
    /// 0 none, 1 goal kick, 2 pushing free kick, 3 corner kick, 4 kick-in, 5 penalty kick.
    pub set_play: u8,
    /// 0 normal, 1 penalty shoot-out, 2 overtime, 3 timeout.
    pub game_phase: u8,
    pub first_half: bool,
    /// 255: none.
    pub kicking_team: u8,
    pub secs_remaining: i16,
    pub secondary_time: i16,
    /// Whether our team number was found in the packet.
    pub our_team_found: bool,
    pub our_team: TeamStatus,
    pub opponent: TeamStatus,
}

impl GameState {
    pub const INITIAL: u8 = 0;
    pub const READY: u8 = 1;
    pub const SET: u8 = 2;
    pub const PLAYING: u8 = 3;
    pub const FINISHED: u8 = 4;
}

/// What happened to a robot's link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum LinkChange {
    #[default]
    Established,
    /// No packet for longer than the configured time-out.
    RobotNotResponding,
    Restored,
}

/// A robot's link changed (topic `nao/link`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NaoLinkEvent {
    pub header: Header,
    pub player_number: u8,
    pub change: LinkChange,
    /// For `Restored`: how long it was silent; for `RobotNotResponding`: silence so far (s).
    pub silent_for_s: f64,
}

/// Ground truth of the simulated field, for tests and the viewer (topic `sim/field_truth`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldTruth {
    pub header: Header,
    /// Simulated time (s).
    pub time_s: f64,
    pub ball: FieldPoint,
    pub controlled: FieldPose,
    pub teammate: FieldPose,
    /// The controlled robot's current body command, as it executes it (a NaoBody name).
    pub controlled_body: String,
    /// The last command packet the robot accepted: body byte, head byte, strategy byte, x, y.
    pub last_command: Vec<f32>,
    pub commands_received: u64,
    pub score: u8,
    pub passes: u32,
    /// 0 INITIAL .. 4 FINISHED.
    pub game_state: u8,
}

/// A command the coach asks of the controlled robot through the Executive's coach machine
/// (topic `coach/request`), which answers it, checks it against the game and the world model,
/// and only then sends it on `nao/command`. The command panel publishes these.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CoachRequest {
    pub header: Header,
    /// The command as the coach gave it (`target` for GoToPosition and Turn).
    pub command: NaoCommand,
    /// For Kick, Spazza and Pass: whether the coach pointed where the ball should go (`aim`).
    pub aimed: bool,
    /// Where the coach wants the ball to go (global, mm), when `aimed`.
    pub aim: FieldPoint,
}

/// The coach machine's memory and situation, for the command panel (topic `coach/status`,
/// on every change and at least once a second). Ages are seconds, `-1` when never.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CoachStatus {
    pub header: Header,
    /// The machine's active state (`coach/playing`, `coach/robot_down`, ...).
    pub state: String,
    /// GameController state (see [`GameState::state`]), when `game_known`.
    pub game_state: u8,
    pub game_known: bool,
    pub link_up: bool,
    pub fallen: bool,
    pub penalised: bool,
    /// The last command sent to the robot, when `has_last`.
    pub last_command: NaoCommand,
    pub has_last: bool,
    /// Whether the coach believes the last command is done (reached, kicked, seen).
    pub last_done: bool,
    /// A command kept for later (refused outside PLAYING, or while down), when `has_pending`.
    pub pending: NaoCommand,
    pub has_pending: bool,
    /// The last answer the robot gave.
    pub last_answer: String,
    /// Seconds since any of our robots saw the ball; `-1` when never.
    pub ball_last_seen_s: f64,
    /// Seconds since the most recently seen obstacle was seen; `-1` when never.
    pub obstacle_last_seen_s: f64,
    pub obstacles_tracked: u32,
}
