//! `robocog replay`: publish a recording back onto a namespace.
//!
//! A reader thread walks the file from its first byte ([`crate::mcap_io::RecordingReader`]: no
//! summary needed) and hands messages through a small bounded queue to the publishing loop,
//! which paces them by their `log_time` (the time the recorder received them) scaled by
//! `--rate`. Payload bytes and type names go out exactly as recorded, so components decode them
//! and the headers keep their original stamps and sequence numbers.
//!
//! The recording's time goes out on `clock` ([`interfaces::msg::std_msgs::ClockTime`]) when a
//! component of the namespace follows it (subscribes to `clock`, `--clock bus`; unless
//! `--no-clock`): before each message, the log time of that message, and while paced, the
//! recorded time as it passes. Components started with `--clock bus` run their timers on it, so
//! they take the recorded steps at any rate. Across `--loop` passes the clock keeps going
//! forward (each pass starts just after the previous one ended).
//!
//! `--sync` names outputs of the graph the replay feeds (left out of the replay): at each
//! recorded message of such a topic, the replay moves the clock to its log time, then waits
//! (at most `--sync-timeout-s`) until the graph has published as many messages on the topic as
//! the recording had by then. So the replay never runs ahead of the graph: what a component
//! answered before a recorded input, it has answered before the replayed one, however fast the
//! replay goes.

use crate::mcap_io::{Damage, Recorded, RecordingReader};
use interfaces::msg::std_msgs::ClockTime;
use std::collections::{BTreeMap, HashMap};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Duration;
use tokio::time::Instant;

/// What `robocog replay --help` prints after the flags.
const ABOUT: &str = "\
Messages go out on their recorded topics with their recorded type names (so components decode\n\
them) and their exact bytes (so headers keep their original stamps), paced as they were\n\
received, scaled by --rate; or as fast as possible; or step by step (--step: a line on stdin,\n\
Enter on a terminal, publishes the next N messages).\n\
\n\
The recording's time goes out on `clock` when a component follows it (started with\n\
`--clock bus`; --no-clock: never), so its timers run on the recorded time at any rate. --sync T,...\n\
names topics the replayed graph publishes itself (not replayed): the replay waits for the\n\
graph's own message wherever the recording has one, so it never runs ahead of the graph.\n\
\n\
A truncated or corrupt file replays up to the damage, then the replay fails (exit code 1)\n\
with the problem and its byte offset, and how many messages were read before it.\n\
\n\
Examples:\n\
\x20 robocog replay game.mcap --namespace replay      # into a namespace of its own\n\
\x20 robocog replay game.mcap --rate 4 --topics vision/ball\n\
\x20 robocog replay game.mcap --step 10               # Enter publishes the next 10\n\
\x20 robocog replay game.mcap --as-fast-as-possible --sync vision/ball,executive/transitions";

/// The flags of `robocog replay`; what it does is told in [`ABOUT`].
#[derive(Debug, clap::Args)]
#[command(after_help = ABOUT)]
pub struct Args {
    #[command(flatten)]
    pub connect: interfaces::ConnectArgs,
    /// The MCAP file (written by `robocog record`).
    pub file: PathBuf,
    /// Speed factor on the recorded timing: 2 plays twice as fast, 0.5 at half speed.
    #[arg(long, default_value_t = 1.0, value_name = "X")]
    pub rate: f64,
    /// Publish back to back, without the recorded timing.
    #[arg(long, conflicts_with_all = ["rate", "step"])]
    pub as_fast_as_possible: bool,
    /// Step by step: wait for a line on stdin (Enter) before each N messages (default 1).
    #[arg(long, num_args = 0..=1, default_missing_value = "1", value_name = "N", conflicts_with = "rate")]
    pub step: Option<u64>,
    /// Replay only these topics (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub topics: Vec<String>,
    /// Leave these topics out (comma-separated).
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub exclude: Vec<String>,
    /// Start again from the beginning at the end, until interrupted.
    #[arg(long = "loop")]
    pub looping: bool,
    /// After joining the bus, wait this long for subscribers to be known before the first
    /// message (s), so the first messages are not published into the void.
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub wait_s: f64,
    /// Print progress on stderr this often (s); 0 for never.
    #[arg(long, default_value_t = 3.0, value_name = "S")]
    pub progress_s: f64,
    /// Do not publish the recording's time on `clock` (by default it is, when a component of the
    /// namespace follows it: started with `--clock bus`).
    #[arg(long)]
    pub no_clock: bool,
    /// Topics the replayed graph publishes itself (comma-separated): not replayed; at each
    /// recorded message of one, wait until the graph has published as many on it.
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub sync: Vec<String>,
    /// Longest wait for the graph's message on a --sync topic (s); after one such wait the topic
    /// is no longer waited for (the graph diverged from the recording, or is stuck).
    #[arg(long, default_value_t = 30.0, value_name = "S")]
    pub sync_timeout_s: f64,
}

