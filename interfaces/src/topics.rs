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
