//! `scripts/bench bus`: the typed bus against raw zenoh, measured in the same run.
//!
//! Three zenoh sessions in one process, joined over TCP on loopback exactly as components are:
//! a router (as `robocog launch` hosts), a sender and an echoer, both clients of the router.
//! - Latency: ping-pong, one-way = round trip / 2, p50 and p99, typed and raw round trips
//!   interleaved one for one (both see the same load), for 64 B, 4 KiB, 1 MiB and one
//!   640x480 RGB-D frame (RGB8 + u16 depth, 1.5 MB). Typed: `Publisher<T>`/`Subscriber<T>` with
//!   CDR and shared memory for large payloads. Raw: `put` of the same bytes and a plain (default
//!   FIFO) subscriber, shared memory left to zenoh's defaults.
//! - The RGB-D frame as a consumer reads it: the sender publishes an `RgbdFrame` (encoded into
//!   shared memory), the echo forwards it (`Publisher::relay`; raw: `put` of the received
//!   payload), and the sender takes it back with `Subscriber::recv_borrowed`, checks its sizes and
//!   reads every byte of the colour and depth buffers in place. Raw reads every byte of its
//!   payload the same way. Two more typed rows for reference, against the same raw round trip:
//!   the echo re-publishes the frame from its view (`publish_view`: one copy into a new
//!   shared-memory buffer), and the owned path (`recv` decodes into an owned `RgbdFrame` at both
//!   ends and the echo publishes it again: a copy out and a copy in at each hop).
//! - Where a frame's time goes: each step of the typed path timed alone (encode into a buffer,
//!   owned decode, decode of the view, reading the pixels), medians of 200.
//! - Throughput: 8-byte payloads (raw) and `Counter64` messages (typed, 8 bytes of value plus
//!   the header), as fast as the sender can put them, counted at the receiver.
//!
//! The last line printed is one JSON object with every figure.
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark measures and paces on the wall clock"
)]

use interfaces::msg::std_msgs::{Counter64, Ping};
use interfaces::msg::vision::{Intrinsics, RgbdFrame, RgbdFrameView};
use interfaces::{Bus, ConnectArgs, Message, codec, topics};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

