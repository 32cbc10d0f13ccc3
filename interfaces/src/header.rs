//! The header every message carries; its stamp comes from the component's [`Clock`].

use serde::{Deserialize, Serialize};

pub use crate::clock::{Clock, system_now_ns};

/// Every message starts with this: when it was stamped, its sequence number on its publisher, and
/// the coordinate frame its geometry is expressed in (empty when it has none).
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Header {
    /// Nanoseconds since the Unix epoch on the publishing component's [`Clock`] (system or virtual).
    pub stamp_ns: i64,
    /// Per-publisher sequence number, from 0; a gap on a subscriber means a lost message.
    pub seq: u64,
    /// Frame of the message's geometry, a link or sensor name of the robot model or `world`.
    pub frame_id: String,
}

impl Header {
    pub fn new(frame_id: impl Into<String>) -> Self {
        Self {
            stamp_ns: 0,
            seq: 0,
            frame_id: frame_id.into(),
        }
    }
    /// The stamp in seconds.
    pub fn stamp_s(&self) -> f64 {
        self.stamp_ns as f64 * 1e-9
    }
}
