//! The `command_generator` process: the bus on one side, the pages on the other.
//!
//! Subscribes to what both games publish, keeps the latest value of each state topic in the
//! [`Hub`] (throttled per page, see [`STATE_RATES`]) and passes events on; `coach/status` goes
//! to the pages in its own shape ([`crate::coach_status`]); publishes the accepted
//! commands on `coach/request`, `game/command` and `game/answer`. Camera frames are decimated to
//! `camera_hz` before they are encoded, so a 30 Hz camera costs a few encodes a second.

use crate::camera;
use crate::coach_status;
use crate::panel::Outgoing;
use crate::server::{Hub, router};
use interfaces::bus::Counters;
use interfaces::clock::Moment;
use interfaces::liveliness::Readers;
use interfaces::msg::Message;
use interfaces::msg::command::{Answer, GameCommand};
use interfaces::msg::nao::CoachRequest;
use interfaces::node::Interface;
use interfaces::outbox::{Offered, Outbox};
use interfaces::{Bus, Shutdown, Subscriber, Topic, topics};
use serde::Serialize;
use serde_json::json;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc;
use tokio::task::JoinSet;

/// The panel's settings.
#[derive(Debug, Clone)]
pub struct Config {
    /// Where the HTTP server listens (port 0: any free port, printed at start).
    pub listen: SocketAddr,
    /// Required on `/` and `/ws` when set.
    pub token: Option<String>,
    /// Camera images per second sent to the pages (at most).
    pub camera_hz: f64,
}

/// Most updates per second each page gets of each state topic (per robot for local models).
pub const STATE_RATES: &[(&str, f64)] = &[
    ("nao/world_model", 10.0),
    ("nao/local_model", 5.0),
    ("nao/game_state", 4.0),
    ("vision/ball", 10.0),
    ("executive/transitions", 10.0),
    ("coach/status", 4.0),
    ("speech/listening", 5.0),
];

fn interval_of(topic: &str) -> Duration {
    let hz = STATE_RATES
        .iter()
        .find(|(t, _)| *t == topic)
        .map_or(10.0, |(_, hz)| *hz);
    Duration::from_secs_f64(1.0 / hz)
}

/// The JSON message a page gets for a state or an event: `{"type", "topic", "data"}`.
pub fn envelope<T: Serialize>(kind: &str, topic: &str, data: &T) -> String {
    json!({ "type": kind, "topic": topic, "data": data }).to_string()
}

