//! Every topic and service of robocog, as typed constants.

use crate::msg::{diag::Diagnostics, std_msgs};
use crate::topic::{Service, Topic};

/// Each component's counters (decode failures, drops by reason), about once a second.
pub const DIAGNOSTICS: Topic<Diagnostics> = Topic::new("diagnostics");

/// Free text, for fixtures and demos.
pub const CHATTER: Topic<std_msgs::Text> = Topic::new("chatter");
/// An echo service (fixtures, health checks): replies with the request's text.
pub const ECHO: Service<std_msgs::Text, std_msgs::Text> = Service::new("echo");

/// The bus benchmark's probes.
pub const BENCH_PING: Topic<std_msgs::Ping> = Topic::new("bench/ping");
pub const BENCH_PONG: Topic<std_msgs::Ping> = Topic::new("bench/pong");
pub const BENCH_COUNT: Topic<std_msgs::Counter64> = Topic::new("bench/count");
pub const BENCH_FRAME: Topic<crate::msg::vision::RgbdFrame> = Topic::new("bench/frame");
pub const BENCH_FRAME_BACK: Topic<crate::msg::vision::RgbdFrame> = Topic::new("bench/frame_back");

// deep_representation
/// The world model's change events, in order (every accepted change of the live graph).
pub const DR_CHANGES: Topic<crate::msg::dr::DrChange> = Topic::new("dr/changes");
/// One node of the world model by name.
pub const DR_GET_NODE: Service<crate::msg::dr::GetNodeRequest, crate::msg::dr::NodeInfo> =
    Service::new("dr/get_node");
/// `target_T_source`, now or at a past time.
pub const DR_TRANSFORM: Service<crate::msg::dr::TransformRequest, crate::msg::dr::TransformReply> =
    Service::new("dr/transform");
/// Perception and odometry updates (attributes, free poses, joint values), applied straight in.
pub const DR_UPDATE: Service<crate::msg::dr::UpdateRequest, crate::msg::dr::UpdateReply> =
    Service::new("dr/update");
/// A structural change, accepted or rejected with the reason.
pub const DR_PROPOSE: Service<crate::msg::dr::ProposeRequest, crate::msg::dr::ProposeReply> =
    Service::new("dr/propose");
/// Whether a predicate holds (or every fact that holds).
pub const DR_PREDICATE: Service<crate::msg::dr::PredicateRequest, crate::msg::dr::PredicateReply> =
    Service::new("dr/predicate");
/// Virtual actions on a private copy; the predicate changes and the differences.
pub const DR_FORK: Service<crate::msg::dr::ForkRequest, crate::msg::dr::ForkReply> =
    Service::new("dr/fork");
/// The state as a PDDL problem.
pub const DR_PDDL: Service<crate::msg::dr::PddlRequest, crate::msg::dr::PddlReply> =
    Service::new("dr/pddl");
/// The state as snapshot JSON.
pub const DR_SNAPSHOT: Service<crate::msg::dr::SnapshotRequest, crate::msg::dr::SnapshotData> =
    Service::new("dr/snapshot");
/// Replace the state with a snapshot (replies with the new state's snapshot).
pub const DR_RESTORE: Service<crate::msg::dr::SnapshotData, crate::msg::dr::SnapshotData> =
    Service::new("dr/restore");
