//! What each robot decides to do: the controlled robot's command, the autonomous teammate's
//! striker play, the opponents' keeper and defender.

use super::*;

impl SplField {
    // ----- behaviour ---------------------------------------------------------------------

    pub(super) fn robot_pos(&self, id: RobotId) -> Option<V2> {
        self.robot(id).map(|r| r.pos)
    }

    pub(super) fn active(&self, id: RobotId) -> bool {
        self.robot(id)
            .is_some_and(|r| !r.is_fallen() && !r.is_penalised())
    }

    /// Our team's ball: the most recent sighting of either of our robots.
    pub(super) fn team_ball(&self) -> Option<(V2, f64)> {
        self.robots
            .iter()
            .filter(|r| r.id.side == Side::Us)
            .filter_map(|r| r.seen_ball)
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// A shot target in the opponent goal, on the side away from the keeper.
    pub(super) fn shot_target(&self) -> V2 {
        let keeper_y = self.robot_pos(RobotId::KEEPER).map_or(0.0, |p| p.y);
        let y = if keeper_y > 0.0 { -450.0 } else { 450.0 };
        V2::new(FIELD_HALF_LENGTH_MM + 300.0, y)
    }

    /// Whether no opponent stands within `margin` (mm) of a ball rolling from `from` to `to`.
    pub(super) fn lane_clear(&self, from: V2, to: V2, margin: f64) -> bool {
        let d = to - from;
        let len2 = d.dot(d).max(1.0);
        [RobotId::KEEPER, RobotId::DEFENDER]
            .iter()
            .filter_map(|id| self.robot(*id))
            .filter(|r| !r.is_fallen())
            .all(|r| {
                let k = ((r.pos - from).dot(d) / len2).clamp(0.0, 1.0);
                (from + d * k - r.pos).norm() >= margin
            })
    }

    /// A shot at the goal with a free lane, if there is one: aimed inside either post, the
    /// side away from the keeper first, then nearer the posts.
    pub(super) fn open_shot(&self, ball: V2) -> Option<V2> {
        let first = self.shot_target();
        let x = first.x;
        [
            first.y,
            -first.y,
            first.y.signum() * 600.0,
            -first.y.signum() * 600.0,
        ]
        .into_iter()
        .map(|y| V2::new(x, y))
        .find(|t| self.lane_clear(ball, *t, SHOT_LANE_MARGIN_MM))
    }

    /// A free point to dribble to: towards the opponent goal, away from the nearest opponent.
    pub(super) fn free_point(&self, from: V2) -> V2 {
        let goal = opponent_goal();
        let mut p = from + (goal - from).normalized() * 1000.0;
        if let Some(opp) = [RobotId::KEEPER, RobotId::DEFENDER]
            .iter()
            .filter_map(|id| self.robot_pos(*id))
            .min_by(|a, b| (*a - from).norm().total_cmp(&(*b - from).norm()))
            && (opp - p).norm() < 800.0
        {
            let side = if opp.y > from.y { -1.0 } else { 1.0 };
            p.y += side * 700.0;
        }
        V2::new(
            p.x.clamp(-FIELD_HALF_LENGTH_MM, FIELD_HALF_LENGTH_MM),
            p.y.clamp(-FIELD_HALF_WIDTH_MM + 300.0, FIELD_HALF_WIDTH_MM - 300.0),
        )
    }

    pub(super) fn pass_speed(&self, distance_mm: f64) -> f64 {
        // Arrive with ~300 mm/s left: v0² = v1² + 2 a d.
        (300.0f64.powi(2) + 2.0 * self.config.ball_friction_mm_s2 * distance_mm).sqrt()
    }

    pub(super) fn decide(&self, i: usize) -> Intent {
        let r = &self.robots[i];
        if r.is_fallen() || r.is_penalised() || self.time_s < r.busy_until {
            return Intent::Stand;
        }
        match self.state {
            GameState::Ready => {
                let (p, th) = ready_pose(r.id);
                return Intent::Walk {
                    to: p,
                    face: Some(th),
                };
            }
            GameState::Playing => {}
            // INITIAL, SET, FINISHED, STANDBY: no motion.
            _ => return Intent::Stand,
        }
        if self.config.passive_robots.contains(&r.id) {
            return Intent::Stand;
        }
        match r.id.side {
            Side::Us if r.id == RobotId::CONTROLLED => self.decide_controlled(r),
            Side::Us => self.decide_autonomous(r),
            Side::Them if r.id == RobotId::KEEPER => self.decide_keeper(r),
            Side::Them => self.decide_defender(r),
        }
    }

    pub(super) fn decide_controlled(&self, r: &SimRobot) -> Intent {
        let c = &self.controlled;
        let Some(body) = c.body else {
            return Intent::Stand;
        };
        if c.done {
            return Intent::Stand;
        }
        let ball = r.seen_ball.map(|(b, _)| b);
        let ball_age = r.seen_ball.map_or(f64::INFINITY, |(_, t)| self.time_s - t);
        match body {
            NaoBody::GoToPosition => Intent::Walk {
                to: c.target,
                face: None,
            },
            // `Keep` is never stored: a packet keeping the body leaves `body` as it was.
            NaoBody::Stop | NaoBody::Keep => Intent::Stand,
            // Intent, not the quirk: face the target (x, y), not (y, x).
            NaoBody::Turn => Intent::Face((c.target - r.pos).angle()),
            // Intent, not the quirk: turn (head scanning) until the ball is seen.
            NaoBody::SearchTheBall => Intent::Spin(0.8),
            NaoBody::AskForTheBall => match ball {
                Some(b) => Intent::Face((b - r.pos).angle()),
                None => Intent::Stand,
            },
            _ if ball.is_none() || ball_age > 5.0 => Intent::Spin(0.8),
            NaoBody::Dribble => {
                let b = ball.unwrap_or(self.ball);
                if (b - r.pos).norm() <= 600.0 {
                    Intent::Dribble {
                        target: self.free_point(b),
                    }
                } else {
                    // Dribble assumes the ball at the feet; far from it the robot waits.
                    Intent::Stand
                }
            }
            NaoBody::GoToBallAndDribble => {
                let b = ball.unwrap_or(self.ball);
                Intent::Dribble {
                    target: self.free_point(b),
                }
            }
            NaoBody::Kick => Intent::Kick {
                target: self.shot_target(),
                speed: 3000.0,
            },
            NaoBody::Spazza => {
                let b = ball.unwrap_or(self.ball);
                let away = (b - own_goal()).normalized();
                Intent::Kick {
                    target: b + away * 3000.0,
                    speed: 3500.0,
                }
            }
            NaoBody::Pass => {
                // Intent, not the quirk: pass to the active teammate; dribble without one.
                if self.active(RobotId::AUTONOMOUS) {
                    let mate = self.robot_pos(RobotId::AUTONOMOUS).unwrap_or_default();
                    let b = ball.unwrap_or(self.ball);
                    Intent::Kick {
                        target: mate,
                        speed: self.pass_speed((mate - b).norm()),
                    }
                } else {
                    let b = ball.unwrap_or(self.ball);
                    Intent::Dribble {
                        target: self.free_point(b),
                    }
                }
            }
        }
    }

    pub(super) fn after_controlled(&mut self, outcome: Outcome) {
        let t = self.time_s;
        let c = &mut self.controlled;
        let Some(body) = c.body else { return };
        let seen_recently = self.robots.iter().any(|r| {
            r.id == RobotId::CONTROLLED && r.seen_ball.is_some_and(|(_, ts)| t - ts < 0.2)
        });
        c.done |= match body {
            NaoBody::Kick | NaoBody::Spazza => outcome == Outcome::Kicked,
            NaoBody::Pass => outcome == Outcome::Kicked,
            NaoBody::GoToPosition | NaoBody::Turn => outcome == Outcome::Arrived,
            NaoBody::SearchTheBall => seen_recently,
            _ => false,
        };
    }

    pub(super) fn decide_autonomous(&self, r: &SimRobot) -> Intent {
        let Some((ball, _)) = self.team_ball().filter(|(_, t)| self.time_s - t < 4.0) else {
            return Intent::Spin(0.8);
        };
        let me = r.pos;
        let ctl = self.robot(RobotId::CONTROLLED);
        let ctl_active = self.active(RobotId::CONTROLLED);
        let ctl_pos = ctl.map_or(V2::new(-9999.0, 0.0), |c| c.pos);
        let striker = !ctl_active || (ball - me).norm() < (ball - ctl_pos).norm();
        if !striker {
            // Supporter: behind the ball, on the other side of the field.
            let y = if ball.y > 0.0 {
                ball.y - 1500.0
            } else {
                ball.y + 1500.0
            };
            return Intent::Walk {
                to: V2::new(
                    (ball.x - 1200.0).clamp(-4000.0, 3500.0),
                    y.clamp(-2500.0, 2500.0),
                ),
                face: Some((ball - me).angle()),
            };
        }
        let wants_pass = ctl_active
            && (self.controlled.ball_requested
                || (self.controlled.strategy == NaoStrategy::Passages && ctl_pos.x > me.x + 500.0));
        if wants_pass {
            return Intent::Kick {
                target: ctl_pos,
                speed: self.pass_speed((ctl_pos - ball).norm()),
            };
        }
        // Shoot as soon as a lane to the goal is free (from the own half's front on), else
        // from close in anyway; otherwise dribble round the nearest opponent.
        if ball.x > SHOT_FROM_X_MM
            && let Some(target) = self.open_shot(ball)
        {
            Intent::Kick {
                target,
                speed: 3000.0,
            }
        } else if ball.x > 3000.0 {
            Intent::Kick {
                target: self.shot_target(),
                speed: 3000.0,
            }
        } else {
            Intent::Dribble {
                target: self.free_point(ball),
            }
        }
    }

    pub(super) fn decide_keeper(&self, _r: &SimRobot) -> Intent {
        let b = self.ball;
        let y =
            b.y.clamp(-GOAL_HALF_WIDTH_MM + 150.0, GOAL_HALF_WIDTH_MM - 150.0);
        if b.x > 3200.0 && self.ball_vel.norm() < 300.0 {
            // Clear a slow ball in the penalty area.
            return Intent::Kick {
                target: V2::new(0.0, b.y),
                speed: 3000.0,
            };
        }
        Intent::Walk {
            to: V2::new(4300.0, y),
            face: Some(PI),
        }
    }

    pub(super) fn decide_defender(&self, r: &SimRobot) -> Intent {
        let b = self.ball;
        let me = r.pos;
        let nearest_us = [RobotId::AUTONOMOUS, RobotId::CONTROLLED]
            .iter()
            .filter_map(|id| self.robot_pos(*id))
            .map(|p| (p - b).norm())
            .fold(f64::INFINITY, f64::min);
        if (b - me).norm() < nearest_us || b.x > 1500.0 {
            Intent::Kick {
                target: own_goal(),
                speed: 2500.0,
            }
        } else {
            // Between the ball and its goal.
            let goal = opponent_goal();
            let p = b + (goal - b).normalized() * 1200.0;
            Intent::Walk {
                to: p,
                face: Some((b - p).angle()),
            }
        }
    }
}