/// Run the panel until shutdown.
pub async fn run(bus: Bus, config: Config, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .map_err(|e| interfaces::node::bind_error("listen", config.listen, e))?;
    let addr = listener.local_addr()?;
    let (hub, commands) = Hub::new(bus.counters().clone(), config.token.clone());

    let mut tasks = JoinSet::new();
    // State topics: the latest value, throttled per page.
    state(&mut tasks, &bus, &hub, &topics::NAO_WORLD_MODEL, |_| {
        String::new()
    })
    .await?;
    state(&mut tasks, &bus, &hub, &topics::NAO_LOCAL_MODEL, |m| {
        format!("/{}", m.player_number)
    })
    .await?;
    state(&mut tasks, &bus, &hub, &topics::NAO_GAME_STATE, |_| {
        String::new()
    })
    .await?;
    let tracks = TrackRing::default();
    {
        let sub = bus.subscriber(&topics::VISION_BALL).await?;
        let (hub, tracks) = (hub.clone(), tracks.clone());
        let every = interval_of(topics::VISION_BALL.name());
        tasks.spawn(async move {
            loop {
                let m = sub.recv().await?;
                tracks.push(m.frame_seq, serde_json::to_value(&m)?);
                hub.set_state("vision/ball", every, envelope("state", "vision/ball", &m));
            }
        });
    }
    state(
        &mut tasks,
        &bus,
        &hub,
        &topics::EXECUTIVE_TRANSITIONS,
        |m| format!("/{}", m.machine),
    )
    .await?;
    state(&mut tasks, &bus, &hub, &topics::SPEECH_LISTENING, |_| {
        String::new()
    })
    .await?;
    // The coach machine's status, in the page's own shape (see `coach_status`).
    {
        let sub = bus.subscriber(&topics::COACH_STATUS).await?;
        let hub = hub.clone();
        let every = interval_of(topics::COACH_STATUS.name());
        tasks.spawn(async move {
            loop {
                let m = sub.recv().await?;
                let view = coach_status::view(&m, crate::server::now_ms());
                hub.set_state(
                    topics::COACH_STATUS.name(),
                    every,
                    serde_json::to_string(&view)?,
                );
            }
        });
    }
    // Events: every one, in order.
    event(&mut tasks, &bus, &hub, &topics::NAO_LINK).await?;
    event(&mut tasks, &bus, &hub, &topics::SPEECH_SAY).await?;
    event(&mut tasks, &bus, &hub, &topics::SPEECH_SPEAKING).await?;
    event(&mut tasks, &bus, &hub, &topics::SPEECH_UTTERANCE).await?;
    event(&mut tasks, &bus, &hub, &topics::GAME_COMMAND).await?;
    event(&mut tasks, &bus, &hub, &topics::EXECUTIVE_LOG).await?;
    event(&mut tasks, &bus, &hub, &topics::VISION_BALL_EVENTS).await?;
    // The camera, decimated and encoded.
    let frames = bus.subscriber_named(topics::VISION_RGBD.name(), 2).await?;
    tasks.spawn(camera_task(
        frames,
        hub.clone(),
        tracks,
        config.camera_hz,
        bus.clone(),
    ));
    tasks.spawn(publish_task(bus.clone(), hub.clone(), commands));

    let app = router(hub.clone());
    let mut stop = shutdown.clone();
    tracing::info!(
        "command panel on http://{addr}/{}",
        if config.token.is_some() {
            "?token=<token>"
        } else {
            ""
        }
    );
    let server =
        axum::serve(listener, app).with_graceful_shutdown(async move { stop.wait().await });
    let result = tokio::select! {
        r = server => r.map_err(|e| anyhow::anyhow!("HTTP server failed: {e}")),
        r = tasks.join_next() => match r {
            Some(Ok(Err(e))) => Err(e),
            Some(Err(e)) => Err(anyhow::anyhow!("a panel task panicked: {e}")),
            _ => Ok(()),
        },
        _ = shutdown.wait() => Ok(()),
    };
    tasks.abort_all();
    result
}

async fn state<T: Message>(
    tasks: &mut JoinSet<anyhow::Result<()>>,
    bus: &Bus,
    hub: &Arc<Hub>,
    topic: &'static Topic<T>,
    key: fn(&T) -> String,
) -> anyhow::Result<()> {
    let sub = bus.subscriber(topic).await?;
    let hub = hub.clone();
    let every = interval_of(topic.name());
    tasks.spawn(async move {
        loop {
            let m = sub.recv().await?;
            let k = format!("{}{}", topic.name(), key(&m));
            hub.set_state(&k, every, envelope("state", topic.name(), &m));
        }
    });
    Ok(())
}

async fn event<T: Message>(
    tasks: &mut JoinSet<anyhow::Result<()>>,
    bus: &Bus,
    hub: &Arc<Hub>,
    topic: &'static Topic<T>,
) -> anyhow::Result<()> {
    let sub = bus.subscriber(topic).await?;
    let hub = hub.clone();
    tasks.spawn(async move {
        loop {
            let m = sub.recv().await?;
            hub.event(envelope("event", topic.name(), &m));
        }
    });
    Ok(())
}

/// The last ball tracks by frame sequence number, so an image goes out with the track computed
/// from it (the tracker's result arrives a few ms after the frame).
#[derive(Debug, Clone, Default)]
struct TrackRing(Arc<std::sync::Mutex<std::collections::VecDeque<(u64, serde_json::Value)>>>);

