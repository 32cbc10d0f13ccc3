//! Error types of the deep representation.
//!
//! Every fallible operation returns [`DrError`]; structural changes that break an integrity rule are
//! not errors but [`crate::graph::Rejection`]s carrying a [`crate::graph::RejectReason`].

use thiserror::Error;

/// Errors of the deep representation library.
#[derive(Debug, Error)]
pub enum DrError {
    /// The URDF text could not be parsed (bad XML, missing required attributes, bad numbers).
    #[error("malformed URDF: {0}")]
    MalformedUrdf(String),
    /// The URDF parsed but is not a tree (no single root, a link with two parents, a joint that
    /// names an undeclared link, an unsupported joint type, a zero axis).
    #[error("invalid URDF model: {0}")]
    InvalidModel(String),
    /// A model or snapshot file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The path that was read.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A frame (link, sensor, object, agent or landmark node) name that is not in the graph/model.
    #[error("unknown frame `{0}`")]
    UnknownFrame(String),
    /// A joint name that is not in the graph/model.
    #[error("unknown joint `{0}`")]
    UnknownJoint(String),
    /// A body part name that is not one of the documented names (see `robot_model::BodyPart`).
    #[error("unknown body part `{0}` (known: {1})")]
    UnknownBodyPart(String, String),
    /// `root` is not an ancestor of `tip`, so there is no open chain from one to the other.
    #[error("no kinematic chain from `{root}` to `{tip}`: `{root}` is not an ancestor of `{tip}`")]
    NotAChain {
        /// Chain root link.
        root: String,
        /// Chain tip link.
        tip: String,
    },
    /// A joint vector has the wrong length for the chain.
    #[error("joint vector has {got} values, the chain has {expected} joints")]
    JointCount {
        /// Joints in the chain.
        expected: usize,
        /// Values passed.
        got: usize,
    },
    /// A joint value that is NaN or infinite.
    #[error("joint `{0}`: value is not finite")]
    NonFiniteValue(String),
    /// The edge is not a joint (it is fixed or a free pose) and cannot take a joint value,
    /// or it is a joint and cannot take a free pose.
    #[error("edge into `{0}` has the wrong kind for this update: {1}")]
    WrongEdgeKind(String, &'static str),
    /// A query time older than the oldest sample kept in an edge's history.
    #[error(
        "time {requested_ns} ns is older than the history of `{frame}` (oldest {oldest_ns} ns)"
    )]
    TimeOutOfHistory {
        /// The node whose edge history is too short.
        frame: String,
        /// The requested stamp.
        requested_ns: u64,
        /// The oldest stamp kept.
        oldest_ns: u64,
    },
    /// A snapshot file that is not valid JSON or not a valid scene graph.
    #[error("corrupt snapshot: {0}")]
    CorruptSnapshot(String),
    /// A field model file that cannot be parsed.
    #[error("invalid field model: {0}")]
    InvalidField(String),
    /// A PDDL text that the small problem parser does not accept.
    #[error("PDDL parse error: {0}")]
    PddlParse(String),
    /// A structural change (e.g. adding a robot) broke an integrity rule.
    #[error(transparent)]
    Rejected(Box<crate::graph::Rejection>),
    /// A change-log event that cannot be applied to this graph.
    #[error("cannot apply change event: {0}")]
    BadEvent(String),
}

impl From<robot_model::ModelError> for DrError {
    fn from(e: robot_model::ModelError) -> Self {
        use robot_model::ModelError as M;
        match e {
            M::MalformedUrdf(m) => DrError::MalformedUrdf(m),
            M::InvalidModel(m) => DrError::InvalidModel(m),
            M::Io { path, source } => DrError::Io { path, source },
            M::UnknownFrame(f) => DrError::UnknownFrame(f),
            M::UnknownJoint(j) => DrError::UnknownJoint(j),
            M::UnknownBodyPart(p, known) => DrError::UnknownBodyPart(p, known),
            M::NotAChain { root, tip } => DrError::NotAChain { root, tip },
            M::JointCount { expected, got } => DrError::JointCount { expected, got },
            M::NonFiniteValue(j) => DrError::NonFiniteValue(j),
        }
    }
}

/// Result alias of the crate.
pub type Result<T, E = DrError> = std::result::Result<T, E>;
