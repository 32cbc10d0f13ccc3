//! The coach's decisions as a pure library: no bus, no clock (times are seconds on the caller's
//! clock, passed in).
//!
//! # Frame and units
//!
//! Field coordinates as on the robot link: millimetres, origin at the centre spot, x towards the
//! opponent goal, y to the left. Our own goal is at x = -4500 mm. Ages are seconds.
//!
//! # What is decided (seed 000 §1.2, §3.1.3-3.1.5)
//!
//! Every request ([`Ask`]) gets a [`Verdict`] with the sentence the robot says *before* anything
//! is sent, checked in this order:
//!
//! 1. **Feasibility of the request itself**: GoToPosition and Turn need a finite target inside
//!    the field lines ([`Refusal::OutsideField`], [`Refusal::NoTarget`]); "turn around" needs the
//!    robot's pose.
//! 2. **The link**: a robot that does not answer cannot be commanded; the request is kept and
//!    sent when the link is back ([`Refusal::LinkDown`], kept).
//! 3. **Social rules from the game state**: a motion command (any body but Stop) is refused
//!    while penalised, and outside PLAYING (INITIAL, READY, SET, FINISHED, STANDBY, or no
//!    GameController yet), with the reason; it is kept for PLAYING when
//!    [`RulesConfig::keep_for_playing`]. Head commands and Stop are always allowed.
//! 4. **The robot on the ground**: kept, done when it is up again ([`Refusal::Fallen`], kept).
//! 5. **The challenge rule**: the operated robot may not shoot at goal itself, so a Kick becomes
//!    a pass to the teammate (or a dribble without one) when [`RulesConfig::challenge_rule`].
//! 6. **Feasibility from the world model**: a pass needs a teammate that reports and stands;
//!    without one it becomes GoToBallAndDribble, and the robot says so (the behaviour card's own
//!    fallback, seed 000 §4.2.2).
//! 7. **Never towards our own goal**: a kick, clearance or pass whose line from the ball runs
//!    into our goal mouth (the coach's aim, or the teammate for a pass) is refused
//!    ([`Refusal::OwnGoal`]), whatever was asked. The aim only decides: the 11-byte command
//!    packet has no field for it (its x, y are GoToPosition's and Turn's target), so it is not
//!    sent.
//!
//! [`Memory`] keeps the last command sent (to resume it after a fall, a penalty or a lost link,
//! unless it is done), a pending command (refused for now, kept for later), and the last-seen
//! times of the ball and the obstacles.

use interfaces::msg::command::Command;
use interfaces::msg::nao::{
    FieldPoint, GameState, NaoBody, NaoCommand, NaoHead, NaoStrategy, NaoWorldModel,
};
use serde::{Deserialize, Serialize};

/// Half the field's length between the goal lines (mm).
pub const FIELD_HALF_LENGTH_MM: f32 = 4500.0;
/// Half the field's width between the touch lines (mm).
pub const FIELD_HALF_WIDTH_MM: f32 = 3000.0;
/// Half the goal mouth (mm).
pub const GOAL_HALF_WIDTH_MM: f32 = 750.0;

