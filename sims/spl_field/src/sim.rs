//! The field simulation: four robots, a ball, the GameController timeline, perception and the
//! wire packets. Deterministic: the state after any sequence of `step` and command calls is a
//! function of the seed and those calls only. Time advances in fixed ticks of [`TICK_S`],
//! whatever `dt_s` the caller passes.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use spl::{
    FieldPoint, FieldPose, GameControllerState, GamePhase, GameState, NaoBody, NaoCommand, NaoHead,
    NaoLocalModel, NaoObstacle, NaoStrategy, ObstacleKind, PacketError, Penalty, PlayerInfo,
    PlayerRole, SetPlay, TeamInfo, WhistleState, decode_command, encode_debug,
    encode_gamecontroller,
};

use crate::field::{
    BALL_CONTACT_MM, FIELD_HALF_LENGTH_MM, FIELD_HALF_WIDTH_MM, GOAL_HALF_WIDTH_MM, GOALPOSTS,
    KICK_REACH_MM, V2, angle_diff, opponent_goal, own_goal,
};
use crate::rng::SimRng;
use crate::types::{Datagram, RobotId, Side, SimConfig, SimEvent};

/// Simulation tick (s).
pub const TICK_S: f64 = 0.01;
/// Debug packet period (s).
pub const DEBUG_PERIOD_S: f64 = 0.1;
/// GameController packet period (s): 2 Hz.
pub const GC_PERIOD_S: f64 = 0.5;
/// How long a robot keeps an unseen obstacle in its model (s).
const OBSTACLE_MEMORY_S: f64 = 2.0;
/// A shot needs this much room (mm) between the ball's path and any opponent's centre.
const SHOT_LANE_MARGIN_MM: f64 = 250.0;
/// The autonomous striker shoots through a free lane from this far up the field on (mm).
const SHOT_FROM_X_MM: f64 = 1000.0;
/// A pass needs the ball to travel this far between kick and touch (mm).
const PASS_MIN_DISTANCE_MM: f64 = 1000.0;
/// Kick motion duration: the robot stands still (s).
const KICK_DURATION_S: f64 = 0.5;
/// After its kick, the kicker's contact with the ball is ignored for this long (s).
const KICKER_NO_CONTACT_S: f64 = 0.4;
/// Head yaw limit (rad) and speed (rad/s).
const HEAD_YAW_MAX: f64 = 2.0;
const HEAD_SPEED: f64 = 3.0;
/// Team message rate while playing (messages per robot per second).
const TEAM_MESSAGE_RATE: f64 = 1.0;

/// What a robot wants to do this tick.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Intent {
    Stand,
    /// Walk to a point, then face `face` (rad) if given.
    Walk {
        to: V2,
        face: Option<f64>,
    },
    /// Turn on the spot to `face` (rad).
    Face(f64),
    /// Turn on the spot at a rate (rad/s).
    Spin(f64),
    /// Go behind the ball and kick it towards `target` at `speed` (mm/s).
    Kick {
        target: V2,
        speed: f64,
    },
    /// Go behind the ball and push it towards `target`.
    Dribble {
        target: V2,
    },
}

/// What the executor did.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Outcome {
    Busy,
    Arrived,
    Kicked,
}

#[derive(Debug, Clone)]
struct Seen {
    pos: V2,
    t: f64,
    kind: ObstacleKind,
}

/// One simulated robot.
#[derive(Debug, Clone)]
pub struct SimRobot {
    /// Identity.
    pub id: RobotId,
    /// True position (mm).
    pub pos: V2,
    /// True heading (rad).
    pub theta: f64,
    /// Head yaw relative to the body (rad).
    pub head_yaw: f64,
    vel: V2,
    fallen_until: Option<f64>,
    penalised_until: Option<f64>,
    busy_until: f64,
    no_contact_until: f64,
    in_contact: bool,
    seen_ball: Option<(V2, f64)>,
    seen_robots: BTreeMap<RobotId, Seen>,
    seen_posts: BTreeMap<usize, Seen>,
    boot_offset_ms: u32,
}

