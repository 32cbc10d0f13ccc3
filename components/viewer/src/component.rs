//! The viewer process: the bus side (one wildcard subscription into the bounded
//! [`Intake`]) and the one logging thread that talks to rerun. `main.rs` only parses the flags.

use crate::blueprint::{self, Game};
use crate::intake::{Intake, Sample};
use crate::mapping::{MapError, Mapper, MapperOptions};
use interfaces::msg::Message;
use interfaces::msg::dr::{SnapshotData, SnapshotRequest};
use interfaces::node::Interface;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, Shutdown, topics};
use robot_model::RobotModel;
use robot_model::find_model;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::RecvTimeoutError;
use std::time::{Duration, Instant};
use world_model::field::FieldModel;

/// What the viewer does (from the command line).
#[derive(Debug)]
pub struct Settings {
    pub sink: Sink,
    /// Only these topics; empty: every topic of the namespace.
    pub topics: Vec<String>,
    pub exclude: Vec<String>,
    pub game: Option<Game>,
    pub urdf: Option<PathBuf>,
    pub field: Option<PathBuf>,
    pub image_hz: f64,
    pub queue: usize,
    pub queue_per_topic: usize,
}

/// The viewer's interface (what `--describe` prints).
pub fn interface() -> Interface {
    Interface::new("viewer").calls(&topics::DR_SNAPSHOT)
}

/// Where the entities go.
#[derive(Debug, Clone)]
pub enum Sink {
    /// A viewer started for this run (`rerun` on PATH).
    Spawn,
    /// A running viewer's gRPC endpoint (`rerun+http://HOST:PORT/proxy`).
    Connect(String),
    /// An `.rrd` file, finished on shutdown.
    Save(PathBuf),
}

impl Sink {
    fn describe(&self) -> String {
        match self {
            Sink::Spawn => "a spawned rerun viewer".into(),
            Sink::Connect(u) => format!("the rerun viewer at {u}"),
            Sink::Save(p) => p.display().to_string(),
        }
    }
    fn open(&self) -> anyhow::Result<rerun::RecordingStream> {
        let builder = rerun::RecordingStreamBuilder::new("robocog");
        Ok(match self {
            Sink::Spawn => builder.spawn().map_err(|e| {
                anyhow::anyhow!(
                    "cannot start a rerun viewer: {e}. Install it with `pip install \
                     rerun-sdk==0.36.3` (the `rerun` executable must be on PATH), or use --save"
                )
            })?,
            Sink::Connect(url) => builder
                .connect_grpc_opts(url.clone())
                .map_err(|e| anyhow::anyhow!("cannot connect to the rerun viewer at {url}: {e}"))?,
            Sink::Save(path) => builder
                .save(path)
                .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?,
        })
    }
}

fn load_models(settings: &Settings) -> (Option<RobotModel>, Option<FieldModel>) {
    let urdf = find_model(settings.urdf.as_deref(), "loki.urdf");
    let robot = match RobotModel::from_urdf_file(&urdf) {
        Ok(r) => Some(r),
        Err(e) => {
            tracing::warn!(
                "robot model {}: {e}; joint states and camera frames are logged without the robot",
                urdf.display()
            );
            None
        }
    };
    let field_path = find_model(settings.field.as_deref(), "spl_field.toml");
    let field = match FieldModel::from_file(&field_path) {
        Ok(f) => Some(f),
        Err(e) => {
            tracing::warn!(
                "field model {}: {e}; the Nao game is logged without field lines",
                field_path.display()
            );
            None
        }
    };
    (robot, field)
}

/// What the logging thread reports at the end.
#[derive(Debug, Default)]
struct Report {
    received: BTreeMap<String, u64>,
    unknown: BTreeMap<String, String>,
    undecodable: BTreeMap<String, u64>,
}

/// What the logging thread (the only place that talks to rerun) owns.
struct Logging {
    rec: rerun::RecordingStream,
    mapper: Mapper,
    rx: std::sync::mpsc::Receiver<Sample>,
    intake: Arc<Intake>,
    counters: Arc<interfaces::bus::Counters>,
    game: Option<Game>,
    wants_dr_snapshot: Arc<AtomicBool>,
    /// `None`: wait for everything (a file); else give up on a viewer after this long.
    flush_timeout: Option<Duration>,
    report_tx: tokio::sync::oneshot::Sender<Report>,
    /// Told when everything went to rerun (or the flush gave up).
    done_tx: tokio::sync::oneshot::Sender<()>,
}

