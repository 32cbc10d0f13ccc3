//! Several clients, one body: joint ownership by leases, and [`JointMotor`] which puts a driver
//! behind it. The rule is stated in the crate docs ("Ownership").

use std::collections::BTreeMap;

use crate::driver::JointDriver;
use crate::error::JointError;
use crate::types::{JointCommand, JointGoal, JointRelease, JointStates, JointTarget, LinkStats};

/// Who holds a joint, with what priority, and when it last commanded it (s, caller's clock).
#[derive(Debug, Clone, PartialEq)]
pub struct Lease {
    pub client: String,
    pub priority: u8,
    pub last_goal_s: f64,
}

/// A joint taken from a client by a higher-priority goal.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Preempted {
    pub joint: String,
    pub from: String,
}

/// The lease table: which client owns which joint. Pure bookkeeping, no driver.
#[derive(Debug, Clone)]
pub struct Arbiter {
    lease_s: f64,
    leases: BTreeMap<String, Lease>,
}

impl Arbiter {
    /// `lease_s`: how long (s) a client keeps a joint without sending a goal for it; > 0.
    pub fn new(lease_s: f64) -> Result<Self, JointError> {
        if !(lease_s.is_finite() && lease_s > 0.0) {
            return Err(JointError::config("lease_s", "must be finite and > 0"));
        }
        Ok(Self {
            lease_s,
            leases: BTreeMap::new(),
        })
    }

    /// The live lease on `joint` at `now_s`, if any.
    pub fn owner(&self, joint: &str, now_s: f64) -> Option<&Lease> {
        self.leases
            .get(joint)
            .filter(|l| now_s - l.last_goal_s <= self.lease_s)
    }

    /// Checks whether `client` at `priority` may command all `joints` now; on success returns the
    /// joints it would take from others (preemptions). Changes nothing.
    pub fn check<'a>(
        &self,
        client: &str,
        priority: u8,
        joints: impl IntoIterator<Item = &'a str>,
        now_s: f64,
    ) -> Result<Vec<Preempted>, JointError> {
        let mut preempted = Vec::new();
        for joint in joints {
            if let Some(l) = self.owner(joint, now_s)
                && l.client != client
            {
                if priority > l.priority {
                    preempted.push(Preempted {
                        joint: joint.to_owned(),
                        from: l.client.clone(),
                    });
                } else {
                    return Err(JointError::Owned {
                        joint: joint.to_owned(),
                        owner: l.client.clone(),
                        owner_priority: l.priority,
                    });
                }
            }
        }
        Ok(preempted)
    }

    /// Gives `client` the `joints` (lease renewed at `now_s` with `priority`). Call after
    /// [`Arbiter::check`] succeeded.
    pub fn claim<'a>(
        &mut self,
        client: &str,
        priority: u8,
        joints: impl IntoIterator<Item = &'a str>,
        now_s: f64,
    ) {
        for joint in joints {
            self.leases.insert(
                joint.to_owned(),
                Lease {
                    client: client.to_owned(),
                    priority,
                    last_goal_s: now_s,
                },
            );
        }
    }

    /// Frees the joints `client` owns among `joints` (all it owns if empty); returns them.
    /// Joints owned by someone else are left alone.
    pub fn release(&mut self, client: &str, joints: &[String]) -> Vec<String> {
        let freed: Vec<String> = self
            .leases
            .iter()
            .filter(|(j, l)| l.client == client && (joints.is_empty() || joints.contains(j)))
            .map(|(j, _)| j.clone())
            .collect();
        for j in &freed {
            self.leases.remove(j);
        }
        freed
    }

    /// Drops the leases lapsed at `now_s`; returns `(joint, client)` for each.
    pub fn expire(&mut self, now_s: f64) -> Vec<(String, String)> {
        let lease_s = self.lease_s;
        let lapsed: Vec<(String, String)> = self
            .leases
            .iter()
            .filter(|(_, l)| now_s - l.last_goal_s > lease_s)
            .map(|(j, l)| (j.clone(), l.client.clone()))
            .collect();
        for (j, _) in &lapsed {
            self.leases.remove(j);
        }
        lapsed
    }
}

/// A driver behind the ownership rule: what a `joint_motor` component process runs.
pub struct JointMotor {
    driver: Box<dyn JointDriver>,
    arbiter: Arbiter,
    /// Per driver joint: whether its last accepted command was a non-zero velocity.
    moving_by_velocity: Vec<bool>,
}

impl std::fmt::Debug for JointMotor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JointMotor")
            .field("driver", &self.driver.name())
            .field("arbiter", &self.arbiter)
            .finish()
    }
}

impl JointMotor {
    /// Wraps `driver`; clients keep joints `lease_s` seconds after their last goal.
    pub fn new(driver: Box<dyn JointDriver>, lease_s: f64) -> Result<Self, JointError> {
        let n = driver.joints().len();
        Ok(Self {
            driver,
            arbiter: Arbiter::new(lease_s)?,
            moving_by_velocity: vec![false; n],
        })
    }