/// How often the clock is published while the replay waits for the next message (wall time).
const CLOCK_TICK: Duration = Duration::from_millis(20);

/// The `clock` topic's publisher and the last time it published.
struct ClockOut {
    publisher: Option<interfaces::Publisher<ClockTime>>,
    last_ns: i64,
}

impl ClockOut {
    /// Publishes `t_ns` when it is later than the last time published.
    async fn to(&mut self, t_ns: i64) -> anyhow::Result<()> {
        if let Some(p) = &self.publisher
            && t_ns > self.last_ns
        {
            self.last_ns = t_ns;
            let mut msg = ClockTime {
                header: interfaces::Header {
                    stamp_ns: t_ns,
                    ..Default::default()
                },
                time_ns: t_ns,
            };
            p.publish(&mut msg)
                .await
                .map_err(|e| anyhow::anyhow!("publishing the clock: {e}"))?;
        }
        Ok(())
    }
}

/// The components of the namespace that follow the bus clock (they subscribe to `clock`).
async fn clock_followers(bus: &interfaces::Bus) -> anyhow::Result<Vec<String>> {
    let mut names: Vec<String> = bus
        .graph(Duration::from_secs(2))
        .await?
        .into_iter()
        .filter_map(|t| match t {
            interfaces::liveliness::Token::Subscriber {
                component, topic, ..
            } if topic == interfaces::topics::CLOCK.name() => Some(component),
            _ => None,
        })
        .collect();
    names.sort();
    names.dedup();
    Ok(names)
}

/// Counts what the graph publishes on a `--sync` topic.
struct SyncTopic {
    seen: tokio::sync::watch::Receiver<u64>,
    /// How many the graph must have published (the recording's count so far, this pass).
    expected: u64,
    /// The count when this pass started.
    base: u64,
    /// No longer waited for (a wait timed out).
    given_up: bool,
    _subscriber: interfaces::RawListener,
}

impl SyncTopic {
    async fn declare(bus: &interfaces::Bus, topic: &str) -> anyhow::Result<SyncTopic> {
        let (tx, seen) = tokio::sync::watch::channel(0u64);
        let subscriber = bus
            .raw_listener(topic, move |_| tx.send_modify(|n| *n += 1))
            .await
            .map_err(|e| anyhow::anyhow!("cannot subscribe to {topic}: {e}"))?;
        Ok(SyncTopic {
            seen,
            expected: 0,
            base: 0,
            given_up: false,
            _subscriber: subscriber,
        })
    }
}

/// What the reader thread sends.
enum Event {
    Message(Recorded),
    /// The file ended cleanly; `looping` says whether it starts over.
    End,
    Damage {
        damage: Damage,
        read: u64,
    },
}