/// The coach's parameters: the `[coach]` table of the Executive's settings file, every key
/// optional.
///
/// ```toml
/// [coach]
/// challenge_rule = true
/// keep_for_playing = true
/// home_position = [-1500.0, -1200.0]
/// ```
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RulesConfig {
    /// The controlled robot's player number (2 in the challenge).
    pub controlled_player: u8,
    /// The 2024 challenge rule: the operated robot may not shoot at goal itself.
    pub challenge_rule: bool,
    /// Keep a motion command refused outside PLAYING (or while penalised) and do it when play
    /// starts.
    pub keep_for_playing: bool,
    /// Where "go to your position" by voice goes when the panel never clicked a target (mm).
    pub home_position: [f32; 2],
    /// A teammate is visible for a pass when its last packet is at most this old (s).
    pub teammate_max_age_s: f64,
    /// Margin added to each side of our goal mouth by the own-goal check (mm).
    pub own_goal_margin_mm: f32,
    /// A pass is refused when its line runs into our goal mouth and the teammate stands within
    /// this distance of our goal line (mm); a kick or clearance aimed at the goal mouth always is.
    pub own_goal_pass_zone_mm: f32,
    /// GoToPosition is done within this distance of the target (mm).
    pub arrived_mm: f32,
    /// A kick, clearance or pass is done once the ball rolls faster than this (mm/s).
    pub kicked_ball_speed_mm_s: f32,
    /// Say "I am still on the ground" once when the robot is still down after this long (s).
    pub still_down_s: f64,
    /// Say "the robot is still not responding" once when the link is still lost after this
    /// long (s).
    pub still_lost_s: f64,
    /// The components that take `nao/command` to the robot. While none of them subscribes to
    /// it (a bridge restarting), a command is held and sent once one does; empty: never held.
    pub bridges: Vec<String>,
}

impl Default for RulesConfig {
    fn default() -> Self {
        RulesConfig {
            controlled_player: 2,
            challenge_rule: true,
            keep_for_playing: true,
            home_position: [-1500.0, -1200.0],
            teammate_max_age_s: 2.0,
            own_goal_margin_mm: 250.0,
            own_goal_pass_zone_mm: 2000.0,
            arrived_mm: 300.0,
            kicked_ball_speed_mm_s: 1000.0,
            still_down_s: 20.0,
            still_lost_s: 10.0,
            bridges: vec!["nao_bridge".into()],
        }
    }
}

/// A request from the coach, by voice or from the panel, before any check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ask {
    pub body: NaoBody,
    pub head: NaoHead,
    pub strategy: NaoStrategy,
    /// GoToPosition, Turn: where (mm).
    pub target: Option<FieldPoint>,
    /// Kick, Spazza, Pass: where the coach wants the ball to go (mm).
    pub aim: Option<FieldPoint>,
    /// `voice`, `panel`, ...
    pub source: String,
}

impl Ask {
    /// A body command with no target.
    pub fn body(body: NaoBody, source: &str) -> Ask {
        Ask {
            body,
            head: NaoHead::Keep,
            strategy: NaoStrategy::Default,
            target: None,
            aim: None,
            source: source.to_string(),
        }
    }

    /// Whether the request moves the robot's body (any body but Keep and Stop).
    pub fn is_motion(&self) -> bool {
        !matches!(self.body, NaoBody::Keep | NaoBody::Stop)
    }

    /// The command the robot would get for this request as it stands.
    fn command(&self) -> NaoCommand {
        NaoCommand {
            body: self.body,
            head: self.head,
            strategy: self.strategy,
            target: self.target.unwrap_or_default(),
            source: "executive".into(),
            ..Default::default()
        }
    }