    /// The driver inside.
    pub fn driver(&self) -> &dyn JointDriver {
        self.driver.as_ref()
    }

    /// The driver inside, to read its counters and warnings.
    pub fn driver_mut(&mut self) -> &mut dyn JointDriver {
        self.driver.as_mut()
    }

    /// The lease table.
    pub fn arbiter(&self) -> &Arbiter {
        &self.arbiter
    }

    /// Applies a client's goal at `now_s`, all or nothing: refused if a joint is unknown, beyond
    /// its limits, or owned (live lease) by another client of equal or higher priority. On success
    /// the client owns the named joints; returns the joints taken from other clients.
    pub fn submit(&mut self, goal: &JointGoal, now_s: f64) -> Result<Vec<Preempted>, JointError> {
        self.stop_lapsed(now_s)?;
        let names = || goal.targets.iter().map(|t| t.joint.as_str());
        let preempted = self
            .arbiter
            .check(&goal.client, goal.priority, names(), now_s)?;
        self.driver.command(&goal.targets, now_s)?;
        self.arbiter
            .claim(&goal.client, goal.priority, names(), now_s);
        for t in &goal.targets {
            if let Some(i) = self.index(&t.joint) {
                self.moving_by_velocity[i] =
                    matches!(t.command, JointCommand::Velocity { velocity } if velocity != 0.0);
            }
        }
        Ok(preempted)
    }

    /// Frees joints a client owns; joints left moving by velocity are brought to rest.
    pub fn release(
        &mut self,
        release: &JointRelease,
        now_s: f64,
    ) -> Result<Vec<String>, JointError> {
        let freed = self.arbiter.release(&release.client, &release.joints);
        self.stop(&freed, now_s)?;
        Ok(freed)
    }

    /// The joint states at `now_s` (the `body/joint_states` message; the publisher stamps the
    /// header and names the driver), with the owner of each joint (empty: nobody). Also lapses silent clients'
    /// leases, stopping joints they left moving by velocity.
    pub fn states(&mut self, now_s: f64) -> Result<JointStates, JointError> {
        self.stop_lapsed(now_s)?;
        let mut joints = self.driver.read_state(now_s)?;
        for j in &mut joints {
            j.owner = self
                .arbiter
                .owner(&j.name, now_s)
                .map_or_else(String::new, |l| l.client.clone());
        }
        Ok(JointStates {
            joints,
            ..Default::default()
        })
    }

    /// The driver's bus counters.
    pub fn link_stats(&self) -> LinkStats {
        self.driver.link_stats()
    }

    fn index(&self, joint: &str) -> Option<usize> {
        self.driver.joints().iter().position(|s| s.name == joint)
    }

    fn stop_lapsed(&mut self, now_s: f64) -> Result<(), JointError> {
        let lapsed: Vec<String> = self
            .arbiter
            .expire(now_s)
            .into_iter()
            .map(|(j, _)| j)
            .collect();
        if !lapsed.is_empty() {
            tracing::info!(?lapsed, "joint leases lapsed");
        }
        self.stop(&lapsed, now_s)
    }