#[expect(
    clippy::disallowed_methods,
    reason = "rerun's logging thread blocks on its queue on the wall: its once-a-second stats of \
              what it took and its log limiter (what a person reads) are on the wall too, as the \
              system time it stamps them with"
)]
fn logging_loop(ctx: Logging) {
    let Logging {
        rec,
        mut mapper,
        rx,
        intake,
        counters,
        mut game,
        wants_dr_snapshot,
        flush_timeout,
        report_tx,
        done_tx,
    } = ctx;
    let camera = mapper.head_camera_path();
    let mut report = Report::default();
    let mut seen: BTreeSet<String> = BTreeSet::new();
    let mut limiters: HashMap<String, RateLimiter> = HashMap::new();
    let mut next_stats = Instant::now() + Duration::from_secs(1);
    let mut blueprint_sent = false;
    let send_blueprint = |g: Game| {
        let bp = blueprint::blueprint(g, &camera);
        if let Err(e) = bp.send(&rec, rerun::blueprint::BlueprintActivation::default()) {
            tracing::warn!("cannot send the {g:?} layout: {e}");
        } else {
            tracing::info!("layout: {g:?} game");
        }
    };
    if let Some(g) = game {
        send_blueprint(g);
        blueprint_sent = true;
    }
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(s) => {
                intake.taken(&s.topic);
                if seen.insert(s.topic.clone()) {
                    tracing::info!(topic = %s.topic, type_name = %s.type_name, "new topic");
                    if !blueprint_sent
                        && let Some(g) = game.or(Game::from_topics(seen.iter().map(String::as_str)))
                    {
                        game = Some(g);
                        send_blueprint(g);
                        blueprint_sent = true;
                    }
                }
                match mapper.map(&s.topic, &s.type_name, &s.payload, s.receipt_ns) {
                    Ok(m) => {
                        let t = if m.stamp_ns > 0 {
                            m.stamp_ns
                        } else {
                            s.receipt_ns
                        };
                        rec.set_timestamp_nanos_since_epoch("stamp", t);
                        for it in m.items {
                            let r = if it.is_static {
                                rec.log_static(it.path.as_str(), &*it.data)
                            } else {
                                rec.log(it.path.as_str(), &*it.data)
                            };
                            if let Err(e) = r {
                                tracing::warn!(path = %it.path, "rerun refused the entity: {e}");
                            }
                        }
                    }
                    Err(e @ MapError::UnknownType { .. }) => {
                        counters.incr(&format!("view_unknown/{}", s.topic));
                        if !report.unknown.contains_key(&s.topic) {
                            tracing::warn!("{e}: skipped (listed once)");
                            report.unknown.insert(s.topic.clone(), s.type_name.clone());
                        }
                    }
                    Err(e) => {
                        counters.incr(&format!("view_undecodable/{}", s.topic));
                        *report.undecodable.entry(s.topic.clone()).or_default() += 1;
                        let l = limiters
                            .entry(s.topic.clone())
                            .or_insert_with(|| RateLimiter::new(Duration::from_secs(5)));
                        if let Some(suppressed) = l.allow(Instant::now()) {
                            tracing::warn!(suppressed, "{e:#}: sample skipped");
                        }
                    }
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => break,
        }
        let dr = mapper.dr_draw(interfaces::header::system_now_ns());
        if !dr.is_empty() {
            rec.set_timestamp_nanos_since_epoch("stamp", interfaces::header::system_now_ns());
            for it in dr {
                let _ = rec.log(it.path.as_str(), &*it.data);
            }
        }
        wants_dr_snapshot.store(mapper.wants_dr_snapshot(), Ordering::Relaxed);
        if Instant::now() >= next_stats {
            next_stats += Duration::from_secs(1);
            let now = interfaces::header::system_now_ns();
            rec.set_timestamp_nanos_since_epoch("stamp", now);
            for it in mapper.stats(now, &intake.dropped()) {
                let _ = rec.log(it.path.as_str(), &*it.data);
            }
        }
    }
    report.received = mapper.received();
    // The summary first: a viewer that stopped reading may keep the flush below from finishing.
    let _ = report_tx.send(report);
    let flushed = match flush_timeout {
        None => rec.flush_blocking(),
        Some(t) => rec.flush_with_timeout(t),
    };
    if let Err(e) = flushed {
        tracing::warn!("rerun did not take everything before the end: {e}");
    }
    drop(rec);
    let _ = done_tx.send(());
}

