//! The simulated person on the bus: plays a [`Scenario`] against the running game.
//!
//! - **Ball**: publishes the ball on `sim/ball` at `ball_rate_hz` (what the `rgbd` sim renders).
//! - **Voice**: a continuous 16 kHz stream on `audio/in` in 100 ms chunks, in real time: room noise
//!   at the scenario's SNR below the voice, with the person's sentences (espeak-ng) mixed in.
//! - **Senses**: what the robot says (`speech/speaking`), the Executive's steps
//!   (`executive/transitions`), the arm's reach status (`body/reach_status`), the tracker's events
//!   (`vision/ball_events`), and the robot's hand and camera poses from the DR (`dr/transform`).
//!
//! The person prints a readable log line for everything she does and every expectation met, with
//! the figures (hand-to-ball distance, gaze angle, time taken). A failed expectation ends the run
//! with an error naming the step, what was expected and what was seen instead.
//!
//! Time: the scenario (the ball's moves and its `sim/ball` rate, the pauses, the turn-taking and
//! the expectations' time-outs) runs on the bus clock; her voice (`voice`) is a real-time
//! stream on the wall, as a microphone or a sound server paces it.

use crate::ball::Ball;
use crate::scenario::{BallMove, Scenario, Step};
use audio::signal as pcm;
use audio::synth::{self, Voice};
use interfaces::msg::body::ReachState;
use interfaces::msg::speech::{SpeakingEvent, SpeakingState};
use interfaces::msg::tracking::{BallEventKind, SimBall};
use interfaces::{Bus, Clock, Moment, topics};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};

mod expect;
mod voice;
#[cfg(test)]
use expect::rotate;
use expect::{Waited, expect};
use voice::{AudioOut, SpeechJob, audio_stream, into_room};

/// Audio stream rate (Hz).
pub const RATE_HZ: u32 = 16_000;

/// How the person runs.
#[derive(Debug, Clone)]
pub struct PersonConfig {
    pub scenario: Scenario,
    /// `sim/ball` rate (Hz).
    pub ball_rate_hz: f64,
    /// The robot's hand link in the DR.
    pub hand_frame: String,
    /// The robot's head camera optical frame in the DR.
    pub camera_frame: String,
    /// Seconds of room noise before the first step (lets the recognizer settle).
    pub settle_s: f64,
    /// Seed of the room noise.
    pub seed: u64,
    /// Where her voice goes.
    pub voice_out: VoiceOut,
    /// How many times the scenario is played, each time by a new visitor (the ball back where
    /// the scenario starts it, what the person saw forgotten): a day at an exhibition.
    pub games: u32,
    /// Seconds between one visitor's last step and the next one's first.
    pub visitor_gap_s: f64,
}

/// Where the person's voice (and the room noise around it) goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum VoiceOut {
    /// Straight onto `audio/in`, as the microphone's chunks would be.
    Bus,
    /// Into a sound server's sink (the room), for a microphone (`audio_io`) to capture.
    Pulse {
        /// The server's address (`None`: libpulse's usual one).
        server: Option<String>,
        sink: String,
    },
}

/// What the room's sink keeps queued of her voice (the voice's own latency into the room).
pub const PULSE_BUFFER: Duration = Duration::from_millis(200);

/// What the person saw, for the expectations.
#[derive(Debug, Default)]
struct Seen {
    said: Vec<(Moment, String)>,
    /// The robot's sentences queued or being said, by id, with when they will be over at the
    /// latest (from Queued or Started until Finished, Interrupted, Dropped or Failed): the robot
    /// has the floor while one is left, including the short gap between two sentences it says
    /// in a row. The time bound lets a sentence whose end never comes (a speech generator
    /// killed mid-sentence) go.
    robot_sentences: BTreeMap<u64, Moment>,
    /// The robot said it cannot hear her (its recognizer is restarting): she waits until it
    /// says it hears her again, [`DEAF_AT_MOST`] at most.
    deaf_until: Option<Moment>,
    entered: Vec<(Moment, String)>,
    active: Vec<String>,
    reach: Vec<(Moment, String, ReachState)>,
    ball_events: Vec<(Moment, BallEventKind)>,
}

/// How long after its audio should have ended a sentence still counts as being said.
const SENTENCE_SLACK: Duration = Duration::from_secs(1);
/// How long a queued sentence counts as coming at most.
const QUEUED_AT_MOST: Duration = Duration::from_secs(15);
/// How long she waits at most after the robot said it cannot hear her.
const DEAF_AT_MOST: Duration = Duration::from_secs(60);

