//! The neck as three revolute joints (pitch, roll, yaw) over a driver that moves its three
//! prismatic legs: [`NeckDriver`] wraps any [`JointDriver`] and converts with
//! [`NeckGeometry`] (closed-form inverse for goals, Newton forward for states).
//!
//! - Joints: the inner driver's joints minus the three legs, then `pitch`, `roll`, `yaw`
//!   (names from [`NeckJoints`]), revolute, limits ± the geometry's maxima (rad), velocity and
//!   acceleration limits from [`NeckJoints`] (rad/s, rad/s²).
//! - Goals: position goals only. Axes not named keep their last goal. The legs are sent the
//!   lengths of the goal pose, each at the speed that makes all legs arrive together in the time
//!   the slowest axis needs at its max speed (never above a leg's `max_velocity`), so the head
//!   moves roughly straight in angle space. The hard speed and acceleration limits are the
//!   legs'; the axes' speeds follow from them and match the goal's max speed only
//!   approximately (the `sim` test measures a 0.5 % excess on pitch).
//! - A goal within the axes' limits whose legs would leave their stroke (a corner of the angle
//!   box the platform cannot reach) is clamped to the nearest reachable pose
//!   ([`NeckGeometry::nearest_reachable`]), counted (`neck/clamped` in
//!   [`JointDriver::counters`]) and told in [`JointDriver::take_warnings`]; the goal is
//!   accepted, and the measured angles show where the head went.
//! - States: angles by Newton from the measured leg lengths; angle rates `J⁻¹ · l̇`.

use crate::driver::{JointDriver, check_targets};
use crate::error::JointError;
use crate::stewart::{NeckAngles, NeckError, NeckGeometry};
use crate::types::{JointCommand, JointSpec, JointState, JointTarget, LinkStats};

/// Names and limits of the neck's virtual joints and of the legs in the inner driver.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NeckJoints {
    pub pitch: String,
    pub roll: String,
    pub yaw: String,
    /// Inner driver's prismatic joints for legs 0, 1, 2 (anchors at 90°, 210°, 330°).
    pub legs: [String; 3],
    /// Max angular speed of each axis (rad/s).
    pub max_velocity: f64,
    /// Max angular acceleration of each axis (rad/s²).
    pub max_acceleration: f64,
}

/// A driver whose three leg joints are presented as pitch, roll and yaw.
pub struct NeckDriver {
    inner: Box<dyn JointDriver>,
    geometry: NeckGeometry,
    specs: Vec<JointSpec>,
    /// Inner indices of the legs.
    legs: [usize; 3],
    /// Inner indices of the joints passed through, in `specs` order.
    passthrough: Vec<usize>,
    /// Last measured pose (for leg timing), and the current goal.
    measured: Option<NeckAngles>,
    goal: Option<NeckAngles>,
    /// Goals clamped into the platform's reach, and the last one (asked, given) not yet told.
    clamped: u64,
    last_clamp: Option<(NeckAngles, NeckAngles)>,
}

impl std::fmt::Debug for NeckDriver {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NeckDriver")
            .field("inner", &self.inner.name())
            .field("geometry", &self.geometry)
            .field("goal", &self.goal)
            .finish()
    }
}

impl NeckDriver {
    /// Wraps `inner`, whose joints must include `names.legs` (prismatic); the axes' limits are
    /// ± the geometry's maxima.
    pub fn new(
        inner: Box<dyn JointDriver>,
        geometry: NeckGeometry,
        names: &NeckJoints,
    ) -> Result<Self, JointError> {
        let axes = [
            (&names.pitch, geometry.max_pitch_rad),
            (&names.roll, geometry.max_roll_rad),
            (&names.yaw, geometry.max_yaw_rad),
        ]
        .map(|(name, max)| {
            JointSpec::revolute(name, -max, max, names.max_velocity, names.max_acceleration)
        });
        Self::with_axes(inner, geometry, &names.legs, axes)
    }