    /// A spoken or panel game command as a request. `clicked` is the panel's last clicked point
    /// (the target of "go to position" by voice; [`RulesConfig::home_position`] without one);
    /// "turn around" faces the opposite way, so it needs the robot's pose from `world`. `None`
    /// for commands that are no robot command (yes, no, the other game's).
    pub fn from_voice(
        command: Command,
        clicked: Option<FieldPoint>,
        world: Option<&NaoWorldModel>,
        config: &RulesConfig,
    ) -> Option<Ask> {
        let src = "voice";
        let head = |h: NaoHead| Ask {
            head: h,
            ..Ask::body(NaoBody::Keep, src)
        };
        Some(match command {
            Command::GoToBallAndDribble => Ask::body(NaoBody::GoToBallAndDribble, src),
            Command::Pass => Ask::body(NaoBody::Pass, src),
            Command::Kick => Ask::body(NaoBody::Kick, src),
            Command::ClearBall => Ask::body(NaoBody::Spazza, src),
            Command::Stop => Ask::body(NaoBody::Stop, src),
            Command::SearchBall => Ask::body(NaoBody::SearchTheBall, src),
            Command::AskForBall => Ask::body(NaoBody::AskForTheBall, src),
            Command::LookLeft => head(NaoHead::LookLeft),
            Command::LookRight => head(NaoHead::LookRight),
            Command::LookAtBall => head(NaoHead::LookAtTheBall),
            Command::GoToPosition => Ask {
                target: Some(clicked.unwrap_or(FieldPoint {
                    x_mm: config.home_position[0],
                    y_mm: config.home_position[1],
                })),
                ..Ask::body(NaoBody::GoToPosition, src)
            },
            Command::Turn => Ask {
                // Face the opposite way: a point 1 m behind the robot. Without a pose there is
                // no target, and the check refuses it with the reason.
                target: world
                    .and_then(|w| controlled(w, config.controlled_player))
                    .map(|r| FieldPoint {
                        x_mm: r.pose.x_mm - 1000.0 * r.pose.theta_rad.cos(),
                        y_mm: r.pose.y_mm - 1000.0 * r.pose.theta_rad.sin(),
                    }),
                ..Ask::body(NaoBody::Turn, src)
            },
            _ => return None,
        })
    }

    /// A panel request as a request.
    pub fn from_panel(r: &interfaces::msg::nao::CoachRequest) -> Ask {
        let c = &r.command;
        let needs_target = matches!(c.body, NaoBody::GoToPosition | NaoBody::Turn);
        Ask {
            body: c.body,
            head: c.head,
            strategy: c.strategy,
            target: needs_target.then_some(c.target),
            aim: r.aimed.then_some(r.aim),
            source: if c.source.is_empty() {
                "panel".into()
            } else {
                c.source.clone()
            },
        }
    }
}

/// What the robot knows of the game and of itself when a request arrives.
#[derive(Debug, Clone, Default)]
pub struct Situation {
    /// The latest GameController state (None before the first packet).
    pub game: Option<GameState>,
    /// The latest fused world model (None before the first).
    pub world: Option<NaoWorldModel>,
    /// Whether the controlled robot's link is up (no "robot not responding" outstanding).
    pub link_up: bool,
}

impl Situation {
    /// Whether the controlled robot has a penalty.
    pub fn penalised(&self, config: &RulesConfig) -> bool {
        self.game.as_ref().is_some_and(|g| {
            g.our_team_found
                && g.our_team
                    .players
                    .get(usize::from(config.controlled_player.max(1)) - 1)
                    .is_some_and(|p| p.penalty != 0)
        })
    }
    /// Whether the controlled robot reports it is on the ground.
    pub fn fallen(&self, config: &RulesConfig) -> bool {
        self.world
            .as_ref()
            .and_then(|w| controlled(w, config.controlled_player))
            .is_some_and(|r| r.fallen)
    }
    /// Whether the game is in PLAYING.
    pub fn playing(&self) -> bool {
        self.game
            .as_ref()
            .is_some_and(|g| g.state == GameState::PLAYING)
    }
    /// The teammate a pass would go to: reporting recently and standing.
    pub fn pass_partner(&self, config: &RulesConfig) -> Option<FieldPoint> {
        let w = self.world.as_ref()?;
        w.robots
            .iter()
            .filter(|r| r.player_number != config.controlled_player)
            .filter(|r| !r.fallen && r.age_s <= config.teammate_max_age_s)
            .map(|r| FieldPoint {
                x_mm: r.pose.x_mm,
                y_mm: r.pose.y_mm,
            })
            .next()
    }
    /// Where the ball is believed to be: the fused ball, else the controlled robot's position.
    fn ball_or_robot(&self, config: &RulesConfig) -> Option<FieldPoint> {
        let w = self.world.as_ref()?;
        if w.ball_known {
            return Some(w.ball);
        }
        controlled(w, config.controlled_player).map(|r| FieldPoint {
            x_mm: r.pose.x_mm,
            y_mm: r.pose.y_mm,
        })
    }
}

