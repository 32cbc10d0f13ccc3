//! The `sim` driver: joints with a first-order response under velocity and acceleration limits.
//!
//! # Model
//! Each joint has a position `q` (rad or m) and a velocity `v`. Every internal sub-step `h`
//! (≤ [`SimParams::substep_s`]) the joint picks a desired velocity and moves its velocity towards
//! it by at most `max_acceleration · h`:
//! - position goal `q*` with speed `s`: `v_des = (q* − q) / τ` (first order, time constant
//!   [`SimParams::time_constant_s`]), capped to `s` and to the braking speed
//!   `√(2 · 0.9 · a_max · |q* − q|)` so that the joint can stop on the target without overshoot;
//! - velocity goal `w`: `v_des = w`, capped to the braking speed towards the position limit it
//!   moves to, so the joint stops at the limit instead of hitting it.
//!
//! Hence `|v| ≤ max_velocity` and `|Δv/Δt| ≤ max_acceleration` at all times, and a position goal
//! converges exponentially (time constant τ) once close. Joints start at rest at position 0, or at
//! the nearest limit when 0 is outside them. Time is the caller's `now_s`; the first call sets the
//! origin. Efforts are not simulated (`None`).

use serde::Deserialize;

use crate::driver::{JointDriver, check_specs, check_targets};
use crate::error::JointError;
use crate::types::{JointCommand, JointSpec, JointState, JointTarget};

/// Fraction of the acceleration limit used when planning a stop (margin for the discrete steps).
const BRAKE_FRACTION: f64 = 0.9;

/// Tuning of the simulated joints (optional TOML file for `open_driver("sim", ..)`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimParams {
    /// First-order time constant τ of the position response (s), > 0.
    pub time_constant_s: f64,
    /// Largest internal integration step (s), in `(0, τ]`.
    pub substep_s: f64,
}

impl Default for SimParams {
    fn default() -> Self {
        Self {
            time_constant_s: 0.05,
            substep_s: 0.001,
        }
    }
}

impl SimParams {
    /// Parses and checks a TOML text such as `time_constant_s = 0.08`.
    pub fn from_toml(text: &str) -> Result<Self, JointError> {
        let p: Self = toml::from_str(text).map_err(|e| JointError::config("sim", e.to_string()))?;
        p.check()?;
        Ok(p)
    }

    fn check(&self) -> Result<(), JointError> {
        if !(self.time_constant_s.is_finite() && self.time_constant_s > 0.0) {
            return Err(JointError::config(
                "time_constant_s",
                "must be finite and > 0",
            ));
        }
        if !(self.substep_s > 0.0 && self.substep_s <= self.time_constant_s) {
            return Err(JointError::config(
                "substep_s",
                "must be > 0 and at most time_constant_s",
            ));
        }
        Ok(())
    }
}

#[derive(Debug, Clone, Copy)]
struct SimJoint {
    q: f64,
    v: f64,
    command: JointCommand,
}

/// Simulated joints; see the module docs for the model.
#[derive(Debug)]
pub struct SimDriver {
    specs: Vec<JointSpec>,
    params: SimParams,
    joints: Vec<SimJoint>,
    last_s: Option<f64>,
}

impl SimDriver {
    /// Joints at rest, holding their start position (0 clamped into the limits).
    pub fn new(specs: Vec<JointSpec>, params: SimParams) -> Result<Self, JointError> {
        check_specs(&specs)?;
        params.check()?;
        let joints = specs
            .iter()
            .map(|s| {
                let q = 0.0_f64.clamp(s.lower, s.upper);
                SimJoint {
                    q,
                    v: 0.0,
                    command: JointCommand::Position {
                        position: q,
                        max_speed: s.max_velocity,
                    },
                }
            })
            .collect();
        Ok(Self {
            specs,
            params,
            joints,
            last_s: None,
        })
    }

