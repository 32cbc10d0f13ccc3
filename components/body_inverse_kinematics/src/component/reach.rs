//! A reach's life after its goal is accepted: locating the target in the DR, solving (seeded
//! restarts in a time budget, the self-collision check), and stepping along the trajectory until
//! reached, unreachable or failed.

use super::*;

impl Ik {
    /// Looks the target up in the DR: into the root frame, and into `world` for the status.
    pub(super) async fn locate(&self, a: &mut Active) -> Result<(), Failure> {
        let in_frame =
            goal_pose(&a.goal).map_err(|e| Failure::new(format!("invalid goal: {e}")))?;
        let root_t_frame = self.transform(a.part.root, &a.goal.frame).await?;
        let world_t_frame = self.transform("world", &a.goal.frame).await?;
        a.world_t_root = self.transform("world", a.part.root).await?;
        a.target_root = root_t_frame * in_frame;
        a.target_world = world_t_frame * in_frame;
        Ok(())
    }

    /// Solves the goal from the measured joints. `Moving` and a plan, or `Unreachable` / `Failed`.
    /// Returns whether the goal stays active.
    pub(super) fn fresh(&self) -> bool {
        self.measured_at
            .is_some_and(|t| self.bus.clock().elapsed(t).as_secs_f64() < STALE_JOINT_STATES_S)
    }

