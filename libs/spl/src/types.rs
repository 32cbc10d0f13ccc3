//! Bus-facing data types of the Nao link, as plain serde structs.
//!
//! Everything here is meant to move into the `interfaces` crate once the bus exists; nothing in
//! this module depends on the wire layout (see [`crate::command`], [`crate::debug`],
//! [`crate::gamecontroller`] for the byte codecs).
//!
//! Conventions: global field frame, millimetres, origin at the centre spot, x towards the
//! opponent goal, y to the left, angles in radians counter-clockwise from +x. Times are seconds
//! (`_s`) of the caller's clock unless the name says `_ms` (robot-clock milliseconds).

use serde::{Deserialize, Serialize};

/// A point on the field, global frame, millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
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

/// A robot pose, global frame: position in millimetres and heading `theta_rad`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2 {
    /// x (mm).
    pub x_mm: f32,
    /// y (mm).
    pub y_mm: f32,
    /// Heading (rad), counter-clockwise from the +x axis.
    pub theta_rad: f32,
}

impl Pose2 {
    /// The position part of the pose.
    pub fn position(&self) -> FieldPoint {
        FieldPoint::new(self.x_mm, self.y_mm)
    }
}

/// Body commands of the controlled robot (the robot's `HumanCommand::CommandBody`).
///
/// Wire values (byte 0 of the command packet): 0 is "none, keep the current body command" and
/// is represented by `Option::<BodyCommand>::None`; the variants are 1..=10 in declaration
/// order (see [`BodyCommand::wire_value`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum BodyCommand {
    /// 1: walk to the target point (needs a target).
    GoToPosition,
    /// 2: dribble the ball towards a free point.
    Dribble,
    /// 3: walk to the ball, then dribble it.
    GoToBallAndDribble,
    /// 4: kick the ball towards the opponent goal.
    Kick,
    /// 5: "Spazza", clear the ball away from our half.
    Spazza,
    /// 6: pass to the teammate (dribble when there is none).
    Pass,
    /// 7: ask the teammate for the ball.
    AskForTheBall,
    /// 8: turn on the spot to face the target point (needs a target).
    Turn,
    /// 9: search the ball (turn on the spot until it is seen).
    SearchTheBall,
    /// 10: stop and stand.
    Stop,
}

impl BodyCommand {
    /// All body commands, in wire order.
    pub const ALL: [BodyCommand; 10] = [
        BodyCommand::GoToPosition,
        BodyCommand::Dribble,
        BodyCommand::GoToBallAndDribble,
        BodyCommand::Kick,
        BodyCommand::Spazza,
        BodyCommand::Pass,
        BodyCommand::AskForTheBall,
        BodyCommand::Turn,
        BodyCommand::SearchTheBall,
        BodyCommand::Stop,
    ];

    /// The byte the robot expects (1..=10).
    pub fn wire_value(self) -> u8 {
        match self {
            BodyCommand::GoToPosition => 1,
            BodyCommand::Dribble => 2,
            BodyCommand::GoToBallAndDribble => 3,
            BodyCommand::Kick => 4,
            BodyCommand::Spazza => 5,
            BodyCommand::Pass => 6,
            BodyCommand::AskForTheBall => 7,
            BodyCommand::Turn => 8,
            BodyCommand::SearchTheBall => 9,
            BodyCommand::Stop => 10,
        }
    }

    /// The command for a wire byte; `None` for 0 ("keep") and for unknown values.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value).checked_sub(1)?).copied()
    }

    /// Whether the robot uses the packet's (x, y) for this command.
    pub fn needs_target(self) -> bool {
        matches!(self, BodyCommand::GoToPosition | BodyCommand::Turn)
    }
}

/// Head commands of the controlled robot (the robot's `HumanCommand::CommandHead`).
///
/// Wire values (byte 1): 0 is "none, keep the current head command" (`None`); the variants are
/// 1..=5 in declaration order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum HeadCommand {
    /// 1: track the ball.
    LookAtTheBall,
    /// 2: look straight ahead.
    LookForward,
    /// 3: look to the left.
    LookLeft,
    /// 4: look to the right.
    LookRight,
    /// 5: scan left and right.
    Scan,
}