impl SimRobot {
    fn new(id: RobotId, pos: V2, theta: f64, boot_offset_ms: u32) -> Self {
        Self {
            id,
            pos,
            theta,
            head_yaw: 0.0,
            vel: V2::ZERO,
            fallen_until: None,
            penalised_until: None,
            busy_until: 0.0,
            no_contact_until: 0.0,
            in_contact: false,
            seen_ball: None,
            seen_robots: BTreeMap::new(),
            seen_posts: BTreeMap::new(),
            boot_offset_ms,
        }
    }

    /// Whether the robot is down.
    pub fn is_fallen(&self) -> bool {
        self.fallen_until.is_some()
    }

    /// Whether the robot has a penalty (it stands still, out of play).
    pub fn is_penalised(&self) -> bool {
        self.penalised_until.is_some()
    }

    fn robot_ms(&self, t: f64) -> u32 {
        self.boot_offset_ms
            .wrapping_add((t * 1000.0).round().clamp(0.0, f64::from(u32::MAX)) as u32)
    }
}

/// The controlled robot's command state (the robot's `HumanCommand` representation).
#[derive(Debug, Clone, PartialEq)]
pub struct ControlledState {
    /// Current body command (`None` until the first one; never `Keep`).
    pub body: Option<NaoBody>,
    /// Target of the body command (mm).
    pub target: V2,
    /// Current head command (never `Keep`).
    pub head: NaoHead,
    /// Current strategy.
    pub strategy: NaoStrategy,
    /// Whether a one-shot body command (Kick, Spazza, Pass, Turn, GoToPosition, SearchTheBall)
    /// has finished; the robot then stands.
    pub done: bool,
    /// Whether the controlled robot asked the teammate for the ball.
    pub ball_requested: bool,
}

#[derive(Debug, Clone, Copy)]
struct PendingPass {
    from: RobotId,
    origin: V2,
}

/// The simulated field.
#[derive(Debug, Clone)]
pub struct SplField {
    config: SimConfig,
    rng: SimRng,
    time_s: f64,
    tick: u64,
    state: GameState,
    state_since_s: f64,
    /// True ball position (mm).
    pub ball: V2,
    /// True ball velocity (mm/s).
    pub ball_vel: V2,
    robots: Vec<SimRobot>,
    controlled: ControlledState,
    pending_pass: Option<PendingPass>,
    last_toucher: Option<RobotId>,
    last_kicker: Option<RobotId>,
    score: u8,
    opponent_score: u8,
    message_budget: u16,
    messages_owed: f64,
    packet_number: u8,
    events: Vec<(f64, SimEvent)>,
    whistle_at_s: Option<f64>,
    /// Whether the scripted penalty ([`SimConfig::penalty_at_s`]) was given.
    scripted_penalty_done: bool,
}

fn ready_pose(id: RobotId) -> (V2, f64) {
    match (id.side, id.number) {
        (Side::Us, 1) => (V2::new(-600.0, 0.0), 0.0),
        (Side::Us, _) => (V2::new(-1500.0, -1200.0), 0.0),
        (Side::Them, 1) => (V2::new(4300.0, 0.0), PI),
        (Side::Them, _) => (V2::new(2500.0, 0.0), PI),
    }
}

impl SplField {
    /// A field in INITIAL, robots on their ready poses, ball on the centre spot.
    pub fn new(config: SimConfig) -> Self {
        let mut rng = SimRng::new(config.seed);
        let robots = RobotId::ALL
            .iter()
            .map(|id| {
                let (p, th) = ready_pose(*id);
                let boot = 20_000 + (rng.next_u64() % 100_000) as u32;
                SimRobot::new(*id, p, th, boot)
            })
            .collect();
        Self {
            rng,
            time_s: 0.0,
            tick: 0,
            state: GameState::Initial,
            state_since_s: 0.0,
            ball: V2::ZERO,
            ball_vel: V2::ZERO,
            robots,
            controlled: ControlledState {
                body: None,
                target: V2::ZERO,
                head: NaoHead::LookAtTheBall,
                strategy: NaoStrategy::Default,
                done: false,
                ball_requested: false,
            },
            pending_pass: None,
            last_toucher: None,
            last_kicker: None,
            score: 0,
            opponent_score: 0,
            message_budget: 1200,
            messages_owed: 0.0,
            packet_number: 0,
            events: Vec::new(),
            whistle_at_s: None,
            scripted_penalty_done: false,
            config,
        }
    }

