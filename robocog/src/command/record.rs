//! `robocog record`: every topic of a namespace (or a selection) into an MCAP file.
//!
//! Samples are taken by a bus callback ([`interfaces::Bus::raw_listener`]), copied once and queued to a writer thread through a
//! bounded queue (messages and bytes): a slow disk makes the recorder drop samples, counted per
//! topic and reported, and never slows the publishers. The file layout is described in
//! [`crate::mcap_io`].

use crate::mcap_io::{self, RecordWriter};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What `robocog record --help` prints after the flags.
const ABOUT: &str = "\
One channel per topic (its robocog name), message encoding `cdr`, one schema per message type\n\
as ROS 2 tools read it (rosbag2's convention: named robocog_msgs/msg/<Type>, encoding\n\
`ros2msg`, the full .msg definition; see `robocog interface`), so Foxglove, mcap-ros2-support\n\
and rosbags decode the file. A type ROS 2 cannot describe (the deep representation's tagged\n\
unions) gets robocog's own schema (`robocog.msg-shape+json`). Payloads are the exact bytes of\n\
the bus (CDR with its 4-byte encapsulation header); log_time is the receive time,\n\
publish_time the message header's stamp, sequence its seq. Topics that appear while\n\
recording are picked up.\n\
\n\
Stops after --duration-s, or on Ctrl-C / SIGTERM, and then finishes the file (summary and\n\
indexes). Killed without warning, the file still replays up to the last flush (--flush-s).\n\
Samples the disk cannot keep up with are dropped, counted per topic and reported, never\n\
silently; leave heavy streams out with --exclude.\n\
\n\
Examples:\n\
\x20 robocog record -o game.mcap                      # everything, until Ctrl-C\n\
\x20 robocog record --exclude vision/rgbd --duration-s 60\n\
\x20 robocog record --topics executive/transitions,vision/ball";

/// The flags of `robocog record`; what it does is told in [`ABOUT`].
#[derive(Debug, clap::Args)]
#[command(after_help = ABOUT)]
pub struct Args {
    #[command(flatten)]
    pub connect: interfaces::ConnectArgs,
    /// The MCAP file to write (default: <namespace>-<UTC date>-<time>.mcap in the current folder).
    #[arg(long, short)]
    pub output: Option<PathBuf>,
    /// Record only these topics (comma-separated). Default: every topic of the namespace.
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub topics: Vec<String>,
    /// Leave these topics out (comma-separated), e.g. camera frames.
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub exclude: Vec<String>,
    /// Stop after this many seconds (default: until Ctrl-C or SIGTERM).
    #[arg(long, value_name = "S")]
    pub duration_s: Option<f64>,
    /// At most this many samples wait for the disk, half of them at most from one topic; more are
    /// dropped (and counted).
    #[arg(long, default_value_t = 8192, value_name = "N")]
    pub queue: usize,
    /// At most this many megabytes of samples wait for the disk; more are dropped (and counted).
    #[arg(long, default_value_t = 512, value_name = "MB")]
    pub queue_mb: usize,
    /// Write what was received to disk at least this often (s): the most a kill can lose.
    #[arg(long, default_value_t = 1.0, value_name = "S")]
    pub flush_s: f64,
    /// Print the counts per topic on stderr this often (s); 0 for never.
    #[arg(long, default_value_t = 3.0, value_name = "S")]
    pub progress_s: f64,
}

/// One sample on its way to the disk.
struct Item {
    topic: String,
    type_name: String,
    log_time_ns: u64,
    /// The publisher's sequence number (the sample's attachment).
    seq: Option<u64>,
    payload: Vec<u8>,
}

#[derive(Debug, Default, Clone)]
struct TopicStats {
    types: Vec<String>,
    /// Written to the file.
    written: u64,
    bytes: u64,
    /// Dropped because the queue was full.
    dropped: u64,
    /// In the queue now.
    queued: usize,
}

#[derive(Debug, Default)]
struct Stats {
    topics: BTreeMap<String, TopicStats>,
    /// Samples whose encoding named no type (not from a robocog publisher): not recorded.
    untyped: u64,
}

impl Stats {
    fn totals(&self) -> (u64, u64, u64) {
        self.topics.values().fold((0, 0, 0), |(w, b, d), t| {
            (w + t.written, b + t.bytes, d + t.dropped)
        })
    }
}

/// What the writer thread reports when it is done.
struct WriterReport {
    headerless: u64,
}