impl HeadCommand {
    /// All head commands, in wire order.
    pub const ALL: [HeadCommand; 5] = [
        HeadCommand::LookAtTheBall,
        HeadCommand::LookForward,
        HeadCommand::LookLeft,
        HeadCommand::LookRight,
        HeadCommand::Scan,
    ];

    /// The byte the robot expects (1..=5).
    pub fn wire_value(self) -> u8 {
        match self {
            HeadCommand::LookAtTheBall => 1,
            HeadCommand::LookForward => 2,
            HeadCommand::LookLeft => 3,
            HeadCommand::LookRight => 4,
            HeadCommand::Scan => 5,
        }
    }

    /// The command for a wire byte; `None` for 0 ("keep") and unknown values.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value).checked_sub(1)?).copied()
    }
}

/// Team strategy. The one numbering of this project is the robot's: `Default` = 0,
/// `Passages` = 1 on the wire. The original operator GUI numbered 1 Default, 2 Passages,
/// 3 Defence; [`Strategy::from_gui_number`] maps that numbering at the edge (Defence has no robot
/// counterpart and is refused).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum Strategy {
    /// Wire 0: the robot's default play.
    #[default]
    Default,
    /// Wire 1: play through passes.
    Passages,
}

impl Strategy {
    /// The byte the robot reads (0 or 1).
    pub fn wire_value(self) -> u8 {
        match self {
            Strategy::Default => 0,
            Strategy::Passages => 1,
        }
    }

    /// The strategy for a robot wire byte.
    pub fn from_wire(value: u8) -> Option<Self> {
        match value {
            0 => Some(Strategy::Default),
            1 => Some(Strategy::Passages),
            _ => None,
        }
    }

    /// The strategy for the original operator GUI's number (1 Default, 2 Passages); 3 (Defence)
    /// and anything else is `None` because the robot has no such strategy.
    pub fn from_gui_number(value: u8) -> Option<Self> {
        match value {
            1 => Some(Strategy::Default),
            2 => Some(Strategy::Passages),
            _ => None,
        }
    }
}

/// A typed operator command for the controlled robot: what one 11-byte packet carries.
///
/// At least one of `body` and `head` must be set (a packet never carries "nothing");
/// `target` is required by [`BodyCommand::needs_target`] bodies and ignored (sent as 0, 0)
/// otherwise. The strategy is always applied by the robot.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NaoCommand {
    /// New body command, or `None` to keep the robot's current one.
    pub body: Option<BodyCommand>,
    /// New head command, or `None` to keep the robot's current one.
    pub head: Option<HeadCommand>,
    /// Strategy (always replaced on the robot).
    pub strategy: Strategy,
    /// Target point (global, mm) for GoToPosition / Turn.
    pub target: Option<FieldPoint>,
}

/// Obstacle kinds of the debug packet (B-Human `Obstacle::Type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ObstacleKind {
    /// 0
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
        match self {
            ObstacleKind::Goalpost => 0,
            ObstacleKind::Unknown => 1,
            ObstacleKind::SomeRobot => 2,
            ObstacleKind::Opponent => 3,
            ObstacleKind::Teammate => 4,
            ObstacleKind::FallenSomeRobot => 5,
            ObstacleKind::FallenOpponent => 6,
            ObstacleKind::FallenTeammate => 7,
        }
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

    /// The kind for a wire byte, `None` when out of range.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value)).copied()
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

/// One obstacle of a robot's local model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Obstacle {
    /// What it is.
    pub kind: ObstacleKind,
    /// Centre, global (mm).
    pub center: FieldPoint,
    /// When it was last seen, robot clock (ms).
    pub last_seen_ms: u32,
}

/// The whistle detector's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum WhistleState {
    /// 0
    DontKnow,
    /// 1
    NotDetected,
    /// 2
    Detected,
}