impl TrackRing {
    const LEN: usize = 64;
    fn push(&self, seq: u64, track: serde_json::Value) {
        let mut r = self.0.lock().unwrap_or_else(|p| p.into_inner());
        if r.len() == Self::LEN {
            r.pop_front();
        }
        r.push_back((seq, track));
    }
    fn get(&self, seq: u64) -> Option<serde_json::Value> {
        let r = self.0.lock().unwrap_or_else(|p| p.into_inner());
        r.iter()
            .rev()
            .find(|(s, _)| *s == seq)
            .map(|(_, t)| t.clone())
    }
}

/// How long an image waits for the tracker's result on it.
const TRACK_WAIT: Duration = Duration::from_millis(60);

async fn camera_task(
    frames: Subscriber<interfaces::msg::vision::RgbdFrame>,
    hub: Arc<Hub>,
    tracks: TrackRing,
    camera_hz: f64,
    bus: Bus,
) -> anyhow::Result<()> {
    let every = Duration::from_secs_f64(1.0 / camera_hz.clamp(0.1, 30.0));
    let counters = bus.counters().clone();
    // The page's frame rate and the wait for a frame's track are on the component's clock.
    let clock = bus.clock().clone();
    let mut last: Option<Moment> = None;
    loop {
        let frame = frames.recv().await?;
        if last.is_some_and(|t| clock.elapsed(t) < every) {
            continue;
        }
        last = Some(clock.now());
        let seq = frame.header.seq;
        let mut meta = json!({
            "width": frame.width, "height": frame.height, "seq": seq,
            "stamp_ns": frame.header.stamp_ns, "frame_id": frame.header.frame_id,
        });
        let encoded = tokio::task::spawn_blocking(move || camera::to_jpeg(&frame)).await?;
        match encoded {
            Ok(jpeg) => {
                let deadline = clock.now() + TRACK_WAIT;
                let track = loop {
                    if let Some(t) = tracks.get(seq) {
                        break t;
                    }
                    if clock.now() >= deadline {
                        break serde_json::Value::Null;
                    }
                    clock.sleep(Duration::from_millis(5)).await;
                };
                meta["track"] = track;
                hub.set_camera(every, envelope("state", "vision/rgbd", &meta), jpeg);
                counters.incr("camera/encoded");
            }
            Err(e) => {
                counters.incr("camera/dropped");
                tracing::warn!("camera frame not shown: {e}");
            }
        }
    }
}

/// How long a command waits for the component that acts on it (restarting) before it is
/// dropped, the page told so.
pub const HOLD: Duration = Duration::from_secs(15);

/// One command topic out of the panel: its publisher, who reads it, and what waits for them.
/// While no other component subscribes (the Executive, or the dialog, is restarting), a command
/// is held and sent when one is back; the page hears of both (`panel/delivery` events).
struct Lane<T: Message> {
    publisher: interfaces::Publisher<T>,
    readers: Readers,
    outbox: Outbox<T>,
    me: String,
    topic: &'static str,
    what: fn(&T) -> String,
}

impl<T: Message> Lane<T> {
    async fn new(
        bus: &Bus,
        topic: &'static Topic<T>,
        what: fn(&T) -> String,
    ) -> anyhow::Result<Lane<T>> {
        Ok(Lane {
            publisher: bus.publisher(topic).await?,
            readers: Readers::watch(bus, topic).await?,
            outbox: Outbox::new(bus.clock().clone(), HOLD),
            me: bus.component().to_string(),
            topic: topic.name(),
            what,
        })
    }

    /// Some component other than the panel reads the topic.
    fn read(&self) -> bool {
        self.readers.now().iter().any(|c| *c != self.me)
    }