/// Write one sample and count it.
fn store(
    writer: &mut RecordWriter,
    stats: &Mutex<Stats>,
    in_flight: &AtomicUsize,
    item: Item,
) -> Result<(), mcap_io::WriteError> {
    let len = item.payload.len();
    let result = writer.write(
        &item.topic,
        &item.type_name,
        item.log_time_ns,
        item.seq,
        &item.payload,
    );
    in_flight.fetch_sub(len, Ordering::AcqRel);
    let mut s = lock(stats);
    let t = s.topics.entry(item.topic).or_default();
    t.queued = t.queued.saturating_sub(1);
    result?;
    if !t.types.contains(&item.type_name) {
        t.types.push(item.type_name);
    }
    t.written += 1;
    t.bytes += len as u64;
    Ok(())
}

fn lock(stats: &Mutex<Stats>) -> std::sync::MutexGuard<'_, Stats> {
    stats.lock().unwrap_or_else(|p| p.into_inner())
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    for t in args.topics.iter().chain(&args.exclude) {
        super::topic::check_topic(t)?;
    }
    if !(args.flush_s > 0.0 && args.flush_s.is_finite()) {
        anyhow::bail!("--flush-s must be a positive number of seconds");
    }
    if let Some(d) = args.duration_s
        && !(d > 0.0 && d.is_finite())
    {
        anyhow::bail!("--duration-s must be a positive number of seconds");
    }
    let bus = super::cli_bus(&args.connect).await?;
    let ns = bus.namespace().to_string();
    let path = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{ns}-{}.mcap", utc_stamp())));
    let mut writer = RecordWriter::create(&path, &ns)?;

    let stats = Arc::new(Mutex::new(Stats::default()));
    // `stop`: the callbacks take no more samples; `done`: the writer drains the queue and ends.
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicBool::new(false));
    let in_flight = Arc::new(AtomicUsize::new(0));
    let max_bytes = args.queue_mb.max(1).saturating_mul(1 << 20);
    let (tx, rx) = std::sync::mpsc::sync_channel::<Item>(args.queue.max(1));

    // The writer thread: the only place that touches the file.
    let flush_every = Duration::from_secs_f64(args.flush_s);
    #[expect(
        clippy::disallowed_methods,
        reason = "the writer thread flushes the file to the disk on the wall"
    )]
    let writer_thread = {
        let stats = stats.clone();
        let stop = stop.clone();
        let done = done.clone();
        let in_flight = in_flight.clone();
        std::thread::Builder::new()
            .name("record-writer".into())
            .spawn(
                move || -> Result<(RecordWriter, WriterReport), mcap_io::WriteError> {
                    let mut last_flush = Instant::now();
                    let mut dirty = false;
                    loop {
                        let wait = flush_every
                            .saturating_sub(last_flush.elapsed())
                            .clamp(Duration::from_millis(1), Duration::from_millis(50));
                        match rx.recv_timeout(wait) {
                            Ok(item) => {
                                if let Err(e) = store(&mut writer, &stats, &in_flight, item) {
                                    stop.store(true, Ordering::Release);
                                    return Err(e);
                                }
                                dirty = true;
                            }
                            Err(RecvTimeoutError::Timeout) => {}
                            Err(RecvTimeoutError::Disconnected) => break,
                        }
                        if dirty && last_flush.elapsed() >= flush_every {
                            writer.flush()?;
                            dirty = false;
                            last_flush = Instant::now();
                        }
                        // Once the subscriptions are gone, drain what is queued, then finish.
                        if done.load(Ordering::Acquire) {
                            while let Ok(item) = rx.try_recv() {
                                store(&mut writer, &stats, &in_flight, item)?;
                            }
                            break;
                        }
                    }
                    let headerless = writer.headerless;
                    Ok((writer, WriterReport { headerless }))
                },
            )?
    };

    // Subscriptions: one per selected topic, or one for the whole namespace.
    let patterns: Vec<&str> = if args.topics.is_empty() {
        vec![interfaces::raw::EVERY_TOPIC]
    } else {
        args.topics.iter().map(String::as_str).collect()
    };
    let exclude: Arc<Vec<String>> = Arc::new(args.exclude.clone());
    let mut subscribers = Vec::new();
    for pattern in patterns {
        let cb = Callback {
            exclude: exclude.clone(),
            tx: tx.clone(),
            stats: stats.clone(),
            stop: stop.clone(),
            in_flight: in_flight.clone(),
            max_bytes,
            per_topic: (args.queue / 2).max(1),
        };
        let sub = bus
            .raw_listener(pattern, move |sample| cb.take(sample))
            .await
            .map_err(|e| anyhow::anyhow!("cannot subscribe to {pattern}: {e}"))?;
        subscribers.push(sub);
    }
    drop(tx);
    #[expect(
        clippy::disallowed_methods,
        reason = "a recording of the live bus: its length is the wall's"
    )]
    let started = Instant::now();
    let started_ns = interfaces::header::system_now_ns();
    eprintln!(
        "recording namespace {ns:?} to {} ({}{}); Ctrl-C to stop",
        path.display(),
        if args.topics.is_empty() {
            "every topic".to_string()
        } else {
            args.topics.join(", ")
        },
        if args.exclude.is_empty() {
            String::new()
        } else {
            format!(" except {}", args.exclude.join(", "))
        }
    );
    if let Ok(graph) = bus.graph(Duration::from_millis(700)).await {
        let mut published: Vec<String> = graph
            .iter()
            .filter_map(|t| match t {
                interfaces::liveliness::Token::Publisher {
                    topic, type_name, ..
                } => Some(format!("{topic} ({type_name})")),
                _ => None,
            })
            .collect();
        published.sort();
        published.dedup();
        if published.is_empty() {
            eprintln!("no publisher in the graph yet; topics are picked up as they appear");
        } else {
            eprintln!("published now: {}", published.join(", "));
        }
    }

    // Run until told to stop, printing progress.
    #[expect(
        clippy::disallowed_methods,
        reason = "a recording of the live bus: its duration and progress reports are the wall's"
    )]
    let why = {
        let mut sigterm =
            tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
        let until = args
            .duration_s
            .map(|d| tokio::time::Instant::now() + Duration::from_secs_f64(d));
        let progress = (args.progress_s > 0.0).then(|| Duration::from_secs_f64(args.progress_s));
        let mut next_report = progress.map(|p| tokio::time::Instant::now() + p);
        loop {
            let far = tokio::time::Instant::now() + Duration::from_secs(3600);
            tokio::select! {
                _ = tokio::signal::ctrl_c() => break "interrupted",
                _ = sigterm.recv() => break "terminated",
                _ = tokio::time::sleep_until(until.unwrap_or(far)), if until.is_some() => break "duration reached",
                _ = tokio::time::sleep_until(next_report.unwrap_or(far)), if next_report.is_some() => {
                    next_report = progress.map(|p| tokio::time::Instant::now() + p);
                    eprintln!("{}", progress_line(started.elapsed(), &lock(&stats)));
                }
                _ = tokio::time::sleep(Duration::from_millis(200)) => {}
            }
            if writer_thread.is_finished() {
                break "the writer stopped";
            }
        }
    };

    // Stop taking samples, let the writer drain the queue, and finish the file.
    stop.store(true, Ordering::Release);
    for s in subscribers {
        let _ = s.undeclare().await;
    }
    // A callback that passed the stop check just before it was set has finished by now.
    #[expect(
        clippy::disallowed_methods,
        reason = "lets the transport's last callbacks finish, on the wall"
    )]
    tokio::time::sleep(Duration::from_millis(100)).await;
    done.store(true, Ordering::Release);
    let elapsed = started.elapsed();
    let joined = tokio::task::spawn_blocking(move || writer_thread.join())
        .await
        .map_err(|e| anyhow::anyhow!("the writer thread failed: {e}"))?;
    let (writer, report) = match joined {
        Ok(Ok(r)) => r,
        Ok(Err(e)) => anyhow::bail!("recording to {} failed: {e}", path.display()),
        Err(_) => anyhow::bail!(
            "the writer thread panicked; {} is incomplete",
            path.display()
        ),
    };
    let s = lock(&stats);
    let mut metadata = BTreeMap::from([
        ("namespace".to_string(), ns.clone()),
        ("started_ns".to_string(), started_ns.to_string()),
        (
            "ended_ns".to_string(),
            interfaces::header::system_now_ns().to_string(),
        ),
        ("untyped_samples".to_string(), s.untyped.to_string()),
        (
            "headerless_messages".to_string(),
            report.headerless.to_string(),
        ),
    ]);
    for (topic, t) in &s.topics {
        metadata.insert(format!("dropped/{topic}"), t.dropped.to_string());
    }
    writer
        .finish(metadata)
        .map_err(|e| anyhow::anyhow!("finishing {} failed: {e}", path.display()))?;

    let (written, bytes, dropped) = s.totals();
    let secs = elapsed.as_secs_f64().max(1e-9);
    let mut out = std::io::stderr().lock();
    let _ = writeln!(
        out,
        "recorded {written} messages ({:.1} MB) in {:.1} s to {} ({why}); {dropped} dropped",
        bytes as f64 / 1e6,
        secs,
        path.display()
    );
    for (topic, t) in &s.topics {
        let _ = writeln!(
            out,
            "  {topic:30} {:24} {:>8} msgs {:>9.2} Hz {:>10.1} kB{}",
            t.types.join("|"),
            t.written,
            t.written as f64 / secs,
            t.bytes as f64 / 1e3,
            if t.dropped > 0 {
                format!(
                    "  {} DROPPED (disk too slow: --exclude it, or raise --queue-mb)",
                    t.dropped
                )
            } else {
                String::new()
            }
        );
    }
    for topic in &args.topics {
        if s.topics
            .get(topic)
            .is_none_or(|t| t.written + t.dropped == 0)
        {
            let _ = writeln!(out, "  {topic:30} no message (nobody published it)");
        }
    }
    if s.untyped > 0 {
        let _ = writeln!(
            out,
            "  {} samples carried no type name (not from a robocog publisher) and were not recorded",
            s.untyped
        );
    }
    if report.headerless > 0 {
        let _ = writeln!(
            out,
            "  {} messages had no decodable header: their publish_time is their receive time",
            report.headerless
        );
    }
    Ok(0)
}

