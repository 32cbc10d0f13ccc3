//! The header every message carries, and the clock components take their time from.

use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};

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

/// Where a component takes its time from. Components never read the wall clock for message stamps
/// or timers directly: a replay drives a [`Clock::Virtual`] from the recording.
#[derive(Debug, Clone, Default)]
pub enum Clock {
    /// The system's real-time clock.
    #[default]
    System,
    /// A clock set from outside (a replay, a test); nanoseconds since the epoch.
    Virtual(Arc<AtomicI64>),
}

impl Clock {
    /// A virtual clock starting at `start_ns`.
    pub fn virtual_at(start_ns: i64) -> Self {
        Clock::Virtual(Arc::new(AtomicI64::new(start_ns)))
    }
    /// Now, in nanoseconds since the epoch.
    pub fn now_ns(&self) -> i64 {
        match self {
            Clock::System => system_now_ns(),
            Clock::Virtual(t) => t.load(Ordering::Acquire),
        }
    }
    /// Move a virtual clock to `t_ns` (ignored on the system clock).
    pub fn set_ns(&self, t_ns: i64) {
        if let Clock::Virtual(t) = self {
            t.store(t_ns, Ordering::Release);
        }
    }
    /// Advance a virtual clock by `dt_ns` (ignored on the system clock).
    pub fn advance_ns(&self, dt_ns: i64) {
        if let Clock::Virtual(t) = self {
            t.fetch_add(dt_ns, Ordering::AcqRel);
        }
    }
}

/// The system clock in nanoseconds since the epoch (0 if the clock is before 1970).
pub fn system_now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as i64)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn virtual_clock_moves_only_when_told() {
        let c = Clock::virtual_at(1_000);
        assert_eq!(c.now_ns(), 1_000);
        c.advance_ns(500);
        assert_eq!(c.now_ns(), 1_500);
        c.set_ns(10);
        assert_eq!(c.now_ns(), 10);
        let s = Clock::System;
        assert!(s.now_ns() > 1_600_000_000_000_000_000);
    }
}
