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