    // ----- accessors and scripting -------------------------------------------------------

    /// Simulated time (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Current game state.
    pub fn game_state(&self) -> GameState {
        self.state
    }

    /// Our challenge points (goal 2, completed pass 1).
    pub fn score(&self) -> u8 {
        self.score
    }

    /// Seconds left in the attack (the full attack before PLAYING, 0 when FINISHED).
    pub fn secs_remaining(&self) -> f64 {
        match self.state {
            GameState::Playing => {
                (self.config.attack_s - (self.time_s - self.state_since_s)).max(0.0)
            }
            GameState::Finished => 0.0,
            _ => self.config.attack_s,
        }
    }

    /// Every event so far, with its time (s).
    pub fn events(&self) -> &[(f64, SimEvent)] {
        &self.events
    }

    /// A robot.
    pub fn robot(&self, id: RobotId) -> Option<&SimRobot> {
        self.robots.iter().find(|r| r.id == id)
    }

    /// The controlled robot's command state.
    pub fn controlled(&self) -> &ControlledState {
        &self.controlled
    }

    /// Put a robot somewhere (scripted scenarios).
    pub fn place_robot(&mut self, id: RobotId, pos: V2, theta: f64) {
        if let Some(r) = self.robots.iter_mut().find(|r| r.id == id) {
            r.pos = pos;
            r.theta = theta;
            r.vel = V2::ZERO;
        }
    }

    /// Put the ball somewhere with a velocity (scripted scenarios).
    pub fn place_ball(&mut self, pos: V2, vel: V2) {
        self.ball = pos;
        self.ball_vel = vel;
    }

    /// Jump to a game state now (scripted scenarios); the timeline continues from it.
    pub fn set_game_state(&mut self, state: GameState) {
        self.change_state(state);
    }

    /// Make a robot fall now (scripted scenarios).
    pub fn knock_over(&mut self, id: RobotId) {
        let until = self.time_s + self.config.getup_s;
        if let Some(r) = self.robots.iter_mut().find(|r| r.id == id)
            && r.fallen_until.is_none()
        {
            r.fallen_until = Some(until);
            r.vel = V2::ZERO;
            self.events
                .push((self.time_s, SimEvent::Fell { robot: id }));
        }
    }

    /// Penalise a robot now for `secs` (scripted scenarios; see [`SimConfig::penalty_at_s`]).
    pub fn penalise(&mut self, id: RobotId, secs: f64) {
        let until = self.time_s + secs.max(0.0);
        if let Some(r) = self.robots.iter_mut().find(|r| r.id == id) {
            r.penalised_until = Some(until);
            r.vel = V2::ZERO;
            self.events
                .push((self.time_s, SimEvent::Penalised { robot: id }));
        }
    }

    // ----- commands ----------------------------------------------------------------------

    /// Apply a command packet as the controlled robot's `CommandReceiver` would: exactly 11
    /// bytes, decoded strictly; a body replaces body and target, a head replaces the head, the
    /// strategy is always replaced. Bad packets change nothing.
    pub fn receive_command(&mut self, bytes: &[u8]) -> Result<NaoCommand, PacketError> {
        let cmd = decode_command(bytes)?;
        self.apply_command(&cmd);
        Ok(cmd)
    }

    fn apply_command(&mut self, cmd: &NaoCommand) {
        let c = &mut self.controlled;
        if cmd.body != NaoBody::Keep {
            c.body = Some(cmd.body);
            c.target = V2::new(f64::from(cmd.target.x_mm), f64::from(cmd.target.y_mm));
            c.done = false;
            c.ball_requested = cmd.body == NaoBody::AskForTheBall;
        }
        if cmd.head != NaoHead::Keep {
            c.head = cmd.head;
        }
        c.strategy = cmd.strategy;
        self.events.push((self.time_s, SimEvent::CommandApplied));
    }

    // ----- stepping ----------------------------------------------------------------------