/// Runs the viewer until `shutdown`, then finishes the file (or gives a viewer that stopped
/// reading a bounded time).
pub async fn run(bus: Bus, settings: Settings, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let sink = settings.sink.clone();
    for t in settings.topics.iter().chain(&settings.exclude) {
        if !interfaces::topic::is_valid_name(t) {
            anyhow::bail!("invalid topic name {t:?}: lowercase letters, digits, '_', '-', '/'");
        }
    }
    if !(settings.image_hz >= 0.0 && settings.image_hz.is_finite()) {
        anyhow::bail!("--image-hz must be 0 or a positive rate");
    }
    let (robot, field) = load_models(&settings);
    let mapper = Mapper::new(
        robot,
        field,
        MapperOptions {
            image_hz: settings.image_hz,
            ..MapperOptions::default()
        },
    );
    // A file sink always finishes; a viewer that stopped reading gets this long.
    let flush_timeout = match &sink {
        Sink::Save(_) => None,
        _ => Some(Duration::from_secs(10)),
    };
    let (rec, target) = sink.open_blocking().await?;
    tracing::info!("logging namespace {:?} to {target}", bus.namespace());

    let counters = bus.counters().clone();
    let for_intake = counters.clone();
    let (intake, rx) = Intake::new(
        settings.queue,
        settings.queue_per_topic,
        Box::new(move |name| for_intake.counter(name)),
    );
    let wants_dr_snapshot = Arc::new(AtomicBool::new(true));
    let (report_tx, report_rx) = tokio::sync::oneshot::channel::<Report>();
    let (done_tx, done_rx) = tokio::sync::oneshot::channel::<()>();
    let logger = {
        let intake = intake.clone();
        let counters = counters.clone();
        let game = settings.game;
        let wants = wants_dr_snapshot.clone();
        std::thread::Builder::new()
            .name("viewer-log".into())
            .spawn(move || {
                logging_loop(Logging {
                    rec,
                    mapper,
                    rx,
                    intake,
                    counters,
                    game,
                    wants_dr_snapshot: wants,
                    flush_timeout,
                    report_tx,
                    done_tx,
                })
            })?
    };
    // The DR's state, for the viewer's copy of it: asked for at the start, and again
    // whenever the copy missed changes. A graph without a DR answers "no server" at once.
    let snapshots = tokio::spawn(fetch_dr_snapshots(
        bus.clone(),
        intake.clone(),
        wants_dr_snapshot,
    ));

    // One subscription for the whole namespace, or one per topic given.
    let patterns: Vec<&str> = if settings.topics.is_empty() {
        vec![interfaces::raw::EVERY_TOPIC]
    } else {
        settings.topics.iter().map(String::as_str).collect()
    };
    let exclude: Arc<BTreeSet<String>> = Arc::new(settings.exclude.iter().cloned().collect());
    let mut subscribers = Vec::new();
    for pattern in patterns {
        let intake = intake.clone();
        let exclude = exclude.clone();
        let untyped = counters.counter("view_untyped");
        let sub = bus
            .raw_listener(pattern, move |sample| {
                if exclude.contains(&sample.topic) {
                    return;
                }
                let Some(type_name) = sample.type_name.clone() else {
                    untyped.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    return;
                };
                intake.offer(Sample {
                    topic: sample.topic.clone(),
                    type_name,
                    receipt_ns: sample.receipt_ns,
                    payload: sample.into_payload(),
                });
            })
            .await
            .map_err(|e| anyhow::anyhow!("cannot subscribe to {pattern}: {e}"))?;
        subscribers.push(sub);
    }

    shutdown.wait().await;
    snapshots.abort();
    for s in subscribers {
        let _ = s.undeclare().await;
    }
    intake.close();
    let dropped = intake.dropped();
    // The logging thread may be stuck in rerun behind a viewer that stopped reading:
    // wait for it on channels (never on a blocking task the runtime would wait for).
    let patience = flush_timeout.map_or(Duration::from_secs(3600), |t| t + Duration::from_secs(5));
    #[expect(
        clippy::disallowed_methods,
        reason = "a grace for the process's exit behind a rerun viewer that stopped reading \
                  (transport): a virtual clock that stopped must not hold the exit"
    )]
    let report = tokio::time::timeout(patience, report_rx).await;
    let report = match report {
        Ok(Ok(r)) => r,
        Ok(Err(_)) => anyhow::bail!("the logging thread ended without a report"),
        Err(_) => {
            tracing::warn!(
                dropped = dropped.values().sum::<u64>(),
                "the rerun viewer is not taking data: stopping without it"
            );
            return Ok(());
        }
    };
    let total: u64 = report.received.values().sum();
    tracing::info!(
        "logged {total} samples of {} topics; dropped {}; undecodable {}; unknown types on [{}]",
        report.received.len(),
        dropped.values().sum::<u64>(),
        report.undecodable.values().sum::<u64>(),
        report
            .unknown
            .iter()
            .map(|(t, ty)| format!("{t} ({ty})"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // Then the rest goes to rerun: a file is always finished; a viewer gets the flush
    // time-out plus a margin, after which the process ends without waiting for it.
    drop(logger);
    #[expect(
        clippy::disallowed_methods,
        reason = "a grace for the process's exit behind a rerun viewer that stopped reading \
                  (transport): a virtual clock that stopped must not hold the exit"
    )]
    let done = tokio::time::timeout(patience, done_rx).await;
    if done.is_err() {
        tracing::warn!("the rerun viewer did not take the last data: stopping without it");
    }
    Ok(())
}

