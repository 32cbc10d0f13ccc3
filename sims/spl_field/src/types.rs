//! Plain data of the simulated field: configuration, identities, events and outgoing datagrams
//! (serde structs, ready to move to `interfaces` if the bus needs them).
//!
//! Units: millimetres, radians, seconds of simulated time.

use serde::{Deserialize, Serialize};
use spl::GameState;

/// Which side a robot plays for. `Us` attacks towards +x (the coach's team), `Them` defends the
/// goal at x = +4500 mm.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Side {
    /// The coach's team: player 1 autonomous, player 2 controlled.
    Us,
    /// The opponents: player 1 keeper, player 2 defender.
    Them,
}

/// A robot on the field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct RobotId {
    /// Team.
    pub side: Side,
    /// Player number (1 or 2).
    pub number: u8,
}

impl RobotId {
    /// Our autonomous teammate (player 1, role 17).
    pub const AUTONOMOUS: RobotId = RobotId {
        side: Side::Us,
        number: 1,
    };
    /// Our operator-controlled robot (player 2, role 18).
    pub const CONTROLLED: RobotId = RobotId {
        side: Side::Us,
        number: 2,
    };
    /// The opponents' keeper.
    pub const KEEPER: RobotId = RobotId {
        side: Side::Them,
        number: 1,
    };
    /// The opponents' defender.
    pub const DEFENDER: RobotId = RobotId {
        side: Side::Them,
        number: 2,
    };
    /// All four robots in index order.
    pub const ALL: [RobotId; 4] = [
        RobotId::AUTONOMOUS,
        RobotId::CONTROLLED,
        RobotId::KEEPER,
        RobotId::DEFENDER,
    ];
}

/// Simulation parameters. `Default` is a plausible challenge attempt.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimConfig {
    /// Seed of every random draw (noise, falls).
    pub seed: u64,
    /// Our team number.
    pub team_number: u8,
    /// The opponents' team number.
    pub opponent_team_number: u8,
    /// Time in INITIAL before READY (s).
    pub initial_s: f64,
    /// Time in READY (s).
    pub ready_s: f64,
    /// Time in SET (s).
    pub set_s: f64,
    /// Length of the attack in PLAYING (s): 90 in the challenge.
    pub attack_s: f64,
    /// Ball rolling friction deceleration (mm/s²).
    pub ball_friction_mm_s2: f64,
    /// Walking speed (mm/s).
    pub walk_speed_mm_s: f64,
    /// Turning speed (rad/s).
    pub turn_speed_rad_s: f64,
    /// Falls per minute of a walking robot (0 disables falls).
    pub falls_per_min: f64,
    /// Time to get up after a fall (s).
    pub getup_s: f64,
    /// Camera half field of view (rad).
    pub camera_half_fov_rad: f64,
    /// Ball detection range (mm).
    pub ball_range_mm: f64,
    /// Robot detection range (mm).
    pub robot_range_mm: f64,
    /// Perception noise at 0 mm (mm).
    pub perception_sigma_mm: f64,
    /// Perception noise per mm of distance.
    pub perception_sigma_per_mm: f64,
    /// Self-localisation noise (mm).
    pub localisation_sigma_mm: f64,
    /// Robots that stand still in PLAYING (scripted scenarios, a robot out of play).
    pub passive_robots: Vec<RobotId>,
    /// A scripted penalty of the controlled robot: this many seconds into PLAYING (none when
    /// `None`). The GameController reports it (pushing, with the seconds left) and the robot
    /// stands still, executing no command, until it is over.
    pub penalty_at_s: Option<f64>,
    /// Length of a penalty (s).
    pub penalty_s: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            team_number: 19,
            opponent_team_number: 5,
            initial_s: 2.0,
            ready_s: 5.0,
            set_s: 3.0,
            attack_s: 90.0,
            ball_friction_mm_s2: 400.0,
            walk_speed_mm_s: 250.0,
            turn_speed_rad_s: 1.5,
            falls_per_min: 0.3,
            getup_s: 6.0,
            camera_half_fov_rad: 30f64.to_radians(),
            ball_range_mm: 6000.0,
            robot_range_mm: 4500.0,
            perception_sigma_mm: 15.0,
            perception_sigma_per_mm: 0.02,
            localisation_sigma_mm: 20.0,
            passive_robots: Vec::new(),
            penalty_at_s: None,
            penalty_s: 45.0,
        }
    }
}

/// Something that happened on the field, with its simulated time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SimEvent {
    /// The GameController state changed.
    StateChanged {
        /// New state.
        state: GameState,
    },
    /// A robot kicked the ball (a kick, a clearance or a pass; not a dribble touch).
    Kick {
        /// Who.
        by: RobotId,
        /// Ball speed after the kick (mm/s).
        speed_mm_s: f64,
    },
    /// A robot touched the ball (contact, dribble, interception).
    Touch {
        /// Who.
        by: RobotId,
    },
    /// A completed pass: kicked over 1 m, then touched by a teammate before an opponent.
    PassCompleted {
        /// Kicker.
        from: RobotId,
        /// Receiver.
        to: RobotId,
        /// Ball travel from the kick to the touch (mm).
        distance_mm: f64,
    },
    /// A goal.
    Goal {
        /// Scoring side.
        side: Side,
        /// Whether it counts (the controlled robot may not score directly).
        counted: bool,
    },
    /// The ball left the field and was put back in.
    BallOut,
    /// A robot fell.
    Fell {
        /// Who.
        robot: RobotId,
    },
    /// A robot got up.
    GotUp {
        /// Who.
        robot: RobotId,
    },
    /// The GameController penalised a robot.
    Penalised {
        /// Who.
        robot: RobotId,
    },
    /// A robot's penalty is over.
    Unpenalised {
        /// Who.
        robot: RobotId,
    },
    /// A command packet was applied to the controlled robot.
    CommandApplied,
}

/// A datagram the simulation wants sent, as it would appear on the wire.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Datagram {
    /// A robot's 356-byte debug packet, to the operator's port 65305.
    Debug {
        /// Our player number.
        player: u8,
        /// Packet bytes.
        bytes: Vec<u8>,
    },
    /// A 118-byte GameController packet, to port 3838.
    GameController {
        /// Packet bytes.
        bytes: Vec<u8>,
    },
}
