//! The touch game's loop on the bus: commands, ball events and tracks, reach status and the
//! machine's timers into the touch machine; its outputs (speech, gaze, reaches, the arm sent home
//! with retries) out; the tracker and camera watchdogs (a restart of the tracker is ridden out,
//! see [`TrackerWatch`]).

use super::*;
use crate::state_file::StateFile;

/// A finished home request, back to the main loop for the game log.
pub(super) struct HomeResult {
    what: String,
    result: Result<(), String>,
}

/// How often a rest posture is retried while the joints are still owned (the reach component
/// releases them when its goal is cancelled), and how long apart.
pub(super) const HOME_ATTEMPTS: usize = 5;
pub(super) const HOME_RETRY: Duration = Duration::from_millis(300);

pub(super) async fn send_home(bus: Bus, goal: JointGoal, results: mpsc::Sender<HomeResult>) {
    let what = if goal.release {
        "the release of the executive's joints".to_string()
    } else {
        format!("the rest posture of {} joints", goal.targets.len())
    };
    let mut last = String::new();
    for attempt in 1..=HOME_ATTEMPTS {
        match bus
            .call(&topics::BODY_JOINT_GOAL, &goal, Duration::from_secs(2))
            .await
        {
            Ok(r) if r.accepted => {
                if results
                    .try_send(HomeResult {
                        what,
                        result: Ok(()),
                    })
                    .is_err()
                {
                    bus.counters().incr("home_results_dropped");
                }
                return;
            }
            Ok(r) => {
                last = format!("refused: {}", r.detail);
                if r.refusal != JointRefusal::Owned {
                    break;
                }
            }
            Err(e) => last = e.to_string(),
        }
        if attempt < HOME_ATTEMPTS {
            bus.clock().sleep(HOME_RETRY).await;
        }
    }
    if results
        .try_send(HomeResult {
            what,
            result: Err(last),
        })
        .is_err()
    {
        bus.counters().incr("home_results_dropped");
    }
}

/// What the robot says when nothing brings the person's voice to the game any more.
pub const CANNOT_HEAR: &str = "I can't hear you for a moment. Please wait.";
/// What it says when the voice is back.
pub const HEAR_AGAIN: &str = "I can hear you again.";

/// Follows the components that bring the person's voice to the game (`--hearing-from`): when
/// all of them have been gone [`HearingWatch::grace`] (their machine dropped off the network,
/// say), the robot says it cannot hear; once one is back, that it can again. A restart shorter
/// than the grace goes unsaid (the voice's components announce their own restarts).
#[derive(Debug)]
pub(super) struct HearingWatch {
    from: Vec<String>,
    grace: Duration,
    /// Heard at least once (before that, nothing is missing).
    seen: bool,
    gone_since: Option<Moment>,
    said: bool,
}

impl HearingWatch {
    pub(super) fn new(from: Vec<String>, grace: Duration) -> Self {
        Self {
            from: from.into_iter().filter(|f| !f.is_empty()).collect(),
            grace,
            seen: false,
            gone_since: None,
            said: false,
        }
    }
    pub(super) fn names(&self) -> &[String] {
        &self.from
    }
    /// The components present changed at `now` (`present`: one of ours publishes): what to log
    /// and say, if anything.
    pub(super) fn update(&mut self, present: bool, now: Moment) -> Option<(&'static str, String)> {
        if self.from.is_empty() {
            return None;
        }
        if present {
            self.seen = true;
            self.gone_since = None;
            if std::mem::take(&mut self.said) {
                return Some((
                    HEAR_AGAIN,
                    format!(
                        "the voice is back ({} publishes commands again)",
                        self.from.join(", ")
                    ),
                ));
            }
        } else if self.seen && self.gone_since.is_none() {
            self.gone_since = Some(now);
        }
        None
    }
    /// When "cannot hear" falls due, for the loop's sleep.
    pub(super) fn deadline(&self) -> Option<Moment> {
        self.gone_since
            .filter(|_| !self.said)
            .map(|t| t + self.grace)
    }
    /// Whether "cannot hear" is due at `now` (once per absence).
    pub(super) fn due(&mut self, now: Moment) -> Option<(&'static str, String)> {
        match self.deadline() {
            Some(d) if now >= d => {
                self.said = true;
                Some((
                    CANNOT_HEAR,
                    format!(
                        "nothing brings the person's voice to the game: {} gone for {:.0} s (its machine or its link down?)",
                        self.from.join(", "),
                        self.grace.as_secs_f64()
                    ),
                ))
            }
            _ => None,
        }
    }
}