    async fn offer(&mut self, msg: T, hub: &Hub, counters: &Counters) -> anyhow::Result<()> {
        let what = (self.what)(&msg);
        match self.outbox.offer(msg) {
            Offered::Send(mut m) => self.publisher.publish(&mut m).await?,
            Offered::Held { evicted, .. } => {
                counters.incr("commands_held");
                let topic = self.topic;
                tracing::warn!("nobody reads {topic} (restarting?): holding {what}");
                delivery(
                    hub,
                    "held",
                    &what,
                    topic,
                    "waiting for its reader to come back",
                );
                if let Some(old) = evicted {
                    counters.incr("commands_dropped_no_reader");
                    let old = (self.what)(&old.msg);
                    tracing::warn!("dropped {old}: too many commands held");
                    delivery(hub, "dropped", &old, topic, "too many commands held");
                }
            }
        }
        Ok(())
    }

    /// After a change of readers, or on the tick: what was held goes out, or is dropped.
    async fn update(&mut self, hub: &Hub, counters: &Counters) -> anyhow::Result<()> {
        let topic = self.topic;
        for r in self.outbox.readers(self.read()) {
            let what = (self.what)(&r.msg);
            counters.incr("commands_released");
            tracing::info!(
                "sending {what} on {topic}, held {:.1} s{}",
                r.waited.as_secs_f64(),
                if r.again { " (again)" } else { "" }
            );
            self.publisher.publish(&mut r.msg.clone()).await?;
            if !r.again {
                let detail = format!("sent after {:.1} s", r.waited.as_secs_f64());
                delivery(hub, "sent", &what, topic, &detail);
            }
        }
        for r in self.outbox.expire() {
            counters.incr("commands_dropped_no_reader");
            let what = (self.what)(&r.msg);
            tracing::warn!(
                "dropped {what}{}: nobody read {topic} within {} s",
                if r.again { " (sent once already)" } else { "" },
                HOLD.as_secs()
            );
            if !r.again {
                let detail = format!(
                    "nobody read it within {} s: not carried out",
                    HOLD.as_secs()
                );
                delivery(hub, "dropped", &what, topic, &detail);
            }
        }
        Ok(())
    }
}

/// Tells the pages what became of a held command.
fn delivery(hub: &Hub, state: &str, what: &str, topic: &str, detail: &str) {
    hub.event(envelope(
        "event",
        "panel/delivery",
        &json!({ "state": state, "what": what, "topic": topic, "detail": detail }),
    ));
}

async fn publish_task(
    bus: Bus,
    hub: Arc<Hub>,
    mut commands: mpsc::Receiver<Outgoing>,
) -> anyhow::Result<()> {
    let mut coach = Lane::new(&bus, &topics::COACH_REQUEST, |m: &CoachRequest| {
        format!("{:?}", m.command.body)
    })
    .await?;
    let mut game = Lane::new(&bus, &topics::GAME_COMMAND, |m: &GameCommand| {
        format!("{:?}", m.command)
    })
    .await?;
    let mut answer = Lane::new(&bus, &topics::GAME_ANSWER, |m: &Answer| {
        (if m.yes { "yes" } else { "no" }).to_string()
    })
    .await?;
    let talk = bus.publisher(&topics::SPEECH_TALK).await?;
    let counters = bus.counters().clone();
    let mut tick = bus.clock().interval(Duration::from_millis(250));
    loop {
        tokio::select! {
            out = commands.recv() => {
                let Some(out) = out else { return Ok(()) };
                if let Some(command) = out.nao {
                    // A coach command: the Executive's coach machine checks and answers it, then
                    // sends it to the robot. Not also on `game/command`, or the machine would get
                    // it twice.
                    let m = CoachRequest {
                        command,
                        ..CoachRequest::default()
                    };
                    coach.offer(m, &hub, &counters).await?;
                } else if let Some(m) = out.game {
                    game.offer(m, &hub, &counters).await?;
                }
                if let Some(m) = out.answer {
                    answer.offer(m, &hub, &counters).await?;
                }
                // The key is only worth anything now: published at once, never held.
                if let Some(mut m) = out.talk {
                    talk.publish(&mut m).await?;
                }
            }
            _ = coach.readers.changed() => {}
            _ = game.readers.changed() => {}
            _ = answer.readers.changed() => {}
            _ = tick.tick() => {}
        }
        coach.update(&hub, &counters).await?;
        game.update(&hub, &counters).await?;
        answer.update(&hub, &counters).await?;
    }
}

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// Address and port of the panel's HTTP server (port 0: any free port, printed at start).
    /// (`--listen` is the bus's own flag.)
    #[arg(long, default_value = "127.0.0.1:8642")]
    pub http: SocketAddr,
    /// Allow a non-loopback --http address (needs --token).
    #[arg(long)]
    pub allow_remote: bool,
    /// Access token the page must present (`/?token=...`); required with --allow-remote.
    #[arg(long, env = "ROBOCOG_PANEL_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// Camera images per second sent to each page (the camera itself runs at 30 Hz).
    #[arg(long, default_value_t = 4.0)]
    pub camera_hz: f64,
}