    pub(super) async fn solve(&mut self, a: &mut Active) -> bool {
        if !self.fresh() {
            // joint_motor away: solved by a tick once joint states are back (or failed after
            // the grace).
            a.waiting_since = Some(self.bus.clock().now());
            a.plan = None;
            return true;
        }
        let q_now = match chain_q(&a.chain, &self.measured) {
            Ok(q) => q,
            Err(joint) => {
                self.fail(&a.goal, format!("joint states have no joint `{joint}`"))
                    .await;
                return false;
            }
        };
        let Some(mut body) = self.body.take() else {
            return false;
        };
        for (name, &v) in &self.measured {
            // Joints the model lacks are counted by the DR; here they are simply not used.
            let _ = body.set_joint(name, v);
        }
        let mut req = IkRequest::new(a.part.name, ik_target(a.goal.kind, &a.target_root));
        req.tolerance_m = a.tolerance_m.min(1e-3);
        req.max_time_s = self.config.solve_budget_ms * 1e-3;
        req.q_start = Some(q_now.clone());
        req.seed = a.goal.id;
        #[expect(
            clippy::disallowed_methods,
            reason = "the solve time (`solve_ms`): a measurement of the solver's compute, on the wall"
        )]
        let started = Instant::now();
        let joined = tokio::task::spawn_blocking(move || {
            let r = body.solve(&req);
            (body, r)
        })
        .await;
        let (body, result) = match joined {
            Ok(x) => x,
            Err(e) => {
                // The model is lost with the task: rebuild it before anything else.
                tracing::error!("the IK task failed: {e}");
                self.body = self.reload();
                self.fail(&a.goal, format!("the IK solver failed: {e}"))
                    .await;
                return false;
            }
        };
        let solve_ms = started.elapsed().as_secs_f64() * 1e3;
        self.body = Some(body);
        let result = match result {
            Ok(r) => r,
            Err(e) => {
                self.fail(&a.goal, format!("IK request refused: {e}")).await;
                return false;
            }
        };
        // A best attempt within the goal's (looser) tolerance is good enough, if collision-free.
        let (q, residual_m) = match result {
            IkResult::Reached { q, residual_m, .. } => (q, residual_m),
            IkResult::Unreachable {
                best_q,
                residual_m,
                cause: UnreachableCause::OutOfTolerance,
                ..
            } if residual_m <= a.tolerance_m
                && a.goal.kind != ReachKind::Pose
                && self.collision_free(a.part.name, &best_q) =>
            {
                (best_q, residual_m)
            }
            IkResult::Unreachable {
                residual_m, cause, ..
            } => {
                self.bus.counters().incr("unreachable");
                let why = match cause {
                    UnreachableCause::OutOfTolerance => "no configuration within the joint limits",
                    UnreachableCause::SelfCollision => {
                        "every configuration within tolerance collides with the body"
                    }
                };
                let detail = format!(
                    "{why}: best residual {residual_m:.3} m (tolerance {:.3} m), solved in {solve_ms:.1} ms",
                    a.tolerance_m
                );
                tracing::info!(part = %a.goal.body_part, id = a.goal.id, "unreachable: {detail}");
                let mut s = self.active_status(a, ReachState::Unreachable, detail);
                s.residual_m = residual_m;
                self.publish(s).await;
                if a.goal.follow {
                    // Keep following: the target may come within reach. Nothing moves meanwhile.
                    a.plan = None;
                    return true;
                }
                return false;
            }
        };
        let vmax: Vec<f64> = a
            .vmax
            .iter()
            .map(|v| v * self.config.speed_fraction)
            .collect();
        let trajectory = match Trajectory::quintic(&q_now, &q, &vmax, None, a.goal.min_duration_s) {
            Ok(t) => t.jerk_limited(&vec![self.config.max_joint_jerk; q.len()]),
            Err(e) => {
                self.fail(&a.goal, format!("no trajectory to the solution: {e}"))
                    .await;
                return false;
            }
        };
        // The tip's path, in the part's root frame: slowed down if the hand would go too fast.
        let tip = |q: &[f64]| {
            let p = a.chain.fk_unchecked(q).translation.vector;
            [p.x, p.y, p.z]
        };
        let (mut tip_speed, mut tip_jerk) = trajectory.point_peaks(tip, 200);
        let trajectory =
            if a.goal.kind != ReachKind::Gaze && tip_speed > self.config.max_hand_speed_m_s {
                self.bus.counters().incr("hand_speed_limited");
                let stretch = tip_speed / self.config.max_hand_speed_m_s;
                tip_speed /= stretch;
                tip_jerk /= stretch.powi(3);
                let t = trajectory.duration_s() * stretch;
                trajectory.stretched(t)
            } else {
                trajectory
            };
        tracing::info!(
            part = %a.goal.body_part,
            id = a.goal.id,
            "moving: residual {:.2} mm, solved in {solve_ms:.1} ms, trajectory {:.2} s, tip peak {tip_speed:.2} m/s, {tip_jerk:.1} m/s³",
            residual_m * 1e3,
            trajectory.duration_s()
        );
        a.plan = Some(Plan {
            trajectory,
            started: self.bus.clock().now(),
            residual_m,
            reached: false,
            settle_failed: false,
            last_sent: None,
        });
        let s = self.active_status(a, ReachState::Moving, "");
        self.publish(s).await;
        self.bus.counters().incr("solved");
        true
    }

    /// Adds the eyes' targets (aimed at `target`, in the part's root frame, from the measured
    /// head) to a gaze's joint targets. Returns whether the eyes go on being driven: not when
    /// the joint states do not report them (logged and counted once; the eyes stay still from
    /// then on).
    pub(super) fn aim_eyes(
        &mut self,
        goal: &ReachGoal,
        target: &Vector3<f64>,
        targets: &mut Vec<JointTarget>,
    ) -> bool {
        let Some(eyes) = &self.eyes else {
            return false;
        };
        match eyes.aim(&self.measured, target) {
            Ok(q) => {
                targets.extend(eyes.joints().iter().zip(q).zip(eyes.max_speeds()).map(
                    |((j, position), max_speed)| JointTarget {
                        joint: j.clone(),
                        mode: JointMode::Position,
                        position,
                        max_speed,
                        velocity: 0.0,
                    },
                ));
                true
            }
            Err(joint) => {
                self.eyes = None;
                self.bus.counters().incr("eyes_not_driven");
                tracing::warn!(
                    part = %goal.body_part,
                    id = goal.id,
                    "the eyes stay still from now on: {} reports no `{joint}` (joint_motor does not drive it)",
                    topics::BODY_JOINT_STATES.name()
                );
                false
            }
        }
    }

    pub(super) fn collision_free(&mut self, part: &str, q: &[f64]) -> bool {
        self.body
            .as_mut()
            .and_then(|b| b.self_collision(part, q).ok())
            .is_some_and(|c| c.is_none())
    }

    pub(super) fn reload(&self) -> Option<BodyIk> {
        let urdf = find_model(self.config.urdf.as_deref(), "loki.urdf");
        BodyIk::from_urdf_file(&urdf).ok()
    }

    /// One tick of the stream: every active part streams, holds, checks "reached", follows.
    pub(super) async fn tick(&mut self) {
        let names: Vec<String> = self.parts.keys().cloned().collect();
        for name in names {
            let Some(mut a) = self.parts.remove(&name) else {
                continue;
            };
            let keep = match self.step(&mut a).await {
                Ok(keep) => {
                    if keep && let Some(since) = a.peer_away_since.take() {
                        tracing::info!(
                            part = %a.goal.body_part,
                            id = a.goal.id,
                            "the peers answer again after {:.1} s: the goal goes on",
                            self.bus.clock().elapsed(since).as_secs_f64()
                        );
                    }
                    keep
                }
                Err(f) if f.peer_away && self.within_grace(&mut a, &f.detail) => true,
                Err(f) => {
                    self.bus.counters().incr("goals_failed");
                    let detail = f.detail;
                    tracing::warn!(part = %a.goal.body_part, id = a.goal.id, "failed: {detail}");
                    let s = self.active_status(&a, ReachState::Failed, detail);
                    self.publish(s).await;
                    false
                }
            };
            if keep {
                self.parts.insert(name, a);
            } else {
                self.release_goal(&a).await;
            }
        }
    }

    /// A peer is away (`detail`): the goal holds from now (logged once per absence).
    pub(super) fn peer_away(&self, a: &mut Active, detail: &str) {
        if a.peer_away_since.is_none() {
            a.peer_away_since = Some(self.bus.clock().now());
            self.bus.counters().incr("peer_away");
            tracing::warn!(
                part = %a.goal.body_part,
                id = a.goal.id,
                "{detail}: riding it out for up to {:.1} s, the arm holding where it is",
                self.config.peer_grace_s
            );
        }
    }

    /// Whether a goal whose peer is away (`detail`) is still within the grace.
    pub(super) fn within_grace(&self, a: &mut Active, detail: &str) -> bool {
        self.peer_away(a, detail);
        a.peer_away_since.is_some_and(|since| {
            self.bus.clock().elapsed(since).as_secs_f64() < self.config.peer_grace_s
        })
    }

    pub(super) async fn step(&mut self, a: &mut Active) -> Result<bool, Failure> {
        let now = self.bus.clock().now();
        if !a.located {
            self.locate(a).await?;
            a.located = true;
            return Ok(self.solve(a).await);
        }
        if let Some(since) = a.waiting_since {
            if self.fresh() {
                a.waiting_since = None;
                return Ok(self.solve(a).await);
            }
            if now.duration_since(since).as_secs_f64()
                < self.config.peer_grace_s.max(2.0 * STALE_JOINT_STATES_S)
            {
                return Ok(true);
            }
            return Err(Failure::new(format!(
                "no joint states on {} for {:.1} s: is joint_motor running?",
                topics::BODY_JOINT_STATES.name(),
                self.config.peer_grace_s
            )));
        }
        let period = 1.0 / self.config.stream_hz;
        if let Some(plan) = a.plan.as_mut() {
            let t = now.duration_since(plan.started).as_secs_f64();
            let moving = t <= plan.trajectory.duration_s() + period;
            let hold_due = plan
                .last_sent
                .is_none_or(|s| now.duration_since(s).as_secs_f64() >= 1.0 / self.config.hold_hz);
            if moving || hold_due {
                let mut q = vec![0.0; plan.trajectory.dof()];
                plan.trajectory.sample_into(t + period, &mut q, None);
                plan.last_sent = Some(now);
                let mut goal = JointGoal {
                    header: Header::default(),
                    client: self.client(&a.goal.body_part),
                    priority: self.config.priority,
                    targets: a
                        .chain
                        .joints
                        .iter()
                        .zip(q.iter().zip(&a.vmax))
                        .map(|(j, (&position, &max_speed))| JointTarget {
                            joint: j.name.clone(),
                            mode: JointMode::Position,
                            position,
                            max_speed,
                            velocity: 0.0,
                        })
                        .collect(),
                    release: false,
                };
                if a.eyes {
                    let target = a.target_root.translation.vector;
                    a.eyes = self.aim_eyes(&a.goal, &target, &mut goal.targets);
                }
                self.send(&goal).await?;
            }
            if !moving && !plan.reached && !plan.settle_failed {
                let err = self.measured_tip(a).map(|(_, d)| d);
                let Some(plan) = a.plan.as_mut() else {
                    return Ok(true);
                };
                match err {
                    Some(d) if d <= a.tolerance_m => {
                        plan.reached = true;
                        self.bus.counters().incr("reached");
                        let s = self.active_status(a, ReachState::Reached, "");
                        tracing::info!(
                            part = %a.goal.body_part,
                            id = a.goal.id,
                            "reached: tip {:.1} mm from the target",
                            s.distance_m * 1e3
                        );
                        self.publish(s).await;
                    }
                    _ if t > plan.trajectory.duration_s() + SETTLE_TIMEOUT_S => {
                        plan.settle_failed = true;
                        let detail = format!(
                            "the measured joints did not bring the tip within {:.3} m of the target {SETTLE_TIMEOUT_S} s after the trajectory ended (now {})",
                            a.tolerance_m,
                            err.map_or("unknown".to_owned(), |d| format!("{d:.3} m"))
                        );
                        if !a.goal.follow {
                            return Err(Failure::new(detail));
                        }
                        let s = self.active_status(a, ReachState::Failed, detail);
                        self.publish(s).await;
                    }
                    _ => {}
                }
            }
        }
        if a.goal.follow
            && now.duration_since(a.last_follow).as_secs_f64() >= 1.0 / self.config.follow_hz
        {
            a.last_follow = now;
            let before = (a.target_root, a.target_world, a.world_t_root);
            let had_plan = a.plan.is_some();
            self.locate(a).await?;
            let moved = (a.target_root.translation.vector - before.0.translation.vector).norm();
            if moved > self.config.follow_threshold_m || (!had_plan && moved > 1e-6) {
                tracing::debug!(part = %a.goal.body_part, "target moved {moved:.3} m: solving again");
                self.bus.counters().incr("follow_resolves");
                return Ok(self.solve(a).await);
            }
            // A move within the threshold is ignored: the goal stays the target it was solved for.
            (a.target_root, a.target_world, a.world_t_root) = before;
        }
        Ok(true)
    }
}