    /// Advance by `dt_s` (in ticks of [`TICK_S`]) and return the datagrams due meanwhile.
    pub fn step(&mut self, dt_s: f64) -> Vec<Datagram> {
        let mut out = Vec::new();
        let ticks = (dt_s / TICK_S).round().max(0.0) as u64;
        for _ in 0..ticks {
            self.tick_once(&mut out);
        }
        out
    }

    fn change_state(&mut self, state: GameState) {
        if self.state != state {
            self.state = state;
            self.state_since_s = self.time_s;
            if state == GameState::Playing {
                self.whistle_at_s = Some(self.time_s);
            }
            self.events
                .push((self.time_s, SimEvent::StateChanged { state }));
        }
    }

    fn tick_once(&mut self, out: &mut Vec<Datagram>) {
        self.tick += 1;
        self.time_s = self.tick as f64 * TICK_S;
        let in_state = self.time_s - self.state_since_s;
        match self.state {
            GameState::Initial if in_state >= self.config.initial_s => {
                self.change_state(GameState::Ready)
            }
            GameState::Ready if in_state >= self.config.ready_s => {
                self.change_state(GameState::Set)
            }
            GameState::Set if in_state >= self.config.set_s => {
                self.change_state(GameState::Playing)
            }
            GameState::Playing if in_state >= self.config.attack_s => {
                self.change_state(GameState::Finished)
            }
            _ => {}
        }

        if self.state == GameState::Playing
            && let Some(at) = self.config.penalty_at_s
            && in_state >= at
            && !self.scripted_penalty_done
        {
            self.scripted_penalty_done = true;
            self.penalise(RobotId::CONTROLLED, self.config.penalty_s);
        }
        self.update_falls();
        for i in 0..self.robots.len() {
            if let Some(until) = self.robots[i].penalised_until
                && self.time_s >= until
            {
                self.robots[i].penalised_until = None;
                let id = self.robots[i].id;
                self.events
                    .push((self.time_s, SimEvent::Unpenalised { robot: id }));
            }
        }
        for i in 0..self.robots.len() {
            self.update_head(i);
            self.perceive(i);
        }
        for i in 0..self.robots.len() {
            let intent = self.decide(i);
            let outcome = self.execute(i, intent);
            if self.robots[i].id == RobotId::CONTROLLED && self.state == GameState::Playing {
                self.after_controlled(outcome);
            }
        }
        self.update_ball();

        if self.state == GameState::Playing {
            self.messages_owed += 2.0 * TEAM_MESSAGE_RATE * TICK_S;
            while self.messages_owed >= 1.0 {
                self.messages_owed -= 1.0;
                self.message_budget = self.message_budget.saturating_sub(1);
            }
        }
        if self
            .tick
            .is_multiple_of((DEBUG_PERIOD_S / TICK_S).round() as u64)
        {
            for id in [RobotId::AUTONOMOUS, RobotId::CONTROLLED] {
                if let Some(bytes) = self.debug_packet(id) {
                    out.push(Datagram::Debug {
                        player: id.number,
                        bytes,
                    });
                }
            }
        }
        if self
            .tick
            .is_multiple_of((GC_PERIOD_S / TICK_S).round() as u64)
        {
            out.push(Datagram::GameController {
                bytes: self.gamecontroller_packet(),
            });
        }
    }

    fn update_falls(&mut self) {
        let p_tick = self.config.falls_per_min / 60.0 * TICK_S;
        for i in 0..self.robots.len() {
            let t = self.time_s;
            let walking = self.robots[i].vel.norm() > 20.0;
            match self.robots[i].fallen_until {
                Some(until) if t >= until => {
                    self.robots[i].fallen_until = None;
                    let id = self.robots[i].id;
                    self.events.push((t, SimEvent::GotUp { robot: id }));
                }
                None if walking && self.rng.chance(p_tick) => {
                    let id = self.robots[i].id;
                    self.knock_over(id);
                }
                _ => {}
            }
        }
    }

    // ----- perception --------------------------------------------------------------------

