//! The GameController packet's data types, as plain serde structs, and the Nao link's bus
//! messages re-exported from `interfaces::msg::nao` (their one definition).
//!
//! The command ([`NaoCommand`]), a robot's local model ([`NaoLocalModel`]) and the fused team
//! model ([`NaoWorldModel`]) are bus messages: the codecs ([`crate::command`], [`crate::debug`])
//! and the fusion ([`crate::world_model`]) read and write them directly, so nothing converts
//! between copies. The GameController packet ([`GameControllerState`]) is the protocol's own:
//! the bus carries a summary of it, our team first ([`GameControllerState::message`]).
//!
//! Conventions: global field frame, millimetres, origin at the centre spot, x towards the
//! opponent goal, y to the left, angles in radians counter-clockwise from +x. Times are seconds
//! (`_s`) of the caller's clock unless the name says `_ms` (robot-clock milliseconds).

use serde::{Deserialize, Serialize};

pub use interfaces::msg::nao::{
    FieldPoint, FieldPose, NaoBody, NaoCommand, NaoHead, NaoLocalModel, NaoObstacle, NaoStrategy,
    NaoWorldModel, ObstacleKind, PlayerRole, TeamRobot, TrackedObstacle, WhistleState,
};

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

    /// The bus's summary of the packet (`nao/game_state`): our team (by number) first, the
    /// other second; in the packet's order when our number is not in it (`our_team_found`
    /// false). The header is left for the publisher to stamp.
    pub fn message(&self, our_team: u8) -> interfaces::msg::nao::GameState {
        use interfaces::msg::nao::{PlayerPenalty, TeamStatus};
        let status = |t: &TeamInfo| TeamStatus {
            team_number: t.team_number,
            score: t.score,
            message_budget: t.message_budget,
            players: t
                .players
                .iter()
                .map(|p| PlayerPenalty {
                    penalty: p.penalty.wire_value(),
                    secs_till_unpenalised: p.secs_till_unpenalised,
                })
                .collect(),
        };
        let ours = self.team(our_team);
        let (our, their) = match (ours, self.opponent_of(our_team)) {
            (Some(o), Some(t)) => (status(o), status(t)),
            _ => (status(&self.teams[0]), status(&self.teams[1])),
        };
        interfaces::msg::nao::GameState {
            header: Default::default(),
            state: self.state.wire_value(),
            set_play: self.set_play.wire_value(),
            game_phase: self.game_phase.wire_value(),
            first_half: self.first_half,
            kicking_team: self.kicking_team.unwrap_or(255),
            secs_remaining: self.secs_remaining,
            secondary_time: self.secondary_time,
            our_team_found: ours.is_some(),
            our_team: our,
            opponent: their,
        }
    }
}
