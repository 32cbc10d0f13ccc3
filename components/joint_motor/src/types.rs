//! The joint driver's data types: plain serde structs. The joint states are the bus message of
//! `interfaces::msg::body` (re-exported here); the goal types are the library's own, checked
//! and read from `body/joint_goal` in [`crate::bus`] (why: [`JointGoal`]).
//!
//! Units: revolute joints in rad, rad/s, rad/s², effort in N·m; prismatic joints in m, m/s, m/s²,
//! effort in N. Times are seconds on the caller's clock (`now_s`), never read from the wall clock
//! inside this crate's algorithms.

use serde::{Deserialize, Serialize};

/// A joint's measured state and all joints at one instant: the `body/joint_states` message
/// itself (effort flagged by `has_effort`, `owner` empty when nobody owns the joint).
pub use interfaces::msg::body::{JointState, JointStates};

/// Whether a joint turns or slides, which fixes the units of its position (rad or m): the
/// workspace's one joint kind (the drivers see only revolute and prismatic joints).
pub use interfaces::msg::dr::JointKind;

/// One joint as the drivers know it (filled from the URDF by the component).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// Unique joint name, as in the URDF.
    pub name: String,
    pub kind: JointKind,
    /// Lowest allowed position (rad or m).
    pub lower: f64,
    /// Highest allowed position (rad or m).
    pub upper: f64,
    /// Largest allowed speed magnitude (rad/s or m/s), > 0.
    pub max_velocity: f64,
    /// Largest allowed acceleration magnitude (rad/s² or m/s²), > 0.
    pub max_acceleration: f64,
}

impl JointSpec {
    /// A revolute joint spec (rad, rad/s, rad/s²).
    pub fn revolute(
        name: &str,
        lower_rad: f64,
        upper_rad: f64,
        max_vel: f64,
        max_acc: f64,
    ) -> Self {
        Self {
            name: name.to_owned(),
            kind: JointKind::Revolute,
            lower: lower_rad,
            upper: upper_rad,
            max_velocity: max_vel,
            max_acceleration: max_acc,
        }
    }

    /// A prismatic joint spec (m, m/s, m/s²).
    pub fn prismatic(name: &str, lower_m: f64, upper_m: f64, max_vel: f64, max_acc: f64) -> Self {
        Self {
            kind: JointKind::Prismatic,
            ..Self::revolute(name, lower_m, upper_m, max_vel, max_acc)
        }
    }
}

/// What one joint is asked to do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "mode")]
pub enum JointCommand {
    /// Go to `position` (rad or m) moving no faster than `max_speed` (rad/s or m/s, > 0 and at most
    /// the joint's `max_velocity`), then hold it.
    Position { position: f64, max_speed: f64 },
    /// Move at `velocity` (rad/s or m/s, |velocity| ≤ the joint's `max_velocity`) until another
    /// goal; the joint still stops at its position limits.
    Velocity { velocity: f64 },
}

/// One joint's target inside a [`JointGoal`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointTarget {
    pub joint: String,
    pub command: JointCommand,
}

/// A goal from one client for some joints (read from a `body/joint_goal` request by
/// [`crate::bus::request_from_msg`]; the component's start posture is one too).
///
/// Accepted or refused as a whole: if any joint is unknown, out of limits or owned by another
/// client of equal or higher priority, nothing moves (see the crate docs for ownership).
///
/// Why not the bus message itself (`interfaces::msg::body::JointGoal`): that one is one shape for
/// two requests (a goal, or with `release` a give-back) and each target carries `mode` plus every
/// mode's fields (`position`, `max_speed`, `velocity`; the others ignored), as a CDR message must
/// without tagged fields. This type is what is left once the request is checked: a goal only
/// (the give-back is [`JointRelease`]), with at least one target and a client, each target's
/// command the [`JointCommand`] of its mode with exactly that mode's values. The driver and the
/// ownership code match on it and cannot read a field that does not apply.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointGoal {
    /// Who sends it (e.g. the component name); owns the named joints once accepted.
    pub client: String,
    /// Higher wins: a goal may take joints from a live owner only with a strictly higher priority.
    #[serde(default)]
    pub priority: u8,
    pub targets: Vec<JointTarget>,
}

/// A client gives joints back (a `body/joint_goal` request with `release`). Empty `joints` = all
/// it owns.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointRelease {
    pub client: String,
    #[serde(default)]
    pub joints: Vec<String>,
}

/// Health counters of a servo bus link (zero for the `sim` driver).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct LinkStats {
    /// Instruction packets sent (first tries and retries).
    pub transactions: u64,
    /// Expected status packets not validly received within the read timeout (never came, or
    /// came with a bad CRC or the wrong length).
    pub missing_replies: u64,
    /// Status packets dropped for a bad CRC.
    pub crc_errors: u64,
    /// Bytes or packets that did not parse (bad header, length, instruction, unexpected id).
    pub malformed: u64,
    /// Status packets whose error byte was not zero.
    pub servo_errors: u64,
    /// Repeated instructions after one of the above.
    pub retries: u64,
    /// Operations that still failed after all retries (reported to the caller as errors).
    pub failures: u64,
}