/// Follows `vision/camera_status`: the robot says when its camera stops, and when it is back.
/// A camera that flaps (stops and comes back again and again) is announced once per
/// [`CAMERA_REPEAT`]; every change is logged.
#[derive(Debug, Default)]
pub(super) struct CameraWatch {
    streaming: Option<bool>,
    /// When "cannot see" was last said (on the component's clock); "see again" is said only
    /// after it.
    said_lost: Option<Moment>,
    lost_pending: bool,
}

/// At most one "I can't see" in this long.
pub(super) const CAMERA_REPEAT: Duration = Duration::from_secs(20);

/// What the robot says when its camera stops delivering.
pub const CANNOT_SEE: &str = "I can't see: my camera stopped. Give me a moment.";
/// What it says when the camera is back.
pub const SEE_AGAIN: &str = "I can see again.";

impl CameraWatch {
    /// On a change of the camera's state at `now`: what to log, and what to say (if anything).
    pub(super) fn update(
        &mut self,
        s: &interfaces::msg::vision::CameraStatus,
        now: Moment,
    ) -> Option<(Option<&'static str>, String)> {
        let before = self.streaming.replace(s.streaming);
        match (before, s.streaming) {
            (Some(true) | None, false) => {
                let log = format!("the camera stopped ({}): {}", s.driver, s.detail);
                let say = self
                    .said_lost
                    .is_none_or(|t| now.duration_since(t) >= CAMERA_REPEAT);
                if say {
                    self.said_lost = Some(now);
                    self.lost_pending = true;
                }
                Some((say.then_some(CANNOT_SEE), log))
            }
            (Some(false), true) => {
                let say = std::mem::take(&mut self.lost_pending);
                Some((
                    say.then_some(SEE_AGAIN),
                    format!("the camera is back: {}", s.detail),
                ))
            }
            _ => None,
        }
    }
}

/// The anomaly logged when a restart of the tracker starts to be ridden out (`why`): nothing is
/// said, the machine's states stay, and gaze and reach keep following the DR's `ball`, where the
/// tracker last put it.
fn riding_out_line(why: &str, game: &TouchGame, watch: &TrackerWatch) -> LogLine {
    let at = game.ball_world().map_or("where it was".to_string(), |p| {
        format!(
            "where it was, ({:.2}, {:.2}, {:.2}) in world,",
            p[0], p[1], p[2]
        )
    });
    LogLine {
        kind: "anomaly",
        text: format!(
            "{why}: riding out its restart, the ball taken to be {at} for up to {:.1} s",
            watch.grace().as_secs_f64()
        ),
        distance_m: -1.0,
    }
}

/// Whether the game's eyes need the tracker to have a target (out of sight too: the tracker
/// watches for the ball to come back into view).
pub(super) fn wants_tracker(game: &TouchGame) -> bool {
    let m = game.machine();
    m.is_active(touch::state::SEARCHING)
        || m.is_active(touch::state::TRACKING)
        || m.is_active(touch::state::OUT_OF_SIGHT)
}

pub(super) fn ball_target(s: &crate::settings::TouchSettings) -> BallTarget {
    BallTarget {
        active: true,
        hue_deg: s.ball_hue_deg,
        saturation: s.ball_saturation,
        diameter_m: s.ball_diameter_m,
        ..BallTarget::default()
    }
}

pub(super) struct TouchOut {
    bus: Bus,
    say: interfaces::Publisher<SayRequest>,
    target: interfaces::Publisher<interfaces::msg::tracking::BallTarget>,
    reach: interfaces::Publisher<interfaces::msg::body::ReachGoal>,
    transitions: interfaces::Publisher<StateTransition>,
    log: interfaces::Publisher<GameLog>,
    home: mpsc::Sender<HomeResult>,
    say_id: u64,
    finished: bool,
    /// The reach goals in force, per body part (sent, not cancelled nor replaced): sent again
    /// to a reach component that restarted, which lost them.
    goals: std::collections::BTreeMap<String, ReachGoal>,
    /// What the robot was asked to say and has not finished saying (by id, the newest
    /// [`UNSAID_KEPT`]): said again by a speech generator that restarted, which lost it.
    unsaid: std::collections::BTreeMap<u64, (Moment, SayRequest)>,
}