impl Seen {
    /// A new visitor: what the last one saw is forgotten (what the robot is saying now and
    /// whether it can hear stay: they are the room's, not hers).
    fn new_visitor(&mut self) {
        self.said.clear();
        self.entered.clear();
        self.reach.clear();
        self.ball_events.clear();
    }

    /// Whether the robot is speaking, or about to say a sentence it has queued.
    fn robot_has_the_floor(&self, now: Moment) -> bool {
        self.robot_sentences.values().any(|&until| until > now)
            || self.deaf_until.is_some_and(|until| until > now)
    }

    /// What the person makes of the robot's `speech/speaking` event at `now`.
    fn on_speaking(&mut self, m: &SpeakingEvent, now: Moment) {
        // Sentences whose end never came (their generator was killed) are over by now.
        self.robot_sentences.retain(|_, until| *until > now);
        match m.state {
            SpeakingState::Started => {
                let text = m.text.to_lowercase();
                if text.contains("can't hear you") {
                    self.deaf_until = Some(now + DEAF_AT_MOST);
                } else if text.contains("can hear you again") {
                    self.deaf_until = None;
                }
                self.said.push((now, text));
                let lasts = Duration::from_secs_f64(m.duration_s.clamp(0.0, 60.0));
                self.robot_sentences
                    .insert(m.id, now + lasts + SENTENCE_SLACK);
            }
            SpeakingState::Queued => {
                self.robot_sentences.insert(m.id, now + QUEUED_AT_MOST);
            }
            SpeakingState::Finished
            | SpeakingState::Interrupted
            | SpeakingState::Dropped
            | SpeakingState::Failed => {
                self.robot_sentences.remove(&m.id);
            }
        }
    }
}

fn reach_name(s: ReachState) -> &'static str {
    match s {
        ReachState::Moving => "moving",
        ReachState::Reached => "reached",
        ReachState::Unreachable => "unreachable",
        ReachState::Cancelled => "cancelled",
        ReachState::Failed => "failed",
    }
}

fn ball_event_name(k: BallEventKind) -> &'static str {
    match k {
        BallEventKind::Detected => "detected",
        BallEventKind::OutOfView => "out_of_view",
        BallEventKind::Lost => "lost",
        BallEventKind::DetectionTimedOut => "detection_timed_out",
    }
}

/// The result of a whole scenario.
#[derive(Debug, Clone, Default)]
pub struct Outcome {
    pub steps: usize,
    pub duration_s: f64,
    /// Closest the hand came to the ball's surface while an expectation watched it (m).
    pub closest_hand_to_ball_m: Option<f64>,
    /// Every expectation met, with the time it took after the action before it.
    pub timings: Vec<Timing>,
}

/// One expectation met, for benchmarks (one JSON object on the `person: timings` line).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Timing {
    /// The expectation's step number (from 1).
    pub step: usize,
    /// What was expected ([`Expect::describe`]).
    pub what: String,
    /// Seconds from the end of the action before it (the end of the person's sentence or the
    /// start of the ball's move) to the moment the person saw it, to the millisecond.
    pub after_s: f64,
    /// The step of that action (the expectation's own step when she said her sentence again
    /// while waiting), and what it was: `says "scan the ball"`, `moves the ball to ...`.
    pub action_step: usize,
    pub action: String,
}