    /// Commands velocity 0 to those of `joints` last moved by a non-zero velocity goal.
    fn stop(&mut self, joints: &[String], now_s: f64) -> Result<(), JointError> {
        let targets: Vec<JointTarget> = joints
            .iter()
            .filter(|j| self.index(j).is_some_and(|i| self.moving_by_velocity[i]))
            .map(|j| JointTarget {
                joint: j.clone(),
                command: JointCommand::Velocity { velocity: 0.0 },
            })
            .collect();
        if targets.is_empty() {
            return Ok(());
        }
        self.driver.command(&targets, now_s)?;
        for t in &targets {
            if let Some(i) = self.index(&t.joint) {
                self.moving_by_velocity[i] = false;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{SimDriver, SimParams};
    use crate::types::JointSpec;

    fn motor() -> JointMotor {
        let specs = vec![
            JointSpec::revolute("neck_yaw", -1.0, 1.0, 2.0, 10.0),
            JointSpec::revolute("shoulder", -1.0, 1.0, 1.0, 5.0),
            JointSpec::revolute("elbow", 0.0, 2.0, 1.0, 5.0),
        ];
        let d = SimDriver::new(specs, SimParams::default()).unwrap();
        JointMotor::new(Box::new(d), 0.5).unwrap()
    }

    fn goal(client: &str, priority: u8, joints: &[(&str, f64)]) -> JointGoal {
        JointGoal {
            client: client.into(),
            priority,
            targets: joints
                .iter()
                .map(|(j, p)| JointTarget {
                    joint: (*j).into(),
                    command: JointCommand::Position {
                        position: *p,
                        max_speed: 0.5,
                    },
                })
                .collect(),
        }
    }

    fn owner(m: &mut JointMotor, joint: &str, now_s: f64) -> Option<String> {
        let owner = m.states(now_s).unwrap().get(joint).unwrap().owner.clone();
        (!owner.is_empty()).then_some(owner)
    }

    #[test]
    fn first_goal_owns_and_others_are_refused_naming_the_owner() {
        let mut m = motor();
        m.submit(&goal("gaze", 0, &[("neck_yaw", 0.3)]), 0.0)
            .unwrap();
        assert_eq!(owner(&mut m, "neck_yaw", 0.1).as_deref(), Some("gaze"));
        assert_eq!(owner(&mut m, "elbow", 0.1), None);
        // Same priority, other client: refused, whole goal (elbow not claimed either).
        let e = m
            .submit(
                &goal("reach", 0, &[("elbow", 1.0), ("neck_yaw", -0.3)]),
                0.2,
            )
            .unwrap_err();
        assert_eq!(
            e,
            JointError::Owned {
                joint: "neck_yaw".into(),
                owner: "gaze".into(),
                owner_priority: 0
            }
        );
        assert_eq!(owner(&mut m, "elbow", 0.2), None);
        // The owner itself may re-command; others may take free joints.
        m.submit(&goal("gaze", 0, &[("neck_yaw", 0.1)]), 0.3)
            .unwrap();
        m.submit(&goal("reach", 0, &[("elbow", 1.0)]), 0.3).unwrap();
        let s = m.states(0.35).unwrap();
        assert_eq!(s.get("elbow").unwrap().owner, "reach");
        assert_eq!(s.get("neck_yaw").unwrap().owner, "gaze");
    }

    #[test]
    fn higher_priority_preempts_lower_does_not() {
        let mut m = motor();
        m.submit(&goal("game", 1, &[("shoulder", 0.2)]), 0.0)
            .unwrap();
        let e = m
            .submit(&goal("idle", 0, &[("shoulder", 0.0)]), 0.1)
            .unwrap_err();
        assert!(
            matches!(e, JointError::Owned { ref owner, owner_priority: 1, .. } if owner == "game")
        );
        let p = m
            .submit(&goal("safety", 9, &[("shoulder", 0.0)]), 0.2)
            .unwrap();
        assert_eq!(
            p,
            vec![Preempted {
                joint: "shoulder".into(),
                from: "game".into()
            }]
        );
        assert_eq!(owner(&mut m, "shoulder", 0.2).as_deref(), Some("safety"));
        // The preempted client is now the one refused.
        assert!(
            m.submit(&goal("game", 1, &[("shoulder", 0.2)]), 0.3)
                .is_err()
        );
    }

    #[test]
    fn lease_lapses_after_silence_and_release_frees() {
        let mut m = motor();
        m.submit(&goal("a", 5, &[("elbow", 1.0), ("shoulder", 0.1)]), 0.0)
            .unwrap();
        // Still owned at exactly the lease time, free just after.
        assert!(m.submit(&goal("b", 0, &[("elbow", 0.5)]), 0.5).is_err());
        assert_eq!(owner(&mut m, "elbow", 0.5).as_deref(), Some("a"));
        assert_eq!(owner(&mut m, "elbow", 0.51), None);
        m.submit(&goal("b", 0, &[("elbow", 0.5)]), 0.6).unwrap();
        // Release: only the releasing client's joints.
        m.submit(&goal("a", 0, &[("shoulder", 0.1)]), 0.7).unwrap();
        let freed = m
            .release(
                &JointRelease {
                    client: "a".into(),
                    joints: vec![],
                },
                0.8,
            )
            .unwrap();
        assert_eq!(freed, vec!["shoulder".to_string()]);
        let s = m.states(0.8).unwrap();
        assert_eq!(s.get("shoulder").unwrap().owner, "");
        assert_eq!(s.get("elbow").unwrap().owner, "b");
    }

    #[test]
    fn silent_velocity_client_is_stopped() {
        let mut m = motor();
        let g = JointGoal {
            client: "teleop".into(),
            priority: 0,
            targets: vec![JointTarget {
                joint: "shoulder".into(),
                command: JointCommand::Velocity { velocity: 0.3 },
            }],
        };
        m.submit(&g, 0.0).unwrap();
        assert!(m.states(0.4).unwrap().get("shoulder").unwrap().velocity > 0.29);
        // Lease lapses at 0.5 s; the joint decelerates (5 rad/s²) to rest.
        let s = m.states(0.51).unwrap();
        assert_eq!(s.get("shoulder").unwrap().owner, "");
        let s = m.states(1.0).unwrap();
        let sh = s.get("shoulder").unwrap();
        assert!(sh.velocity.abs() < 1e-9, "{}", sh.velocity);
        assert!(sh.position < 0.2, "{}", sh.position);
    }
}