/// How many unfinished sentences are kept for a restarted speech generator, and for how long
/// (older ones are stale: the game has moved on).
const UNSAID_KEPT: usize = 8;
const UNSAID_FOR: Duration = Duration::from_secs(20);

/// Whether the components publishing a topic came back: seen, gone (killed, restarting), then
/// present again. Their first appearance (a component starting after this one, or the bus's
/// history arriving late) is no comeback.
#[derive(Debug)]
pub(super) struct Comeback {
    present: bool,
    seen: bool,
}

impl Comeback {
    pub(super) fn new(present: bool) -> Self {
        Self {
            present,
            seen: present,
        }
    }
    /// The publishers are `present` now: true when they had been seen, then gone.
    pub(super) fn back(&mut self, present: bool) -> bool {
        let back = present && !self.present && self.seen;
        self.present = present;
        self.seen |= present;
        back
    }
}

#[cfg(test)]
mod comeback_tests {
    use super::Comeback;

    #[test]
    fn only_a_return_after_a_leave_is_a_comeback() {
        // Not there at start (the history not in yet), then there: no comeback.
        let mut c = Comeback::new(false);
        assert!(!c.back(false));
        assert!(!c.back(true));
        assert!(!c.back(true));
        // Gone, then back: a comeback, once.
        assert!(!c.back(false));
        assert!(c.back(true));
        assert!(!c.back(true));
        // There from the start, gone, back.
        let mut c = Comeback::new(true);
        assert!(!c.back(false));
        assert!(c.back(true));
    }
}

impl TouchOut {
    /// Says `text` at once (outside the game's machine: what the robot tells about itself).
    async fn say_now(&mut self, text: &str) -> anyhow::Result<()> {
        self.say_text(text.into(), interfaces::msg::speech::Priority::High)
            .await
    }

    async fn say_text(
        &mut self,
        text: String,
        priority: interfaces::msg::speech::Priority,
    ) -> anyhow::Result<()> {
        self.say_id += 1;
        let mut r = SayRequest {
            id: self.say_id,
            text,
            priority,
            ..Default::default()
        };
        self.say.publish(&mut r).await?;
        self.unsaid.insert(r.id, (self.bus.clock().now(), r));
        while self.unsaid.len() > UNSAID_KEPT {
            self.unsaid.pop_first();
        }
        Ok(())
    }

    /// The reach component came back (restarted): it lost the goals in force, sent again.
    async fn send_goals_again(&mut self) -> anyhow::Result<()> {
        if self.goals.is_empty() {
            return Ok(());
        }
        let parts: Vec<&str> = self.goals.keys().map(String::as_str).collect();
        let text = format!(
            "the reach component is back (restarted?): sending its goals again ({})",
            parts.join(", ")
        );
        self.log_line(LogLine {
            kind: "anomaly",
            text,
            distance_m: -1.0,
        })
        .await?;
        let goals: Vec<ReachGoal> = self.goals.values().cloned().collect();
        for mut g in goals {
            self.reach.publish(&mut g).await?;
        }
        Ok(())
    }

    /// The speech generator came back (restarted) at `now`: it lost what it was saying, said
    /// again unless stale.
    async fn say_unfinished_again(&mut self, now: Moment) -> anyhow::Result<()> {
        self.unsaid
            .retain(|_, (at, _)| now.duration_since(*at) < UNSAID_FOR);
        if self.unsaid.is_empty() {
            return Ok(());
        }
        let again: Vec<SayRequest> = self.unsaid.values().map(|(_, r)| r.clone()).collect();
        let said: Vec<String> = again.iter().map(|r| format!("\"{}\"", r.text)).collect();
        let text = format!(
            "the speech generator is back (restarted?): saying again what it did not finish ({})",
            said.join(", ")
        );
        self.log_line(LogLine {
            kind: "anomaly",
            text,
            distance_m: -1.0,
        })
        .await?;
        for mut r in again {
            self.say.publish(&mut r).await?;
        }
        Ok(())
    }

