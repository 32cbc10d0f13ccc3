//! Link-loss detection for one robot: no valid packet for `timeout_s` => "robot not responding",
//! then "link restored" at the next packet. Pure: time (s, caller's clock) is passed in.

use interfaces::msg::nao::{LinkChange, NaoLinkEvent};

/// Link state changes of one robot, with the monitor's times.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinkEvent {
    /// The first packet ever arrived.
    Established {
        /// Time of the packet (s).
        at_s: f64,
    },
    /// No packet for longer than the timeout: the robot is not responding.
    RobotNotResponding {
        /// Time of detection (s).
        at_s: f64,
        /// Time of the last packet (s), `None` if none ever came.
        last_packet_s: Option<f64>,
    },
    /// Packets are coming again after a `RobotNotResponding`.
    LinkRestored {
        /// Time of the packet (s).
        at_s: f64,
        /// How long the link was silent (s).
        silent_for_s: f64,
    },
}

impl LinkEvent {
    /// The `nao/link` message of player `player` for this event: for `RobotNotResponding`, the
    /// silence so far (the detection time when no packet ever came); for `LinkRestored`, how
    /// long it was silent. The header is left for the publisher to stamp.
    pub fn message(&self, player: u8) -> NaoLinkEvent {
        let (change, silent_for_s) = match *self {
            LinkEvent::Established { .. } => (LinkChange::Established, 0.0),
            LinkEvent::RobotNotResponding {
                at_s,
                last_packet_s,
            } => (
                LinkChange::RobotNotResponding,
                last_packet_s.map_or(at_s, |t| at_s - t),
            ),
            LinkEvent::LinkRestored { silent_for_s, .. } => (LinkChange::Restored, silent_for_s),
        };
        NaoLinkEvent {
            header: Default::default(),
            player_number: player,
            change,
            silent_for_s,
        }
    }
}

/// Whether the link is considered up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkState {
    /// No packet yet, and the start-up grace period has not run out.
    Waiting,
    /// Packets arrive.
    Up,
    /// Silent for longer than the timeout.
    Lost,
}

/// Watches the packets of one robot.
#[derive(Debug, Clone)]
pub struct LinkMonitor {
    timeout_s: f64,
    started_s: f64,
    last_packet_s: Option<f64>,
    state: LinkState,
}

impl LinkMonitor {
    /// A monitor started at `now_s`; a robot that never sends is reported after `timeout_s`.
    pub fn new(timeout_s: f64, now_s: f64) -> Self {
        Self {
            timeout_s,
            started_s: now_s,
            last_packet_s: None,
            state: LinkState::Waiting,
        }
    }

    /// A valid packet arrived at `now_s`. Returns `Established` for the first packet and
    /// `LinkRestored` after a loss.
    pub fn on_packet(&mut self, now_s: f64) -> Option<LinkEvent> {
        let previous = self.last_packet_s.replace(now_s);
        let event = match self.state {
            LinkState::Up => None,
            LinkState::Waiting => Some(LinkEvent::Established { at_s: now_s }),
            LinkState::Lost => Some(LinkEvent::LinkRestored {
                at_s: now_s,
                silent_for_s: now_s - previous.unwrap_or(self.started_s),
            }),
        };
        self.state = LinkState::Up;
        event
    }

    /// Check the timeout at `now_s`; returns `RobotNotResponding` once per loss.
    pub fn poll(&mut self, now_s: f64) -> Option<LinkEvent> {
        if self.state == LinkState::Lost {
            return None;
        }
        let since = self.last_packet_s.unwrap_or(self.started_s);
        if now_s - since > self.timeout_s {
            self.state = LinkState::Lost;
            Some(LinkEvent::RobotNotResponding {
                at_s: now_s,
                last_packet_s: self.last_packet_s,
            })
        } else {
            None
        }
    }

    /// Current state.
    pub fn state(&self) -> LinkState {
        self.state
    }

    /// Seconds since the last packet at `now_s`, `None` if none ever came.
    pub fn silence_s(&self, now_s: f64) -> Option<f64> {
        self.last_packet_s.map(|t| now_s - t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loss_and_restoration_are_reported_once_each() {
        let mut m = LinkMonitor::new(1.0, 0.0);
        assert_eq!(m.poll(0.5), None);
        assert_eq!(m.on_packet(0.6), Some(LinkEvent::Established { at_s: 0.6 }));
        // Packets every 100 ms: nothing to report.
        for i in 1..20 {
            let t = 0.6 + f64::from(i) * 0.1;
            assert_eq!(m.on_packet(t), None);
            assert_eq!(m.poll(t + 0.05), None);
        }
        let last = 0.6 + 19.0 * 0.1;
        assert_eq!(
            m.poll(last + 1.0),
            None,
            "exactly the timeout is not yet a loss"
        );
        assert_eq!(
            m.poll(last + 1.01),
            Some(LinkEvent::RobotNotResponding {
                at_s: last + 1.01,
                last_packet_s: Some(last)
            })
        );
        assert_eq!(m.state(), LinkState::Lost);
        assert_eq!(m.poll(last + 5.0), None, "reported once");
        match m.on_packet(last + 6.0) {
            Some(LinkEvent::LinkRestored { silent_for_s, .. }) => {
                assert!((silent_for_s - 6.0).abs() < 1e-9)
            }
            other => panic!("expected LinkRestored, got {other:?}"),
        }
        assert_eq!(m.state(), LinkState::Up);
    }

    #[test]
    fn a_robot_that_never_speaks_is_reported() {
        let mut m = LinkMonitor::new(2.0, 10.0);
        assert_eq!(m.poll(11.9), None);
        assert_eq!(
            m.poll(12.5),
            Some(LinkEvent::RobotNotResponding {
                at_s: 12.5,
                last_packet_s: None
            })
        );
        assert!(matches!(
            m.on_packet(13.0),
            Some(LinkEvent::LinkRestored { .. })
        ));
    }
}