fn controlled(w: &NaoWorldModel, player: u8) -> Option<&interfaces::msg::nao::TeamRobot> {
    w.robots.iter().find(|r| r.player_number == player)
}

/// Why a request is not done now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// GoToPosition or Turn with a target outside the field lines or not finite.
    OutsideField,
    /// GoToPosition or Turn without a target (or "turn around" without a pose).
    NoTarget,
    /// The robot does not answer.
    LinkDown,
    /// The controlled robot has a penalty.
    Penalised,
    /// The game is not in PLAYING (the GameController state, 255 when unknown).
    NotPlaying(u8),
    /// The robot is on the ground.
    Fallen,
    /// The ball would go towards our own goal.
    OwnGoal,
}

/// The decision on one request.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Send `command`, after saying `say`.
    Execute { command: NaoCommand, say: String },
    /// Send `command` instead of what was asked (`asked`), after saying why.
    Replace {
        asked: NaoBody,
        command: NaoCommand,
        say: String,
    },
    /// Send nothing now; say why. `keep`: the request is kept and done when the reason is gone.
    Refuse {
        reason: Refusal,
        say: String,
        keep: bool,
    },
}

impl Verdict {
    /// What the robot says.
    pub fn say(&self) -> &str {
        match self {
            Verdict::Execute { say, .. }
            | Verdict::Replace { say, .. }
            | Verdict::Refuse { say, .. } => say,
        }
    }
    /// The command to send, if any.
    pub fn command(&self) -> Option<&NaoCommand> {
        match self {
            Verdict::Execute { command, .. } | Verdict::Replace { command, .. } => Some(command),
            Verdict::Refuse { .. } => None,
        }
    }
}

/// What the robot says when it starts a body command ("going to the position").
pub fn announce(body: NaoBody) -> &'static str {
    match body {
        NaoBody::Keep => "",
        NaoBody::GoToPosition => "Going to the position.",
        NaoBody::Dribble => "Dribbling.",
        NaoBody::GoToBallAndDribble => "Going to the ball to dribble.",
        NaoBody::Kick => "Kicking at the goal.",
        NaoBody::Spazza => "Clearing the ball away.",
        NaoBody::Pass => "Passing to my teammate.",
        NaoBody::AskForTheBall => "Asking my teammate for the ball.",
        NaoBody::Turn => "Turning.",
        NaoBody::SearchTheBall => "Searching for the ball.",
        NaoBody::Stop => "Stopping.",
    }
}

/// What the robot says for a head command ("looking left").
pub fn announce_head(head: NaoHead) -> &'static str {
    match head {
        NaoHead::Keep => "",
        NaoHead::LookAtTheBall => "Looking at the ball.",
        NaoHead::LookForward => "Looking forward.",
        NaoHead::LookLeft => "Looking left.",
        NaoHead::LookRight => "Looking right.",
        NaoHead::Scan => "Scanning.",
    }
}

/// The words for a body command inside a sentence ("go to the position").
pub fn verb(body: NaoBody) -> &'static str {
    match body {
        NaoBody::Keep => "keep going",
        NaoBody::GoToPosition => "go to the position",
        NaoBody::Dribble => "dribble",
        NaoBody::GoToBallAndDribble => "go to the ball and dribble",
        NaoBody::Kick => "kick",
        NaoBody::Spazza => "clear the ball",
        NaoBody::Pass => "pass",
        NaoBody::AskForTheBall => "ask for the ball",
        NaoBody::Turn => "turn",
        NaoBody::SearchTheBall => "search for the ball",
        NaoBody::Stop => "stop",
    }
}