/// What the bus callback needs. The callback runs on zenoh's threads: it never blocks.
struct Callback {
    exclude: Arc<Vec<String>>,
    tx: SyncSender<Item>,
    stats: Arc<Mutex<Stats>>,
    stop: Arc<AtomicBool>,
    in_flight: Arc<AtomicUsize>,
    max_bytes: usize,
    /// Most samples of one topic in the queue at once.
    per_topic: usize,
}

impl Callback {
    fn take(&self, mut sample: interfaces::RawSample) {
        if self.stop.load(Ordering::Acquire) {
            return;
        }
        let topic = std::mem::take(&mut sample.topic);
        let topic = topic.as_str();
        if self.exclude.iter().any(|e| e == topic) {
            return;
        }
        let log_time_ns = u64::try_from(sample.receipt_ns).unwrap_or(0);
        let Some(type_name) = sample.type_name.take() else {
            lock(&self.stats).untyped += 1;
            return;
        };
        let len = sample.payload_len();
        // Admission: room in the byte budget, and this topic holds at most its share of the
        // queue, so a flood on one topic cannot crowd the others out.
        let admitted = {
            let mut s = lock(&self.stats);
            let t = s.topics.entry(topic.to_string()).or_default();
            let queued = self.in_flight.load(Ordering::Acquire);
            let fits = queued == 0 || queued + len <= self.max_bytes;
            if fits && t.queued < self.per_topic {
                t.queued += 1;
                self.in_flight.fetch_add(len, Ordering::AcqRel);
                true
            } else {
                false
            }
        };
        let accepted = admitted && {
            let item = Item {
                topic: topic.to_string(),
                type_name,
                log_time_ns,
                seq: sample.seq,
                payload: sample.into_payload(),
            };
            match self.tx.try_send(item) {
                Ok(()) => true,
                Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => false,
            }
        };
        if !accepted {
            let mut s = lock(&self.stats);
            let t = s.topics.entry(topic.to_string()).or_default();
            if admitted {
                t.queued -= 1;
                self.in_flight.fetch_sub(len, Ordering::AcqRel);
            }
            t.dropped += 1;
            if t.dropped.is_power_of_two() {
                tracing::warn!(
                    "record: queue full, dropped {} samples of {topic} so far (disk too slow)",
                    t.dropped
                );
            }
        }
    }
}

fn progress_line(elapsed: Duration, s: &Stats) -> String {
    let (written, bytes, dropped) = s.totals();
    let mut line = format!(
        "record {:.0} s: {written} messages, {:.1} MB, {dropped} dropped |",
        elapsed.as_secs_f64(),
        bytes as f64 / 1e6
    );
    for (topic, t) in &s.topics {
        line.push_str(&format!(" {topic} {}", t.written));
        if t.dropped > 0 {
            line.push_str(&format!(" ({} dropped)", t.dropped));
        }
        line.push(',');
    }
    line.pop();
    line
}

/// `YYYYmmdd-HHMMSS` in UTC, for default file names.
fn utc_stamp() -> String {
    let secs = interfaces::header::system_now_ns().div_euclid(1_000_000_000);
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}{m:02}{d:02}-{:02}{:02}{:02}",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}