fn pct(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

struct Lat {
    p50_us: f64,
    p99_us: f64,
}

fn summarise(mut one_way_us: Vec<f64>) -> Lat {
    one_way_us.sort_by(|a, b| a.total_cmp(b));
    Lat {
        p50_us: pct(&one_way_us, 0.5),
        p99_us: pct(&one_way_us, 0.99),
    }
}

/// One typed round trip setup: `Ping`s (or whole RGB-D frames) echoed by the other session.
struct TypedPair<T: interfaces::Message> {
    publisher: interfaces::Publisher<T>,
    back: interfaces::Subscriber<T>,
    echo: tokio::task::JoinHandle<()>,
}

impl<T: interfaces::Message> TypedPair<T> {
    async fn new(
        a: &Bus,
        b: &Bus,
        out: &interfaces::Topic<T>,
        back: &interfaces::Topic<T>,
    ) -> anyhow::Result<Self> {
        let back_pub = b.publisher(back).await?;
        let sub = b.subscriber(out).await?;
        let echo = tokio::spawn(async move {
            while let Ok(mut m) = sub.recv().await {
                if back_pub.publish(&mut m).await.is_err() {
                    return;
                }
            }
        });
        Ok(Self {
            publisher: a.publisher(out).await?,
            back: a.subscriber(back).await?,
            echo,
        })
    }

    /// One-way latency (µs) of one round trip of `msg`.
    async fn once(&self, msg: &mut T) -> anyhow::Result<f64> {
        let t = Instant::now();
        self.publisher.publish(msg).await?;
        tokio::time::timeout(Duration::from_secs(5), self.back.recv())
            .await
            .map_err(|_| anyhow::anyhow!("typed {} lost", T::TYPE_NAME))??;
        Ok(t.elapsed().as_secs_f64() * 1e6 / 2.0)
    }
}

impl<T: interfaces::Message> Drop for TypedPair<T> {
    fn drop(&mut self) {
        self.echo.abort();
    }
}

/// The same with raw zenoh: `put` of bytes and plain (default FIFO) subscribers.
struct RawPair {
    publisher: zenoh::pubsub::Publisher<'static>,
    back: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
    echo: tokio::task::JoinHandle<()>,
}

impl RawPair {
    async fn new(a: &zenoh::Session, b: &zenoh::Session, tag: &str) -> anyhow::Result<Self> {
        let e = |e: zenoh::Error| anyhow::anyhow!("{e}");
        let ping_key = format!("raw/bench/ping/{tag}");
        let pong_key = format!("raw/bench/pong/{tag}");
        let b_sub = b.declare_subscriber(ping_key.clone()).await.map_err(e)?;
        let b_pub = b.declare_publisher(pong_key.clone()).await.map_err(e)?;
        let echo = tokio::spawn(async move {
            while let Ok(s) = b_sub.recv_async().await {
                if b_pub.put(s.payload().clone()).await.is_err() {
                    return;
                }
            }
        });
        Ok(Self {
            publisher: a.declare_publisher(ping_key).await.map_err(e)?,
            back: a.declare_subscriber(pong_key).await.map_err(e)?,
            echo,
        })
    }

    /// One-way latency (µs) of one round trip of `payload`; with `read`, every byte of the
    /// echoed payload is read, as a consumer of a frame reads its pixels.
    async fn once(&self, payload: &[u8], read: bool) -> anyhow::Result<f64> {
        let t = Instant::now();
        self.publisher
            .put(payload.to_vec())
            .await
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        let s = tokio::time::timeout(Duration::from_secs(5), self.back.recv_async())
            .await
            .map_err(|_| anyhow::anyhow!("raw ping lost"))?
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        anyhow::ensure!(s.payload().len() == payload.len(), "echo of the wrong size");
        if read {
            let sum: u64 = s.payload().slices().map(touch).sum();
            std::hint::black_box(sum);
        }
        Ok(t.elapsed().as_secs_f64() * 1e6 / 2.0)
    }
}

impl Drop for RawPair {
    fn drop(&mut self) {
        self.echo.abort();
    }
}

/// Reads every byte once (a sum the optimiser cannot drop, eight bytes at a time, so it runs at
/// memory speed), as a consumer scanning the pixels must at least.
fn touch(bytes: &[u8]) -> u64 {
    let words = bytes.chunks_exact(8);
    let tail: u64 = words.remainder().iter().map(|&b| u64::from(b)).sum();
    words.fold(tail, |acc, w| {
        acc.wrapping_add(u64::from_le_bytes([
            w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7],
        ]))
    })
}

/// `typed` and `raw` round trips interleaved one for one, so both see the same machine load;
/// after a warm-up, `n` of each. Returns (typed, raw).
async fn interleave(
    mut typed: impl AsyncFnMut() -> anyhow::Result<f64>,
    mut raw: impl AsyncFnMut() -> anyhow::Result<f64>,
    n: usize,
) -> anyhow::Result<(Lat, Lat)> {
    let warm = (n / 10).max(5);
    let (mut t, mut r) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n + warm {
        let (ti, ri) = if i % 2 == 0 {
            let ti = typed().await?;
            (ti, raw().await?)
        } else {
            let ri = raw().await?;
            (typed().await?, ri)
        };
        if i >= warm {
            t.push(ti);
            r.push(ri);
        }
    }
    Ok((summarise(t), summarise(r)))
}

/// Typed and raw round trips of `size` bytes; returns (typed, raw).
async fn latency_pair<T: interfaces::Message>(
    a: &Bus,
    b: &Bus,
    typed: (&interfaces::Topic<T>, &interfaces::Topic<T>),
    mut msg: T,
    raw_size: usize,
    n: usize,
) -> anyhow::Result<(Lat, Lat)> {
    let tp = TypedPair::new(a, b, typed.0, typed.1).await?;
    let rp = RawPair::new(a.session(), b.session(), &raw_size.to_string()).await?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let payload = vec![0xabu8; raw_size];
    interleave(
        async || tp.once(&mut msg).await,
        async || rp.once(&payload, false).await,
        n,
    )
    .await
}

/// What the echo of the typed frame round trip does with the frame it receives.
#[derive(Clone, Copy)]
enum Echo {
    /// Forwards the received payload as it is (`Publisher::relay`), as the raw echo does.
    Relay,
    /// Publishes the frame again from its borrowed view (`publish_view`): one copy.
    Republish,
}

/// The typed RGB-D round trip read in place: publish, echo, `recv_borrowed`, read the pixels.
struct FramePair {
    publisher: interfaces::Publisher<RgbdFrame>,
    back: interfaces::Subscriber<RgbdFrame>,
    echo: tokio::task::JoinHandle<()>,
}