    fn update_head(&mut self, i: usize) {
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

    fn visible(&self, r: &SimRobot, p: V2, range: f64) -> bool {
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

    fn perceive(&mut self, i: usize) {
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

    // ----- behaviour ---------------------------------------------------------------------

    fn robot_pos(&self, id: RobotId) -> Option<V2> {
        self.robot(id).map(|r| r.pos)
    }

    fn active(&self, id: RobotId) -> bool {
        self.robot(id)
            .is_some_and(|r| !r.is_fallen() && !r.is_penalised())
    }

    /// Our team's ball: the most recent sighting of either of our robots.
    fn team_ball(&self) -> Option<(V2, f64)> {
        self.robots
            .iter()
            .filter(|r| r.id.side == Side::Us)
            .filter_map(|r| r.seen_ball)
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// A shot target in the opponent goal, on the side away from the keeper.
    fn shot_target(&self) -> V2 {
        let keeper_y = self.robot_pos(RobotId::KEEPER).map_or(0.0, |p| p.y);
        let y = if keeper_y > 0.0 { -450.0 } else { 450.0 };
        V2::new(FIELD_HALF_LENGTH_MM + 300.0, y)
    }

    /// Whether no opponent stands within `margin` (mm) of a ball rolling from `from` to `to`.
    fn lane_clear(&self, from: V2, to: V2, margin: f64) -> bool {
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
    fn open_shot(&self, ball: V2) -> Option<V2> {
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
    fn free_point(&self, from: V2) -> V2 {
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

    fn pass_speed(&self, distance_mm: f64) -> f64 {
        // Arrive with ~300 mm/s left: v0² = v1² + 2 a d.
        (300.0f64.powi(2) + 2.0 * self.config.ball_friction_mm_s2 * distance_mm).sqrt()
    }

    fn decide(&self, i: usize) -> Intent {
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

    fn decide_controlled(&self, r: &SimRobot) -> Intent {
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

    fn after_controlled(&mut self, outcome: Outcome) {
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

    fn decide_autonomous(&self, r: &SimRobot) -> Intent {
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

    fn decide_keeper(&self, _r: &SimRobot) -> Intent {
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

    fn decide_defender(&self, r: &SimRobot) -> Intent {
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

    // ----- motion ------------------------------------------------------------------------

    fn execute(&mut self, i: usize, intent: Intent) -> Outcome {
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

    fn kick(&mut self, i: usize, vel: V2) {
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
    fn touched_by(&mut self, id: RobotId) {
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

    fn update_ball(&mut self) {
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

    fn debug_packet(&mut self, id: RobotId) -> Option<Vec<u8>> {
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

    fn gamecontroller_packet(&mut self) -> Vec<u8> {
        let s = self.gamecontroller_state();
        self.packet_number = self.packet_number.wrapping_add(1);
        encode_gamecontroller(&s)
            .map(|b| b.to_vec())
            .unwrap_or_default()
    }
}

impl SimRobot {
    fn side_of(&self, side: Side) -> bool {
        self.id.side == side
    }
}

fn wrap(a: f64) -> f64 {
    angle_diff(a, 0.0)
}

/// Whether `pos` is behind the ball with respect to direction `dir`.
fn behind(pos: V2, ball: V2, dir: V2) -> bool {
    let rel = pos - ball;
    rel.dot(dir) < -100.0 && rel.cross(dir).abs() < 120.0
}

/// Where to walk to get behind `ball` for a kick along `dir` from `reach` mm: returns the walk
/// target, the heading to hold and whether the robot is aligned for the kick.
fn approach(pos: V2, theta: f64, ball: V2, dir: V2, reach: f64) -> (V2, f64, bool) {
    let kick_pose = ball - dir * reach;
    let face = dir.angle();
    let rel = pos - ball;
    let along = rel.dot(dir);
    if along > -reach * 0.6 {
        // In front of or beside the ball: go around it, on the side the robot is on.
        let perp = V2::new(-dir.y, dir.x);
        let side = if rel.dot(perp) >= 0.0 { 1.0 } else { -1.0 };
        let waypoint = ball - dir * 350.0 + perp * (side * 350.0);
        return (waypoint, (ball - pos).angle(), false);
    }
    let aligned = (pos - kick_pose).norm() < 60.0 && angle_diff(face, theta).abs() < 0.2;
    (kick_pose, face, aligned)
}
