//! The `dynamixel` driver: ROBOTIS X-series servos (e.g. XM430) speaking Protocol 2.0 on a
//! serial line, in position control mode.
//!
//! # Conventions
//! - One servo per revolute joint; servo angle = `sign · joint angle + offset_rad`
//!   ([`ServoMapping`]), servo angle 0 rad = tick 2048, 4096 ticks per revolution
//!   ([`units`]).
//! - Registers used: Torque Enable (64, 1 byte), Profile Acceleration (108, 4 bytes,
//!   214.577 rev/min²), Profile Velocity (112, 4 bytes, 0.229 rev/min), Goal Position (116,
//!   4 bytes), Present Position (132, 4 bytes, signed).
//! - Opening: every servo is pinged, its Profile Acceleration set to the joint's
//!   `max_acceleration` (rounded down), its goal set to its present position, and its torque
//!   enabled (so it holds where it is instead of jumping to a stale goal).
//! - Position goals: one SYNC WRITE of Profile Velocity (the goal's max speed, never faster)
//!   then one of Goal Position. Velocity goals are refused ([`JointError::Unsupported`]).
//! - States: one SYNC READ of Present Position; velocities are finite differences between
//!   reads (0 on the first); efforts are not read.
//! - Faults: a missing or corrupt reply is retried (`retries` times, per servo) and counted in
//!   [`LinkStats`]; an operation that still fails returns [`JointError::Bus`], never panics.

mod bus;
pub mod config;
pub mod protocol;
pub mod transport;
pub mod units;

pub use bus::Bus;
pub use config::{DynamixelConfig, ServoMapping};
pub use transport::{SerialPort, Transport};

use std::time::Duration;

use crate::driver::{JointDriver, check_specs, check_targets};
use crate::error::JointError;
use crate::types::{JointCommand, JointSpec, JointState, JointTarget, LinkStats};

/// Control table addresses of the X-series (Protocol 2.0).
pub mod reg {
    pub const MODEL_NUMBER: u16 = 0;
    pub const TORQUE_ENABLE: u16 = 64;
    pub const PROFILE_ACCELERATION: u16 = 108;
    pub const PROFILE_VELOCITY: u16 = 112;
    pub const GOAL_POSITION: u16 = 116;
    pub const PRESENT_POSITION: u16 = 132;
}

/// X-series servos as joints; see the module docs.
#[derive(Debug)]
pub struct DynamixelDriver {
    specs: Vec<JointSpec>,
    servos: Vec<ServoMapping>,
    ids: Vec<u8>,
    bus: Bus,
    last: Option<(f64, Vec<f64>)>,
    velocities: Vec<f64>,
}

impl DynamixelDriver {
    /// Connects to the servos of `config` over `transport`: pings each, sets its goal to its
    /// present position and enables its torque. Errors name the joint whose servo failed.
    pub fn new(
        specs: Vec<JointSpec>,
        config: DynamixelConfig,
        transport: Box<dyn Transport>,
    ) -> Result<Self, JointError> {
        check_specs(&specs)?;
        config.check(&specs)?;
        let servos: Vec<ServoMapping> = specs
            .iter()
            .map(|s| {
                config
                    .joints
                    .get(&s.name)
                    .copied()
                    .ok_or_else(|| JointError::config(format!("joints.{}", s.name), "no servo"))
            })
            .collect::<Result<_, _>>()?;
        let ids: Vec<u8> = servos.iter().map(|m| m.id).collect();
        let bus = Bus::new(
            transport,
            Duration::from_millis(config.read_timeout_ms),
            config.retries,
        );
        let n = specs.len();
        let mut d = Self {
            specs,
            servos,
            ids,
            bus,
            last: None,
            velocities: vec![0.0; n],
        };
        for ((spec, &id), mapping) in d.specs.iter().zip(&d.ids).zip(&d.servos) {
            let named = |e: JointError| JointError::Bus(format!("joint `{}`: {e}", spec.name));
            let (model, firmware) = d.bus.ping(id).map_err(named)?;
            tracing::info!(joint = %spec.name, id, model, firmware, "servo found");
            let acc = units::profile_acceleration(mapping.servo_rate(spec.max_acceleration))
                .to_le_bytes();
            d.bus
                .write(id, reg::PROFILE_ACCELERATION, &acc)
                .map_err(named)?;
            let present = d.bus.read(id, reg::PRESENT_POSITION, 4).map_err(named)?;
            d.bus
                .write(id, reg::GOAL_POSITION, &present)
                .map_err(named)?;
            d.bus.write(id, reg::TORQUE_ENABLE, &[1]).map_err(named)?;
        }
        Ok(d)
    }
}

