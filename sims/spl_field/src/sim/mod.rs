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

mod behaviour;
mod motion;
mod packets;
mod perception;

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

impl Default for ControlledState {
    /// A robot that was never commanded: it stands, looking at the ball.
    fn default() -> Self {
        Self {
            body: None,
            target: V2::ZERO,
            head: NaoHead::LookAtTheBall,
            strategy: NaoStrategy::Default,
            done: false,
            ball_requested: false,
        }
    }
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
            controlled: ControlledState::default(),
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

    /// The next attack: robots on their ready poses (standing, no penalty), the ball on the
    /// centre spot, the score at zero, the controlled robot without a command, and the
    /// GameController in INITIAL again (a challenge's attempts one after another). Time, the
    /// robots' clocks, the packet numbers and the random draws go on.
    pub fn next_attack(&mut self) {
        for r in &mut self.robots {
            let (p, th) = ready_pose(r.id);
            let boot = r.boot_offset_ms;
            *r = SimRobot::new(r.id, p, th, boot);
        }
        self.ball = V2::ZERO;
        self.ball_vel = V2::ZERO;
        self.controlled = ControlledState::default();
        self.pending_pass = None;
        self.last_toucher = None;
        self.last_kicker = None;
        (self.score, self.opponent_score) = (0, 0);
        self.message_budget = 1200;
        self.messages_owed = 0.0;
        self.whistle_at_s = None;
        self.scripted_penalty_done = false;
        self.change_state(GameState::Initial);
    }

    /// The events since the last call (the process logs them; a long run keeps none).
    pub fn take_events(&mut self) -> Vec<(f64, SimEvent)> {
        std::mem::take(&mut self.events)
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