fn state_name(s: u8) -> &'static str {
    match s {
        0 => "INITIAL",
        1 => "READY",
        2 => "SET",
        3 => "PLAYING",
        4 => "FINISHED",
        5 => "STANDBY",
        _ => "unknown",
    }
}

fn inside_field(p: FieldPoint) -> bool {
    p.x_mm.is_finite()
        && p.y_mm.is_finite()
        && p.x_mm.abs() <= FIELD_HALF_LENGTH_MM
        && p.y_mm.abs() <= FIELD_HALF_WIDTH_MM
}

/// Whether the ball, sent from `from` towards `to` and beyond, would cross our goal line inside
/// the goal mouth widened by `margin_mm` on each side.
pub fn towards_own_goal(from: FieldPoint, to: FieldPoint, margin_mm: f32) -> bool {
    let dx = to.x_mm - from.x_mm;
    let dy = to.y_mm - from.y_mm;
    // Only backwards (NaN included: not a direction).
    if dx.is_nan() || dx >= 0.0 || !dy.is_finite() {
        return false;
    }
    // Where the line reaches x = -4500.
    let t = (-FIELD_HALF_LENGTH_MM - from.x_mm) / dx;
    let y = from.y_mm + t * dy;
    y.abs() <= GOAL_HALF_WIDTH_MM + margin_mm
}

/// Whether a kick aimed at `aim` from `from` (the ball, else the robot) goes towards our goal.
/// Without a known position, an aim within 1 m of our goal mouth (or not finite) counts.
fn aimed_at_own_goal(from: Option<FieldPoint>, aim: FieldPoint, config: &RulesConfig) -> bool {
    if !aim.x_mm.is_finite() || !aim.y_mm.is_finite() {
        return true;
    }
    let near_goal = aim.x_mm < -FIELD_HALF_LENGTH_MM + 1000.0
        && aim.y_mm.abs() <= GOAL_HALF_WIDTH_MM + config.own_goal_margin_mm;
    match from {
        Some(from) => near_goal || towards_own_goal(from, aim, config.own_goal_margin_mm),
        None => near_goal,
    }
}

fn metres(p: FieldPoint) -> String {
    format!("{:.1}, {:.1} metres", p.x_mm / 1000.0, p.y_mm / 1000.0)
}