impl JointDriver for DynamixelDriver {
    fn name(&self) -> &'static str {
        "dynamixel"
    }

    fn joints(&self) -> &[JointSpec] {
        &self.specs
    }

    fn command(&mut self, targets: &[JointTarget], _now_s: f64) -> Result<(), JointError> {
        let checked = check_targets(&self.specs, targets)?;
        let mut speeds = Vec::with_capacity(checked.len());
        let mut goals = Vec::with_capacity(checked.len());
        for c in &checked {
            let JointCommand::Position {
                position,
                max_speed,
            } = c.command
            else {
                return Err(JointError::Unsupported {
                    driver: "dynamixel",
                    joint: self.specs[c.index].name.clone(),
                    what: "velocity goals (servos run in position mode)",
                });
            };
            let m = self.servos[c.index];
            let id = self.ids[c.index];
            let v = units::profile_velocity(m.servo_rate(max_speed));
            speeds.push((id, v.to_le_bytes().to_vec()));
            let ticks = units::rad_to_ticks(m.servo_rad(position));
            goals.push((id, ticks.to_le_bytes().to_vec()));
        }
        if goals.is_empty() {
            return Ok(());
        }
        self.bus.sync_write(reg::PROFILE_VELOCITY, 4, &speeds)?;
        self.bus.sync_write(reg::GOAL_POSITION, 4, &goals)
    }

    fn read_state(&mut self, now_s: f64) -> Result<Vec<JointState>, JointError> {
        if let Some((last_s, _)) = self.last
            && now_s < last_s
        {
            return Err(JointError::TimeWentBack { now_s, last_s });
        }
        let data = self.bus.sync_read(reg::PRESENT_POSITION, 4, &self.ids)?;
        let positions: Vec<f64> = data
            .iter()
            .zip(&self.servos)
            .map(|(d, m)| {
                let ticks = i32::from_le_bytes([d[0], d[1], d[2], d[3]]);
                m.joint_rad(units::ticks_to_rad(ticks))
            })
            .collect();
        if let Some((last_s, prev)) = &self.last
            && now_s > *last_s
        {
            let dt = now_s - last_s;
            for (v, (q, q0)) in self.velocities.iter_mut().zip(positions.iter().zip(prev)) {
                *v = (q - q0) / dt;
            }
        }
        let states = self
            .specs
            .iter()
            .zip(positions.iter().zip(&self.velocities))
            .map(|(s, (&position, &velocity))| JointState {
                name: s.name.clone(),
                position,
                velocity,
                has_effort: false,
                effort: 0.0,
                owner: String::new(),
            })
            .collect();
        self.last = Some((now_s, positions));
        Ok(states)
    }

    fn link_stats(&self) -> LinkStats {
        self.bus.stats()
    }
}

#[cfg(test)]
#[expect(
    clippy::disallowed_methods,
    reason = "the tests wait on the simulated servo chain's real thread behind a pseudo-terminal"
)]
mod tests {
    use super::*;
    use crate::error::LimitKind;
    use crate::servo_sim::{Faults, MODEL_NUMBER, ServoChain};
    use std::f64::consts::PI;

    fn specs() -> Vec<JointSpec> {
        vec![
            JointSpec::revolute("neck_yaw", -1.5, 1.5, 4.0, 20.0),
            JointSpec::revolute("eye_pan_left", -0.8, 0.8, 6.0, 50.0),
            JointSpec::revolute("eye_pan_right", -0.8, 0.8, 6.0, 50.0),
        ]
    }

    fn config(timeout_ms: u64, retries: u32) -> DynamixelConfig {
        let text = format!(
            r#"
port = "/dev/null"
baud = 1000000
read_timeout_ms = {timeout_ms}
retries = {retries}
[joints.neck_yaw]
id = 1
[joints.eye_pan_left]
id = 7
sign = -1
[joints.eye_pan_right]
id = 3
offset_rad = 0.5
"#
        );
        DynamixelConfig::from_toml(&text, &specs()).unwrap()
    }

