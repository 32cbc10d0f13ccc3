//! The Nao coach game on the bus: operator commands, the robots' local world models, the fused
//! team world model, the GameController state and the link's health.
//!
//! Field frame: millimetres, origin at the centre spot, x towards the opponent goal, y to the
//! left; angles in radians counter-clockwise from +x. Enum-like bytes keep the robot's own
//! numbering (documented per field) so nothing is lost between the wire and the bus: the
//! command's enums in their variant order, [`ObstacleKind`], [`PlayerRole`] and
//! [`WhistleState`] as the byte itself (`u8` in CDR and JSON).
//!
//! These are the only definitions: the `spl` library's codecs (command and debug packets) and
//! its team world model fusion read and write these messages directly.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// A point on the field (mm).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldPoint {
    /// x (mm), towards the opponent goal.
    pub x_mm: f32,
    /// y (mm), to the left when looking at the opponent goal.
    pub y_mm: f32,
}

impl FieldPoint {
    /// A point from its coordinates in millimetres.
    pub const fn new(x_mm: f32, y_mm: f32) -> Self {
        Self { x_mm, y_mm }
    }

    /// Euclidean distance to `other`, in millimetres.
    pub fn distance_to(&self, other: &FieldPoint) -> f32 {
        (self.x_mm - other.x_mm).hypot(self.y_mm - other.y_mm)
    }

    /// Whether both coordinates are finite.
    pub fn is_finite(&self) -> bool {
        self.x_mm.is_finite() && self.y_mm.is_finite()
    }
}

/// A pose on the field: position (mm) and heading `theta_rad`, counter-clockwise from +x.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FieldPose {
    pub x_mm: f32,
    pub y_mm: f32,
    pub theta_rad: f32,
}

impl FieldPose {
    /// The position part of the pose.
    pub fn position(&self) -> FieldPoint {
        FieldPoint::new(self.x_mm, self.y_mm)
    }
}

/// Body commands; `Keep` leaves the robot's current body command. The variant order is the
/// robot's numbering (byte 0 of the command packet): `Keep` 0, `GoToPosition` 1 ... `Stop` 10.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
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

/// Head commands; `Keep` leaves the robot's current head command. The variant order is the
/// robot's numbering (byte 1 of the command packet): `Keep` 0, `LookAtTheBall` 1 ... `Scan` 5.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NaoHead {
    #[default]
    Keep,
    LookAtTheBall,
    LookForward,
    LookLeft,
    LookRight,
    Scan,
}

/// The robot's strategy (always replaced by a command): `Default` 0, `Passages` 1 on the wire.
/// The original operator GUI numbered 1 Default, 2 Passages, 3 Defence; see
/// [`NaoStrategy::from_gui_number`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum NaoStrategy {
    #[default]
    Default,
    Passages,
}

impl NaoBody {
    /// All body commands but `Keep`, in wire order (1..=10).
    pub const ALL: [NaoBody; 10] = [
        NaoBody::GoToPosition,
        NaoBody::Dribble,
        NaoBody::GoToBallAndDribble,
        NaoBody::Kick,
        NaoBody::Spazza,
        NaoBody::Pass,
        NaoBody::AskForTheBall,
        NaoBody::Turn,
        NaoBody::SearchTheBall,
        NaoBody::Stop,
    ];

    /// The byte the robot expects (0 for `Keep`, 1..=10).
    pub fn wire_value(self) -> u8 {
        match self {
            NaoBody::Keep => 0,
            NaoBody::GoToPosition => 1,
            NaoBody::Dribble => 2,
            NaoBody::GoToBallAndDribble => 3,
            NaoBody::Kick => 4,
            NaoBody::Spazza => 5,
            NaoBody::Pass => 6,
            NaoBody::AskForTheBall => 7,
            NaoBody::Turn => 8,
            NaoBody::SearchTheBall => 9,
            NaoBody::Stop => 10,
        }
    }

    /// The command for a wire byte (0 is `Keep`); `None` for unknown values.
    pub fn from_wire(value: u8) -> Option<Self> {
        match value {
            0 => Some(NaoBody::Keep),
            v => Self::ALL.get(usize::from(v) - 1).copied(),
        }
    }