impl WhistleState {
    /// The wire byte.
    pub fn wire_value(self) -> u8 {
        match self {
            WhistleState::DontKnow => 0,
            WhistleState::NotDetected => 1,
            WhistleState::Detected => 2,
        }
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

/// The player role byte: 17 autonomous, 18 controlled, anything else a B-Human `PlayerRole`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PlayerRole {
    /// 17: the autonomous teammate of the challenge.
    Autonomous,
    /// 18: the operator-controlled robot.
    Controlled,
    /// Any other B-Human role value, kept as sent.
    Other(u8),
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

/// Arm contact state of one arm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ArmContact {
    /// Whether the arm currently touches something.
    pub contact: bool,
    /// Push direction as sent (B-Human `ArmContactModel::PushDirection`).
    pub push_direction: u8,
    /// Robot-clock time of the last contact (ms).
    pub time_of_last_contact_ms: u32,
}

/// One robot's local world model, as decoded from a 356-byte debug packet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalWorldModel {
    /// Player number (1 autonomous teammate, 2 controlled robot in the challenge).
    pub player_number: u8,
    /// Team number.
    pub team_number: u8,
    /// Whether the robot is down.
    pub fallen: bool,
    /// Self-localisation (global).
    pub pose: Pose2,
    /// Seconds since the robot last saw the ball.
    pub ball_age_s: f32,
    /// Last seen ball position (global, mm).
    pub ball: FieldPoint,
    /// Role.
    pub role: PlayerRole,
    /// How many obstacles the robot sees (may exceed `obstacles.len()`, at most 20 are sent).
    pub obstacles_seen: u8,
    /// The first `min(obstacles_seen, 20)` obstacles.
    pub obstacles: Vec<Obstacle>,
    /// Team message budget left.
    pub message_budget: u16,
    /// Seconds remaining in the half.
    pub secs_remaining: u16,
    /// Left arm.
    pub left_arm: ArmContact,
    /// Right arm.
    pub right_arm: ArmContact,
    /// Time since the last whistle detection (ms).
    pub time_since_whistle_ms: u32,
    /// Whistle detector state.
    pub whistle: WhistleState,
    /// The robot's team ball estimate (global, mm).
    pub team_ball: FieldPoint,
    /// The team ball velocity (mm/s).
    pub team_ball_velocity: FieldPoint,
    /// Battery level as sent (B-Human: fraction 0..1).
    pub battery: f32,
    /// CPU temperature (degrees Celsius).
    pub cpu_temperature_c: f32,
    /// Referee gesture byte as sent (0: none).
    pub referee_gesture: u8,
}

/// GameController game state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum GameState {
    /// 0
    Initial,
    /// 1
    Ready,
    /// 2: no motion allowed.
    Set,
    /// 3
    Playing,
    /// 4
    Finished,
    /// 5
    Standby,
}

impl GameState {
    /// All states in wire order.
    pub const ALL: [GameState; 6] = [
        GameState::Initial,
        GameState::Ready,
        GameState::Set,
        GameState::Playing,
        GameState::Finished,
        GameState::Standby,
    ];

    /// Wire byte.
    pub fn wire_value(self) -> u8 {
        match self {
            GameState::Initial => 0,
            GameState::Ready => 1,
            GameState::Set => 2,
            GameState::Playing => 3,
            GameState::Finished => 4,
            GameState::Standby => 5,
        }
    }

    /// State for a wire byte.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value)).copied()
    }
}

/// GameController set play.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SetPlay {
    /// 0
    None,
    /// 1
    GoalKick,
    /// 2
    PushingFreeKick,
    /// 3
    CornerKick,
    /// 4
    KickIn,
    /// 5
    PenaltyKick,
}

impl SetPlay {
    /// All set plays in wire order.
    pub const ALL: [SetPlay; 6] = [
        SetPlay::None,
        SetPlay::GoalKick,
        SetPlay::PushingFreeKick,
        SetPlay::CornerKick,
        SetPlay::KickIn,
        SetPlay::PenaltyKick,
    ];

    /// Wire byte.
    pub fn wire_value(self) -> u8 {
        match self {
            SetPlay::None => 0,
            SetPlay::GoalKick => 1,
            SetPlay::PushingFreeKick => 2,
            SetPlay::CornerKick => 3,
            SetPlay::KickIn => 4,
            SetPlay::PenaltyKick => 5,
        }
    }

    /// Set play for a wire byte.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value)).copied()
    }
}

