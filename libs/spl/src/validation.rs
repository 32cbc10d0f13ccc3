//! Input validation: typed decode errors, drop counters per reason, a rate-limited drop logger
//! and the source-address filter.
//!
//! Every received datagram either decodes or yields a [`PacketError`]; the caller hands the
//! error to a [`DropMonitor`], which counts it under its [`DropReason`] and logs at most one line
//! per reason per interval (the rest are counted and summarised on the next line). Time is
//! passed in as seconds of the caller's clock.

use std::collections::BTreeMap;
use std::fmt;
use std::net::{IpAddr, SocketAddr};

use serde::{Deserialize, Serialize};

/// Which packet a decoder was reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum PacketKind {
    /// Operator -> robot command (11 bytes).
    Command,
    /// Robot -> operator debug packet (356 bytes).
    Debug,
    /// GameController -> robots (118 bytes).
    GameController,
}

impl fmt::Display for PacketKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PacketKind::Command => "command",
            PacketKind::Debug => "debug",
            PacketKind::GameController => "gamecontroller",
        })
    }
}

/// Why a received packet was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PacketError {
    /// The datagram's length is not the packet's.
    #[error("{kind} packet of {got} bytes, expected {expected}")]
    WrongSize {
        /// Packet being decoded.
        kind: PacketKind,
        /// Expected length.
        expected: usize,
        /// Received length.
        got: usize,
    },
    /// The 4-byte header is not the expected one.
    #[error("{kind} packet with header {found:?}, expected {expected:?}")]
    WrongHeader {
        /// Packet being decoded.
        kind: PacketKind,
        /// Expected header.
        expected: [u8; 4],
        /// Received header bytes.
        found: [u8; 4],
    },
    /// The version byte is not the supported one.
    #[error("{kind} packet version {found}, expected {expected}")]
    UnknownVersion {
        /// Packet being decoded.
        kind: PacketKind,
        /// Supported version.
        expected: u8,
        /// Received version.
        found: u8,
    },
    /// A float field is NaN or infinite.
    #[error("{kind} packet field {field} is not finite")]
    NonFinite {
        /// Packet being decoded.
        kind: PacketKind,
        /// Field name.
        field: &'static str,
    },
    /// An enumerated or bounded field holds a value outside its range.
    #[error("{kind} packet field {field} has invalid value {value}")]
    InvalidValue {
        /// Packet being decoded.
        kind: PacketKind,
        /// Field name.
        field: &'static str,
        /// Received value.
        value: u32,
    },
    /// A command packet with neither a body nor a head command.
    #[error("command packet carries neither a body nor a head command")]
    EmptyCommand,
    /// The datagram came from an address that is not configured.
    #[error("{kind} packet from unknown source {source_addr}")]
    UnknownSource {
        /// Packet being received.
        kind: PacketKind,
        /// Sender.
        source_addr: SocketAddr,
    },
}

/// The reason under which a [`PacketError`] is counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum DropReason {
    /// [`PacketError::WrongSize`]
    WrongSize,
    /// [`PacketError::WrongHeader`]
    WrongHeader,
    /// [`PacketError::UnknownVersion`]
    UnknownVersion,
    /// [`PacketError::NonFinite`]
    NonFinite,
    /// [`PacketError::InvalidValue`]
    InvalidValue,
    /// [`PacketError::EmptyCommand`]
    EmptyCommand,
    /// [`PacketError::UnknownSource`]
    UnknownSource,
}

impl DropReason {
    /// All reasons, in rendering order.
    pub const ALL: [DropReason; 7] = [
        DropReason::WrongSize,
        DropReason::WrongHeader,
        DropReason::UnknownVersion,
        DropReason::NonFinite,
        DropReason::InvalidValue,
        DropReason::EmptyCommand,
        DropReason::UnknownSource,
    ];

    /// Short snake_case name, used when rendering counters.
    pub fn name(self) -> &'static str {
        match self {
            DropReason::WrongSize => "wrong_size",
            DropReason::WrongHeader => "wrong_header",
            DropReason::UnknownVersion => "unknown_version",
            DropReason::NonFinite => "non_finite",
            DropReason::InvalidValue => "invalid_value",
            DropReason::EmptyCommand => "empty_command",
            DropReason::UnknownSource => "unknown_source",
        }
    }
}

