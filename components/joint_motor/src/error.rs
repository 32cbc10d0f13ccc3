//! The typed errors of this crate: every refusal names the joint, the limit or the owner.

use thiserror::Error;

/// Which limit a goal broke.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LimitKind {
    /// The lower position limit (rad or m).
    Lower,
    /// The upper position limit (rad or m).
    Upper,
    /// The joint's maximum velocity (rad/s or m/s).
    MaxVelocity,
}

impl std::fmt::Display for LimitKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Lower => "lower position limit",
            Self::Upper => "upper position limit",
            Self::MaxVelocity => "maximum velocity",
        })
    }
}

/// Why a goal, a configuration or a driver operation failed.
#[derive(Debug, Error, PartialEq)]
pub enum JointError {
    #[error("unknown joint `{0}`")]
    UnknownJoint(String),
    #[error("joint `{joint}`: requested {requested} is beyond its {limit} {limit_value}")]
    OutOfLimits {
        joint: String,
        limit: LimitKind,
        limit_value: f64,
        requested: f64,
    },
    #[error("joint `{joint}`: {what} must be finite and positive, got {value}")]
    InvalidValue {
        joint: String,
        what: &'static str,
        value: f64,
    },
    #[error("joint `{joint}` named twice in one goal")]
    DuplicateTarget { joint: String },
    #[error("joint `{joint}` is owned by client `{owner}` (priority {owner_priority})")]
    Owned {
        joint: String,
        owner: String,
        owner_priority: u8,
    },
    #[error("driver `{driver}` does not support {what} (joint `{joint}`)")]
    Unsupported {
        driver: &'static str,
        joint: String,
        what: &'static str,
    },
    #[error("unknown driver `{0}` (known: sim, dynamixel)")]
    UnknownDriver(String),
    #[error("invalid configuration at `{key}`: {reason}")]
    Config { key: String, reason: String },
    #[error("servo bus: {0}")]
    Bus(String),
    #[error("neck: {0}")]
    Neck(#[from] crate::stewart::NeckError),
    #[error("time went backwards: {now_s} s after {last_s} s")]
    TimeWentBack { now_s: f64, last_s: f64 },
}

impl JointError {
    pub(crate) fn config(key: impl Into<String>, reason: impl Into<String>) -> Self {
        Self::Config {
            key: key.into(),
            reason: reason.into(),
        }
    }
}