    fn driver(faults: Faults, seed: u64, timeout_ms: u64) -> (ServoChain, DynamixelDriver) {
        let (chain, port) = ServoChain::spawn_on_pty(&[1, 7, 3], faults, seed).unwrap();
        let d = DynamixelDriver::new(specs(), config(timeout_ms, 3), Box::new(port)).unwrap();
        (chain, d)
    }

    fn goal(joint: &str, position: f64, max_speed: f64) -> JointTarget {
        JointTarget {
            joint: joint.into(),
            command: JointCommand::Position {
                position,
                max_speed,
            },
        }
    }

    #[test]
    fn bus_ping_read_write_against_the_simulated_chain() {
        let (chain, port) = ServoChain::spawn_on_pty(&[1, 2], Faults::default(), 1).unwrap();
        let mut bus = Bus::new(Box::new(port), Duration::from_millis(50), 0);
        assert_eq!(bus.ping(2).unwrap(), (MODEL_NUMBER, 45));
        // No servo 9: a time-out, reported and counted, no panic.
        assert!(matches!(bus.ping(9), Err(JointError::Bus(_))));
        bus.write(2, reg::GOAL_POSITION, &3000i32.to_le_bytes())
            .unwrap();
        assert_eq!(chain.register(2, reg::GOAL_POSITION), Some(3000));
        assert_eq!(
            bus.read(2, reg::GOAL_POSITION, 4).unwrap(),
            3000i32.to_le_bytes()
        );
        // Data containing the header pattern crosses the line stuffed, both ways.
        let tricky = [0xFF, 0xFF, 0xFD, 0x00];
        bus.write(1, reg::GOAL_POSITION, &tricky).unwrap();
        assert_eq!(
            chain.register(1, reg::GOAL_POSITION),
            Some(i32::from_le_bytes(tricky))
        );
        assert_eq!(bus.read(1, reg::GOAL_POSITION, 4).unwrap(), tricky);
        // Out of the control table: the servo's access error comes back typed.
        let e = bus.read(1, 200, 4).unwrap_err();
        assert!(e.to_string().contains("access error"), "{e}");
        chain.set_register(1, reg::PRESENT_POSITION, 100);
        chain.set_register(2, reg::PRESENT_POSITION, -5);
        let data = bus.sync_read(reg::PRESENT_POSITION, 4, &[2, 1]).unwrap();
        assert_eq!(
            data,
            vec![
                (-5i32).to_le_bytes().to_vec(),
                100i32.to_le_bytes().to_vec()
            ]
        );
        let s = bus.stats();
        assert_eq!((s.missing_replies, s.failures, s.servo_errors), (1, 1, 1));
    }

    #[test]
    fn opening_holds_present_position_and_maps_units() {
        let (chain, port) = ServoChain::spawn_on_pty(&[1, 7, 3], Faults::default(), 2).unwrap();
        // neck at +90° servo = +π/2 joint; left eye sign -1; right eye offset 0.5 rad.
        chain.set_register(1, reg::PRESENT_POSITION, 3072);
        chain.set_register(7, reg::PRESENT_POSITION, 2048 + 256);
        chain.set_register(3, reg::PRESENT_POSITION, units::rad_to_ticks(0.5));
        let mut d = DynamixelDriver::new(specs(), config(50, 3), Box::new(port)).unwrap();
        assert_eq!(chain.torque(1), Some(true));
        assert_eq!(chain.register(1, reg::GOAL_POSITION), Some(3072));
        // 20 rad/s² = 11459 rev/min² → 53 units of 214.577 rev/min².
        assert_eq!(chain.register(1, reg::PROFILE_ACCELERATION), Some(53));
        let s = d.read_state(0.0).unwrap();
        assert!((s[0].position - PI / 2.0).abs() < 1e-12);
        assert!((s[1].position + PI / 8.0).abs() < 1e-12);
        assert!(s[2].position.abs() < 2e-3);
        assert_eq!(d.link_stats().missing_replies, 0);
    }

