//! The bridge's receive path in one pure type: source filtering, decoding, drop counting with
//! rate-limited logs, and per-robot link monitoring. A process feeds it datagrams with their
//! sender and the current time; it hands back typed packets and link events.

use std::net::{IpAddr, SocketAddr};

use serde::{Deserialize, Serialize};

use crate::link::LinkEvent;
use crate::link::LinkMonitor;
use spl::types::{GameControllerState, NaoLocalModel};
use spl::validation::{DropMonitor, PacketError, PacketKind, SourceFilter};
use spl::{decode_debug, decode_gamecontroller};

/// One robot the bridge expects debug packets from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExpectedRobot {
    /// Its IP address.
    pub address: IpAddr,
    /// Its player number (2 controlled, 1 autonomous teammate).
    pub player_number: u8,
}

/// Configuration of the receive path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InboundConfig {
    /// Robots whose debug packets are accepted.
    pub robots: Vec<ExpectedRobot>,
    /// GameController addresses; empty accepts any sender (the GameController's address is
    /// often not known in advance).
    pub gamecontrollers: Vec<IpAddr>,
    /// No packet for this long => robot not responding (s).
    pub link_timeout_s: f64,
    /// At most one log line per drop reason per this interval (s).
    pub log_interval_s: f64,
}

impl Default for InboundConfig {
    fn default() -> Self {
        Self {
            robots: Vec::new(),
            gamecontrollers: Vec::new(),
            link_timeout_s: 1.0,
            log_interval_s: 1.0,
        }
    }
}

/// The receive path.
#[derive(Debug, Clone)]
pub struct Inbound {
    config: InboundConfig,
    robot_filter: SourceFilter,
    gc_filter: Option<SourceFilter>,
    drops: DropMonitor,
    links: Vec<(ExpectedRobot, LinkMonitor)>,
}