    /// Wraps `inner`, whose joints must include `legs` (prismatic), presenting the pitch, roll
    /// and yaw joints `axes` (their limits within the geometry's).
    pub fn with_axes(
        inner: Box<dyn JointDriver>,
        geometry: NeckGeometry,
        leg_names: &[String; 3],
        axes: [JointSpec; 3],
    ) -> Result<Self, JointError> {
        let inner_specs = inner.joints();
        let mut legs = [0; 3];
        for (k, leg) in leg_names.iter().enumerate() {
            legs[k] = inner_specs
                .iter()
                .position(|s| &s.name == leg)
                .ok_or_else(|| {
                    JointError::config(format!("neck.legs[{k}]"), format!("no joint `{leg}`"))
                })?;
        }
        let passthrough: Vec<usize> = (0..inner_specs.len())
            .filter(|i| !legs.contains(i))
            .collect();
        let mut specs: Vec<JointSpec> = passthrough
            .iter()
            .map(|&i| inner_specs[i].clone())
            .collect();
        for (axis, max) in axes.iter().zip([
            geometry.max_pitch_rad,
            geometry.max_roll_rad,
            geometry.max_yaw_rad,
        ]) {
            if axis.lower < -max || axis.upper > max {
                return Err(JointError::config(
                    format!("joints.{}", axis.name),
                    format!(
                        "limits {}..{} rad beyond the neck platform's ±{max} rad",
                        axis.lower, axis.upper
                    ),
                ));
            }
        }
        specs.extend(axes);
        crate::driver::check_specs(&specs)?;
        Ok(Self {
            inner,
            geometry,
            specs,
            legs,
            passthrough,
            measured: None,
            goal: None,
            clamped: 0,
            last_clamp: None,
        })
    }

    fn neck_offset(&self) -> usize {
        self.passthrough.len()
    }
}

fn axis(a: &NeckAngles, k: usize) -> f64 {
    [a.pitch, a.roll, a.yaw][k]
}

fn set_axis(a: &mut NeckAngles, k: usize, v: f64) {
    match k {
        0 => a.pitch = v,
        1 => a.roll = v,
        _ => a.yaw = v,
    }
}

impl JointDriver for NeckDriver {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn joints(&self) -> &[JointSpec] {
        &self.specs
    }

    fn command(&mut self, targets: &[JointTarget], now_s: f64) -> Result<(), JointError> {
        let checked = check_targets(&self.specs, targets)?;
        let off = self.neck_offset();
        let mut inner_targets = Vec::with_capacity(targets.len() + 3);
        let mut neck: Vec<(usize, f64, f64)> = Vec::new();
        for c in &checked {
            let name = &self.specs[c.index].name;
            if c.index < off {
                inner_targets.push(JointTarget {
                    joint: name.clone(),
                    command: c.command,
                });
                continue;
            }
            let JointCommand::Position {
                position,
                max_speed,
            } = c.command
            else {
                return Err(JointError::Unsupported {
                    driver: "neck",
                    joint: name.clone(),
                    what: "velocity goals",
                });
            };
            neck.push((c.index - off, position, max_speed));
        }
        let mut pending_goal = None;
        if !neck.is_empty() {
            if self.measured.is_none() {
                self.read_state(now_s)?;
            }
            let current = self
                .measured
                .ok_or_else(|| JointError::Bus("neck pose unknown".into()))?;
            let mut goal = self.goal.unwrap_or(current);
            let mut duration_s = 0.0_f64;
            for &(k, position, max_speed) in &neck {
                set_axis(&mut goal, k, position);
                duration_s = duration_s.max((position - axis(&current, k)).abs() / max_speed);
            }
            let lengths = match self.geometry.inverse(goal) {
                Ok(l) => l,
                Err(NeckError::LengthOutOfRange { .. }) => {
                    let asked = goal;
                    goal = self.geometry.nearest_reachable(asked).ok_or_else(|| {
                        JointError::Neck(NeckError::Inconsistent(
                            "the home pose is out of the legs' stroke".into(),
                        ))
                    })?;
                    self.clamped += 1;
                    self.last_clamp = Some((asked, goal));
                    self.geometry.inverse(goal)?
                }
                Err(e) => return Err(e.into()),
            };
            let now_lengths = self.geometry.inverse(current).ok();
            for (k, &leg) in self.legs.iter().enumerate() {
                let spec = &self.inner.joints()[leg];
                let speed = match now_lengths {
                    Some(l) if duration_s > 0.0 => ((lengths[k] - l[k]).abs() / duration_s)
                        .clamp(spec.max_velocity * 1e-3, spec.max_velocity),
                    _ => spec.max_velocity,
                };
                inner_targets.push(JointTarget {
                    joint: spec.name.clone(),
                    command: JointCommand::Position {
                        position: lengths[k],
                        max_speed: speed,
                    },
                });
            }
            pending_goal = Some(goal);
        }
        self.inner.command(&inner_targets, now_s)?;
        if pending_goal.is_some() {
            self.goal = pending_goal;
        }
        Ok(())
    }