    #[test]
    fn goals_reach_the_servos_and_are_tracked() {
        let (chain, mut d) = driver(Faults::default(), 3, 50);
        d.command(
            &[goal("neck_yaw", 0.5, 2.0), goal("eye_pan_left", 0.3, 6.0)],
            0.0,
        )
        .unwrap();
        // SYNC WRITE has no reply: give the chain's thread a moment to apply it.
        let start = std::time::Instant::now();
        while chain.register(7, reg::GOAL_POSITION) == Some(2048) {
            assert!(
                start.elapsed() < Duration::from_secs(2),
                "sync write never applied"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(
            chain.register(1, reg::GOAL_POSITION),
            Some(units::rad_to_ticks(0.5))
        );
        assert_eq!(
            chain.register(7, reg::GOAL_POSITION),
            Some(units::rad_to_ticks(-0.3))
        );
        assert_eq!(
            chain.register(1, reg::PROFILE_VELOCITY),
            Some(units::profile_velocity(2.0) as i32)
        );
        // Poll like the component does until the neck arrives (≈ 0.25 s at 2 rad/s).
        let start = std::time::Instant::now();
        let mut peak_v = 0.0_f64;
        loop {
            let t = start.elapsed().as_secs_f64();
            let s = d.read_state(t).unwrap();
            peak_v = peak_v.max(s[0].velocity);
            if (s[0].position - 0.5).abs() < 2e-3 && (s[1].position - 0.3).abs() < 2e-3 {
                // 0.5 rad at the profile's ≤ 2 rad/s takes at least 0.25 s.
                assert!(t > 0.24, "arrived too fast: {t} s");
                break;
            }
            assert!(t < 3.0, "goal not reached: {s:?}");
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(peak_v > 0.5, "neck speed {peak_v} rad/s");
    }

    #[test]
    fn bad_goals_refused_before_touching_the_bus() {
        let (_chain, mut d) = driver(Faults::default(), 4, 50);
        let before = d.link_stats().transactions;
        let e = d
            .command(&[goal("eye_pan_right", 0.9, 1.0)], 0.0)
            .unwrap_err();
        assert!(matches!(
            e,
            JointError::OutOfLimits { ref joint, limit: LimitKind::Upper, .. } if joint == "eye_pan_right"
        ));
        let v = JointTarget {
            joint: "neck_yaw".into(),
            command: JointCommand::Velocity { velocity: 0.1 },
        };
        assert!(matches!(
            d.command(&[v], 0.0),
            Err(JointError::Unsupported { .. })
        ));
        assert_eq!(d.link_stats().transactions, before);
    }

    #[test]
    fn dropped_and_corrupt_replies_are_reported_retried_and_counted() {
        let faults = Faults {
            drop: 0.1,
            corrupt: 0.1,
        };
        let (chain, mut d) = driver(faults, 42, 50);
        let mut ok = 0;
        for k in 0..100 {
            let t = f64::from(k) * 0.01;
            match d.read_state(t) {
                Ok(s) => {
                    assert_eq!(s.len(), 3);
                    assert!(s[0].position.abs() < 1e-12);
                    ok += 1;
                }
                Err(e) => assert!(matches!(e, JointError::Bus(_))),
            }
        }
        let c = chain.counters();
        let s = d.link_stats();
        // Faults happened, and each one is accounted for on the driver's side.
        assert!(c.dropped > 10 && c.corrupted > 10, "{c:?}");
        assert_eq!(s.crc_errors, c.corrupted, "{s:?} {c:?}");
        assert_eq!(s.missing_replies, c.dropped + c.corrupted, "{s:?} {c:?}");
        // Every missing reply was retried (unless its read gave up after all retries).
        assert!(s.retries <= s.missing_replies);
        if s.failures == 0 {
            assert_eq!(s.retries, s.missing_replies, "{s:?}");
        }
        assert_eq!(u64::try_from(100 - ok).unwrap(), s.failures);
        assert!(ok >= 98, "only {ok} of 100 reads succeeded");
        assert_eq!(s.malformed, 0);
        eprintln!("link stats after 100 reads with 10 % drops, 10 % bad CRCs: {s:?}; chain {c:?}");
    }

    #[test]
    fn dead_bus_is_an_error_then_recovers() {
        let (chain, mut d) = driver(Faults::default(), 5, 20);
        chain.set_faults(Faults {
            drop: 1.0,
            corrupt: 0.0,
        });
        let e = d.read_state(0.0).unwrap_err();
        assert!(e.to_string().contains("no valid reply"), "{e}");
        let s = d.link_stats();
        assert_eq!(s.failures, 1);
        // 3 servos missing from the sync read, then 4 tries for the first one.
        assert_eq!(s.missing_replies, 3 + 4);
        chain.set_faults(Faults::default());
        assert!(d.read_state(0.1).is_ok());
    }
}
