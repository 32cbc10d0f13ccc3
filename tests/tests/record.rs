#![allow(clippy::unwrap_used)]
//! `robocog record` and `robocog replay` between real processes: a talker graph is recorded,
//! stopped with SIGTERM, the MCAP file is checked with the `mcap` crate, replayed into fresh
//! namespaces (bytes, order and timing compared with what a test subscriber receives), and
//! damaged copies are replayed (clear error, readable part replayed, no panic).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::std_msgs::Counter64;
use interfaces::msg::vision::{Intrinsics, RgbdFrame};
use interfaces::{Bus, ConnectArgs};
use robocog_tests::*;
use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What a test subscriber received on every topic of a namespace.
type Received = Arc<Mutex<Vec<(Instant, String, String, Vec<u8>)>>>;

/// A subscriber on every topic of `ns`: (arrival, topic, type name of the encoding, payload).
struct Tap {
    got: Received,
    _sub: interfaces::RawListener,
    _bus: Bus,
}

async fn tap(launch: &Launch, ns: &str) -> Tap {
    let bus = Bus::open(&ConnectArgs::to_router(&launch.endpoint, ns), "test-tap")
        .await
        .unwrap();
    let got: Received = Arc::default();
    let g = got.clone();
    let sub = bus
        .raw_listener(interfaces::raw::EVERY_TOPIC, move |s| {
            g.lock().unwrap().push((
                Instant::now(),
                s.topic.clone(),
                s.type_name.clone().unwrap_or_default(),
                s.into_payload(),
            ));
        })
        .await
        .unwrap();
    Tap {
        got,
        _sub: sub,
        _bus: bus,
    }
}

impl Tap {
    fn len(&self) -> usize {
        self.got.lock().unwrap().len()
    }
    fn wait_for(&self, n: usize, timeout: Duration) {
        eventually(&format!("{n} messages on the tap"), timeout, || {
            (self.len() >= n).then_some(())
        });
        // Anything more would be a duplicate: give it a moment to show up.
        std::thread::sleep(Duration::from_millis(200));
    }
}

fn replay(launch: &Launch, ns: &str, file: &Path, extra: &[&str]) -> std::process::Output {
    let mut args: Vec<String> = vec!["replay".into(), file.display().to_string()];
    args.extend(extra.iter().map(|s| s.to_string()));
    args.extend([
        "--namespace".into(),
        ns.into(),
        "--connect".into(),
        launch.endpoint.clone(),
        "--wait-s".into(),
        "0.5".into(),
    ]);
    run(&bin("robocog"), &args, Duration::from_secs(60))
}