impl FramePair {
    async fn new(a: &Bus, b: &Bus, mode: Echo) -> anyhow::Result<Self> {
        let back_pub = b.publisher(&topics::BENCH_FRAME_BACK).await?;
        let sub = b.subscriber(&topics::BENCH_FRAME).await?;
        let echo = tokio::spawn(async move {
            while let Ok(frame) = sub.recv_borrowed().await {
                let sent = match mode {
                    Echo::Relay => back_pub.relay(&frame).await,
                    Echo::Republish => back_pub.publish_view(&mut frame.view()).await,
                };
                if sent.is_err() {
                    return;
                }
            }
        });
        Ok(Self {
            publisher: a.publisher(&topics::BENCH_FRAME).await?,
            back: a.subscriber(&topics::BENCH_FRAME_BACK).await?,
            echo,
        })
    }

    async fn once(&self, frame: &mut RgbdFrame) -> anyhow::Result<f64> {
        let t = Instant::now();
        self.publisher.publish(frame).await?;
        let got = tokio::time::timeout(Duration::from_secs(5), self.back.recv_borrowed())
            .await
            .map_err(|_| anyhow::anyhow!("typed frame lost"))??;
        let view = got.view();
        anyhow::ensure!(view.is_consistent(), "echo of an inconsistent frame");
        std::hint::black_box(touch(view.rgb) + touch(view.depth_mm));
        Ok(t.elapsed().as_secs_f64() * 1e6 / 2.0)
    }
}

impl Drop for FramePair {
    fn drop(&mut self) {
        self.echo.abort();
    }
}

/// The frame round trips, typed (`typed`: a frame pair, or `None` for the owned path) and raw
/// (reading every byte), interleaved; returns (typed, raw).
async fn frame_latency(
    a: &Bus,
    b: &Bus,
    mode: Option<Echo>,
    mut frame: RgbdFrame,
    tag: &str,
    n: usize,
) -> anyhow::Result<(Lat, Lat)> {
    let raw_size = codec::encoded_len(&frame);
    let rp = RawPair::new(a.session(), b.session(), tag).await?;
    let payload = vec![0xabu8; raw_size];
    match mode {
        Some(mode) => {
            let fp = FramePair::new(a, b, mode).await?;
            tokio::time::sleep(Duration::from_millis(300)).await;
            interleave(
                async || fp.once(&mut frame).await,
                async || rp.once(&payload, true).await,
                n,
            )
            .await
        }
        None => {
            let tp = TypedPair::new(a, b, &topics::BENCH_FRAME, &topics::BENCH_FRAME_BACK).await?;
            tokio::time::sleep(Duration::from_millis(300)).await;
            interleave(
                async || tp.once(&mut frame).await,
                async || rp.once(&payload, true).await,
                n,
            )
            .await
        }
    }
}

/// Median time (µs) of `f` over `n` runs.
fn median_us(n: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..n)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    t.sort_by(|a, b| a.total_cmp(b));
    pct(&t, 0.5)
}

/// Each step of the typed frame path alone, in µs (medians): where a frame's time goes.
fn frame_steps(frame: &RgbdFrame) -> anyhow::Result<Vec<(&'static str, &'static str, f64)>> {
    const N: usize = 200;
    let len = codec::encoded_len(frame);
    let mut buf = vec![0u8; len];
    let encode = median_us(N, || {
        let r = codec::encode_into(frame, &mut buf, RgbdFrame::TYPE_NAME);
        std::hint::black_box(r.is_ok());
    });
    let bytes = codec::encode(frame, RgbdFrame::TYPE_NAME)?;
    let owned = median_us(N, || {
        let r = codec::decode::<RgbdFrame>(&bytes, RgbdFrame::TYPE_NAME);
        std::hint::black_box(r.map(|f| f.rgb.len()).ok());
    });
    let owned_cdr = median_us(N, || {
        let r = cdr::deserialize::<RgbdFrame>(&bytes);
        std::hint::black_box(r.map(|f| f.rgb.len()).ok());
    });
    let view = median_us(N, || {
        let r = codec::decode_borrowed::<RgbdFrameView<'_>>(&bytes, RgbdFrame::TYPE_NAME);
        std::hint::black_box(r.map(|f| f.rgb.len()).ok());
    });
    let read = median_us(N, || {
        std::hint::black_box(touch(&bytes));
    });
    let copy = median_us(N, || {
        std::hint::black_box(bytes.to_vec());
    });
    Ok(vec![
        (
            "encode_into_buffer",
            "encode into a ready buffer (`encode_into`)",
            encode,
        ),
        ("decode_owned", "owned decode (`recv`)", owned),
        (
            "decode_owned_cdr_crate",
            "owned decode with the cdr crate (before)",
            owned_cdr,
        ),
        ("decode_view", "decode of the view (`recv_borrowed`)", view),
        (
            "read_all_bytes",
            "reading every byte once (the consumer's pass)",
            read,
        ),
        ("copy_to_new_vec", "one copy into a new `Vec`", copy),
    ])
}