/// GameController game phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum GamePhase {
    /// 0
    Normal,
    /// 1
    PenaltyShootout,
    /// 2
    Overtime,
    /// 3
    Timeout,
}

impl GamePhase {
    /// All phases in wire order.
    pub const ALL: [GamePhase; 4] = [
        GamePhase::Normal,
        GamePhase::PenaltyShootout,
        GamePhase::Overtime,
        GamePhase::Timeout,
    ];

    /// Wire byte.
    pub fn wire_value(self) -> u8 {
        match self {
            GamePhase::Normal => 0,
            GamePhase::PenaltyShootout => 1,
            GamePhase::Overtime => 2,
            GamePhase::Timeout => 3,
        }
    }

    /// Phase for a wire byte.
    pub fn from_wire(value: u8) -> Option<Self> {
        Self::ALL.get(usize::from(value)).copied()
    }
}

/// Penalty of one player. Codes not listed on the protocol page are kept as `Other`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum Penalty {
    /// 0
    #[default]
    None,
    /// 1
    IllegalBallContact,
    /// 2
    Pushing,
    /// 3
    MotionInSet,
    /// 4
    Inactive,
    /// 5
    IllegalPosition,
    /// 6
    LeavingTheField,
    /// 7
    RequestForPickup,
    /// 8
    LocalGameStuck,
    /// 9
    IllegalPositionInSet,
    /// 10
    PlayerStance,
    /// 11
    MotionInStandby,
    /// 14
    Substitute,
    /// 15
    Manual,
    /// Any other code, as sent.
    Other(u8),
}

impl Penalty {
    /// Wire byte.
    pub fn wire_value(self) -> u8 {
        match self {
            Penalty::None => 0,
            Penalty::IllegalBallContact => 1,
            Penalty::Pushing => 2,
            Penalty::MotionInSet => 3,
            Penalty::Inactive => 4,
            Penalty::IllegalPosition => 5,
            Penalty::LeavingTheField => 6,
            Penalty::RequestForPickup => 7,
            Penalty::LocalGameStuck => 8,
            Penalty::IllegalPositionInSet => 9,
            Penalty::PlayerStance => 10,
            Penalty::MotionInStandby => 11,
            Penalty::Substitute => 14,
            Penalty::Manual => 15,
            Penalty::Other(v) => v,
        }
    }

    /// Penalty for a wire byte (total).
    pub fn from_wire(value: u8) -> Self {
        match value {
            0 => Penalty::None,
            1 => Penalty::IllegalBallContact,
            2 => Penalty::Pushing,
            3 => Penalty::MotionInSet,
            4 => Penalty::Inactive,
            5 => Penalty::IllegalPosition,
            6 => Penalty::LeavingTheField,
            7 => Penalty::RequestForPickup,
            8 => Penalty::LocalGameStuck,
            9 => Penalty::IllegalPositionInSet,
            10 => Penalty::PlayerStance,
            11 => Penalty::MotionInStandby,
            14 => Penalty::Substitute,
            15 => Penalty::Manual,
            v => Penalty::Other(v),
        }
    }
}

/// One player's entry in a team info.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct PlayerInfo {
    /// Current penalty.
    pub penalty: Penalty,
    /// Seconds until the penalty ends.
    pub secs_till_unpenalised: u8,
}

/// One team's block of the GameController packet.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TeamInfo {
    /// Team number.
    pub team_number: u8,
    /// Field player colour code.
    pub field_player_colour: u8,
    /// Goalkeeper colour code.
    pub goalkeeper_colour: u8,
    /// Goalkeeper's player number.
    pub goalkeeper: u8,
    /// Score.
    pub score: u8,
    /// Penalty shot counter.
    pub penalty_shot: u8,
    /// Single shots bit field.
    pub single_shots: u16,
    /// Team messages left.
    pub message_budget: u16,
    /// Players 1..=20 (index 0 is player 1).
    pub players: Vec<PlayerInfo>,
}

impl TeamInfo {
    /// The entry of player `number` (1-based), if any.
    pub fn player(&self, number: u8) -> Option<&PlayerInfo> {
        self.players.get(usize::from(number).checked_sub(1)?)
    }
}