    /// What the speech generator says of a sentence: a sentence over (said, cut, dropped,
    /// failed) is no longer the robot's to say again.
    fn spoken(&mut self, s: &interfaces::msg::speech::SpeakingEvent) {
        if matches!(
            s.state,
            SpeakingState::Finished
                | SpeakingState::Interrupted
                | SpeakingState::Dropped
                | SpeakingState::Failed
        ) {
            self.unsaid.remove(&s.id);
        }
    }

    async fn log_line(&mut self, l: LogLine) -> anyhow::Result<()> {
        if l.distance_m >= 0.0 {
            tracing::info!("[{}] {} ({:.3} m)", l.kind, l.text, l.distance_m);
        } else {
            tracing::info!("[{}] {}", l.kind, l.text);
        }
        if l.kind == "anomaly" {
            self.bus.counters().incr("anomalies");
        }
        let mut g = GameLog {
            machine: touch::MACHINE.into(),
            kind: l.kind.into(),
            text: l.text,
            distance_m: l.distance_m,
            ..Default::default()
        };
        self.log.publish(&mut g).await?;
        Ok(())
    }

    async fn step(&mut self, s: &Step<touch::Act>) -> anyhow::Result<()> {
        if s.ignored {
            self.bus.counters().incr("ignored_events");
            tracing::debug!("{} ignored in {:?}", s.event, s.active);
            return Ok(());
        }
        self.transitions
            .publish(&mut transition_msg(touch::MACHINE, s))
            .await?;
        Ok(())
    }

    /// Publishes an outcome: the transitions, then the outputs in order.
    async fn emit(&mut self, o: touch::Outcome) -> anyhow::Result<()> {
        for s in &o.steps {
            self.step(s).await?;
        }
        for out in o.outputs {
            match out {
                Output::Say { text, priority } => self.say_text(text, priority).await?,
                Output::SetBallTarget(mut t) => self.target.publish(&mut t).await?,
                Output::Reach(mut g) => {
                    self.reach.publish(&mut g).await?;
                    self.goals.insert(g.body_part.clone(), g);
                }
                Output::CancelReach(mut g) => {
                    self.reach.publish(&mut g).await?;
                    self.goals.remove(&g.body_part);
                }
                Output::Home(goal) | Output::Release(goal) => {
                    tokio::spawn(send_home(self.bus.clone(), goal, self.home.clone()));
                }
                Output::Log(l) => self.log_line(l).await?,
                Output::Finish => self.finished = true,
            }
        }
        Ok(())
    }
}

pub(super) fn snapshot_of(game: &TouchGame, mermaid: &str) -> Snapshot {
    let m = game.machine();
    Snapshot {
        machine: touch::MACHINE.into(),
        active: m.active_leaves(),
        all_active: m.configuration(),
        step: m.steps(),
        mermaid: mermaid.to_string(),
        game_on: !m.is_finished(),
    }
}