impl Inbound {
    /// A receive path started at `now_s`.
    pub fn new(config: InboundConfig, now_s: f64) -> Self {
        let robot_filter = SourceFilter::new(config.robots.iter().map(|r| r.address));
        let gc_filter = (!config.gamecontrollers.is_empty())
            .then(|| SourceFilter::new(config.gamecontrollers.iter().copied()));
        let links = config
            .robots
            .iter()
            .map(|r| (r.clone(), LinkMonitor::new(config.link_timeout_s, now_s)))
            .collect();
        Self {
            drops: DropMonitor::new(config.log_interval_s),
            robot_filter,
            gc_filter,
            links,
            config,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &InboundConfig {
        &self.config
    }

    /// Drop counters and accepted counts.
    pub fn drops(&self) -> &DropMonitor {
        &self.drops
    }

    fn refuse<T>(&mut self, e: PacketError, now_s: f64) -> Option<T> {
        self.drops.record(&e, now_s);
        None
    }

    /// A datagram on the debug port. Returns the robot's model and, when its link changed, the
    /// event with the robot's player number; `None` when dropped (counted).
    pub fn on_debug(
        &mut self,
        bytes: &[u8],
        from: SocketAddr,
        now_s: f64,
    ) -> Option<(NaoLocalModel, Option<(u8, LinkEvent)>)> {
        if let Err(e) = self.robot_filter.check(PacketKind::Debug, from) {
            return self.refuse(e, now_s);
        }
        let model = match decode_debug(bytes) {
            Ok(m) => m,
            Err(e) => return self.refuse(e, now_s),
        };
        let Some((robot, link)) = self.links.iter_mut().find(|(r, _)| r.address == from.ip())
        else {
            // Unreachable with a filter built from the same list; counted all the same.
            let e = PacketError::UnknownSource {
                kind: PacketKind::Debug,
                source_addr: from,
            };
            return self.refuse(e, now_s);
        };
        if robot.player_number != model.player_number {
            let e = PacketError::InvalidValue {
                kind: PacketKind::Debug,
                field: "player_number",
                value: u32::from(model.player_number),
            };
            return self.refuse(e, now_s);
        }
        let player = robot.player_number;
        let event = link.on_packet(now_s).map(|e| (player, e));
        self.drops.accepted(PacketKind::Debug);
        Some((model, event))
    }

    /// A datagram on the GameController port; `None` when dropped (counted).
    pub fn on_gamecontroller(
        &mut self,
        bytes: &[u8],
        from: SocketAddr,
        now_s: f64,
    ) -> Option<GameControllerState> {
        if let Some(f) = &self.gc_filter
            && let Err(e) = f.check(PacketKind::GameController, from)
        {
            return self.refuse(e, now_s);
        }
        match decode_gamecontroller(bytes) {
            Ok(s) => {
                self.drops.accepted(PacketKind::GameController);
                Some(s)
            }
            Err(e) => self.refuse(e, now_s),
        }
    }

    /// Check every robot's link at `now_s`; returns `(player, RobotNotResponding)` events.
    pub fn poll(&mut self, now_s: f64) -> Vec<(u8, LinkEvent)> {
        self.links
            .iter_mut()
            .filter_map(|(r, l)| l.poll(now_s).map(|e| (r.player_number, e)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use spl::validation::DropReason;

    fn config() -> InboundConfig {
        InboundConfig {
            robots: vec![
                ExpectedRobot {
                    address: "10.0.19.2".parse().unwrap(),
                    player_number: 2,
                },
                ExpectedRobot {
                    address: "10.0.19.1".parse().unwrap(),
                    player_number: 1,
                },
            ],
            gamecontrollers: vec![],
            link_timeout_s: 1.0,
            log_interval_s: 1.0,
        }
    }

    #[test]
    fn accepts_counts_and_reports_link_changes() {
        let mut inb = Inbound::new(config(), 0.0);
        let pkt = spl::samples::debug_packet(); // player 2
        let from2: SocketAddr = "10.0.19.2:40000".parse().unwrap();
        let (m, ev) = inb.on_debug(&pkt, from2, 0.1).unwrap();
        assert_eq!(m.player_number, 2);
        assert_eq!(ev, Some((2, LinkEvent::Established { at_s: 0.1 })));
        assert!(inb.on_debug(&pkt, from2, 0.2).unwrap().1.is_none());
        // Player 2's packet from player 1's address: refused.
        assert!(
            inb.on_debug(&pkt, "10.0.19.1:40000".parse().unwrap(), 0.3)
                .is_none()
        );
        // A stranger: refused.
        assert!(
            inb.on_debug(&pkt, "10.0.19.9:40000".parse().unwrap(), 0.3)
                .is_none()
        );
        // Truncated: refused.
        assert!(inb.on_debug(&pkt[..300], from2, 0.4).is_none());
        let c = inb.drops().counters();
        assert_eq!(c.accepted(PacketKind::Debug), 2);
        assert_eq!(c.reason_total(DropReason::UnknownSource), 1);
        assert_eq!(c.reason_total(DropReason::InvalidValue), 1);
        assert_eq!(c.reason_total(DropReason::WrongSize), 1);
        // Player 1 never spoke: reported at 1 s; player 2 silent since 0.2 s: at 1.2 s.
        assert_eq!(inb.poll(1.05).len(), 1);
        let later = inb.poll(1.25);
        assert_eq!(later.len(), 1);
        assert_eq!(later[0].0, 2);
        let (_, ev) = inb.on_debug(&pkt, from2, 2.0).unwrap();
        assert!(matches!(ev, Some((2, LinkEvent::LinkRestored { .. }))));
        // GameController from anywhere (no address configured).
        let gc = spl::samples::gamecontroller_packet();
        assert!(
            inb.on_gamecontroller(&gc, "10.0.0.100:3838".parse().unwrap(), 2.0)
                .is_some()
        );
    }
}