    /// Joints at rest at `start` (one position per spec, rad or m, each within its limits:
    /// a start outside them is refused naming the joint and the limit).
    pub fn new_at(
        specs: Vec<JointSpec>,
        params: SimParams,
        start: &[f64],
    ) -> Result<Self, JointError> {
        let mut d = Self::new(specs, params)?;
        if start.len() != d.specs.len() {
            return Err(JointError::config(
                "start",
                format!("{} positions for {} joints", start.len(), d.specs.len()),
            ));
        }
        let targets: Vec<JointTarget> = d
            .specs
            .iter()
            .zip(start)
            .map(|(s, &position)| JointTarget {
                joint: s.name.clone(),
                command: JointCommand::Position {
                    position,
                    max_speed: s.max_velocity,
                },
            })
            .collect();
        for c in check_targets(&d.specs, &targets)? {
            d.joints[c.index].command = c.command;
            if let JointCommand::Position { position, .. } = c.command {
                d.joints[c.index].q = position;
            }
        }
        Ok(d)
    }

    /// Advances the simulation to `now_s`.
    fn advance(&mut self, now_s: f64) -> Result<(), JointError> {
        if !now_s.is_finite() {
            return Err(JointError::InvalidValue {
                joint: String::new(),
                what: "now_s",
                value: now_s,
            });
        }
        let Some(last_s) = self.last_s else {
            self.last_s = Some(now_s);
            return Ok(());
        };
        if now_s < last_s {
            return Err(JointError::TimeWentBack { now_s, last_s });
        }
        let dt = now_s - last_s;
        if dt > 0.0 {
            // Far more than any real gap between publications; the bound keeps the loop finite.
            let steps = (dt / self.params.substep_s).ceil().clamp(1.0, 1.0e7) as u64;
            let h = dt / steps as f64;
            for _ in 0..steps {
                for (j, spec) in self.joints.iter_mut().zip(&self.specs) {
                    step(j, spec, self.params.time_constant_s, h);
                }
            }
        }
        self.last_s = Some(now_s);
        Ok(())
    }
}

/// The fastest speed from which the joint can still stop within `distance`.
fn braking_speed(spec: &JointSpec, distance: f64) -> f64 {
    (2.0 * BRAKE_FRACTION * spec.max_acceleration * distance.max(0.0)).sqrt()
}

fn step(j: &mut SimJoint, spec: &JointSpec, tau: f64, h: f64) {
    let v_des = match j.command {
        JointCommand::Position {
            position,
            max_speed,
        } => {
            let e = position - j.q;
            let cap = max_speed.min(braking_speed(spec, e.abs()));
            (e / tau).clamp(-cap, cap)
        }
        JointCommand::Velocity { velocity } => {
            if velocity >= 0.0 {
                velocity.min(braking_speed(spec, spec.upper - j.q))
            } else {
                velocity.max(-braking_speed(spec, j.q - spec.lower))
            }
        }
    };
    let v_des = v_des.clamp(-spec.max_velocity, spec.max_velocity);
    let dv = spec.max_acceleration * h;
    j.v += (v_des - j.v).clamp(-dv, dv);
    j.q += j.v * h;
    // Last-resort guard for rounding: the braking caps keep the joint inside its limits.
    if j.q > spec.upper {
        j.q = spec.upper;
        j.v = j.v.min(0.0);
    } else if j.q < spec.lower {
        j.q = spec.lower;
        j.v = j.v.max(0.0);
    }
}