/// A decoded GameController packet.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct GameControllerState {
    /// Packet number (wraps).
    pub packet_number: u8,
    /// Players per team.
    pub players_per_team: u8,
    /// Competition phase byte (0 round robin, 1 playoff).
    pub competition_phase: u8,
    /// Competition type byte (0 normal, 1 shared autonomy).
    pub competition_type: u8,
    /// Game phase.
    pub game_phase: GamePhase,
    /// Game state.
    pub state: GameState,
    /// Set play.
    pub set_play: SetPlay,
    /// Whether it is the first half.
    pub first_half: bool,
    /// Team number of the kicking team, `None` when the byte is 255.
    pub kicking_team: Option<u8>,
    /// Seconds remaining (may be negative in overtime).
    pub secs_remaining: i16,
    /// Secondary time (s), e.g. the set-play or READY countdown.
    pub secondary_time: i16,
    /// The two teams, ordered as sent (by the side they defend).
    pub teams: [TeamInfo; 2],
}

impl GameControllerState {
    /// Our team's info, found by team number.
    pub fn team(&self, team_number: u8) -> Option<&TeamInfo> {
        self.teams.iter().find(|t| t.team_number == team_number)
    }

    /// The other team's info, when `team_number` is one of the two.
    pub fn opponent_of(&self, team_number: u8) -> Option<&TeamInfo> {
        let ours = self
            .teams
            .iter()
            .position(|t| t.team_number == team_number)?;
        self.teams.get(1 - ours)
    }
}

/// Link state changes of one robot (see `LinkMonitor` of the Nao bridge).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum LinkEvent {
    /// The first packet ever arrived.
    Established {
        /// Time of the packet (s).
        at_s: f64,
    },
    /// No packet for longer than the timeout: the robot is not responding.
    RobotNotResponding {
        /// Time of detection (s).
        at_s: f64,
        /// Time of the last packet (s), `None` if none ever came.
        last_packet_s: Option<f64>,
    },
    /// Packets are coming again after a `RobotNotResponding`.
    LinkRestored {
        /// Time of the packet (s).
        at_s: f64,
        /// How long the link was silent (s).
        silent_for_s: f64,
    },
}

/// A robot in the global world model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TeamRobot {
    /// Player number.
    pub player_number: u8,
    /// Role.
    pub role: PlayerRole,
    /// Last reported pose.
    pub pose: Pose2,
    /// Whether it is down.
    pub fallen: bool,
    /// Seconds since its last packet.
    pub age_s: f64,
}

/// The filtered ball of the global world model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BallEstimate {
    /// Position (global, mm), predicted to the model's time.
    pub position: FieldPoint,
    /// Velocity (mm/s).
    pub velocity: FieldPoint,
    /// Seconds since any robot last saw the ball.
    pub age_s: f64,
    /// Position standard deviation (mm, root of the mean of the two variances).
    pub sigma_mm: f64,
    /// Confidence in [0, 1].
    pub confidence: f64,
}

/// A tracked obstacle of the global world model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackedObstacle {
    /// The track's identity: stable while it lives, never reused by the same fusion (names
    /// its DR node, `obstacle_<id>`).
    pub id: u32,
    /// Most specific kind seen.
    pub kind: ObstacleKind,
    /// Smoothed centre (global, mm).
    pub center: FieldPoint,
    /// Seconds since last seen by any robot.
    pub age_s: f64,
    /// How many observations were associated with it.
    pub observations: u32,
}

/// The fused team world model (see [`crate::world_model::WorldModelFusion`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GlobalWorldModel {
    /// Time of the model (s, caller's clock).
    pub time_s: f64,
    /// Our robots, by player number.
    pub robots: Vec<TeamRobot>,
    /// The ball, when it has been seen.
    pub ball: Option<BallEstimate>,
    /// Obstacles (other robots, goalposts), excluding our own robots.
    pub obstacles: Vec<TrackedObstacle>,
    /// Whether the autonomous teammate is nearer the ball than the controlled robot (the
    /// original GUI's "autonomous is striker"); `None` without both robots and a ball.
    pub autonomous_is_striker: Option<bool>,
    /// Overall confidence in [0, 1]: the ball's confidence times the freshness of the
    /// controlled robot's link.
    pub confidence: f64,
}