/// Decides what to do with `ask` in `situation`.
pub fn decide(ask: &Ask, situation: &Situation, config: &RulesConfig) -> Verdict {
    let refuse = |reason, say: String, keep| Verdict::Refuse { reason, say, keep };
    // 1. The request itself.
    if matches!(ask.body, NaoBody::GoToPosition | NaoBody::Turn) {
        match ask.target {
            None => {
                return refuse(
                    Refusal::NoTarget,
                    format!(
                        "I cannot {}: I do not know where. Click a point on the field.",
                        verb(ask.body)
                    ),
                    false,
                );
            }
            Some(t) if !inside_field(t) => {
                let at = if t.x_mm.is_finite() && t.y_mm.is_finite() {
                    format!(" at {}", metres(t))
                } else {
                    String::new()
                };
                return refuse(
                    Refusal::OutsideField,
                    format!("I cannot {}{at}: it is outside the field.", verb(ask.body)),
                    false,
                );
            }
            Some(_) => {}
        }
    }
    if ask.body == NaoBody::Keep && ask.head == NaoHead::Keep {
        return refuse(
            Refusal::NoTarget,
            "That command asks me to do nothing.".into(),
            false,
        );
    }
    // 2. The link.
    if !situation.link_up {
        return refuse(
            Refusal::LinkDown,
            "The robot is not responding. I will send the command when it is back.".into(),
            true,
        );
    }
    // 3. Social rules.
    if ask.is_motion() {
        if situation.penalised(config) {
            return refuse(
                Refusal::Penalised,
                format!(
                    "I cannot {} now: I am penalised.{}",
                    verb(ask.body),
                    if config.keep_for_playing {
                        " I will do it when I am back."
                    } else {
                        ""
                    }
                ),
                config.keep_for_playing,
            );
        }
        if !situation.playing() {
            let s = situation.game.as_ref().map_or(255, |g| g.state);
            let why = if s == 255 {
                "I have no game state from the GameController yet".to_string()
            } else {
                format!("the game is in {}", state_name(s))
            };
            let keep = config.keep_for_playing && s != GameState::FINISHED;
            return refuse(
                Refusal::NotPlaying(s),
                format!(
                    "I cannot {} now: {why}.{}",
                    verb(ask.body),
                    if keep {
                        " I will do it when we play."
                    } else {
                        ""
                    }
                ),
                keep,
            );
        }
        // 4. On the ground.
        if situation.fallen(config) {
            return refuse(
                Refusal::Fallen,
                format!(
                    "I am on the ground. I will {} when I am up.",
                    verb(ask.body)
                ),
                true,
            );
        }
    }
    // 5-7. What happens to the ball.
    let mut ask = ask.clone();
    let mut prefix = String::new();
    let asked = ask.body;
    if ask.body == NaoBody::Kick && config.challenge_rule {
        if let Some(aim) = ask.aim
            && aimed_at_own_goal(situation.ball_or_robot(config), aim, config)
        {
            return refuse(
                Refusal::OwnGoal,
                "I will not kick towards our own goal.".into(),
                false,
            );
        }
        ask.body = NaoBody::Pass;
        ask.aim = None;
        prefix = "I may not shoot at the goal myself. ".into();
    }
    if ask.body == NaoBody::Pass {
        match situation.pass_partner(config) {
            None => {
                ask.body = NaoBody::GoToBallAndDribble;
                ask.aim = None;
                let say = format!(
                    "{prefix}I see no teammate to pass to: I will go to the ball and dribble."
                );
                return Verdict::Replace {
                    asked,
                    command: ask.command(),
                    say,
                };
            }
            Some(mate) => {
                // A pass stops near the teammate: it is dangerous when the teammate stands
                // near our goal on the line of the pass (a miss rolls in).
                if let Some(ball) = situation.ball_or_robot(config)
                    && mate.x_mm < -FIELD_HALF_LENGTH_MM + config.own_goal_pass_zone_mm
                    && towards_own_goal(ball, mate, config.own_goal_margin_mm)
                {
                    return refuse(
                        Refusal::OwnGoal,
                        format!("{prefix}I will not pass: the ball would go towards our own goal."),
                        false,
                    );
                }
            }
        }
    }
    if matches!(ask.body, NaoBody::Kick | NaoBody::Spazza)
        && let Some(aim) = ask.aim
        && aimed_at_own_goal(situation.ball_or_robot(config), aim, config)
    {
        return refuse(
            Refusal::OwnGoal,
            format!(
                "I will not {} towards our own goal.",
                if ask.body == NaoBody::Kick {
                    "kick"
                } else {
                    "clear the ball"
                }
            ),
            false,
        );
    }
    let mut say = announce(ask.body).to_string();
    let head = announce_head(ask.head);
    if !head.is_empty() {
        if !say.is_empty() {
            say.push(' ');
        }
        say.push_str(head);
    }
    if ask.body != asked {
        Verdict::Replace {
            asked,
            command: ask.command(),
            say: format!("{prefix}{say}"),
        }
    } else {
        Verdict::Execute {
            command: ask.command(),
            say,
        }
    }
}