impl JointDriver for SimDriver {
    fn name(&self) -> &'static str {
        "sim"
    }

    fn joints(&self) -> &[JointSpec] {
        &self.specs
    }

    fn command(&mut self, targets: &[JointTarget], now_s: f64) -> Result<(), JointError> {
        let checked = check_targets(&self.specs, targets)?;
        self.advance(now_s)?;
        for c in checked {
            self.joints[c.index].command = c.command;
        }
        Ok(())
    }

    fn read_state(&mut self, now_s: f64) -> Result<Vec<JointState>, JointError> {
        self.advance(now_s)?;
        Ok(self
            .joints
            .iter()
            .zip(&self.specs)
            .map(|(j, s)| JointState {
                name: s.name.clone(),
                position: j.q,
                velocity: j.v,
                has_effort: false,
                effort: 0.0,
                owner: String::new(),
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::LimitKind;

    fn arm() -> Vec<JointSpec> {
        vec![
            JointSpec::revolute("shoulder", -1.5, 1.5, 1.0, 4.0),
            JointSpec::revolute("elbow", 0.0, 2.0, 2.0, 8.0),
            JointSpec::prismatic("leg", 0.0, 0.04, 0.05, 0.5),
        ]
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

    /// Samples at 100 Hz for `duration_s`; returns (t, positions, velocities) per sample.
    fn run(d: &mut SimDriver, t0: f64, duration_s: f64) -> Vec<(f64, Vec<f64>, Vec<f64>)> {
        let n = (duration_s * 100.0).round() as usize;
        (1..=n)
            .map(|k| {
                let t = t0 + k as f64 * 0.01;
                let s = d.read_state(t).unwrap();
                (
                    t,
                    s.iter().map(|j| j.position).collect(),
                    s.iter().map(|j| j.velocity).collect(),
                )
            })
            .collect()
    }

    #[test]
    fn starts_at_the_given_positions_and_refuses_a_start_beyond_a_limit() {
        let mut d = SimDriver::new_at(arm(), SimParams::default(), &[0.5, 1.0, 0.02]).unwrap();
        let s = d.read_state(0.0).unwrap();
        assert_eq!(s[0].position, 0.5);
        let s = d.read_state(1.0).unwrap();
        assert_eq!(
            s.iter().map(|j| j.position).collect::<Vec<_>>(),
            [0.5, 1.0, 0.02],
            "holds the start"
        );
        assert!(matches!(
            SimDriver::new_at(arm(), SimParams::default(), &[0.0, 2.5, 0.0]),
            Err(JointError::OutOfLimits { ref joint, limit: LimitKind::Upper, .. }) if joint == "elbow"
        ));
        assert!(SimDriver::new_at(arm(), SimParams::default(), &[0.0]).is_err());
    }

    #[test]
    fn goal_beyond_limit_refused_naming_joint_and_nothing_moves() {
        let mut d = SimDriver::new(arm(), SimParams::default()).unwrap();
        let e = d
            .command(&[goal("shoulder", 1.0, 0.5), goal("elbow", 2.2, 1.0)], 0.0)
            .unwrap_err();
        assert_eq!(
            e,
            JointError::OutOfLimits {
                joint: "elbow".into(),
                limit: LimitKind::Upper,
                limit_value: 2.0,
                requested: 2.2
            }
        );
        // All-or-nothing: the shoulder target of the refused goal was not applied either.
        let s = d.read_state(1.0).unwrap();
        assert_eq!(s[0].position, 0.0);
        assert_eq!(
            d.command(&[goal("knee", 0.0, 0.1)], 1.0),
            Err(JointError::UnknownJoint("knee".into()))
        );
    }

    #[test]
    fn tracking_respects_velocity_and_acceleration_limits_and_converges() {
        let specs = arm();
        let mut d = SimDriver::new(specs.clone(), SimParams::default()).unwrap();
        d.command(
            &[
                goal("shoulder", 1.4, 1.0),
                goal("elbow", 2.0, 2.0),
                goal("leg", 0.04, 0.03),
            ],
            0.0,
        )
        .unwrap();
        let trace = run(&mut d, 0.0, 2.0);
        // Re-target mid-motion, the other way, at full speed.
        d.command(&[goal("shoulder", -1.5, 1.0), goal("elbow", 0.0, 2.0)], 2.0)
            .unwrap();
        let trace2 = run(&mut d, 2.0, 6.0);
        let all: Vec<_> = trace.iter().chain(&trace2).collect();
        let mut peak_v = [0.0_f64; 3];
        for w in all.windows(2) {
            let (t0, _, v0) = w[0];
            let (t1, q1, v1) = w[1];
            for i in 0..3 {
                let s = &specs[i];
                assert!(v1[i].abs() <= s.max_velocity + 1e-12, "{} too fast", s.name);
                let acc = (v1[i] - v0[i]) / (t1 - t0);
                assert!(
                    acc.abs() <= s.max_acceleration + 1e-9,
                    "{} acc {acc}",
                    s.name
                );
                assert!(
                    q1[i] >= s.lower && q1[i] <= s.upper,
                    "{} out of limits",
                    s.name
                );
                peak_v[i] = peak_v[i].max(v1[i].abs());
            }
        }
        // The goal speeds were reached (limits bind, not an over-cautious model)...
        assert!(peak_v[0] > 0.99 && peak_v[1] > 1.99, "{peak_v:?}");
        // ...and the leg never went faster than its goal's 0.03 m/s.
        assert!(peak_v[2] <= 0.03 + 1e-12 && peak_v[2] > 0.029);
        // Converged after the first phase and at the end.
        let (_, q, _) = &trace[trace.len() - 1];
        assert!(
            (q[0] - 1.4).abs() < 1e-3 && (q[1] - 2.0).abs() < 1e-3,
            "{q:?}"
        );
        assert!((q[2] - 0.04).abs() < 1e-4);
        let (_, q, v) = &trace2[trace2.len() - 1];
        assert!((q[0] + 1.5).abs() < 1e-6 && q[1].abs() < 1e-6, "{q:?}");
        assert!(v.iter().all(|v| v.abs() < 1e-5));
    }

    #[test]
    fn close_goal_is_a_first_order_response() {
        // A stiff joint (1000 rad/s²) and a 0.02 rad step: the speed and acceleration caps stay
        // slack, so e(t) = e0·exp(-t/τ).
        let specs = vec![JointSpec::revolute("eye", -1.0, 1.0, 10.0, 1000.0)];
        let mut d = SimDriver::new(specs, SimParams::default()).unwrap();
        d.command(&[goal("eye", 0.02, 2.0)], 0.0).unwrap();
        let q = d.read_state(0.05).unwrap()[0].position;
        let expected = 0.02 * (1.0 - (-1.0_f64).exp());
        assert!((q - expected).abs() < 2e-4, "q {q} expected {expected}");
    }

    #[test]
    fn velocity_goal_stops_at_the_limit_smoothly() {
        let specs = arm();
        let mut d = SimDriver::new(specs, SimParams::default()).unwrap();
        d.command(
            &[JointTarget {
                joint: "shoulder".into(),
                command: JointCommand::Velocity { velocity: 1.0 },
            }],
            0.0,
        )
        .unwrap();
        let trace = run(&mut d, 0.0, 3.0);
        for w in trace.windows(2) {
            let acc = (w[1].2[0] - w[0].2[0]) / 0.01;
            assert!(acc.abs() <= 4.0 + 1e-9);
        }
        let (_, q, v) = &trace[trace.len() - 1];
        assert!(q[0] <= 1.5 && q[0] > 1.49, "{}", q[0]);
        assert!(v[0].abs() < 1e-3);
    }

    #[test]
    fn time_must_not_go_back_and_params_are_checked() {
        let mut d = SimDriver::new(arm(), SimParams::default()).unwrap();
        d.read_state(1.0).unwrap();
        assert!(matches!(
            d.read_state(0.5),
            Err(JointError::TimeWentBack { .. })
        ));
        assert!(SimParams::from_toml("time_constant_s = 0.1").is_ok());
        assert!(SimParams::from_toml("time_constant_s = -1.0").is_err());
        assert!(SimParams::from_toml("tau = 0.1").is_err());
    }
}