pub(super) async fn run_touch(
    bus: Bus,
    config: Config,
    settings: Settings,
    mut shutdown: Shutdown,
) -> anyhow::Result<()> {
    let mut game = TouchGame::new(settings.touch.clone())?;
    let mermaid = game.machine().definition().mermaid();
    let snapshot: Shared = Arc::new(Mutex::new(snapshot_of(&game, &mermaid)));
    let commands = bus.subscriber(&topics::GAME_COMMAND).await?;
    let ball_events = bus.subscriber(&topics::VISION_BALL_EVENTS).await?;
    let tracks = bus.subscriber(&topics::VISION_BALL).await?;
    let statuses = bus.subscriber(&topics::BODY_REACH_STATUS).await?;
    let speaking = bus.subscriber(&topics::SPEECH_SPEAKING).await?;
    let cameras = bus.subscriber(&topics::VISION_CAMERA_STATUS).await?;
    let mut camera = CameraWatch::default();
    let mut hearing = HearingWatch::new(
        config.hearing_from.clone(),
        Duration::from_secs_f64(config.hearing_grace_s.clamp(0.5, 600.0)),
    );
    let mut voices =
        interfaces::liveliness::Readers::watch_writers(&bus, &topics::GAME_COMMAND).await?;
    // Who publishes the tracks: a tracker that leaves (killed, crashed) is ridden out.
    let mut trackers =
        interfaces::liveliness::Readers::watch_writers(&bus, &topics::VISION_BALL).await?;
    // And who publishes the frames: a camera that leaves (killed, crashed) is ridden out too.
    let mut camera_writers =
        interfaces::liveliness::Readers::watch_writers(&bus, &topics::VISION_RGBD).await?;
    // And who reports on reaches: a reach component that comes back (restarted) lost the goals
    // it had, and is sent them again.
    let mut reachers =
        interfaces::liveliness::Readers::watch_writers(&bus, &topics::BODY_REACH_STATUS).await?;
    let mut reacher = Comeback::new(!reachers.now().is_empty());
    // And who speaks: a speech generator that comes back lost what it was saying.
    let mut speakers =
        interfaces::liveliness::Readers::watch_writers(&bus, &topics::SPEECH_SPEAKING).await?;
    let mut speaker = Comeback::new(!speakers.now().is_empty());
    let (home_tx, mut home_rx) = mpsc::channel(16);
    let mut out = TouchOut {
        bus: bus.clone(),
        say: bus.publisher(&topics::SPEECH_SAY).await?,
        target: bus.publisher(&topics::VISION_BALL_TARGET).await?,
        reach: bus.publisher(&topics::BODY_REACH).await?,
        transitions: bus.publisher(&topics::EXECUTIVE_TRANSITIONS).await?,
        log: bus.publisher(&topics::EXECUTIVE_LOG).await?,
        home: home_tx,
        say_id: 0,
        finished: false,
        goals: Default::default(),
        unsaid: Default::default(),
    };
    let _services = serve(&bus, snapshot.clone(), settings.propose.clone()).await?;
    tracing::info!(
        "touch the ball: arm {}, courtesy delay {} s, ball hue {} deg saturation {} diameter {} m",
        settings.touch.arm,
        settings.touch.courtesy_delay_s,
        settings.touch.ball_hue_deg,
        settings.touch.ball_saturation,
        settings.touch.ball_diameter_m
    );
    // A clock that follows a replay has no time before the replay's first `clock` message.
    let clock = bus.clock().clone();
    tokio::select! {
        _ = shutdown.wait() => return Ok(()),
        _ = clock.started() => {}
    }
    // The resume record (`<state dir>/touch.json`), removed once the game is over.
    let mut kept = StateFile::new(config.state_dir.as_deref(), "touch.json");
    let o = match kept.load() {
        Some(record) => game.resume(&record, bus_now(&bus)),
        None => game.start(bus_now(&bus)),
    };
    *lock(&snapshot) = snapshot_of(&game, &mermaid);
    out.emit(o).await?;
    kept.save(game.resume_record(), bus.counters());
    let mut watch = TrackerWatch::new(Duration::from_secs_f64(
        settings.touch.tracker_restart_grace_s,
    ));
    watch.writers(Feed::Tracker, trackers.now(), false, clock.now());
    watch.writers(Feed::Camera, camera_writers.now(), false, clock.now());
    // The voice's components already there (later changes come from `voices.changed()`).
    let _ = hearing.update(voices.any_of(hearing.names()), clock.now());
    loop {
        // Wake on the clock for the machine's next timer, or the tracker watchdog's.
        let deadline = [
            game.next_deadline().map(Moment::from_duration),
            watch.deadline(game.machine().is_active(touch::state::TRACKING)),
            hearing.deadline(),
        ]
        .into_iter()
        .flatten()
        .min();
        let outcome = tokio::select! {
            _ = shutdown.wait() => return Ok(()),
            c = commands.recv() => {
                let c = c?;
                game.command(&c, bus_now(&bus))
            }
            e = ball_events.recv() => game.ball_event(&e?, bus_now(&bus)),
            t = tracks.recv() => {
                let mut t = t?;
                // Only the newest track matters.
                while let Some(newer) = tracks.try_recv() {
                    t = newer;
                }
                let tracking = game.machine().is_active(touch::state::TRACKING);
                match watch.heard(&t, touch::held(&t), tracking, clock.now()) {
                    TrackNews::Restarted => {
                        let why = "the ball tracker restarted (its track numbers start again, or it has no target)";
                        out.log_line(riding_out_line(why, &game, &watch)).await?;
                    }
                    TrackNews::Back => out.log_line(LogLine {
                        kind: "anomaly",
                        text: "the ball tracker holds the ball again: the game carries on".into(),
                        distance_m: -1.0,
                    }).await?,
                    TrackNews::Nothing => {}
                }
                if t.state == BallTrackState::Waiting && wants_tracker(&game) && watch.may_resend(clock.now()) {
                    // A tracker without a target while the game needs one: it was restarted.
                    out.log_line(LogLine {
                        kind: "anomaly",
                        text: "the ball tracker has no target (was it restarted?): sending it again".into(),
                        distance_m: -1.0,
                    }).await?;
                    let mut target = ball_target(&settings.touch);
                    out.target.publish(&mut target).await?;
                }
                // A ball that moved meanwhile is `ball:moved`, as ever.
                game.ball_track(&t, bus_now(&bus))
            }
            s = statuses.recv() => game.reach_status(&s?, bus_now(&bus)),
            _ = trackers.changed() => {
                let tracking = game.machine().is_active(touch::state::TRACKING);
                if watch.writers(Feed::Tracker, trackers.now(), tracking, clock.now()) {
                    let why = "the ball tracker left vision/ball (killed? restarting?)";
                    out.log_line(riding_out_line(why, &game, &watch)).await?;
                }
                game.advance(bus_now(&bus))
            }
            _ = reachers.changed() => {
                if reacher.back(!reachers.now().is_empty()) {
                    out.send_goals_again().await?;
                }
                game.advance(bus_now(&bus))
            }
            _ = speakers.changed() => {
                if speaker.back(!speakers.now().is_empty()) {
                    out.say_unfinished_again(clock.now()).await?;
                }
                if speakers.now().is_empty() {
                    game.speaking(false, bus_now(&bus))
                } else {
                    game.advance(bus_now(&bus))
                }
            }
            _ = camera_writers.changed() => {
                let tracking = game.machine().is_active(touch::state::TRACKING);
                if watch.writers(Feed::Camera, camera_writers.now(), tracking, clock.now()) {
                    let why = "the camera left vision/rgbd (killed? restarting?)";
                    out.log_line(riding_out_line(why, &game, &watch)).await?;
                }
                game.advance(bus_now(&bus))
            }
            _ = voices.changed() => {
                let present = voices.any_of(hearing.names());
                if let Some((said, log)) = hearing.update(present, clock.now()) {
                    tracing::warn!("{log}");
                    out.log_line(LogLine { kind: "anomaly", text: log, distance_m: -1.0 }).await?;
                    out.say_now(said).await?;
                }
                game.advance(bus_now(&bus))
            }
            c = cameras.recv() => {
                let c = c?;
                if let Some((said, log)) = camera.update(&c, clock.now()) {
                    out.log_line(LogLine { kind: "anomaly", text: log, distance_m: -1.0 }).await?;
                    if let Some(said) = said {
                        out.say_now(said).await?;
                    }
                }
                game.advance(bus_now(&bus))
            }
            s = speaking.recv() => {
                let s = s?;
                out.spoken(&s);
                match s.state {
                    SpeakingState::Failed | SpeakingState::Dropped | SpeakingState::Interrupted => {
                        out.log_line(LogLine {
                            kind: "anomaly",
                            text: format!("speech {:?}: \"{}\" {}", s.state, s.text, s.detail),
                            distance_m: -1.0,
                        }).await?;
                    }
                    _ => tracing::debug!("speech {:?}: {}", s.state, s.text),
                }
                match touch::talking(&s) {
                    Some(talking) => game.speaking(talking, bus_now(&bus)),
                    None => game.advance(bus_now(&bus)),
                }
            }
            h = home_rx.recv() => {
                if let Some(h) = h {
                    let line = match h.result {
                        Ok(()) => LogLine { kind: "reach", text: format!("{} was accepted", h.what), distance_m: -1.0 },
                        Err(e) => LogLine { kind: "anomaly", text: format!("{} failed: {e}", h.what), distance_m: -1.0 },
                    };
                    out.log_line(line).await?;
                }
                game.advance(bus_now(&bus))
            }
            _ = sleep_until(&clock, deadline) => {
                if let Some((said, log)) = hearing.due(clock.now()) {
                    tracing::warn!("{log}");
                    out.log_line(LogLine { kind: "anomaly", text: log, distance_m: -1.0 }).await?;
                    out.say_now(said).await?;
                }
                game.advance(bus_now(&bus))
            }
        };
        // The configuration is current before anyone hears of the step, and the record is kept
        // before the step's outputs go out (with the command's stamp, when a command made it).
        *lock(&snapshot) = snapshot_of(&game, &mermaid);
        kept.save(game.resume_record(), bus.counters());
        out.emit(outcome).await?;
        // A tracker that falls silent while the eyes follow the ball, still on the bus (its
        // camera stalled, it hangs), or a restarted one that does not hold the ball again within
        // the grace: the ball is lost, said so, and searched for again.
        let tracking = game.machine().is_active(touch::state::TRACKING);
        if let Some(due) = watch.due(tracking, clock.now()) {
            let text = match due {
                TrackerDue::Silent => format!(
                    "no ball track for {:.1} s: the ball tracker is silent",
                    TRACKER_SILENCE.as_secs_f64()
                ),
                TrackerDue::GraceOver => format!(
                    "the restarted ball tracker did not hold the ball again within {:.1} s: the ball is lost",
                    watch.grace().as_secs_f64()
                ),
            };
            out.log_line(LogLine {
                kind: "anomaly",
                text,
                distance_m: -1.0,
            })
            .await?;
            let lost = BallEvent {
                kind: BallEventKind::Lost,
                ..BallEvent::default()
            };
            let o = game.ball_event(&lost, bus_now(&bus));
            *lock(&snapshot) = snapshot_of(&game, &mermaid);
            out.emit(o).await?;
        }
        kept.save(game.resume_record(), bus.counters());
        if out.finished && config.exit_when_finished {
            // Let the last messages and the rest postures go out (on the wall clock: this waits
            // for the bus, and a replay's clock may never move again).
            #[expect(
                clippy::disallowed_methods,
                reason = "the last messages drain to the transport on the wall: a replay's clock may never move again"
            )]
            tokio::time::sleep(Duration::from_millis(500)).await;
            while let Ok(h) = home_rx.try_recv() {
                if let Err(e) = h.result {
                    tracing::warn!("rest posture failed: {e}");
                }
            }
            tracing::info!("the game is over: exiting");
            return Ok(());
        }
    }
}