impl Sink {
    /// Open the sink off the async threads (spawning a viewer waits for it to listen).
    async fn open_blocking(self) -> anyhow::Result<(rerun::RecordingStream, String)> {
        tokio::task::spawn_blocking(move || {
            let rec = self.open()?;
            Ok((rec, self.describe()))
        })
        .await
        .map_err(|e| anyhow::anyhow!("opening the rerun sink failed: {e}"))?
    }
}

/// Ask `dr/snapshot` every 3 s while the viewer's copy of the DR wants one, and hand the reply to
/// the logging thread through the intake (as a sample of `dr/snapshot`).
async fn fetch_dr_snapshots(bus: interfaces::Bus, intake: Arc<Intake>, wants: Arc<AtomicBool>) {
    // Every 3 s of the component's clock.
    let mut tick = bus.clock().interval(Duration::from_secs(3));
    loop {
        tick.tick().await;
        if !wants.load(Ordering::Relaxed) {
            continue;
        }
        let Ok(snap) = bus
            .call(
                &topics::DR_SNAPSHOT,
                &SnapshotRequest::default(),
                Duration::from_secs(5),
            )
            .await
        else {
            continue;
        };
        match interfaces::codec::encode(&snap, SnapshotData::TYPE_NAME) {
            Ok(payload) => {
                tracing::info!(
                    nodes = snap.snapshot.nodes.len() + 1,
                    last_seq = snap.last_seq,
                    "DR snapshot for the viewer's copy"
                );
                wants.store(false, Ordering::Relaxed);
                intake.offer(Sample {
                    topic: topics::DR_SNAPSHOT.name().to_string(),
                    type_name: SnapshotData::TYPE_NAME.to_string(),
                    payload,
                    receipt_ns: interfaces::header::system_now_ns(),
                });
            }
            Err(e) => tracing::warn!("cannot re-encode the DR snapshot: {e}"),
        }
    }
}

