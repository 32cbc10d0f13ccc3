//! General-purpose messages: text, the benchmark's ping, counters.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// A line of text (logs, test fixtures, echo services).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Text {
    pub header: Header,
    pub text: String,
}

/// An opaque payload of any size: the bus benchmark's probe.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Ping {
    pub header: Header,
    /// When the probe left its sender, on the sender's monotonic clock (ns).
    pub sent_ns: u64,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// A single counter value (8 bytes of payload): the throughput probe.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Counter64 {
    pub header: Header,
    pub value: u64,
}

/// The time of a replayed recording, on `clock`: components started with `--clock bus` take it
/// as their clock (ROS' `/clock`). `robocog replay` publishes it before each message it replays
/// (and, between messages, as the recorded time passes).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClockTime {
    pub header: Header,
    /// The time, nanoseconds since the Unix epoch; it only moves forward.
    pub time_ns: i64,
}