impl PacketError {
    /// The counter this error goes to.
    pub fn reason(&self) -> DropReason {
        match self {
            PacketError::WrongSize { .. } => DropReason::WrongSize,
            PacketError::WrongHeader { .. } => DropReason::WrongHeader,
            PacketError::UnknownVersion { .. } => DropReason::UnknownVersion,
            PacketError::NonFinite { .. } => DropReason::NonFinite,
            PacketError::InvalidValue { .. } => DropReason::InvalidValue,
            PacketError::EmptyCommand => DropReason::EmptyCommand,
            PacketError::UnknownSource { .. } => DropReason::UnknownSource,
        }
    }

    /// The packet kind concerned.
    pub fn kind(&self) -> PacketKind {
        match self {
            PacketError::WrongSize { kind, .. }
            | PacketError::WrongHeader { kind, .. }
            | PacketError::UnknownVersion { kind, .. }
            | PacketError::NonFinite { kind, .. }
            | PacketError::InvalidValue { kind, .. }
            | PacketError::UnknownSource { kind, .. } => *kind,
            PacketError::EmptyCommand => PacketKind::Command,
        }
    }
}

/// Dropped-packet counters, per packet kind and reason, plus accepted packets per kind.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DropCounters {
    dropped: BTreeMap<(PacketKind, DropReason), u64>,
    accepted: BTreeMap<PacketKind, u64>,
}

impl DropCounters {
    /// Count one dropped packet.
    pub fn count(&mut self, error: &PacketError) {
        *self
            .dropped
            .entry((error.kind(), error.reason()))
            .or_default() += 1;
    }

    /// Count one accepted packet.
    pub fn count_accepted(&mut self, kind: PacketKind) {
        *self.accepted.entry(kind).or_default() += 1;
    }

    /// Drops of `kind` for `reason`.
    pub fn get(&self, kind: PacketKind, reason: DropReason) -> u64 {
        self.dropped.get(&(kind, reason)).copied().unwrap_or(0)
    }

    /// Drops for `reason`, all kinds together.
    pub fn reason_total(&self, reason: DropReason) -> u64 {
        self.dropped
            .iter()
            .filter(|((_, r), _)| *r == reason)
            .map(|(_, n)| n)
            .sum()
    }

    /// All drops.
    pub fn total_dropped(&self) -> u64 {
        self.dropped.values().sum()
    }

    /// Accepted packets of `kind`.
    pub fn accepted(&self, kind: PacketKind) -> u64 {
        self.accepted.get(&kind).copied().unwrap_or(0)
    }

    /// One line, e.g. `accepted debug=12; dropped debug/wrong_size=3 command/empty_command=1`,
    /// or `...; dropped none`.
    pub fn render(&self) -> String {
        let accepted: Vec<String> = self
            .accepted
            .iter()
            .map(|(k, n)| format!("{k}={n}"))
            .collect();
        let dropped: Vec<String> = self
            .dropped
            .iter()
            .filter(|(_, n)| **n > 0)
            .map(|((k, r), n)| format!("{k}/{}={n}", r.name()))
            .collect();
        format!(
            "accepted {}; dropped {}",
            if accepted.is_empty() {
                "none".to_owned()
            } else {
                accepted.join(" ")
            },
            if dropped.is_empty() {
                "none".to_owned()
            } else {
                dropped.join(" ")
            }
        )
    }
}

/// Rate limiter for log lines: at most one line per key per `interval_s`; the lines it holds
/// back are counted and reported with the next line that passes.
#[derive(Debug, Clone)]
pub struct RateLimiter<K: Ord> {
    interval_s: f64,
    slots: BTreeMap<K, (f64, u64)>,
}

impl<K: Ord> RateLimiter<K> {
    /// A limiter letting one line per key through every `interval_s` seconds.
    pub fn new(interval_s: f64) -> Self {
        Self {
            interval_s,
            slots: BTreeMap::new(),
        }
    }

    /// Whether a line for `key` may be written at `now_s`. `Some(n)`: write it, `n` lines were
    /// suppressed since the previous one; `None`: suppressed (and counted).
    pub fn check(&mut self, key: K, now_s: f64) -> Option<u64> {
        match self.slots.get_mut(&key) {
            Some((last, suppressed)) if now_s - *last < self.interval_s => {
                *suppressed += 1;
                None
            }
            Some((last, suppressed)) => {
                let n = *suppressed;
                *last = now_s;
                *suppressed = 0;
                Some(n)
            }
            None => {
                self.slots.insert(key, (now_s, 0));
                Some(0)
            }
        }
    }
}