    /// Whether the robot uses the command's target for this body command.
    pub fn needs_target(self) -> bool {
        matches!(self, NaoBody::GoToPosition | NaoBody::Turn)
    }
}

impl NaoHead {
    /// All head commands but `Keep`, in wire order (1..=5).
    pub const ALL: [NaoHead; 5] = [
        NaoHead::LookAtTheBall,
        NaoHead::LookForward,
        NaoHead::LookLeft,
        NaoHead::LookRight,
        NaoHead::Scan,
    ];

    /// The byte the robot expects (0 for `Keep`, 1..=5).
    pub fn wire_value(self) -> u8 {
        match self {
            NaoHead::Keep => 0,
            NaoHead::LookAtTheBall => 1,
            NaoHead::LookForward => 2,
            NaoHead::LookLeft => 3,
            NaoHead::LookRight => 4,
            NaoHead::Scan => 5,
        }
    }

    /// The command for a wire byte (0 is `Keep`); `None` for unknown values.
    pub fn from_wire(value: u8) -> Option<Self> {
        match value {
            0 => Some(NaoHead::Keep),
            v => Self::ALL.get(usize::from(v) - 1).copied(),
        }
    }
}

impl NaoStrategy {
    /// The byte the robot reads (0 or 1).
    pub fn wire_value(self) -> u8 {
        match self {
            NaoStrategy::Default => 0,
            NaoStrategy::Passages => 1,
        }
    }

    /// The strategy for a robot wire byte.
    pub fn from_wire(value: u8) -> Option<Self> {
        match value {
            0 => Some(NaoStrategy::Default),
            1 => Some(NaoStrategy::Passages),
            _ => None,
        }
    }

    /// The strategy for the original operator GUI's number (1 Default, 2 Passages); 3 (Defence)
    /// and anything else is `None` because the robot has no such strategy.
    pub fn from_gui_number(value: u8) -> Option<Self> {
        match value {
            1 => Some(NaoStrategy::Default),
            2 => Some(NaoStrategy::Passages),
            _ => None,
        }
    }
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

impl NaoCommand {
    /// A body-only command (`target` is used by GoToPosition and Turn only).
    pub fn body(body: NaoBody, strategy: NaoStrategy, target: FieldPoint) -> Self {
        Self {
            body,
            strategy,
            target,
            ..Default::default()
        }
    }

    /// A head-only command.
    pub fn head(head: NaoHead, strategy: NaoStrategy) -> Self {
        Self {
            head,
            strategy,
            ..Default::default()
        }
    }
}

/// Obstacle kinds of the debug packet (B-Human `Obstacle::Type`), on the bus as their wire byte
/// (0..=7) so nothing changes between the packet and the message.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
pub enum ObstacleKind {
    /// 0
    #[default]
    Goalpost,
    /// 1
    Unknown,
    /// 2: a robot of unknown team.
    SomeRobot,
    /// 3
    Opponent,
    /// 4
    Teammate,
    /// 5
    FallenSomeRobot,
    /// 6
    FallenOpponent,
    /// 7
    FallenTeammate,
}

impl ObstacleKind {
    /// All kinds, in wire order 0..=7.
    pub const ALL: [ObstacleKind; 8] = [
        ObstacleKind::Goalpost,
        ObstacleKind::Unknown,
        ObstacleKind::SomeRobot,
        ObstacleKind::Opponent,
        ObstacleKind::Teammate,
        ObstacleKind::FallenSomeRobot,
        ObstacleKind::FallenOpponent,
        ObstacleKind::FallenTeammate,
    ];

    /// The wire byte (0..=7).
    pub fn wire_value(self) -> u8 {
        self as u8
    }

    /// The kind for a wire byte, `None` when out of range.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value)).copied()
    }