/// `--help`'s text after the flags.
const AFTER_HELP: &str = "\
Where the data goes (one of):\n\
\x20 --spawn                 start a rerun viewer (the `rerun` executable on PATH, from\n\
\x20                         `pip install rerun-sdk==0.36.3`) and stream to it; the default\n\
\x20 --connect-viewer URL    stream to a running viewer's gRPC endpoint, e.g.\n\
\x20                         rerun+http://127.0.0.1:9876/proxy (start it with `rerun`)\n\
\x20 --save FILE.rrd         write a recording; open it later with `rerun FILE.rrd`\n\
\n\
Every topic of the namespace is picked up as it appears (or only --topics). Samples are\n\
decoded by their type name; unknown types and undecodable payloads are listed once, counted\n\
(view_unknown/<topic>, view_undecodable/<topic>) and skipped. A viewer slower than the robot\n\
makes this component drop samples (view_dropped/<topic>, also drawn under stats/), never the\n\
publishers wait. Camera frames are thinned to --image-hz.\n\
\n\
Examples:\n\
\x20 robocog view                                    # spawn a viewer, every topic\n\
\x20 robocog view --save game.rrd --game touch\n\
\x20 robocog view --connect-viewer rerun+http://10.0.0.5:9876/proxy --exclude audio/in";

/// The viewer's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// Start a rerun viewer and stream to it (the default when neither --save nor
    /// --connect-viewer is given).
    #[arg(long, conflicts_with_all = ["save", "connect_viewer"])]
    pub spawn: bool,
    /// Stream to a running rerun viewer at this gRPC URL (rerun+http://HOST:PORT/proxy).
    #[arg(long, value_name = "URL", conflicts_with = "save")]
    pub connect_viewer: Option<String>,
    /// Write everything to this .rrd file instead (finished on SIGTERM or Ctrl-C).
    #[arg(long, value_name = "FILE")]
    pub save: Option<PathBuf>,
    /// Only these topics (comma-separated). Default: every topic of the namespace.
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub topics: Vec<String>,
    /// Leave these topics out (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub exclude: Vec<String>,
    /// The layout of the views. Default: chosen from the topics present (Nao topics: coach;
    /// camera, body or ball topics: touch); rerun's automatic layout until one is seen.
    #[arg(long, value_enum)]
    pub game: Option<Game>,
    /// The robot's URDF (default: models/loki.urdf found beside the binaries or the current
    /// folder). Joint states and camera frames are drawn on it.
    #[arg(long, value_name = "FILE")]
    pub urdf: Option<PathBuf>,
    /// The SPL field model (default: models/spl_field.toml), for the coach game's field lines.
    #[arg(long, value_name = "FILE")]
    pub field: Option<PathBuf>,
    /// At most this many camera frames per second go to rerun (0: all of them; a 640x480 RGB-D
    /// frame is about 1.5 MB).
    #[arg(long, default_value_t = 10.0, value_name = "HZ")]
    pub image_hz: f64,
    /// At most this many samples wait for rerun; more are dropped (and counted).
    #[arg(long, default_value_t = 256, value_name = "N")]
    pub queue: usize,
    /// At most this many of them from one topic.
    #[arg(long, default_value_t = 32, value_name = "N")]
    pub queue_per_topic: usize,
}

/// The `viewer` component.
#[derive(Debug)]
pub struct Viewer;

impl interfaces::node::Component for Viewer {
    const NAME: &'static str = "viewer";
    const ABOUT: &'static str = "Logs the live topics of a robocog namespace to rerun.";
    const AFTER_HELP: &'static str = AFTER_HELP;
    type Config = Flags;
    type Prepared = Settings;

    fn interface(_: &Flags) -> Interface {
        interface()
    }

    fn prepare(config: Flags) -> anyhow::Result<Settings> {
        let sink = match (&config.save, &config.connect_viewer) {
            (Some(p), _) => Sink::Save(p.clone()),
            (None, Some(u)) => Sink::Connect(u.clone()),
            (None, None) => Sink::Spawn,
        };
        Ok(Settings {
            sink,
            topics: config.topics,
            exclude: config.exclude,
            game: config.game,
            urdf: config.urdf,
            field: config.field,
            image_hz: config.image_hz,
            queue: config.queue,
            queue_per_topic: config.queue_per_topic,
        })
    }

    async fn run(bus: Bus, prepared: Settings, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}