/// Counts every dropped packet and logs it through `tracing`, rate-limited per reason.
#[derive(Debug, Clone)]
pub struct DropMonitor {
    counters: DropCounters,
    limiter: RateLimiter<DropReason>,
}

impl Default for DropMonitor {
    fn default() -> Self {
        Self::new(1.0)
    }
}

impl DropMonitor {
    /// A monitor logging at most one line per reason per `log_interval_s`.
    pub fn new(log_interval_s: f64) -> Self {
        Self {
            counters: DropCounters::default(),
            limiter: RateLimiter::new(log_interval_s),
        }
    }

    /// Count `error` and maybe log it. Returns whether a line was logged.
    pub fn record(&mut self, error: &PacketError, now_s: f64) -> bool {
        self.counters.count(error);
        match self.limiter.check(error.reason(), now_s) {
            Some(suppressed) => {
                tracing::warn!(
                    reason = error.reason().name(),
                    suppressed,
                    "dropped packet: {error}"
                );
                true
            }
            None => false,
        }
    }

    /// Count an accepted packet.
    pub fn accepted(&mut self, kind: PacketKind) {
        self.counters.count_accepted(kind);
    }

    /// The counters.
    pub fn counters(&self) -> &DropCounters {
        &self.counters
    }
}

/// Accepts datagrams only from configured IP addresses (the robots', the GameController's).
/// An empty filter refuses everything.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SourceFilter {
    allowed: Vec<IpAddr>,
}

impl SourceFilter {
    /// A filter allowing `allowed` (any port).
    pub fn new(allowed: impl IntoIterator<Item = IpAddr>) -> Self {
        Self {
            allowed: allowed.into_iter().collect(),
        }
    }

    /// `Ok` when `from` is allowed, else [`PacketError::UnknownSource`].
    pub fn check(&self, kind: PacketKind, from: SocketAddr) -> Result<(), PacketError> {
        if self.allowed.contains(&from.ip()) {
            Ok(())
        } else {
            Err(PacketError::UnknownSource {
                kind,
                source_addr: from,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rate_limiter_lets_one_line_per_second_and_counts_the_rest() {
        let mut rl = RateLimiter::new(1.0);
        assert_eq!(rl.check(DropReason::WrongSize, 0.0), Some(0));
        for i in 1..10 {
            assert_eq!(rl.check(DropReason::WrongSize, f64::from(i) * 0.1), None);
        }
        // Another reason is not held back by the first one.
        assert_eq!(rl.check(DropReason::NonFinite, 0.5), Some(0));
        assert_eq!(rl.check(DropReason::WrongSize, 1.0), Some(9));
        assert_eq!(rl.check(DropReason::WrongSize, 1.5), None);
        assert_eq!(rl.check(DropReason::WrongSize, 2.0), Some(1));
    }

    #[test]
    fn drop_monitor_logs_once_per_reason_per_interval() {
        let mut m = DropMonitor::new(1.0);
        let e = PacketError::EmptyCommand;
        assert!(m.record(&e, 0.0));
        assert!(!m.record(&e, 0.2));
        assert!(!m.record(&e, 0.9));
        assert!(m.record(&e, 1.0));
        assert_eq!(
            m.counters()
                .get(PacketKind::Command, DropReason::EmptyCommand),
            4
        );
    }

    #[test]
    fn source_filter_refuses_unknown_addresses() {
        let f = SourceFilter::new(["10.0.0.2".parse().unwrap()]);
        assert!(
            f.check(PacketKind::Debug, "10.0.0.2:4000".parse().unwrap())
                .is_ok()
        );
        let err = f
            .check(PacketKind::Debug, "10.0.0.3:4000".parse().unwrap())
            .unwrap_err();
        assert_eq!(err.reason(), DropReason::UnknownSource);
        let mut c = DropCounters::default();
        c.count(&err);
        assert_eq!(c.get(PacketKind::Debug, DropReason::UnknownSource), 1);
        assert_eq!(c.render(), "accepted none; dropped debug/unknown_source=1");
    }
}
