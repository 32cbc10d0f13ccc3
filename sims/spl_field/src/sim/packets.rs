//! What the field sends: each robot's debug packet from its local model, the GameController's
//! state and packets.

use super::*;

impl SplField {
    // ----- packets -----------------------------------------------------------------------

    /// The local world model a robot would send now (perceived, noisy). Draws the
    /// self-localisation noise from the run's generator: calling it from outside changes the
    /// rest of the run (still deterministically).
    pub fn local_model(&mut self, id: RobotId) -> Option<NaoLocalModel> {
        let t = self.time_s;
        let secs = self.secs_remaining().ceil() as u16;
        let budget = self.message_budget;
        let team = self.config.team_number;
        let whistle_since = self.whistle_at_s.map(|w| t - w);
        let team_ball = self.team_ball();
        let team_ball_vel = if team_ball.is_some_and(|(_, ts)| t - ts < 1.0) {
            self.ball_vel
        } else {
            V2::ZERO
        };
        let loc = self.config.localisation_sigma_mm;
        let noise = [
            self.rng.gauss(loc),
            self.rng.gauss(loc),
            self.rng.gauss(0.02),
        ];
        let r = self.robot(id)?;
        let mut obstacles: Vec<NaoObstacle> = r
            .seen_robots
            .values()
            .chain(r.seen_posts.values())
            .map(|s| NaoObstacle {
                kind: s.kind,
                center: s.pos.to_point(),
                last_seen_ms: r.robot_ms(s.t),
            })
            .collect();
        obstacles.truncate(20);
        let (ball, ball_age) = match r.seen_ball {
            Some((b, ts)) => (b.to_point(), (t - ts) as f32),
            None => (FieldPoint::default(), 1000.0),
        };
        Some(NaoLocalModel {
            header: Default::default(),
            player_number: id.number,
            team_number: team,
            fallen: r.is_fallen(),
            pose: FieldPose {
                x_mm: (r.pos.x + noise[0]) as f32,
                y_mm: (r.pos.y + noise[1]) as f32,
                theta_rad: wrap(r.theta + noise[2]) as f32,
            },
            ball_age_s: ball_age,
            ball,
            role: if id == RobotId::CONTROLLED {
                PlayerRole::Controlled
            } else {
                PlayerRole::Autonomous
            },
            obstacles_seen: obstacles.len() as u8,
            obstacles,
            message_budget: budget,
            secs_remaining: secs,
            arm_contact: [false; 2],
            arm_push_direction: [0; 2],
            arm_last_contact_ms: [0; 2],
            time_since_whistle_ms: whistle_since.map_or(0, |s| (s * 1000.0) as u32),
            whistle: match whistle_since {
                Some(s) if s < 1.0 => WhistleState::Detected,
                _ => WhistleState::NotDetected,
            },
            team_ball: team_ball.map_or(FieldPoint::default(), |(b, _)| b.to_point()),
            team_ball_velocity: team_ball_vel.to_point(),
            battery: (1.0 - t / 3600.0).max(0.0) as f32,
            cpu_temperature_c: 50.0 + (t / 60.0).min(20.0) as f32,
            referee_gesture: 0,
        })
    }

    pub(super) fn debug_packet(&mut self, id: RobotId) -> Option<Vec<u8>> {
        let m = self.local_model(id)?;
        encode_debug(&m).ok().map(|b| b.to_vec())
    }

    /// The GameController's view now.
    pub fn gamecontroller_state(&self) -> GameControllerState {
        let penalty = |side: Side, number: u8| {
            self.robot(RobotId { side, number })
                .and_then(|r| r.penalised_until)
                .map_or(
                    PlayerInfo {
                        penalty: Penalty::None,
                        secs_till_unpenalised: 0,
                    },
                    |until| PlayerInfo {
                        penalty: Penalty::Pushing,
                        secs_till_unpenalised: (until - self.time_s).ceil().clamp(0.0, 255.0) as u8,
                    },
                )
        };
        let team = |number: u8, score: u8, budget: u16, side: Side| TeamInfo {
            team_number: number,
            field_player_colour: if side == Side::Us { 1 } else { 0 },
            goalkeeper_colour: if side == Side::Us { 1 } else { 0 },
            goalkeeper: 1,
            score,
            penalty_shot: 0,
            single_shots: 0,
            message_budget: budget,
            players: (1..=20).map(|n| penalty(side, n)).collect(),
        };
        let secondary = match self.state {
            GameState::Ready => self.config.ready_s - (self.time_s - self.state_since_s),
            GameState::Set => self.config.set_s - (self.time_s - self.state_since_s),
            _ => 0.0,
        };
        GameControllerState {
            packet_number: self.packet_number,
            players_per_team: 2,
            competition_phase: 0,
            competition_type: 1,
            game_phase: GamePhase::Normal,
            state: self.state,
            set_play: SetPlay::None,
            first_half: true,
            kicking_team: Some(self.config.team_number),
            secs_remaining: self.secs_remaining().ceil() as i16,
            secondary_time: secondary.max(0.0).ceil() as i16,
            // Ordered by the side they defend: we defend -x.
            teams: [
                team(
                    self.config.team_number,
                    self.score,
                    self.message_budget,
                    Side::Us,
                ),
                team(
                    self.config.opponent_team_number,
                    self.opponent_score,
                    1200,
                    Side::Them,
                ),
            ],
        }
    }

    pub(super) fn gamecontroller_packet(&mut self) -> Vec<u8> {
        let s = self.gamecontroller_state();
        self.packet_number = self.packet_number.wrapping_add(1);
        encode_gamecontroller(&s)
            .map(|b| b.to_vec())
            .unwrap_or_default()
    }
}