/// Inter-arrival gaps (s) against the recorded gaps scaled by `rate`: (p50, p90 abs error in s,
/// replayed span, expected span).
fn timing(
    got: &[(Instant, String, String, Vec<u8>)],
    rec: &[Rec],
    rate: f64,
) -> (f64, f64, f64, f64) {
    let mut errs: Vec<f64> = (1..got.len())
        .map(|i| {
            let replayed = got[i].0.duration_since(got[i - 1].0).as_secs_f64();
            let recorded = (rec[i].log_time - rec[i - 1].log_time) as f64 * 1e-9 / rate;
            (replayed - recorded).abs()
        })
        .collect();
    errs.sort_by(f64::total_cmp);
    let p = |q: f64| errs[((errs.len() - 1) as f64 * q).round() as usize];
    let span = got.last().unwrap().0.duration_since(got[0].0).as_secs_f64();
    let expected = (rec.last().unwrap().log_time - rec[0].log_time) as f64 * 1e-9 / rate;
    (p(0.5), p(0.9), span, expected)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_recording_replays_the_same_bytes_in_order_on_time_and_survives_damage() {
    let ns = unique_namespace("record");
    let dir = scratch(&ns);
    let m = write_manifest(
        &dir,
        "graph.toml",
        r#"
[[component]]
name = "talker"
binary = "@FIXTURE@"
args = ["--role", "talker", "--rate", "20"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("talker up", Duration::from_secs(20), |l| {
            l.contains("talker is up")
        });

    // Record for about 3 s, then SIGTERM.
    let file = dir.join("talk.mcap");
    let log = dir.join("record.log");
    let mut rec = start_tool(
        &launch,
        &ns,
        &[
            "record",
            "--output",
            &file.display().to_string(),
            "--flush-s",
            "0.5",
            "--progress-s",
            "1",
        ],
        &log,
    );
    log_wait(&log, "the recorder", Duration::from_secs(20), |l| {
        l.starts_with("recording namespace")
    });
    std::thread::sleep(Duration::from_secs(3));
    log_wait(&log, "a progress line", Duration::from_secs(5), |l| {
        l.starts_with("record ") && l.contains("chatter")
    });
    let status = sigterm_and_wait(&mut rec, &log);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "{text}");
    assert!(
        text.contains("recorded ") && text.contains("(terminated); 0 dropped"),
        "{text}"
    );

    // The file, read with the mcap crate.
    let (summary, msgs, meta) = read_recording(&file);
    let stats = summary.stats.as_ref().unwrap();
    assert_eq!(stats.message_count as usize, msgs.len());
    // Every topic of the namespace: the talker's chatter and its diagnostics.
    let channels: BTreeMap<&str, &mcap::Channel> = summary
        .channels
        .values()
        .map(|c| (c.topic.as_str(), c.as_ref()))
        .collect();
    assert_eq!(
        channels.keys().copied().collect::<Vec<_>>(),
        ["chatter", "diagnostics"]
    );
    for (topic, type_name) in [
        ("chatter", "robocog.Text"),
        ("diagnostics", "robocog.Diagnostics"),
    ] {
        let ch = channels[topic];
        assert_eq!(ch.message_encoding, "cdr");
        assert_eq!(ch.metadata["robocog.type"], type_name);
        // The schema is the type's ROS 2 definition, as rosbag2 writes it.
        let schema = ch.schema.as_ref().unwrap();
        assert_eq!(
            schema.name,
            ros_msgs::definitions().ros_name(type_name).unwrap()
        );
        assert_eq!(schema.encoding, "ros2msg");
        let text = std::str::from_utf8(&schema.data).unwrap();
        assert!(text.starts_with("std_msgs/Header header\n"), "{text}");
        assert!(text.contains("MSG: std_msgs/Header\n"), "{text}");
        assert_eq!(meta[&format!("dropped/{topic}")], "0");
    }
    assert_eq!(meta["namespace"], ns);
    let mut last_n: Option<u64> = None;
    for r in &msgs {
        assert_eq!(&r.data[..4], &[0, 1, 0, 0], "CDR encapsulation header kept");
        // The bytes decode as the schema's type.
        let v = (interfaces::msg::lookup(&r.type_name).unwrap().to_json)(&r.data).unwrap();
        let stamp = v["header"]["stamp_ns"].as_i64().unwrap() as u64;
        assert_eq!(r.publish_time, stamp, "publish_time is the header's stamp");
        let lag = r.log_time as i128 - r.publish_time as i128;
        assert!(
            (0..1_000_000_000).contains(&lag),
            "received {lag} ns after the stamp"
        );
        if r.topic == "chatter" {
            let n: u64 = v["text"].as_str().unwrap()["hello ".len()..]
                .parse()
                .unwrap();
            if let Some(prev) = last_n {
                assert_eq!(n, prev + 1, "consecutive, in order");
            }
            last_n = Some(n);
            // The talker's sequence number, from the sample's attachment.
            assert_eq!(r.sequence as u64, n);
        }
    }
    let chatter = msgs.iter().filter(|m| m.topic == "chatter").count();
    assert!(
        (50..=75).contains(&chatter),
        "about 3 s at 20 Hz: {chatter}"
    );

    // Replay at the recorded rate into a fresh namespace: same bytes, same order, same type
    // names, same timing.
    let ns1 = unique_namespace("replay1");
    let t1 = tap(&launch, &ns1).await;
    let out = replay(&launch, &ns1, &file, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains(&format!("replayed {} messages", msgs.len())),
        "{err}"
    );
    t1.wait_for(msgs.len(), Duration::from_secs(10));
    let got = t1.got.lock().unwrap().clone();
    assert_eq!(got.len(), msgs.len());
    for (g, r) in got.iter().zip(&msgs) {
        assert_eq!(g.1, r.topic);
        assert!(g.2 == r.type_name, "type name {}", g.2);
        assert_eq!(g.3, r.data, "identical payload bytes");
    }
    let (p50, p90, span, expected) = timing(&got, &msgs, 1.0);
    eprintln!(
        "rate 1: gap error p50 {:.2} ms p90 {:.2} ms; span {span:.3} s for {expected:.3} s recorded",
        p50 * 1e3,
        p90 * 1e3
    );
    assert!(p90 < 0.025, "gaps off by {p90} s (p90)");
    assert!(
        (span - expected).abs() < 0.05 * expected + 0.03,
        "span {span} vs {expected}"
    );

    // At --rate 4, four times faster.
    let ns4 = unique_namespace("replay4");
    let t4 = tap(&launch, &ns4).await;
    let out = replay(&launch, &ns4, &file, &["--rate", "4"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    t4.wait_for(msgs.len(), Duration::from_secs(10));
    let got4 = t4.got.lock().unwrap().clone();
    assert!(got4.iter().zip(&msgs).all(|(g, r)| g.3 == r.data));
    let (p50, p90, span4, expected4) = timing(&got4, &msgs, 4.0);
    eprintln!(
        "rate 4: gap error p50 {:.2} ms p90 {:.2} ms; span {span4:.3} s, recorded/4 {expected4:.3} s (x{:.2})",
        p50 * 1e3,
        p90 * 1e3,
        span / span4
    );
    assert!(
        (span4 - expected4).abs() < 0.1 * expected4 + 0.03,
        "span {span4} vs {expected4}"
    );

    // Step by step: two lines on stdin, 5 messages each, then end of input.
    let nss = unique_namespace("replaystep");
    let ts = tap(&launch, &nss).await;
    let mut child = Command::new(bin("robocog"))
        .args(["replay", &file.display().to_string(), "--step", "5"])
        .args([
            "--namespace",
            &nss,
            "--connect",
            &launch.endpoint,
            "--wait-s",
            "0.5",
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(b"\n\n").unwrap();
    }
    let st = wait_child(&mut child, Duration::from_secs(20)).expect("step replay ends at EOF");
    assert!(st.success());
    ts.wait_for(10, Duration::from_secs(5));
    let steps = ts.got.lock().unwrap().clone();
    assert_eq!(steps.len(), 10, "two steps of five");
    assert!(steps.iter().zip(&msgs).all(|(g, r)| g.3 == r.data));

    // --loop starts over at the end, until SIGTERM.
    let nsl = unique_namespace("replayloop");
    let tl = tap(&launch, &nsl).await;
    let loop_log = dir.join("loop.log");
    let mut looping = start_tool(
        &launch,
        &nsl,
        &[
            "replay",
            &file.display().to_string(),
            "--loop",
            "--as-fast-as-possible",
            "--wait-s",
            "0.5",
        ],
        &loop_log,
    );
    tl.wait_for(2 * msgs.len() + 1, Duration::from_secs(20));
    let st = sigterm_and_wait(&mut looping, &loop_log);
    assert!(
        st.success(),
        "{}",
        std::fs::read_to_string(&loop_log).unwrap()
    );
    let looped = tl.got.lock().unwrap().clone();
    for (i, g) in looped.iter().take(2 * msgs.len()).enumerate() {
        assert_eq!(g.3, msgs[i % msgs.len()].data, "message {i} of the loop");
    }

    // A recorder killed without warning leaves a file that replays up to its last flush.
    let killed = dir.join("killed.mcap");
    let klog = dir.join("killed.log");
    let mut k = start_tool(
        &launch,
        &ns,
        &[
            "record",
            "--output",
            &killed.display().to_string(),
            "--topics",
            "chatter",
            "--flush-s",
            "0.3",
        ],
        &klog,
    );
    log_wait(&klog, "the recorder", Duration::from_secs(20), |l| {
        l.starts_with("recording namespace")
    });
    std::thread::sleep(Duration::from_secs(2));
    signal(k.id(), "KILL");
    wait_child(&mut k, Duration::from_secs(10)).unwrap();
    let nsk = unique_namespace("replaykilled");
    let tk = tap(&launch, &nsk).await;
    let out = replay(&launch, &nsk, &killed, &["--as-fast-as-possible"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("truncated"), "{err}");
    let read: usize = err
        .lines()
        .find_map(|l| {
            l.split(" messages were read before the damage")
                .next()
                .filter(|_| l.contains("were read before"))
        })
        .unwrap()
        .parse()
        .unwrap();
    assert!(
        read >= 20,
        "2 s at 20 Hz, flushed every 0.3 s: {read} messages kept\n{err}"
    );
    tk.wait_for(read, Duration::from_secs(10));
    let kept = tk.got.lock().unwrap().clone();
    assert_eq!(kept.len(), read);
    let texts: Vec<u64> = kept
        .iter()
        .map(|g| {
            let v = (interfaces::msg::lookup("robocog.Text").unwrap().to_json)(&g.3).unwrap();
            v["text"].as_str().unwrap()["hello ".len()..]
                .parse()
                .unwrap()
        })
        .collect();
    assert!(texts.windows(2).all(|w| w[1] == w[0] + 1), "{texts:?}");
    eprintln!(
        "killed recorder: {read} messages kept; {}",
        err.lines().find(|l| l.contains("is damaged")).unwrap_or("")
    );

    // Damage: cut the file at several offsets, and flip one byte of a payload.
    let good = std::fs::read(&file).unwrap();
    // Where the first chatter message from `from` of the way through the messages is in the file
    // (its payload is unique: it holds its stamp), and its payload.
    let chatter_after = |from: usize| {
        let data = &msgs[from..]
            .iter()
            .find(|m| m.topic == "chatter")
            .unwrap()
            .data;
        let offset = good
            .windows(data.len())
            .position(|w| w == data.as_slice())
            .unwrap();
        (offset, data.len())
    };
    let (victim_at, victim_len) = chatter_after(msgs.len() * 2 / 3);
    let at = victim_at + victim_len - 2;
    // Inside the messages (the summary after them is a good part of a short file).
    let three_quarters = chatter_after(msgs.len() * 3 / 4).0 + 2;
    let mut flipped = good.clone();
    flipped[at] ^= 0x20;
    let cases: Vec<(String, Vec<u8>)> = vec![
        ("cut in the magic".into(), good[..5].to_vec()),
        ("cut at 1/4".into(), good[..good.len() / 4].to_vec()),
        ("cut at 1/2".into(), good[..good.len() / 2].to_vec()),
        (
            "cut at 3/4 of the messages".into(),
            good[..three_quarters].to_vec(),
        ),
        (
            "cut in the end magic".into(),
            good[..good.len() - 3].to_vec(),
        ),
        (format!("byte {at} flipped"), flipped),
    ];
    for (what, bytes) in cases {
        let damaged = dir.join("damaged.mcap");
        std::fs::write(&damaged, &bytes).unwrap();
        let nsd = unique_namespace("damaged");
        let td = tap(&launch, &nsd).await;
        let out = replay(&launch, &nsd, &damaged, &["--as-fast-as-possible"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.code(),
            Some(1),
            "{what}: exit code; stderr:\n{err}"
        );
        assert!(!err.contains("panicked"), "{what}: {err}");
        let line = err
            .lines()
            .find(|l| l.contains("is damaged:"))
            .unwrap_or_else(|| panic!("{what}: no damage line in\n{err}"));
        assert!(line.contains("byte offset"), "{what}: {line}");
        let read: usize = err
            .lines()
            .find_map(|l| {
                l.strip_suffix(
                    " messages were read before the damage and were replayed (those selected)",
                )
                .or_else(|| l.strip_suffix(" messages were read before the damage"))
            })
            .unwrap_or_else(|| panic!("{what}: no count in\n{err}"))
            .parse()
            .unwrap();
        if read > 0 {
            td.wait_for(read, Duration::from_secs(10));
        } else {
            std::thread::sleep(Duration::from_millis(300));
        }
        let got = td.got.lock().unwrap().clone();
        eprintln!("{what}: {read} of {} messages replayed; {line}", msgs.len());
        assert_eq!(
            got.len(),
            read,
            "{what}: the tap saw what the replay says it read"
        );
        assert!(
            got.iter().zip(&msgs).all(|(g, r)| g.3 == r.data),
            "{what}: the readable part is a prefix of the recording"
        );
        match what.as_str() {
            "cut in the magic" => {
                assert_eq!(read, 0);
                assert!(line.contains("not an MCAP file"), "{line}")
            }
            "cut in the end magic" => {
                assert_eq!(read, msgs.len(), "every message precedes the footer")
            }
            "cut at 3/4 of the messages" => assert!(read > 0 && read < msgs.len(), "{read}"),
            w if w.contains("flipped") => {
                assert!(line.contains("CRC"), "{line}");
                assert!(read > 0 && read < msgs.len() * 2 / 3 + 1, "{read}");
            }
            _ => assert!(line.contains("truncated"), "{line}"),
        }
    }
}

/// A publisher as fast as it goes plus RGB-D frames at 30 Hz: the recorder writes them, and what
/// it could not write is counted, never silently lost. Prints the throughput.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn recording_keeps_up_with_a_flood_and_counts_what_it_drops() {
    let ns = unique_namespace("recflood");
    let dir = scratch(&ns);
    let m = write_manifest(
        &dir,
        "graph.toml",
        r#"
[[component]]
name = "idle"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("idle up", Duration::from_secs(20), |l| {
            l.contains("idle is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-flood")
        .await
        .unwrap();
    let counters = bus
        .publisher_named::<Counter64>("bench/counter")
        .await
        .unwrap();
    let frames = bus
        .publisher_named::<RgbdFrame>("bench/rgbd")
        .await
        .unwrap();

    let file = dir.join("flood.mcap");
    let log = dir.join("record.log");
    let mut rec = start_recorder(&launch, &ns, &file, &log, Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(1000));

    let run_for = Duration::from_secs(3);
    let started = Instant::now();
    let frame_task = tokio::spawn(async move {
        let mut f = RgbdFrame::blank(640, 480, Intrinsics::default());
        for (i, b) in f.rgb.iter_mut().enumerate() {
            *b = (i * 31 % 251) as u8;
        }
        let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / 30.0));
        let mut sent = 0u64;
        let len = interfaces::codec::encoded_len(&f);
        while started.elapsed() < run_for {
            tick.tick().await;
            f.header.stamp_ns = 0;
            frames.publish(&mut f).await.unwrap();
            sent += 1;
        }
        (sent, len)
    });
    let mut sent_counters = 0u64;
    while started.elapsed() < run_for {
        for _ in 0..100 {
            let mut c = Counter64 {
                value: sent_counters,
                ..Default::default()
            };
            counters.publish(&mut c).await.unwrap();
            sent_counters += 1;
        }
        tokio::task::yield_now().await;
    }
    let (sent_frames, frame_len) = frame_task.await.unwrap();
    let publish_s = started.elapsed().as_secs_f64();
    std::thread::sleep(Duration::from_millis(1500));
    let status = sigterm_and_wait(&mut rec, &log);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "{text}");

    let (_, msgs, meta) = read_recording(&file);
    let written = |t: &str| msgs.iter().filter(|m| m.topic == t).count() as u64;
    let dropped = |t: &str| -> u64 {
        meta.get(&format!("dropped/{t}"))
            .map_or(0, |v| v.parse().unwrap())
    };
    let (wc, dc) = (written("bench/counter"), dropped("bench/counter"));
    let (wf, df) = (written("bench/rgbd"), dropped("bench/rgbd"));
    let bytes: usize = msgs.iter().map(|m| m.data.len()).sum();
    eprintln!(
        "flood: {sent_counters} counters sent in {publish_s:.2} s ({:.0}/s), {wc} written, {dc} dropped; \
         {sent_frames} RGB-D frames of {:.2} MB sent, {wf} written, {df} dropped; \
         recorded {:.0} messages/s, {:.1} MB/s; file {:.1} MB",
        sent_counters as f64 / publish_s,
        frame_len as f64 / 1e6,
        (wc + wf) as f64 / publish_s,
        bytes as f64 / 1e6 / publish_s,
        std::fs::metadata(&file).unwrap().len() as f64 / 1e6
    );
    // Nothing is lost without being counted.
    assert_eq!(
        wc + dc,
        sent_counters,
        "counters: written + dropped = sent\n{text}"
    );
    assert_eq!(
        wf + df,
        sent_frames,
        "frames: written + dropped = sent\n{text}"
    );
    assert!(sent_frames >= 60, "{sent_frames} frames published");
    // The frames are stored whole.
    let frame = msgs.iter().find(|m| m.topic == "bench/rgbd").unwrap();
    assert_eq!(frame.data.len(), frame_len);
    let v: RgbdFrame = interfaces::codec::decode(&frame.data, "robocog.RgbdFrame").unwrap();
    assert!(v.is_consistent());
    assert_eq!(v.rgb[31], (31 * 31 % 251) as u8);
    if dc + df > 0 {
        assert!(text.contains("DROPPED"), "drops are reported:\n{text}");
    }
    let _ = std::fs::remove_file(&file);
}

/// A recorded camera stream, replayed into a graph with the ball tracker alone, drives it to the
/// same tracks as the live run: the replayed frames decode, in order and on time.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn replayed_frames_drive_a_fresh_tracker_to_the_recorded_tracks() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let ns = unique_namespace("receyes");
    let dir = scratch(&ns);
    let live = Launch::start(&repo.join("launch/eyes_sim.toml"), &ns, &[]);
    live.lines
        .wait_for("the camera", Duration::from_secs(30), |l| {
            l.contains("rgbd is up")
        });
    let file = dir.join("eyes.mcap");
    let log = dir.join("record.log");
    let mut rec = start_tool(
        &live,
        &ns,
        &[
            "record",
            "--output",
            &file.display().to_string(),
            "--topics",
            "vision/rgbd,vision/ball",
        ],
        &log,
    );
    log_wait(&log, "the recorder", Duration::from_secs(20), |l| {
        l.starts_with("recording namespace")
    });
    std::thread::sleep(Duration::from_secs(3));
    assert!(sigterm_and_wait(&mut rec, &log).success());
    let (_, msgs, meta) = read_recording(&file);
    assert_eq!(
        meta["dropped/vision/rgbd"], "0",
        "30 Hz of 1.5 MB frames, none dropped"
    );
    let decode = |data: &[u8]| -> serde_json::Value {
        (interfaces::msg::lookup("robocog.BallTrack")
            .unwrap()
            .to_json)(data)
        .unwrap()
    };
    let recorded: BTreeMap<i64, serde_json::Value> = msgs
        .iter()
        .filter(|m| m.topic == "vision/ball")
        .map(|m| {
            let v = decode(&m.data);
            (v["header"]["stamp_ns"].as_i64().unwrap(), v)
        })
        .collect();
    let frames = msgs.iter().filter(|m| m.topic == "vision/rgbd").count();
    assert!(frames >= 60, "{frames} frames recorded");
    drop(live);

    // The tracker alone, fed by the replay.
    let ns2 = unique_namespace("receyes2");
    let m = write_manifest(
        &dir,
        "tracker.toml",
        r#"
[[component]]
name = "ball_tracker"
binary = "ball_tracker"
args = ["--target-hue", "3.2", "--target-saturation", "0.86", "--target-diameter", "0.1", "--no-dr", "--every-frame"]
external_inputs = ["vision/ball_target", "vision/rgbd"]
"#,
    );
    // `--every-frame`: the replayed tracker tracks every frame even on a busy machine (by
    // default a tracker behind jumps to the newest frame and counts the others).
    let graph = Launch::start(&m, &ns2, &[]);
    graph
        .lines
        .wait_for("the tracker", Duration::from_secs(30), |l| {
            l.contains("ball_tracker is up")
        });
    let t = tap(&graph, &ns2).await;
    let out = replay(&graph, &ns2, &file, &["--topics", "vision/rgbd"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eventually(
        "the tracks of the replayed frames",
        Duration::from_secs(30),
        || {
            let n = t
                .got
                .lock()
                .unwrap()
                .iter()
                .filter(|g| g.1 == "vision/ball")
                .count();
            (n >= frames).then_some(())
        },
    );
    let replayed: Vec<serde_json::Value> = t
        .got
        .lock()
        .unwrap()
        .iter()
        .filter(|g| g.1 == "vision/ball")
        .map(|g| decode(&g.3))
        .collect();
    assert_eq!(replayed.len(), frames, "one track per replayed frame");
    // Match by the source frame's stamp (the track carries it); after the first frames (the
    // live tracker had a history, the fresh one starts cold) the tracks agree. The live tracker
    // may have skipped frames when the machine was busy (it counts them): the frames both
    // trackers tracked are compared.
    let replayed_stamps: std::collections::BTreeSet<i64> = replayed
        .iter()
        .map(|v| v["header"]["stamp_ns"].as_i64().unwrap())
        .collect();
    let both = recorded
        .keys()
        .filter(|s| replayed_stamps.contains(s))
        .count();
    let mut compared = 0;
    let mut worst_m = 0.0f64;
    for v in replayed.iter().skip(10) {
        let stamp = v["header"]["stamp_ns"].as_i64().unwrap();
        let Some(r) = recorded.get(&stamp) else {
            continue;
        };
        assert_eq!(v["found"], r["found"], "stamp {stamp}");
        assert_eq!(v["frame_seq"], r["frame_seq"], "the same source frame");
        if v["has_centre_m"].as_bool().unwrap() && r["has_centre_m"].as_bool().unwrap() {
            let d: f64 = (0..3)
                .map(|k| {
                    (v["centre_m"][k].as_f64().unwrap() - r["centre_m"][k].as_f64().unwrap())
                        .powi(2)
                })
                .sum::<f64>()
                .sqrt();
            worst_m = worst_m.max(d);
        }
        compared += 1;
    }
    eprintln!(
        "tracker on replayed frames: {} tracks, the live tracker tracked {both} of the {frames} recorded frames, {compared} compared, worst centre difference {:.4} mm",
        replayed.len(),
        worst_m * 1e3
    );
    assert!(
        compared + 10 >= both && compared * 2 >= frames,
        "{compared} tracks compared, of {both} frames both trackers tracked ({frames} recorded)"
    );
    assert!(worst_m < 0.005, "centres differ by up to {worst_m} m");
    let _ = std::fs::remove_file(&file);
}