/// Run the scenario to its end `cfg.games` times (or to the first failed expectation, or
/// shutdown); one outcome per game.
pub async fn run(
    bus: Bus,
    cfg: PersonConfig,
    mut shutdown: interfaces::node::Shutdown,
) -> anyhow::Result<Vec<Outcome>> {
    let sc = cfg.scenario.clone();
    // The scenario's time (the ball's moves, the pauses, the time-outs) is the bus clock's.
    let clock = bus.clock().clone();
    let t0 = clock.now();
    let now_s = {
        let clock = clock.clone();
        move || clock.elapsed(t0).as_secs_f64()
    };
    let ball = Arc::new(Mutex::new(Ball::new(
        sc.ball.start,
        sc.ball.present,
        sc.ball.held,
    )));
    let seen = Arc::new(Mutex::new(Seen::default()));
    // The ball, the voice and the senses run beside the scenario and end with it (dropping the
    // set aborts them), before the component's session closes under them.
    let mut tasks = tokio::task::JoinSet::new();

    // The ball, at a steady rate.
    let ball_pub = bus.publisher(&topics::SIM_BALL).await?;
    {
        let ball = ball.clone();
        let spec = sc.ball.clone();
        let period = Duration::from_secs_f64(1.0 / cfg.ball_rate_hz.max(1.0));
        let mut tick = clock.interval(period);
        let now_s = now_s.clone();
        tasks.spawn(async move {
            loop {
                tick.tick().await;
                let s = lock(&ball).at(now_s());
                let mut msg = SimBall {
                    present: s.present,
                    centre_world_m: s.position_m,
                    velocity_world_mps: s.velocity_mps,
                    diameter_m: spec.diameter_m,
                    hue_deg: spec.hue_deg,
                    saturation: spec.saturation,
                    held: s.held,
                    ..SimBall::default()
                };
                if let Err(e) = ball_pub.publish(&mut msg).await {
                    tracing::warn!("cannot publish sim/ball: {e}");
                }
            }
        });
    }

    // The voice: synthesize a calibration sentence to set the room noise below speech level.
    let voice = Voice {
        voice: sc.voice.voice.clone(),
        speed_wpm: sc.voice.speed_wpm,
        pitch: sc.voice.pitch,
    };
    let calib = {
        let v = voice.clone();
        tokio::task::spawn_blocking(move || synth::synthesize_16k("hello there", &v)).await??
    };
    let speech_power = pcm::active_power(&calib).max(1e-12);
    let noise_power = speech_power / 10f64.powf(sc.voice.snr_db / 10.0);
    let (speech_tx, speech_rx) = mpsc::channel::<SpeechJob>(4);
    let out = match &cfg.voice_out {
        VoiceOut::Bus => AudioOut::Bus(
            bus.recent_publisher(&topics::AUDIO_IN, topics::AUDIO_IN_KEPT)
                .await?,
        ),
        VoiceOut::Pulse { server, sink } => AudioOut::Pulse(into_room(server.clone(), sink)?),
    };
    tasks.spawn(audio_stream(out, speech_rx, noise_power, cfg.seed));

    // The senses.
    spawn_senses(&bus, seen.clone(), &mut tasks).await?;

    tracing::info!(
        "scenario {:?}: {} steps; ball {:.0} mm at ({:.2}, {:.2}, {:.2}) m",
        sc.name,
        sc.steps.len(),
        sc.ball.diameter_m * 1000.0,
        sc.ball.start[0],
        sc.ball.start[1],
        sc.ball.start[2]
    );
    clock.sleep(Duration::from_secs_f64(cfg.settle_s)).await;

    let games = cfg.games.max(1);
    let mut outcomes = Vec::with_capacity(games.min(1000) as usize);
    for game in 1..=games {
        if game > 1 {
            // The next visitor: the ball where the scenario starts it, a short gap, and what the
            // last one saw forgotten.
            lock(&seen).new_visitor();
            lock(&ball).move_to(now_s(), sc.ball.start, 0.0, sc.ball.present, sc.ball.held);
            tokio::select! {
                _ = clock.sleep(Duration::from_secs_f64(cfg.visitor_gap_s)) => {}
                _ = shutdown.wait() => anyhow::bail!("stopped before game {game} of {games}"),
            }
            println!("person: game {game} of {games}: a new visitor");
        }
        let started = now_s();
        // A failure names the game when there are several.
        let of_game = if games > 1 {
            format!("game {game} of {games}, ")
        } else {
            String::new()
        };
        let mut mark = clock.now();
        let mut action_end = clock.now();
        let mut last_said: Option<String> = None;
        // The last action: its step and what it was (for the timings).
        let mut last_action: (usize, String) = (0, String::new());
        let mut outcome = Outcome::default();
        for (i, step) in sc.steps.iter().enumerate() {
            if shutdown.is_requested() {
                anyhow::bail!("stopped before step {}", i + 1);
            }
            let n = i + 1;
            match step {
                Step::Say(text) | Step::Interrupt(text) => {
                    mark = clock.now();
                    let over = matches!(step, Step::Interrupt(_));
                    if over && lock(&seen).robot_has_the_floor(mark) {
                        println!("person: talks over the robot");
                    }
                    say(
                        &speech_tx,
                        &voice,
                        text,
                        !over,
                        &seen,
                        &clock,
                        &mut shutdown,
                    )
                    .await?;
                    action_end = clock.now();
                    println!("person: says {text:?}");
                    last_said = Some(text.clone());
                    last_action = (n, format!("says {text:?}"));
                }
                Step::Ball(m) => {
                    mark = clock.now();
                    let arrival = move_ball(&ball, now_s(), m);
                    action_end = clock.now();
                    println!("person: {}", describe_move(m));
                    last_action = (n, describe_move(m));
                    if m.wait {
                        clock
                            .sleep(Duration::from_secs_f64((arrival - now_s()).max(0.0)))
                            .await;
                    }
                }
                Step::PauseS(s) => {
                    tokio::select! {
                        _ = clock.sleep(Duration::from_secs_f64(*s)) => {}
                        _ = shutdown.wait() => anyhow::bail!("stopped during step {n}"),
                    }
                }
                Step::Expect(e) => {
                    let mut repeats_left = e.repeat;
                    let mut answered = 0;
                    let mut started = clock.now();
                    loop {
                        let deadline = started + Duration::from_secs_f64(e.timeout_s);
                        match expect(
                            &bus,
                            &cfg,
                            &sc,
                            e,
                            mark,
                            &seen,
                            &ball,
                            &now_s,
                            deadline,
                            last_said.as_deref().map(|t| (t, answered)),
                            &mut shutdown,
                        )
                        .await?
                        {
                            Waited::Asked => {
                                answered += 1;
                                say(
                                    &speech_tx,
                                    &voice,
                                    "yes",
                                    true,
                                    &seen,
                                    &clock,
                                    &mut shutdown,
                                )
                                .await?;
                                println!(
                                    "person: answers yes to the robot's question about {:?}",
                                    last_said.as_deref().unwrap_or_default()
                                );
                                // The answer gives the robot the expectation's whole time again.
                                started = clock.now();
                                continue;
                            }
                            Waited::Seen(figures) => {
                                if let Some(d) = figures.hand_to_ball_m {
                                    outcome.closest_hand_to_ball_m = Some(
                                        outcome.closest_hand_to_ball_m.map_or(d, |c: f64| c.min(d)),
                                    );
                                }
                                let after_s = clock.elapsed(action_end).as_secs_f64();
                                println!(
                                    "person: sees {} ({:.1} s after the last action, waited {:.1} s){}",
                                    e.describe(),
                                    after_s,
                                    clock.elapsed(started).as_secs_f64(),
                                    figures.describe()
                                );
                                outcome.timings.push(Timing {
                                    step: n,
                                    what: e.describe(),
                                    after_s: (after_s * 1e3).round() / 1e3,
                                    action_step: last_action.0,
                                    action: last_action.1.clone(),
                                });
                                break;
                            }
                            Waited::Timeout(why) => {
                                if repeats_left > 0
                                    && let Some(text) = &last_said
                                {
                                    repeats_left -= 1;
                                    println!(
                                        "person: still waiting for {} after {:.0} s; says it again: {text:?}",
                                        e.describe(),
                                        e.timeout_s
                                    );
                                    mark = clock.now();
                                    say(
                                        &speech_tx,
                                        &voice,
                                        text,
                                        true,
                                        &seen,
                                        &clock,
                                        &mut shutdown,
                                    )
                                    .await?;
                                    action_end = clock.now();
                                    last_action = (n, format!("says {text:?}"));
                                    started = clock.now();
                                    answered = 0;
                                    continue;
                                }
                                anyhow::bail!(
                                    "{of_game}step {n}: expected {} within {:.0} s; {why}",
                                    e.describe(),
                                    e.timeout_s
                                );
                            }
                        }
                    }
                }
            }
            outcome.steps = n;
        }
        outcome.duration_s = now_s() - started;
        report(&sc.name, game, games, &outcome)?;
        outcomes.push(outcome);
    }
    Ok(outcomes)
}