/// The `command_generator` component.
#[derive(Debug)]
pub struct CommandGenerator;

impl interfaces::node::Component for CommandGenerator {
    const NAME: &'static str = "command_generator";
    const ABOUT: &'static str = "The command panel: a web page with the games' buttons, the Nao coach's field and \
        the robot's answers. Open the printed address in a browser. Commands go on \
        `coach/request` (the Executive's coach machine checks them and commands the \
        robot), `game/command` and `game/answer`, checked first; the Talk button (or V held) \
        goes on `speech/talk`, for a recognizer in push-to-talk mode; refusals are shown on \
        the page and counted on `diagnostics` (`rejected/<reason>`).  By default only \
        this machine can open it (127.0.0.1). To serve another machine, bind its address \
        with --http, add --allow-remote, and give a --token (or ROBOCOG_PANEL_TOKEN), \
        then open http://<address>/?token=<token>.";
    type Config = Flags;
    type Prepared = Config;

    fn interface(config: &Flags) -> Interface {
        Interface {
            hardware: vec![format!("http:{}", config.http)],
            ..Interface::new("command_generator")
                .publishes(&topics::COACH_REQUEST)
                .publishes(&topics::GAME_COMMAND)
                .publishes(&topics::GAME_ANSWER)
                .publishes(&topics::SPEECH_TALK)
                .subscribes(&topics::NAO_WORLD_MODEL)
                .subscribes(&topics::NAO_LOCAL_MODEL)
                .subscribes(&topics::NAO_GAME_STATE)
                .subscribes(&topics::NAO_LINK)
                .subscribes(&topics::VISION_RGBD)
                .subscribes(&topics::VISION_BALL)
                .subscribes(&topics::VISION_BALL_EVENTS)
                .subscribes(&topics::SPEECH_SAY)
                .subscribes(&topics::SPEECH_SPEAKING)
                .subscribes(&topics::SPEECH_UTTERANCE)
                .subscribes(&topics::GAME_COMMAND)
                .subscribes(&topics::EXECUTIVE_TRANSITIONS)
                .subscribes(&topics::EXECUTIVE_LOG)
                .subscribes(&topics::COACH_STATUS)
                .subscribes(&topics::SPEECH_LISTENING)
        }
    }

    fn prepare(config: Flags) -> anyhow::Result<Config> {
        crate::check_listen(config.http, config.allow_remote, config.token.as_deref())?;
        if !(config.camera_hz > 0.0 && config.camera_hz <= 30.0) {
            anyhow::bail!("--camera-hz must be in (0, 30]");
        }
        Ok(Config {
            listen: config.http,
            token: config.token.filter(|t| !t.is_empty()),
            camera_hz: config.camera_hz,
        })
    }

    async fn run(bus: Bus, prepared: Config, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}
