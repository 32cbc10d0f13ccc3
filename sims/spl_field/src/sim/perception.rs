//! What each simulated robot sees: its head's motion and the field through its camera's
//! range and angle, into the obstacle memory of its local model.

use super::*;

impl SplField {
    // ----- perception --------------------------------------------------------------------

    pub(super) fn update_head(&mut self, i: usize) {
        let t = self.time_s;
        let r = &self.robots[i];
        let head = match r.id {
            RobotId::CONTROLLED => self.controlled.head,
            _ => NaoHead::LookAtTheBall,
        };
        let searching = r.id == RobotId::CONTROLLED
            && self.controlled.body == Some(NaoBody::SearchTheBall)
            && !self.controlled.done;
        let known_ball = r.seen_ball.filter(|(_, ts)| t - ts < 3.0);
        let desired = match (head, searching) {
            (_, true) | (NaoHead::Scan, _) => 1.5 * (t * PI / 2.0).sin(),
            (NaoHead::LookForward, _) => 0.0,
            (NaoHead::LookLeft, _) => 1.0,
            (NaoHead::LookRight, _) => -1.0,
            // `Keep` is never stored: the robot keeps its previous head command.
            (NaoHead::LookAtTheBall | NaoHead::Keep, _) => match known_ball {
                Some((b, _)) => angle_diff((b - r.pos).angle(), r.theta),
                // Ball unknown: scan for it.
                None => 1.5 * (t * PI / 2.0).sin(),
            },
        }
        .clamp(-HEAD_YAW_MAX, HEAD_YAW_MAX);
        let r = &mut self.robots[i];
        let step = HEAD_SPEED * TICK_S;
        r.head_yaw += (desired - r.head_yaw).clamp(-step, step);
    }

    pub(super) fn visible(&self, r: &SimRobot, p: V2, range: f64) -> bool {
        let d = p - r.pos;
        let dist = d.norm();
        if dist > range {
            return false;
        }
        let gaze = r.theta + r.head_yaw;
        let upper = angle_diff(d.angle(), gaze).abs() <= self.config.camera_half_fov_rad;
        // The lower camera sees the feet area in front of the body.
        let lower = dist < 500.0 && angle_diff(d.angle(), r.theta).abs() < 0.9;
        upper || lower
    }

    pub(super) fn perceive(&mut self, i: usize) {
        if self.robots[i].is_fallen() {
            return;
        }
        let t = self.time_s;
        let (sigma0, k) = (
            self.config.perception_sigma_mm,
            self.config.perception_sigma_per_mm,
        );
        let me = self.robots[i].clone();
        if self.visible(&me, self.ball, self.config.ball_range_mm) {
            let s = sigma0 + k * (self.ball - me.pos).norm();
            let seen = self.ball + V2::new(self.rng.gauss(s), self.rng.gauss(s));
            self.robots[i].seen_ball = Some((seen, t));
        }
        for j in 0..self.robots.len() {
            let other = &self.robots[j];
            if j == i || !self.visible(&me, other.pos, self.config.robot_range_mm) {
                continue;
            }
            let kind = match (other.side_of(me.id.side), other.is_fallen()) {
                (true, false) => ObstacleKind::Teammate,
                (true, true) => ObstacleKind::FallenTeammate,
                (false, false) => ObstacleKind::Opponent,
                (false, true) => ObstacleKind::FallenOpponent,
            };
            let (oid, opos) = (other.id, other.pos);
            let s = sigma0 + k * (opos - me.pos).norm();
            let seen = opos + V2::new(self.rng.gauss(s), self.rng.gauss(s));
            self.robots[i]
                .seen_robots
                .insert(oid, Seen { pos: seen, t, kind });
        }
        for (n, post) in GOALPOSTS.iter().enumerate() {
            if self.visible(&me, *post, self.config.robot_range_mm) {
                self.robots[i].seen_posts.insert(
                    n,
                    Seen {
                        pos: *post,
                        t,
                        kind: ObstacleKind::Goalpost,
                    },
                );
            }
        }
        let r = &mut self.robots[i];
        r.seen_robots.retain(|_, s| t - s.t <= OBSTACLE_MEMORY_S);
        r.seen_posts.retain(|_, s| t - s.t <= OBSTACLE_MEMORY_S);
    }
}