/// Messages per second, raw 8-byte puts.
async fn raw_throughput(a: &zenoh::Session, b: &zenoh::Session, n: u64) -> anyhow::Result<f64> {
    let e = |e: zenoh::Error| anyhow::anyhow!("{e}");
    let count = Arc::new(AtomicU64::new(0));
    let first = Arc::new(std::sync::Mutex::new(None::<Instant>));
    let (c2, f2) = (count.clone(), first.clone());
    let _sub = b
        .declare_subscriber("raw/bench/tp")
        .callback(move |_s| {
            if c2.fetch_add(1, Ordering::Relaxed) == 0 {
                *f2.lock().unwrap_or_else(|p| p.into_inner()) = Some(Instant::now());
            }
        })
        .await
        .map_err(e)?;
    let p = a
        .declare_publisher("raw/bench/tp")
        .congestion_control(zenoh::qos::CongestionControl::Block)
        .await
        .map_err(e)?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let payload = 42u64.to_le_bytes();
    for _ in 0..n {
        p.put(payload.to_vec()).await.map_err(e)?;
    }
    let deadline = Instant::now() + Duration::from_secs(30);
    while count.load(Ordering::Relaxed) < n && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    let end = Instant::now();
    let got = count.load(Ordering::Relaxed);
    let start = first
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .unwrap_or(end);
    Ok(got as f64 / end.duration_since(start).as_secs_f64().max(1e-9))
}