#[cfg(test)]
mod hearing_tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn at(s: f64) -> Moment {
        Moment::from_duration(Duration::from_secs_f64(s))
    }

    #[test]
    fn the_robot_says_it_cannot_hear_once_the_voice_is_gone_past_the_grace_and_when_it_is_back() {
        let mut h = HearingWatch::new(vec!["dialogs".into(), "".into()], Duration::from_secs(5));
        assert_eq!(h.names(), ["dialogs"]);
        // Gone before it was ever there: nothing is missing.
        assert_eq!(h.update(false, at(0.0)), None);
        assert_eq!(h.deadline(), None);
        assert_eq!(h.update(true, at(1.0)), None);
        // A restart shorter than the grace goes unsaid.
        assert_eq!(h.update(false, at(2.0)), None);
        assert_eq!(h.due(at(6.9)), None);
        assert_eq!(h.update(true, at(3.0)), None);
        assert_eq!(h.due(at(10.0)), None);
        // Gone for good: said once, at the grace.
        assert_eq!(h.update(false, at(20.0)), None);
        assert_eq!(h.deadline(), Some(at(25.0)));
        assert_eq!(h.due(at(24.9)), None);
        let (said, log) = h.due(at(25.0)).unwrap();
        assert_eq!(said, CANNOT_HEAR);
        assert!(log.contains("dialogs"), "{log}");
        assert_eq!(h.due(at(40.0)), None);
        assert_eq!(h.deadline(), None);
        // Back: said once.
        assert_eq!(h.update(true, at(41.0)).map(|(s, _)| s), Some(HEAR_AGAIN));
        assert_eq!(h.update(true, at(42.0)), None);
        // Nothing to watch: never said.
        let mut none = HearingWatch::new(vec![], Duration::from_secs(1));
        assert_eq!(none.update(true, at(0.0)), None);
        assert_eq!(none.update(false, at(1.0)), None);
        assert_eq!(none.due(at(100.0)), None);
    }
}