/// The coach machine's memory: the last command sent, a pending one, last-seen times.
#[derive(Debug, Clone, Default)]
pub struct Memory {
    /// The last request that reached the robot, and the command it became.
    pub last: Option<(Ask, NaoCommand)>,
    /// Whether the last command is believed done (see [`Memory::observe`]).
    pub last_done: bool,
    /// When the last command was sent (s, caller's clock).
    pub last_sent_s: f64,
    /// A request kept for later (refused outside PLAYING, while penalised, down or unlinked).
    pub pending: Option<Ask>,
    /// The last point clicked on the panel (GoToPosition's target by voice).
    pub clicked: Option<FieldPoint>,
    /// When the ball was last seen (s, caller's clock), from the world model's age.
    pub ball_seen_s: Option<f64>,
    /// When an obstacle was last seen (s, caller's clock).
    pub obstacle_seen_s: Option<f64>,
    pub obstacles_tracked: u32,
}

impl Memory {
    /// Records a command sent to the robot at `now_s`.
    pub fn sent(&mut self, ask: &Ask, command: &NaoCommand, now_s: f64) {
        if command.body != NaoBody::Keep || self.last.is_none() {
            self.last = Some((ask.clone(), command.clone()));
            self.last_done = false;
            self.last_sent_s = now_s;
        } else if let Some((last_ask, last_cmd)) = &mut self.last {
            // A head command keeps the body command and replaces the head.
            last_ask.head = ask.head;
            last_cmd.head = command.head;
        }
    }

    /// Updates the last-seen times and whether the last command is done, from a world model
    /// received at `now_s`.
    pub fn observe(&mut self, w: &NaoWorldModel, now_s: f64, config: &RulesConfig) {
        if w.ball_known && w.ball_age_s.is_finite() && w.ball_age_s >= 0.0 {
            self.ball_seen_s = Some(now_s - w.ball_age_s);
        }
        self.obstacles_tracked = w.obstacles.len() as u32;
        if let Some(age) = w
            .obstacles
            .iter()
            .map(|o| o.age_s)
            .filter(|a| a.is_finite() && *a >= 0.0)
            .min_by(f64::total_cmp)
        {
            let seen = now_s - age;
            self.obstacle_seen_s = Some(self.obstacle_seen_s.map_or(seen, |s| s.max(seen)));
        }
        let Some((_, cmd)) = &self.last else { return };
        if self.last_done {
            return;
        }
        let me = controlled(w, config.controlled_player);
        self.last_done = match cmd.body {
            NaoBody::GoToPosition => me.is_some_and(|r| {
                let d = (r.pose.x_mm - cmd.target.x_mm).hypot(r.pose.y_mm - cmd.target.y_mm);
                d <= config.arrived_mm
            }),
            NaoBody::Turn => me.is_some_and(|r| {
                let want = (cmd.target.y_mm - r.pose.y_mm).atan2(cmd.target.x_mm - r.pose.x_mm);
                let mut e = (want - r.pose.theta_rad).rem_euclid(std::f32::consts::TAU);
                if e > std::f32::consts::PI {
                    e -= std::f32::consts::TAU;
                }
                e.abs() < 0.3
            }),
            NaoBody::Kick | NaoBody::Spazza | NaoBody::Pass => {
                w.ball_known
                    && w.ball_velocity.x_mm.hypot(w.ball_velocity.y_mm)
                        >= config.kicked_ball_speed_mm_s
            }
            NaoBody::SearchTheBall => {
                w.ball_known && self.ball_seen_s.is_some_and(|s| s > self.last_sent_s)
            }
            _ => false,
        };
    }

    /// Seconds since the ball was last seen at `now_s` (None: never).
    pub fn ball_age(&self, now_s: f64) -> Option<f64> {
        self.ball_seen_s.map(|s| (now_s - s).max(0.0))
    }
    /// Seconds since an obstacle was last seen at `now_s` (None: never).
    pub fn obstacle_age(&self, now_s: f64) -> Option<f64> {
        self.obstacle_seen_s.map(|s| (now_s - s).max(0.0))
    }

    /// The request to resume after an interruption: the last one, unless it is done.
    pub fn to_resume(&self) -> Option<Ask> {
        match &self.last {
            Some((ask, _)) if !self.last_done => Some(ask.clone()),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;
