//! `scripts/bench bus`: the typed bus against raw zenoh, measured in the same run.
//!
//! Three zenoh sessions in one process, joined over TCP on loopback exactly as components are:
//! a router (as `robocog launch` hosts), a sender and an echoer, both clients of the router.
//! - Latency: ping-pong, one-way = round trip / 2, p50 and p99, typed and raw round trips
//!   interleaved one for one (both see the same load), for 64 B, 4 KiB, 1 MiB and one
//!   640x480 RGB-D frame (RGB8 + u16 depth, 1.5 MB). Typed: `Publisher<T>`/`Subscriber<T>` with
//!   CDR and shared memory for large payloads. Raw: `put` of the same bytes and a plain (default
//!   FIFO) subscriber, shared memory left to zenoh's defaults.
//! - Throughput: 8-byte payloads (raw) and `Counter64` messages (typed, 8 bytes of value plus
//!   the header), as fast as the sender can put them, counted at the receiver.
//!
//! The last line printed is one JSON object with every figure.

use interfaces::msg::std_msgs::{Counter64, Ping};
use interfaces::msg::vision::{Intrinsics, RgbdFrame};
use interfaces::{Bus, ConnectArgs, topics};
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

    async fn once(&self, payload: &[u8]) -> anyhow::Result<f64> {
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
        Ok(t.elapsed().as_secs_f64() * 1e6 / 2.0)
    }
}

impl Drop for RawPair {
    fn drop(&mut self) {
        self.echo.abort();
    }
}

/// Typed and raw round trips of `size` bytes, interleaved one for one so both see the same
/// machine load; returns (typed, raw).
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
    let warm = (n / 10).max(5);
    let (mut t, mut r) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n + warm {
        let (ti, ri) = if i % 2 == 0 {
            let ti = tp.once(&mut msg).await?;
            (ti, rp.once(&payload).await?)
        } else {
            let ri = rp.once(&payload).await?;
            (tp.once(&mut msg).await?, ri)
        };
        if i >= warm {
            t.push(ti);
            r.push(ri);
        }
    }
    Ok((summarise(t), summarise(r)))
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
    eprintln!("latency RGB-D frame ({n_frames} round trips each)...");
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
    let raw_size = interfaces::codec::encoded_len(&frame);
    let (t, r) = latency_pair(
        &a,
        &b,
        (&topics::BENCH_FRAME, &topics::BENCH_FRAME_BACK),
        frame,
        raw_size,
        n_frames,
    )
    .await?;
    json.insert("typed_rgbd_p50_us".into(), t.p50_us.into());
    json.insert("typed_rgbd_p99_us".into(), t.p99_us.into());
    json.insert("raw_rgbd_p50_us".into(), r.p50_us.into());
    json.insert("raw_rgbd_p99_us".into(), r.p99_us.into());
    json.insert(
        "ratio_rgbd_p50_typed_over_raw".into(),
        (t.p50_us / r.p50_us).into(),
    );
    rows.push(("RGB-D 640x480".into(), t, r));

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
    println!(
        "targets: typed small-message latency within 1.2x of raw ({}), RGB-D p50 under 2 ms ({}), 8-byte throughput at least 1M msg/s (typed {}, raw {})",
        if rows[0].1.p50_us / rows[0].2.p50_us <= 1.2 {
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