/// The person's lines after a game: how it went, and one machine-readable line for benchmarks
/// (each expectation's delay after its action, and that action).
fn report(name: &str, game: u32, games: u32, o: &Outcome) -> anyhow::Result<()> {
    let of = if games > 1 {
        format!(" (game {game} of {games})")
    } else {
        String::new()
    };
    println!(
        "person: scenario {name:?} completed{of}: {} steps in {:.1} s{}",
        o.steps,
        o.duration_s,
        o.closest_hand_to_ball_m
            .map(|d| format!("; closest hand to ball surface {:.1} cm", d * 100.0))
            .unwrap_or_default()
    );
    println!("person: timings {}", serde_json::to_string(&o.timings)?);
    Ok(())
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn describe_move(m: &BallMove) -> String {
    let [x, y, z] = m.to;
    if !m.present {
        return format!("takes the ball away, out of the scene ({x:.2}, {y:.2}, {z:.2})");
    }
    let how = if m.held { "moves" } else { "puts" };
    if m.speed_mps > 0.0 {
        format!(
            "{how} the ball to ({x:.2}, {y:.2}, {z:.2}) m at {:.2} m/s",
            m.speed_mps
        )
    } else {
        format!("{how} the ball at ({x:.2}, {y:.2}, {z:.2}) m")
    }
}

fn move_ball(ball: &Mutex<Ball>, now_s: f64, m: &BallMove) -> f64 {
    let mut b = lock(ball);
    b.move_to(now_s, m.to, m.speed_mps, m.present, m.held);
    b.arrival_s()
}

/// How long the person waits for the robot to finish speaking before she talks anyway (s).
const TURN_WAIT_S: f64 = 8.0;

/// Speak `text`. Taking turns, first wait (at most [`TURN_WAIT_S`]) for the robot to finish what
/// it is saying and what it has queued to say next, as people do (and as the dialog expects
/// without barge-in: it ignores speech heard while the robot talks, its own echo guard).
async fn say(
    speech: &mpsc::Sender<SpeechJob>,
    voice: &Voice,
    text: &str,
    take_turns: bool,
    seen: &Mutex<Seen>,
    clock: &Clock,
    shutdown: &mut interfaces::node::Shutdown,
) -> anyhow::Result<()> {
    let turn = clock.now() + Duration::from_secs_f64(TURN_WAIT_S);
    let mut waited = false;
    // Told it cannot hear her, she waits for it to say it can (bounded by DEAF_AT_MOST).
    let turn = |seen: &Seen| seen.deaf_until.map_or(turn, |d| d.max(turn));
    while take_turns && {
        let s = lock(seen);
        s.robot_has_the_floor(clock.now()) && clock.now() < turn(&s)
    } {
        waited = true;
        tokio::select! {
            _ = clock.sleep(Duration::from_millis(50)) => {}
            _ = shutdown.wait() => anyhow::bail!("stopped while waiting to speak"),
        }
    }
    if waited {
        // A short pause after the robot's last word.
        clock.sleep(Duration::from_millis(400)).await;
    }
    let (v, t) = (voice.clone(), text.to_string());
    let samples = tokio::task::spawn_blocking(move || synth::synthesize_16k(&t, &v)).await??;
    let (done_tx, done_rx) = oneshot::channel();
    speech
        .send((samples, done_tx))
        .await
        .map_err(|_| anyhow::anyhow!("the audio stream stopped"))?;
    tokio::select! {
        r = done_rx => r.map_err(|_| anyhow::anyhow!("the audio stream stopped")),
        _ = shutdown.wait() => anyhow::bail!("stopped while speaking"),
    }
}

async fn spawn_senses(
    bus: &Bus,
    seen: Arc<Mutex<Seen>>,
    tasks: &mut tokio::task::JoinSet<()>,
) -> anyhow::Result<()> {
    let speaking = bus.subscriber(&topics::SPEECH_SPEAKING).await?;
    let transitions = bus.subscriber(&topics::EXECUTIVE_TRANSITIONS).await?;
    let reach = bus.subscriber(&topics::BODY_REACH_STATUS).await?;
    let events = bus.subscriber(&topics::VISION_BALL_EVENTS).await?;
    let clock = bus.clock().clone();
    tasks.spawn(async move {
        loop {
            tokio::select! {
                m = speaking.recv() => {
                    let Ok(m) = m else { break };
                    if m.state == SpeakingState::Started {
                        println!("person: hears the robot say {:?}", m.text);
                    }
                    lock(&seen).on_speaking(&m, clock.now());
                }
                m = transitions.recv() => {
                    let Ok(m) = m else { break };
                    let mut s = lock(&seen);
                    let now = clock.now();
                    for e in m.entered {
                        s.entered.push((now, e));
                    }
                    s.active = m.active;
                }
                m = reach.recv() => {
                    let Ok(m) = m else { break };
                    lock(&seen).reach.push((clock.now(), m.body_part, m.state));
                }
                m = events.recv() => {
                    let Ok(m) = m else { break };
                    lock(&seen).ball_events.push((clock.now(), m.kind));
                }
            }
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests;