    fn read_state(&mut self, now_s: f64) -> Result<Vec<JointState>, JointError> {
        let inner = self.inner.read_state(now_s)?;
        let lengths: [f64; 3] = std::array::from_fn(|k| inner[self.legs[k]].position);
        let rates: [f64; 3] = std::array::from_fn(|k| inner[self.legs[k]].velocity);
        let angles = self.geometry.solve_angles(lengths)?;
        let w = self
            .geometry
            .angle_rates(angles, rates)
            .unwrap_or(NeckAngles {
                pitch: 0.0,
                roll: 0.0,
                yaw: 0.0,
            });
        self.measured = Some(angles);
        let mut out: Vec<JointState> = self.passthrough.iter().map(|&i| inner[i].clone()).collect();
        for k in 0..3 {
            out.push(JointState {
                name: self.specs[self.neck_offset() + k].name.clone(),
                position: axis(&angles, k),
                velocity: axis(&w, k),
                has_effort: false,
                effort: 0.0,
                owner: String::new(),
            });
        }
        Ok(out)
    }

    fn link_stats(&self) -> LinkStats {
        self.inner.link_stats()
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let mut c = self.inner.counters();
        c.push(("neck/clamped", self.clamped));
        c
    }

    fn take_warnings(&mut self) -> Vec<String> {
        let mut w = self.inner.take_warnings();
        if let Some((asked, given)) = self.last_clamp.take() {
            w.push(format!(
                "the neck cannot reach pitch {:.3}, roll {:.3}, yaw {:.3} rad (its legs would leave their stroke): went to pitch {:.3}, roll {:.3}, yaw {:.3} rad instead ({} goals clamped so far)",
                asked.pitch, asked.roll, asked.yaw, given.pitch, given.roll, given.yaw, self.clamped
            ));
        }
        w
    }
}

/// The neck of a URDF that declares a Stewart platform (`<robocog_stewart_neck>`): its geometry,
/// the pitch, roll and yaw joints the platform is presented as (the URDF's joints, with their
/// limits), and the three legs the driver underneath moves.
#[derive(Debug, Clone)]
pub struct NeckPlan {
    pub geometry: NeckGeometry,
    /// Pitch, roll and yaw, as the [`NeckDriver`] presents them.
    pub axes: [JointSpec; 3],
    /// The legs: prismatic joints of the driver underneath (stroke, top speed, and that speed
    /// reached in `accel_time_s`).
    pub legs: [JointSpec; 3],
}

impl NeckPlan {
    /// The plan for `model`'s platform; `None` when it declares none (its neck joints are then
    /// driven as they are). `specs` are the model's joints as the driver would get them.
    /// Errors: the platform's geometry is inconsistent, or an axis is not among `specs`.
    pub fn from_model(
        model: &robot_model::RobotModel,
        specs: &[JointSpec],
        accel_time_s: f64,
    ) -> Result<Option<Self>, JointError> {
        let Some(spec) = &model.stewart_neck else {
            return Ok(None);
        };
        let axis = |name: &String| {
            specs
                .iter()
                .find(|s| &s.name == name)
                .cloned()
                .ok_or_else(|| JointError::UnknownJoint(name.clone()))
        };
        let axes = [axis(&spec.pitch)?, axis(&spec.roll)?, axis(&spec.yaw)?];
        let limits = [0, 1, 2].map(|k| (axes[k].lower, axes[k].upper));
        let geometry = NeckGeometry::from_spec(spec, limits)?;
        let legs = spec.legs.clone().map(|name| {
            JointSpec::prismatic(
                &name,
                spec.min_length_m,
                spec.max_length_m,
                spec.leg_velocity_m_s,
                spec.leg_velocity_m_s / accel_time_s,
            )
        });
        Ok(Some(Self {
            geometry,
            axes,
            legs,
        }))
    }

    /// The joints of the driver underneath: `specs` without the axes, with the legs.
    pub fn inner_specs(&self, specs: &[JointSpec]) -> Vec<JointSpec> {
        specs
            .iter()
            .filter(|s| !self.is_axis(&s.name))
            .cloned()
            .chain(self.legs.iter().cloned())
            .collect()
    }

    /// Whether `joint` is the platform's pitch, roll or yaw.
    pub fn is_axis(&self, joint: &str) -> bool {
        self.axes.iter().any(|a| a.name == joint)
    }

