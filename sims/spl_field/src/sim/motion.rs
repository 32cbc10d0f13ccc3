//! Carrying intents out: walking, turning, kicks and passes, and the ball's physics.

use super::*;

impl SplField {
    // ----- motion ------------------------------------------------------------------------

    pub(super) fn execute(&mut self, i: usize, intent: Intent) -> Outcome {
        let ball = self.ball;
        let r = &self.robots[i];
        let (pos, theta) = (r.pos, r.theta);
        let (walk, turn) = (self.config.walk_speed_mm_s, self.config.turn_speed_rad_s);
        let mut outcome = Outcome::Busy;
        let (to, face, speed) = match intent {
            Intent::Stand => (pos, None, 0.0),
            Intent::Walk { to, face } => {
                let far = (to - pos).norm() > 300.0;
                let face = if far { Some((to - pos).angle()) } else { face };
                if (to - pos).norm() < 50.0 && face.is_none_or(|f| angle_diff(f, theta).abs() < 0.1)
                {
                    outcome = Outcome::Arrived;
                }
                (to, face, walk)
            }
            Intent::Face(f) => {
                if angle_diff(f, theta).abs() < 0.05 {
                    outcome = Outcome::Arrived;
                }
                (pos, Some(f), 0.0)
            }
            Intent::Spin(rate) => {
                let r = &mut self.robots[i];
                r.theta = wrap(r.theta + rate * TICK_S);
                r.vel = V2::ZERO;
                return Outcome::Busy;
            }
            Intent::Kick { target, speed } => {
                let dir = (target - ball).normalized();
                let (to, face, aligned) = approach(pos, theta, ball, dir, KICK_REACH_MM);
                if aligned {
                    self.kick(i, dir * speed);
                    return Outcome::Kicked;
                }
                (to, Some(face), walk)
            }
            Intent::Dribble { target } => {
                let dir = (target - ball).normalized();
                let (to, face, aligned) = approach(pos, theta, ball, dir, KICK_REACH_MM);
                if aligned || (ball - pos).norm() < KICK_REACH_MM + 30.0 && behind(pos, ball, dir) {
                    // Walk through the ball: contact pushes it ahead.
                    (ball + dir * 400.0, Some(dir.angle()), 0.7 * walk)
                } else {
                    (to, Some(face), walk)
                }
            }
        };
        let r = &mut self.robots[i];
        let d = to - pos;
        let v = d.normalized() * (3.0 * d.norm()).min(speed);
        r.pos = r.pos + v * TICK_S;
        r.pos.x = r
            .pos
            .x
            .clamp(-FIELD_HALF_LENGTH_MM - 600.0, FIELD_HALF_LENGTH_MM + 600.0);
        r.pos.y = r
            .pos
            .y
            .clamp(-FIELD_HALF_WIDTH_MM - 600.0, FIELD_HALF_WIDTH_MM + 600.0);
        r.vel = v;
        if let Some(f) = face {
            let step = turn * TICK_S;
            r.theta = wrap(r.theta + angle_diff(f, r.theta).clamp(-step, step));
        }
        outcome
    }

    pub(super) fn kick(&mut self, i: usize, vel: V2) {
        let t = self.time_s;
        let r = &mut self.robots[i];
        r.busy_until = t + KICK_DURATION_S;
        r.no_contact_until = t + KICKER_NO_CONTACT_S;
        r.vel = V2::ZERO;
        let id = r.id;
        self.ball_vel = vel;
        self.events.push((
            t,
            SimEvent::Kick {
                by: id,
                speed_mm_s: vel.norm(),
            },
        ));
        self.touched_by(id);
        self.pending_pass = Some(PendingPass {
            from: id,
            origin: self.ball,
        });
        self.last_kicker = Some(id);
    }