/// Messages per second, typed `Counter64`, received through a typed subscriber.
async fn typed_throughput(a: &Bus, b: &Bus, n: u64) -> anyhow::Result<f64> {
    let sub = b
        .subscriber_named::<Counter64>(topics::BENCH_COUNT.name(), 65536)
        .await?;
    let counter = tokio::spawn(async move {
        let mut got = 0u64;
        let mut start = None;
        while got < n {
            match tokio::time::timeout(Duration::from_secs(10), sub.recv()).await {
                Ok(Ok(_)) => {
                    if got == 0 {
                        start = Some(Instant::now());
                    }
                    got += 1;
                }
                _ => break,
            }
        }
        (got, start.unwrap_or_else(Instant::now), Instant::now())
    });
    let p = a.publisher(&topics::BENCH_COUNT).await?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let mut m = Counter64::default();
    for i in 0..n {
        m.value = i;
        p.publish(&mut m).await?;
    }
    let (got, start, end) = counter.await?;
    Ok(got as f64 / end.duration_since(start).as_secs_f64().max(1e-9))
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let quick = std::env::args().any(|a| a == "--quick");
    let (_router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0").await?;
    let ns = format!("bench-{}", std::process::id());
    let args = ConnectArgs::to_router(&endpoint, &ns);
    let a = Bus::open(&args, "bench-sender").await?;
    let b = Bus::open(&args, "bench-echo").await?;
    eprintln!("bus benchmark: router {endpoint}, namespace {ns}");

    let scale = if quick { 10 } else { 1 };
    let cases: [(&str, usize, usize); 3] = [
        ("64B", 64, 5000 / scale),
        ("4KiB", 4096, 3000 / scale),
        ("1MiB", 1 << 20, 300 / scale),
    ];
    let mut rows = Vec::new();
    let mut json = serde_json::Map::new();
    for (label, size, n) in cases {
        eprintln!("latency {label} ({n} round trips each)...");
        let ping = Ping {
            data: vec![0xab; size],
            ..Default::default()
        };
        let (t, r) = latency_pair(
            &a,
            &b,
            (&topics::BENCH_PING, &topics::BENCH_PONG),
            ping,
            size,
            n,
        )
        .await?;
        json.insert(format!("typed_{label}_p50_us"), t.p50_us.into());
        json.insert(format!("typed_{label}_p99_us"), t.p99_us.into());
        json.insert(format!("raw_{label}_p50_us"), r.p50_us.into());
        json.insert(format!("raw_{label}_p99_us"), r.p99_us.into());
        json.insert(
            format!("ratio_{label}_p50_typed_over_raw"),
            (t.p50_us / r.p50_us).into(),
        );
        rows.push((label.to_string(), t, r));
    }
    let n_frames = 300 / scale;
    let mut frame = RgbdFrame::blank(
        640,
        480,
        Intrinsics {
            fx: 525.0,
            fy: 525.0,
            cx: 319.5,
            cy: 239.5,
        },
    );
    frame.header.frame_id = "head_rgbd_optical_frame".into();
    let frame_rows = [
        ("rgbd", "RGB-D 640x480, read in place", Some(Echo::Relay)),
        (
            "rgbd_republish",
            "RGB-D 640x480, read in place, echo re-publishes",
            Some(Echo::Republish),
        ),
        ("rgbd_owned", "RGB-D 640x480, owned decode", None),
    ];
    for (key, label, mode) in frame_rows {
        eprintln!("latency {label} ({n_frames} round trips each)...");
        let (t, r) = frame_latency(&a, &b, mode, frame.clone(), key, n_frames).await?;
        json.insert(format!("typed_{key}_p50_us"), t.p50_us.into());
        json.insert(format!("typed_{key}_p99_us"), t.p99_us.into());
        json.insert(format!("raw_{key}_p50_us"), r.p50_us.into());
        json.insert(format!("raw_{key}_p99_us"), r.p99_us.into());
        json.insert(
            format!("ratio_{key}_p50_typed_over_raw"),
            (t.p50_us / r.p50_us).into(),
        );
        rows.push((label.to_string(), t, r));
    }
    let steps = frame_steps(&frame)?;
    for (key, _, us) in &steps {
        json.insert(format!("frame_step_{key}_us"), (*us).into());
    }

    let n_tp = 1_000_000 / scale as u64;
    eprintln!("throughput ({n_tp} messages each)...");
    let raw_tp = raw_throughput(a.session(), b.session(), n_tp).await?;
    let typed_tp = typed_throughput(&a, &b, n_tp).await?;
    json.insert("raw_8B_msgs_per_s".into(), raw_tp.into());
    json.insert("typed_8B_msgs_per_s".into(), typed_tp.into());
    json.insert(
        "ratio_throughput_typed_over_raw".into(),
        (typed_tp / raw_tp).into(),
    );

    println!();
    println!(
        "| payload | typed p50 µs | typed p99 µs | raw zenoh p50 µs | raw zenoh p99 µs | typed/raw p50 |"
    );
    println!("|---|---:|---:|---:|---:|---:|");
    for (label, t, r) in &rows {
        println!(
            "| {label} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} |",
            t.p50_us,
            t.p99_us,
            r.p50_us,
            r.p99_us,
            t.p50_us / r.p50_us
        );
    }
    println!();
    println!("| throughput | messages/s |");
    println!("|---|---:|");
    println!("| raw zenoh, 8-byte payload | {raw_tp:.0} |");
    println!("| typed Counter64 (8-byte value + header) | {typed_tp:.0} |");
    println!();
    println!("| one 640x480 RGB-D frame (1.5 MB), alone | median µs |");
    println!("|---|---:|");
    for (_, label, us) in &steps {
        println!("| {label} | {us:.1} |");
    }
    println!();
    println!(
        "targets: typed small-message latency within 1.2x of raw ({}), typed RGB-D frame read in place within 1.2x of raw ({}), RGB-D p50 under 2 ms ({}), 8-byte throughput at least 1M msg/s (typed {}, raw {})",
        if rows[0].1.p50_us / rows[0].2.p50_us <= 1.2 {
            "met"
        } else {
            "NOT met"
        },
        if rows[3].1.p50_us / rows[3].2.p50_us <= 1.2 {
            "met"
        } else {
            "NOT met"
        },
        if rows[3].1.p50_us < 2000.0 {
            "met"
        } else {
            "NOT met"
        },
        if typed_tp >= 1e6 { "met" } else { "NOT met" },
        if raw_tp >= 1e6 { "met" } else { "NOT met" },
    );
    println!("{}", serde_json::Value::Object(json));
    Ok(())
}