    /// Whether `joint` is one of the legs.
    pub fn is_leg(&self, joint: &str) -> bool {
        self.legs.iter().any(|l| l.name == joint)
    }

    /// The legs' lengths (m) for the reachable pose nearest `angles` (each clamped into its
    /// axis' limits first).
    pub fn leg_lengths(&self, angles: NeckAngles) -> Result<[f64; 3], JointError> {
        let clamp = |k: usize, v: f64| v.clamp(self.axes[k].lower, self.axes[k].upper);
        let a = NeckAngles {
            pitch: clamp(0, angles.pitch),
            roll: clamp(1, angles.roll),
            yaw: clamp(2, angles.yaw),
        };
        let near = self.geometry.nearest_reachable(a).ok_or_else(|| {
            JointError::Neck(NeckError::Inconsistent(
                "the home pose is out of the legs' stroke".into(),
            ))
        })?;
        Ok(self.geometry.inverse(near)?)
    }

    /// `inner` (whose joints include the legs) presented with the axes instead of the legs.
    pub fn wrap(&self, inner: Box<dyn JointDriver>) -> Result<NeckDriver, JointError> {
        let names = self.legs.clone().map(|l| l.name);
        NeckDriver::with_axes(inner, self.geometry, &names, self.axes.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::LimitKind;
    use crate::sim::{SimDriver, SimParams};

    fn neck() -> NeckDriver {
        let g = NeckGeometry::default();
        let leg = |n: &str| JointSpec::prismatic(n, g.min_length_m, g.max_length_m, 0.05, 1.0);
        let specs = vec![
            leg("leg0"),
            JointSpec::revolute("eye_pan", -0.8, 0.8, 6.0, 50.0),
            leg("leg1"),
            leg("leg2"),
        ];
        let mut sim = SimDriver::new(specs, SimParams::default()).unwrap();
        // Start the legs at the home pose.
        let home = g
            .inverse(NeckAngles {
                pitch: 0.0,
                roll: 0.0,
                yaw: 0.0,
            })
            .unwrap();
        let start: Vec<JointTarget> = (0..3)
            .map(|k| JointTarget {
                joint: format!("leg{k}"),
                command: JointCommand::Position {
                    position: home[k],
                    max_speed: 0.05,
                },
            })
            .collect();
        sim.command(&start, 0.0).unwrap();
        sim.read_state(5.0).unwrap();
        let names = NeckJoints {
            pitch: "neck_pitch".into(),
            roll: "neck_roll".into(),
            yaw: "neck_yaw".into(),
            legs: ["leg0".into(), "leg1".into(), "leg2".into()],
            max_velocity: 1.0,
            max_acceleration: 5.0,
        };
        NeckDriver::new(Box::new(sim), g, &names).unwrap()
    }

    fn pos(joint: &str, position: f64, max_speed: f64) -> JointTarget {
        JointTarget {
            joint: joint.into(),
            command: JointCommand::Position {
                position,
                max_speed,
            },
        }
    }

    #[test]
    fn presents_angles_instead_of_legs() {
        let mut n = neck();
        let names: Vec<&str> = n.joints().iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["eye_pan", "neck_pitch", "neck_roll", "neck_yaw"]);
        let s = n.read_state(5.0).unwrap();
        assert!(s[1..].iter().all(|j| j.position.abs() < 1e-6), "{s:?}");
    }

    #[test]
    fn commanded_pose_is_reached() {
        let mut n = neck();
        n.command(
            &[
                pos("neck_pitch", 0.3, 0.5),
                pos("neck_yaw", -0.4, 1.0),
                pos("eye_pan", 0.2, 1.0),
            ],
            5.0,
        )
        .unwrap();
        let mut peak = [0.0_f64; 3];
        let mut t = 5.0;
        let mut s = Vec::new();
        while t < 9.0 {
            t += 0.01;
            s = n.read_state(t).unwrap();
            for k in 0..3 {
                peak[k] = peak[k].max(s[1 + k].velocity.abs());
            }
        }
        assert!((s[1].position - 0.3).abs() < 1e-5, "{s:?}");
        assert!(s[2].position.abs() < 1e-5);
        assert!((s[3].position + 0.4).abs() < 1e-5);
        assert!((s[0].position - 0.2).abs() < 1e-5);
        // Legs are timed by the slowest axis (pitch 0.3 rad at 0.5 rad/s): pitch stays within
        // 2 % of its speed, yaw within its own, roll (not commanded) wobbles < 0.1 rad/s.
        assert!(peak[0] < 0.51 && peak[2] < 1.0 && peak[1] < 0.1, "{peak:?}");
        // Roll was not named: it keeps its goal (0) when only yaw changes later.
        n.command(&[pos("neck_yaw", 0.0, 1.0)], t).unwrap();
        let s = n.read_state(t + 3.0).unwrap();
        assert!(
            (s[1].position - 0.3).abs() < 1e-5 && s[3].position.abs() < 1e-5,
            "{s:?}"
        );
    }

    #[test]
    fn a_goal_beyond_the_stroke_is_clamped_counted_and_told() {
        // Loki's platform (models/loki.urdf) and its URDF joints' asymmetric pitch limits.
        let g = NeckGeometry {
            base_radius_m: 0.07,
            platform_radius_m: 0.05,
            pivot_height_m: 0.10,
            twist_rad: 60f64.to_radians(),
            max_pitch_rad: 0.6,
            max_roll_rad: 0.4,
            max_yaw_rad: 0.8,
            min_length_m: 0.080,
            max_length_m: 0.155,
        };
        let legs = ["l0", "l1", "l2"].map(String::from);
        let home = g.inverse(NeckAngles::HOME).unwrap();
        let leg_specs = legs
            .iter()
            .map(|n| JointSpec::prismatic(n, g.min_length_m, g.max_length_m, 0.1, 0.4))
            .collect();
        let sim = SimDriver::new_at(leg_specs, SimParams::default(), &home).unwrap();
        let axes = [("p", -0.5, 0.6), ("r", -0.4, 0.4), ("y", -0.8, 0.8)]
            .map(|(n, lo, hi)| JointSpec::revolute(n, lo, hi, 1.5, 6.0));
        let mut n = NeckDriver::with_axes(Box::new(sim), g, &legs, axes).unwrap();
        assert_eq!(
            n.joints()[0].lower,
            -0.5,
            "the joints keep the URDF's own limits"
        );
        let e = n.command(&[pos("p", -0.55, 1.0)], 0.0).unwrap_err();
        assert!(matches!(e, JointError::OutOfLimits { .. }), "{e}");
        let far = NeckAngles {
            pitch: -0.5,
            roll: -0.4,
            yaw: -0.8,
        };
        n.command(
            &[
                pos("p", far.pitch, 1.0),
                pos("r", far.roll, 1.0),
                pos("y", far.yaw, 1.0),
            ],
            0.0,
        )
        .unwrap();
        let s = n.read_state(10.0).unwrap();
        let near = g.nearest_reachable(far).unwrap();
        for (state, want) in s.iter().zip([near.pitch, near.roll, near.yaw]) {
            assert!((state.position - want).abs() < 1e-5, "{s:?} vs {near:?}");
        }
        assert!(
            (s[2].position - far.yaw).abs() > 0.01,
            "the goal was clamped: {s:?}"
        );
        assert_eq!(n.counters(), [("neck/clamped", 1)]);
        let told = n.take_warnings();
        assert_eq!(told.len(), 1);
        assert!(
            told[0].contains("cannot reach pitch -0.500, roll -0.400, yaw -0.800"),
            "{told:?}"
        );
        assert!(n.take_warnings().is_empty(), "told once");
        // A reachable goal is not clamped.
        n.command(&[pos("r", 0.0, 1.0)], 10.0).unwrap();
        assert_eq!(n.counters(), [("neck/clamped", 1)]);
        let s = n.read_state(20.0).unwrap();
        assert!(s[1].position.abs() < 1e-5, "{s:?}");
    }

    #[test]
    fn out_of_range_neck_goals_refused() {
        let mut n = neck();
        let e = n.command(&[pos("neck_roll", 0.5, 0.5)], 5.0).unwrap_err();
        assert!(
            matches!(e, JointError::OutOfLimits { ref joint, limit: LimitKind::Upper, .. } if joint == "neck_roll")
        );
        let v = JointTarget {
            joint: "neck_yaw".into(),
            command: JointCommand::Velocity { velocity: 0.1 },
        };
        assert!(matches!(
            n.command(&[v], 5.0),
            Err(JointError::Unsupported { .. })
        ));
        // The legs are not joints of the wrapped driver.
        assert!(matches!(
            n.command(&[pos("leg0", 0.1, 0.01)], 5.0),
            Err(JointError::UnknownJoint(_))
        ));
    }
}