    /// Record a touch: resolves a pending pass.
    pub(super) fn touched_by(&mut self, id: RobotId) {
        self.last_toucher = Some(id);
        if let Some(p) = self.pending_pass
            && p.from != id
        {
            self.pending_pass = None;
            let distance = (self.ball - p.origin).norm();
            if p.from.side == id.side && distance >= PASS_MIN_DISTANCE_MM {
                self.events.push((
                    self.time_s,
                    SimEvent::PassCompleted {
                        from: p.from,
                        to: id,
                        distance_mm: distance,
                    },
                ));
                if id.side == Side::Us && self.state == GameState::Playing {
                    self.score = self.score.saturating_add(1);
                }
                if id == RobotId::CONTROLLED {
                    self.controlled.ball_requested = false;
                }
            }
        }
    }

    // ----- ball --------------------------------------------------------------------------

    pub(super) fn update_ball(&mut self) {
        // Rolling friction.
        let speed = self.ball_vel.norm();
        let dv = self.config.ball_friction_mm_s2 * TICK_S;
        self.ball_vel = if speed <= dv {
            V2::ZERO
        } else {
            self.ball_vel * ((speed - dv) / speed)
        };
        let prev = self.ball;
        self.ball = self.ball + self.ball_vel * TICK_S;

        // Contacts with robots (fallen robots are obstacles too).
        let t = self.time_s;
        let mut touches = Vec::new();
        for r in &mut self.robots {
            let d = self.ball - r.pos;
            let dist = d.norm();
            let contact = dist < BALL_CONTACT_MM && t >= r.no_contact_until;
            if contact {
                let n = if dist > 1e-6 {
                    d * (1.0 / dist)
                } else {
                    V2::new(1.0, 0.0)
                };
                self.ball = r.pos + n * BALL_CONTACT_MM;
                let vn = self.ball_vel.dot(n);
                if vn < 0.0 {
                    // Bounce off the robot's legs.
                    self.ball_vel = self.ball_vel - n * (1.3 * vn);
                }
                // Pushed by a walking robot.
                let push = r.vel.dot(n);
                if push > 0.0 && self.ball_vel.dot(n) < 1.8 * push {
                    self.ball_vel = self.ball_vel + n * (1.8 * push - self.ball_vel.dot(n));
                }
                if !r.in_contact {
                    touches.push(r.id);
                }
            }
            r.in_contact = contact;
        }
        for id in touches {
            self.events.push((t, SimEvent::Touch { by: id }));
            self.touched_by(id);
        }

        // Goals and out.
        if self.state == GameState::Playing {
            for (sign, side) in [(1.0, Side::Us), (-1.0, Side::Them)] {
                let line = sign * FIELD_HALF_LENGTH_MM;
                let crossed = (self.ball.x - line) * sign > 0.0 && (prev.x - line) * sign <= 0.0;
                if crossed {
                    let f = (line - prev.x) / (self.ball.x - prev.x);
                    let y = prev.y + f * (self.ball.y - prev.y);
                    if y.abs() < GOAL_HALF_WIDTH_MM {
                        let counted =
                            !(side == Side::Us && self.last_toucher == Some(RobotId::CONTROLLED));
                        self.events.push((t, SimEvent::Goal { side, counted }));
                        if counted {
                            match side {
                                Side::Us => self.score = self.score.saturating_add(2),
                                Side::Them => {
                                    self.opponent_score = self.opponent_score.saturating_add(1)
                                }
                            }
                        }
                        self.ball_vel = V2::ZERO;
                        self.change_state(GameState::Finished);
                        return;
                    }
                }
            }
        }
        let out =
            self.ball.x.abs() > FIELD_HALF_LENGTH_MM || self.ball.y.abs() > FIELD_HALF_WIDTH_MM;
        if out && self.state == GameState::Playing {
            // Put back 400 mm inside the line (a simplified kick-in / goal kick).
            self.ball = V2::new(
                self.ball
                    .x
                    .clamp(-FIELD_HALF_LENGTH_MM + 400.0, FIELD_HALF_LENGTH_MM - 400.0),
                self.ball
                    .y
                    .clamp(-FIELD_HALF_WIDTH_MM + 400.0, FIELD_HALF_WIDTH_MM - 400.0),
            );
            self.ball_vel = V2::ZERO;
            self.pending_pass = None;
            self.events.push((t, SimEvent::BallOut));
        }
    }
}
