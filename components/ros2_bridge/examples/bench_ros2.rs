#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: measures real latency and throughput of zenoh sessions on the wall clock"
)]
//! What the rmw_zenoh-compatible mode costs (`scripts/bench ros2`): one router, a publisher and
//! a subscriber of robocog's bus, each with its own zenoh session, and the bridge in a third.
//!
//! - latency publisher -> robocog subscriber (64 B, 4 KiB and 64 KiB probes at 200 Hz), bridge
//!   off, then bridge on (the peer is the same bus without the bridge);
//! - with the bridge on, latency publisher -> a plain zenoh subscriber on the topic's rmw_zenoh
//!   key (what a ROS 2 subscriber receives: one more hop, through the bridge);
//! - throughput of 8-byte counters publisher -> robocog subscriber, bridge off and on.
//!
//! Prints a table, then one JSON line. `--quick`: fewer samples.

use interfaces::bus::Bus;
use interfaces::msg::Message;
use interfaces::msg::std_msgs::{Counter64, Ping};
use interfaces::node::Shutdown;
use interfaces::topic::Topic;
use interfaces::{ConnectArgs, Header};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

const PING: Topic<Ping> = Topic::new("bench/ping");
const COUNT: Topic<Counter64> = Topic::new("bench/count");

fn pct(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Latencies (µs) of `n` probes of `size` bytes, robocog side and, if given, the ROS 2 side.
async fn latency(
    publisher: &Bus,
    subscriber: &Bus,
    ros_key: Option<&str>,
    size: usize,
    n: usize,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let epoch = Instant::now();
    let sub = subscriber.subscriber(&PING).await?;
    let ros_lat = Arc::new(std::sync::Mutex::new(Vec::new()));
    let _ros_sub = match ros_key {
        Some(k) => {
            let into = ros_lat.clone();
            Some(
                publisher
                    .session()
                    .declare_subscriber(k.to_string())
                    .callback(move |s| {
                        let bytes = s.payload().to_bytes();
                        if let Ok(p) = interfaces::codec::decode::<Ping>(&bytes, Ping::TYPE_NAME) {
                            let now = epoch.elapsed().as_nanos() as u64;
                            into.lock()
                                .unwrap_or_else(|e| e.into_inner())
                                .push(now.saturating_sub(p.sent_ns) as f64 / 1e3);
                        }
                    })
                    .await
                    .map_err(|e| anyhow::anyhow!("{e}"))?,
            )
        }
        None => None,
    };
    let pubr = publisher.publisher(&PING).await?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let mut lat = Vec::with_capacity(n);
    let data = vec![7u8; size];
    for _ in 0..n {
        let mut p = Ping {
            header: Header::default(),
            sent_ns: epoch.elapsed().as_nanos() as u64,
            data: data.clone(),
        };
        pubr.publish(&mut p).await?;
        if let Some(got) = sub.recv_timeout(Duration::from_secs(2)).await? {
            let now = epoch.elapsed().as_nanos() as u64;
            lat.push(now.saturating_sub(got.sent_ns) as f64 / 1e3);
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    lat.sort_by(f64::total_cmp);
    let mut ros = ros_lat.lock().unwrap_or_else(|e| e.into_inner()).clone();
    ros.sort_by(f64::total_cmp);
    Ok((lat, ros))
}

/// Messages per second of 8-byte counters, published as fast as the bus takes them.
async fn throughput(publisher: &Bus, subscriber: &Bus, n: u64) -> anyhow::Result<f64> {
    let sub = subscriber
        .subscriber_named::<Counter64>(COUNT.name(), 1 << 16)
        .await?;
    let pubr = publisher.publisher(&COUNT).await?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let got = Arc::new(AtomicU64::new(0));
    let counter = got.clone();
    let reader = tokio::spawn(async move {
        let mut first = None;
        let mut last = Instant::now();
        while let Ok(Some(_)) = sub.recv_timeout(Duration::from_secs(2)).await {
            first.get_or_insert_with(Instant::now);
            last = Instant::now();
            if counter.fetch_add(1, Ordering::Relaxed) + 1 == n {
                break;
            }
        }
        (first.unwrap_or(last), last)
    });
    for i in 0..n {
        let mut c = Counter64 {
            value: i,
            ..Default::default()
        };
        pubr.publish(&mut c).await?;
    }
    let (first, last) = reader.await?;
    let secs = last.duration_since(first).as_secs_f64().max(1e-9);
    Ok(got.load(Ordering::Relaxed) as f64 / secs)
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let quick = std::env::args().any(|a| a == "--quick");
    let n = if quick { 200 } else { 2000 };
    let n_tp: u64 = if quick { 20_000 } else { 200_000 };
    let (_router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0").await?;
    let ns = format!("bench-ros2-{}", std::process::id());
    let args = ConnectArgs::to_router(&endpoint, &ns);
    let publisher = Bus::open(&args, "bench_pub").await?;
    let subscriber = Bus::open(&args, "bench_sub").await?;
    let sizes = [64usize, 4096, 65536];

    let mut off = Vec::new();
    for &s in &sizes {
        off.push(latency(&publisher, &subscriber, None, s, n).await?.0);
    }
    let tp_off = throughput(&publisher, &subscriber, n_tp).await?;

    // The bridge, in a session of its own.
    let bridge_bus = Bus::open(&args, "ros2_bridge").await?;
    let (stop, shutdown) = Shutdown::new();
    let settings = ros2_bridge::bridge::Settings {
        domain: 0,
        exclude: Vec::new(),
    };
    let bridge = tokio::spawn(ros2_bridge::bridge::run(bridge_bus, settings, shutdown));
    let defs = ros_msgs::definitions();
    let ros_key = ros2_bridge::wire::data_key(
        0,
        "/bench/ping",
        &ros2_bridge::wire::dds_type_name(
            &defs.ros_name(Ping::TYPE_NAME).map_err(anyhow::Error::msg)?,
        )
        .unwrap_or_default(),
        &defs.rihs01(Ping::TYPE_NAME).map_err(anyhow::Error::msg)?,
    );
    let mut on = Vec::new();
    let mut ros = Vec::new();
    for &s in &sizes {
        let (l, r) = latency(&publisher, &subscriber, Some(&ros_key), s, n).await?;
        on.push(l);
        ros.push(r);
    }
    let tp_on = throughput(&publisher, &subscriber, n_tp).await?;
    let _ = stop.send(true);
    let _ = tokio::time::timeout(Duration::from_secs(5), bridge).await;

    println!(
        "rmw_zenoh-compatible mode (ros2_bridge): what it costs robocog's bus, one router on loopback"
    );
    println!(
        "{:<10} {:>16} {:>16} {:>8} {:>18} {:>10}",
        "probe", "off p50/p99 us", "on p50/p99 us", "on/off", "ROS side p50/p99", "ROS got"
    );
    let mut json = serde_json::Map::new();
    for (i, &s) in sizes.iter().enumerate() {
        let label = match s {
            64 => "64B",
            4096 => "4KiB",
            _ => "64KiB",
        };
        let (a, b, r) = (&off[i], &on[i], &ros[i]);
        let ratio = pct(b, 0.5) / pct(a, 0.5);
        println!(
            "{:<10} {:>7.1}/{:>8.1} {:>7.1}/{:>8.1} {:>8.2} {:>8.1}/{:>9.1} {:>10}",
            label,
            pct(a, 0.5),
            pct(a, 0.99),
            pct(b, 0.5),
            pct(b, 0.99),
            ratio,
            pct(r, 0.5),
            pct(r, 0.99),
            format!("{}/{}", r.len(), n)
        );
        json.insert(format!("off_p50_us_{label}"), pct(a, 0.5).into());
        json.insert(format!("on_p50_us_{label}"), pct(b, 0.5).into());
        json.insert(format!("on_p99_us_{label}"), pct(b, 0.99).into());
        json.insert(format!("ratio_on_vs_off_p50_{label}"), ratio.into());
        json.insert(format!("ros_side_p50_us_{label}"), pct(r, 0.5).into());
        json.insert(
            format!("ros_side_received_{label}"),
            (r.len() as u64).into(),
        );
    }
    println!(
        "{:<10} {:>16.0} {:>16.0} {:>8.2}   (8-byte messages/s)",
        "throughput",
        tp_off,
        tp_on,
        tp_on / tp_off
    );
    json.insert("off_throughput_msg_per_s".into(), tp_off.into());
    json.insert("on_throughput_msg_per_s".into(), tp_on.into());
    json.insert("ratio_on_vs_off_throughput".into(), (tp_on / tp_off).into());
    json.insert("samples".into(), (n as u64).into());
    println!("{}", serde_json::Value::Object(json));
    Ok(())
}