#[expect(
    clippy::disallowed_methods,
    reason = "the replay paces the recording on the wall and publishes its time on `clock`: it is the clock source"
)]
pub async fn execute(args: Args) -> anyhow::Result<i32> {
    for t in args.topics.iter().chain(&args.exclude).chain(&args.sync) {
        super::topic::check_topic(t)?;
    }
    if !(args.sync_timeout_s > 0.0 && args.sync_timeout_s.is_finite()) {
        anyhow::bail!("--sync-timeout-s must be a positive number");
    }
    if !(args.rate > 0.0 && args.rate.is_finite()) {
        anyhow::bail!("--rate must be a positive number");
    }
    if args.step == Some(0) {
        anyhow::bail!("--step takes a positive number of messages");
    }
    // Fail early, before joining the bus, when the file cannot be opened at all.
    let first = RecordingReader::open(&args.file)
        .map_err(|e| anyhow::anyhow!("cannot open {}: {e}", args.file.display()))?;
    let file_len = first.file_len();
    let bus = super::cli_bus(&args.connect).await?;
    let ns = bus.namespace().to_string();

    // The reader thread: blocking file I/O, off the runtime.
    let (tx, mut rx) = tokio::sync::mpsc::channel::<Event>(64);
    {
        let path = args.file.clone();
        let topics = args.topics.clone();
        let exclude = args.exclude.clone();
        let sync = args.sync.clone();
        let looping = args.looping;
        std::thread::Builder::new()
            .name("replay-reader".into())
            .spawn(move || {
                let mut reader = first;
                loop {
                    while let Some(m) = reader.next() {
                        let event = match m {
                            Ok(m) => {
                                let selected = (topics.is_empty() || topics.contains(&m.topic))
                                    && !exclude.contains(&m.topic);
                                if !selected && !sync.contains(&m.topic) {
                                    continue;
                                }
                                Event::Message(m)
                            }
                            Err(damage) => Event::Damage {
                                damage,
                                read: reader.messages_read,
                            },
                        };
                        let stop = matches!(event, Event::Damage { .. });
                        if tx.blocking_send(event).is_err() || stop {
                            return;
                        }
                    }
                    if tx.blocking_send(Event::End).is_err() || !looping {
                        return;
                    }
                    reader = match RecordingReader::open(&path) {
                        Ok(r) => r,
                        Err(source) => {
                            let _ = tx.blocking_send(Event::Damage {
                                damage: Damage::Io { offset: 0, source },
                                read: 0,
                            });
                            return;
                        }
                    };
                }
            })?;
    }

    let mode = if let Some(n) = args.step {
        format!("step by step, {n} message(s) per line on stdin")
    } else if args.as_fast_as_possible {
        "as fast as possible".to_string()
    } else {
        format!("at {}x the recorded rate", args.rate)
    };
    let mut sync: HashMap<String, SyncTopic> = HashMap::new();
    for t in &args.sync {
        sync.insert(t.clone(), SyncTopic::declare(&bus, t).await?);
    }
    let sync_timeout = Duration::from_secs_f64(args.sync_timeout_s);
    let (mut sync_waits, mut sync_waited) = (0u64, Duration::ZERO);
    tokio::time::sleep(Duration::from_secs_f64(args.wait_s.max(0.0))).await;
    // The clock goes out when a component of the namespace follows it (`--clock bus`).
    let followers = if args.no_clock {
        Vec::new()
    } else {
        clock_followers(&bus).await?
    };
    let mut clock = ClockOut {
        publisher: if followers.is_empty() {
            None
        } else {
            Some(bus.publisher(&interfaces::topics::CLOCK).await?)
        },
        last_ns: i64::MIN,
    };
    eprintln!(
        "replaying {} ({:.1} MB) into namespace {ns:?}, {mode}{}{}{}",
        args.file.display(),
        file_len as f64 / 1e6,
        if args.looping { ", looping" } else { "" },
        if followers.is_empty() {
            String::new()
        } else {
            format!(", its time on `clock` for {}", followers.join(", "))
        },
        if args.sync.is_empty() {
            String::new()
        } else {
            format!(", in step with the graph's {}", args.sync.join(", "))
        }
    );

    let mut publishers: HashMap<(String, String), Option<Outlet>> = HashMap::new();
    let mut per_topic: BTreeMap<String, u64> = BTreeMap::new();
    let mut skipped: BTreeMap<String, (u64, String)> = BTreeMap::new();
    let mut published = 0u64;
    let mut passes = 0u64;
    let started = Instant::now();
    // Pacing: wall-clock instant of the first message of this pass, and its log time.
    let mut base: Option<(Instant, u64)> = None;
    // Log time of the first message of this pass, for the progress line.
    let mut first_log: Option<u64> = None;
    let progress = (args.progress_s > 0.0).then(|| Duration::from_secs_f64(args.progress_s));
    let mut next_report = progress.map(|p| Instant::now() + p);
    let mut step_left = 0u64;
    let interactive = std::io::stdin().is_terminal();
    let mut sigterm = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
    let mut damage: Option<(Damage, u64)> = None;
    let mut stopped: Option<&str> = None;
    // Added to log times for the clock: 0 on the first pass, then what keeps it going forward.
    let mut clock_offset: i64 = 0;

    'replay: loop {
        let event = tokio::select! {
            e = rx.recv() => e,
            _ = tokio::signal::ctrl_c() => { stopped = Some("interrupted"); break; }
            _ = sigterm.recv() => { stopped = Some("terminated"); break; }
        };
        let Some(event) = event else { break };
        let m = match event {
            Event::Message(m) => m,
            Event::End => {
                passes += 1;
                base = None;
                first_log = None;
                for s in sync.values_mut() {
                    s.base = *s.seen.borrow();
                    s.expected = 0;
                }
                if args.looping {
                    eprintln!("replay: end of the recording (pass {passes}), starting over");
                    continue;
                }
                break;
            }
            Event::Damage { damage: d, read } => {
                damage = Some((d, read));
                break;
            }
        };
        let log_time = m.log_time_ns;
        if first_log.is_none() && passes > 0 && clock.publisher.is_some() {
            // The next pass starts a millisecond after the last one ended, on the clock.
            clock_offset = clock.last_ns.saturating_add(1_000_000) - log_time as i64;
        }
        let log0 = *first_log.get_or_insert(log_time);
        let clock_ns = (log_time as i64).saturating_add(clock_offset);

        // Pace.
        if let Some(n) = args.step
            && !sync.contains_key(&m.topic)
        {
            if step_left == 0 {
                if interactive {
                    eprint!(
                        "next: {} {} stamp {:.3} s, Enter for {n} message(s), Ctrl-D to stop: ",
                        m.topic,
                        m.type_name,
                        m.publish_time_ns as f64 * 1e-9
                    );
                }
                let line = tokio::task::spawn_blocking(|| {
                    let mut s = String::new();
                    std::io::stdin().read_line(&mut s).map(|n| n > 0)
                });
                let more = tokio::select! {
                    r = line => matches!(r, Ok(Ok(true))),
                    _ = tokio::signal::ctrl_c() => false,
                    _ = sigterm.recv() => false,
                };
                if !more {
                    stopped = Some("stdin closed");
                    break;
                }
                step_left = n;
            }
            step_left -= 1;
        } else if args.step.is_none() && !args.as_fast_as_possible {
            match base {
                None => base = Some((Instant::now(), m.log_time_ns)),
                Some((wall0, log0)) => {
                    let offset_s = m.log_time_ns.saturating_sub(log0) as f64 * 1e-9 / args.rate;
                    let at = wall0 + Duration::from_secs_f64(offset_s);
                    // The clock moves on while the replay waits for the message's time.
                    loop {
                        let now = Instant::now();
                        if now >= at {
                            break;
                        }
                        let wake = if clock.publisher.is_some() {
                            at.min(now + CLOCK_TICK)
                        } else {
                            at
                        };
                        tokio::select! {
                            _ = tokio::time::sleep_until(wake) => {}
                            _ = tokio::signal::ctrl_c() => { stopped = Some("interrupted"); break 'replay; }
                            _ = sigterm.recv() => { stopped = Some("terminated"); break 'replay; }
                        }
                        let passed = Instant::now().saturating_duration_since(wall0);
                        let recorded = (passed.as_secs_f64() * args.rate * 1e9) as i64;
                        let t = (log0 as i64)
                            .saturating_add(recorded)
                            .saturating_add(clock_offset)
                            .min(clock_ns);
                        clock.to(t).await?;
                    }
                }
            }
        }

        // The clock first: what the message causes happens at its time. It replaces a recorded
        // clock.
        if clock.publisher.is_some() && m.topic == interfaces::topics::CLOCK.name() {
            continue;
        }
        clock.to(clock_ns).await?;

        // A graph's output: wait for the graph's own.
        if let Some(s) = sync.get_mut(&m.topic) {
            s.expected += 1;
            if !s.given_up {
                let need = s.base + s.expected;
                let waited = Instant::now();
                let got = tokio::select! {
                    r = tokio::time::timeout(sync_timeout, s.seen.wait_for(|n| *n >= need)) => r.is_ok(),
                    _ = tokio::signal::ctrl_c() => { stopped = Some("interrupted"); break; }
                    _ = sigterm.recv() => { stopped = Some("terminated"); break; }
                };
                if waited.elapsed() > Duration::from_millis(1) {
                    sync_waits += 1;
                    sync_waited += waited.elapsed();
                }
                if !got {
                    s.given_up = true;
                    eprintln!(
                        "replay: warning: the graph has published {} message(s) on {} where the recording had {} by {:.3} s; no longer waiting for it (the graph diverged from the recording, or is stuck)",
                        *s.seen.borrow() - s.base,
                        m.topic,
                        s.expected,
                        log_time.saturating_sub(log0) as f64 * 1e-9
                    );
                }
            }
            continue;
        }

        // Publish.
        let key = (m.topic.clone(), m.type_name.clone());
        if !publishers.contains_key(&key) {
            let outlet = match Outlet::check(&m) {
                Err(why) => {
                    eprintln!(
                        "replay: skipping topic {:?} ({}): {why}",
                        m.topic, m.type_name
                    );
                    skipped.insert(m.topic.clone(), (0, why));
                    None
                }
                Ok(()) => Some(Outlet::declare(&bus, &m.topic, &m.type_name).await?),
            };
            publishers.insert(key.clone(), outlet);
        }
        match publishers.get(&key).and_then(Option::as_ref) {
            Some(outlet) => {
                outlet
                    .publisher
                    .put_with_seq(m.data, u64::from(m.sequence))
                    .await
                    .map_err(|e| anyhow::anyhow!("publishing on {}: {e}", m.topic))?;
                published += 1;
                *per_topic.entry(m.topic).or_default() += 1;
            }
            None => {
                if let Some(s) = skipped.get_mut(&m.topic) {
                    s.0 += 1;
                }
            }
        }

        if let (Some(p), Some(at)) = (progress, next_report)
            && Instant::now() >= at
        {
            next_report = Some(Instant::now() + p);
            let recorded_s = log_time.saturating_sub(log0) as f64 * 1e-9;
            let topics: Vec<String> = per_topic.iter().map(|(t, n)| format!("{t} {n}")).collect();
            eprintln!(
                "replay {:.0} s: {published} messages published, {recorded_s:.1} s of recording | {}",
                started.elapsed().as_secs_f64(),
                topics.join(", ")
            );
        }
    }

    // Let zenoh push the last samples out before the session closes.
    tokio::time::sleep(Duration::from_millis(200)).await;
    let elapsed = started.elapsed().as_secs_f64();
    eprintln!(
        "replayed {published} messages in {elapsed:.1} s{}",
        stopped.map(|s| format!(" ({s})")).unwrap_or_default()
    );
    for (topic, n) in &per_topic {
        eprintln!("  {topic:30} {n:>8} msgs");
    }
    for (topic, (n, why)) in &skipped {
        eprintln!("  {topic:30} {n:>8} msgs SKIPPED: {why}");
    }
    if !sync.is_empty() {
        eprintln!(
            "  waited for the graph {sync_waits} time(s), {:.1} s in all",
            sync_waited.as_secs_f64()
        );
    }
    if published == 0 && !args.topics.is_empty() && damage.is_none() {
        eprintln!(
            "warning: no message of {} in {}",
            args.topics.join(", "),
            args.file.display()
        );
    }
    if let Some((d, read)) = damage {
        eprintln!(
            "error: {} is damaged: {d}\n{read} messages were read before the damage{}",
            args.file.display(),
            if read > 0 {
                " and were replayed (those selected)"
            } else {
                ""
            }
        );
        return Ok(1);
    }
    Ok(0)
}

/// A publisher for one (topic, type) of the recording, announced like a component's.
struct Outlet {
    publisher: interfaces::RawPublisher,
}

impl Outlet {
    /// Whether a recorded channel can go onto a robocog namespace.
    fn check(m: &Recorded) -> Result<(), String> {
        if m.message_encoding != crate::mcap_io::MESSAGE_ENCODING {
            return Err(format!(
                "message encoding {:?}, not cdr",
                m.message_encoding
            ));
        }
        if !interfaces::topic::is_valid_name(&m.topic) {
            return Err("not a valid robocog topic name".into());
        }
        if !interfaces::raw::is_valid_type_name(&m.type_name) {
            return Err(format!("no usable type name ({:?})", m.type_name));
        }
        if let Some(why) = &m.wire_mismatch {
            return Err(why.clone());
        }
        Ok(())
    }

    async fn declare(bus: &interfaces::Bus, topic: &str, type_name: &str) -> anyhow::Result<Self> {
        let publisher = bus
            .raw_publisher(topic, type_name, "robocog-replay")
            .await
            .map_err(|e| anyhow::anyhow!("cannot publish on {topic}: {e}"))?;
        if interfaces::msg::lookup(type_name).is_err() {
            eprintln!(
                "replay: warning: {type_name} (on {topic}) is not a type of this build; published anyway"
            );
        }
        Ok(Self { publisher })
    }
}