    /// The snake_case name (`opponent`, `fallen_some_robot`), as the DR's `obstacle_type`.
    pub fn name(self) -> &'static str {
        match self {
            ObstacleKind::Goalpost => "goalpost",
            ObstacleKind::Unknown => "unknown",
            ObstacleKind::SomeRobot => "some_robot",
            ObstacleKind::Opponent => "opponent",
            ObstacleKind::Teammate => "teammate",
            ObstacleKind::FallenSomeRobot => "fallen_some_robot",
            ObstacleKind::FallenOpponent => "fallen_opponent",
            ObstacleKind::FallenTeammate => "fallen_teammate",
        }
    }

    /// How specific the kind is, for merging observations: a known team beats "some robot",
    /// which beats "unknown".
    pub fn specificity(self) -> u8 {
        match self {
            ObstacleKind::Unknown => 0,
            ObstacleKind::SomeRobot | ObstacleKind::FallenSomeRobot => 1,
            _ => 2,
        }
    }
}

impl From<ObstacleKind> for u8 {
    fn from(k: ObstacleKind) -> u8 {
        k.wire_value()
    }
}

impl TryFrom<u8> for ObstacleKind {
    type Error = String;
    fn try_from(v: u8) -> Result<Self, String> {
        Self::from_wire(v).ok_or_else(|| format!("obstacle kind {v} is not 0..=7"))
    }
}

/// The player role byte: 17 autonomous, 18 controlled, anything else a B-Human `PlayerRole`
/// (kept as sent). On the bus as that byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u8", from = "u8")]
pub enum PlayerRole {
    /// 17: the autonomous teammate of the challenge.
    Autonomous,
    /// 18: the operator-controlled robot.
    Controlled,
    /// Any other B-Human role value, kept as sent.
    Other(u8),
}

impl Default for PlayerRole {
    fn default() -> Self {
        PlayerRole::Other(0)
    }
}

impl PlayerRole {
    /// The wire byte.
    pub fn wire_value(self) -> u8 {
        match self {
            PlayerRole::Autonomous => 17,
            PlayerRole::Controlled => 18,
            PlayerRole::Other(v) => v,
        }
    }

    /// The role for a wire byte (total).
    pub fn from_wire(value: u8) -> Self {
        match value {
            17 => PlayerRole::Autonomous,
            18 => PlayerRole::Controlled,
            v => PlayerRole::Other(v),
        }
    }
}

impl From<PlayerRole> for u8 {
    fn from(r: PlayerRole) -> u8 {
        r.wire_value()
    }
}

impl From<u8> for PlayerRole {
    fn from(v: u8) -> Self {
        Self::from_wire(v)
    }
}

impl std::fmt::Display for PlayerRole {
    /// The wire byte, as the robot numbers roles.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.wire_value())
    }
}

/// The whistle detector's state: 0 don't know, 1 not detected, 2 detected (on the bus as that
/// byte).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(into = "u8", try_from = "u8")]
pub enum WhistleState {
    /// 0
    #[default]
    DontKnow,
    /// 1
    NotDetected,
    /// 2
    Detected,
}

impl WhistleState {
    /// The wire byte.
    pub fn wire_value(self) -> u8 {
        self as u8
    }

    /// The state for a wire byte.
    pub fn from_wire(value: u8) -> Option<Self> {
        match value {
            0 => Some(WhistleState::DontKnow),
            1 => Some(WhistleState::NotDetected),
            2 => Some(WhistleState::Detected),
            _ => None,
        }
    }
}

impl From<WhistleState> for u8 {
    fn from(w: WhistleState) -> u8 {
        w.wire_value()
    }
}

impl TryFrom<u8> for WhistleState {
    type Error = String;
    fn try_from(v: u8) -> Result<Self, String> {
        Self::from_wire(v).ok_or_else(|| format!("whistle state {v} is not 0..=2"))
    }
}

/// One obstacle of a robot's local model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct NaoObstacle {
    /// 0 goalpost, 1 unknown, 2 some robot, 3 opponent, 4 teammate, 5-7 fallen variants of 2-4.
    pub kind: ObstacleKind,
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
    pub role: PlayerRole,
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
    pub whistle: WhistleState,
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
    pub role: PlayerRole,
    pub pose: FieldPose,
    pub fallen: bool,
    /// Seconds since its last packet.
    pub age_s: f64,
}

/// A tracked obstacle of the fused model.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TrackedObstacle {
    /// The track's identity: stable while it lives, never reused by the same fusion (names its
    /// DR node, `obstacle_<id>`).
    pub id: u32,
    /// Most specific kind seen.
    pub kind: ObstacleKind,
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
