//! Benchmark of the deep representation: in-process lookups and the bus round trip.
//!
//! 1. The library's in-process figures ([`world_model::bench::local_lookup_bench`]):
//!    `transform(world, left_fingertip)` through 13 joints, latest and at a past time, chain FK,
//!    fork, a whole what-if.
//! 2. The service over the bus: a zenoh router on `tcp/127.0.0.1:<free port>` in this process (as
//!    `robocog launch` hosts it), the DR service ([`deep_representation::service::start`], touch
//!    scene, in memory) and a client, each its own zenoh session in client mode, as separate
//!    processes would be; the client calls `dr/transform` (world -> left_fingertip, latest) and
//!    `dr/update` (one joint value) one after the other and times each call (encode, zenoh query
//!    through the router, handler, reply, decode). As a baseline, the same client calls an empty
//!    echo service on the same sessions: the difference is what the DR itself adds.
//!
//! Run: `scripts/bench.d/dr.sh`, or `cargo run --release -p deep_representation --bin bench_dr --
//! [--calls 5000] [--lookups 200000]`. The last line printed is one JSON object (units in the
//! keys).
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: it times calls over a real bus on the wall's monotonic clock"
)]

use std::time::{Duration, Instant};

use clap::Parser;
use deep_representation::service::{self, Scene, ServiceConfig};
use interfaces::bus::BusOptions;
use interfaces::msg::dr::{JointUpdate, TransformRequest, UpdateRequest};
use interfaces::msg::std_msgs::Text;
use interfaces::router::open_router;
use interfaces::{Bus, ConnectArgs, Header, topics};
use robot_model::RobotModel;
use world_model::bench::{Row, local_lookup_bench, stats};

#[derive(Debug, Parser)]
struct Args {
    /// Bus calls per measured service.
    #[arg(long, default_value_t = 5000)]
    calls: usize,
    /// In-process lookups per row.
    #[arg(long, default_value_t = 200_000)]
    lookups: usize,
    /// Calls before measuring (connection set-up, caches).
    #[arg(long, default_value_t = 300)]
    warmup: usize,
}

/// Target of the bus transform query (median, µs).
const BUS_TRANSFORM_TARGET_P50_US: f64 = 200.0;

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    let calls = args.calls.max(1);
    let config = ServiceConfig::new(Scene::Touch);
    let model = RobotModel::from_urdf_file(&config.urdf)?;

    let local =
        tokio::task::spawn_blocking(move || local_lookup_bench(&model, args.lookups)).await??;

    let (_router, endpoint) = open_router("tcp/127.0.0.1:0").await?;
    let ns = format!("bench-dr-{}", std::process::id());
    let mut connect = ConnectArgs::to_router(&endpoint, &ns);
    // ROBOCOG_MODE is the shared flags' environment variable for --mode.
    if std::env::var("ROBOCOG_MODE").as_deref() == Ok("peer") {
        connect.mode = interfaces::args::Mode::Peer;
    }
    let options = BusOptions {
        announce: true,
        ..BusOptions::default()
    };
    let server = Bus::open_with(&connect, "deep_representation", options.clone()).await?;
    let client = Bus::open_with(&connect, "bench_dr", options).await?;
    let _running = service::start(server.clone(), config).await?;
    // The baseline: an empty service on the same sessions (what the bus alone costs).
    let _echo = server
        .serve(&topics::ECHO, |req: Text| async move { Ok(req) })
        .await?;

    let timeout = Duration::from_secs(2);
    let query = TransformRequest {
        target: "world".into(),
        source: "left_fingertip".into(),
        ..Default::default()
    };
    // Wait until the service is reachable, then warm up.
    let deadline = Instant::now() + Duration::from_secs(10);
    while client
        .call(&topics::DR_TRANSFORM, &query, timeout)
        .await
        .is_err()
    {
        anyhow::ensure!(Instant::now() < deadline, "the service never answered");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    for _ in 0..args.warmup {
        client.call(&topics::DR_TRANSFORM, &query, timeout).await?;
    }
    let mut tf = Vec::with_capacity(calls);
    let mut sink = 0.0;
    for _ in 0..calls {
        let t0 = Instant::now();
        let rep = client.call(&topics::DR_TRANSFORM, &query, timeout).await?;
        tf.push(t0.elapsed().as_nanos() as u64);
        sink += rep.transform.translation_m[0];
    }
    let tf = stats("dr/transform (world <- left_fingertip)", tf);

    let ping = Text {
        text: "left_fingertip".into(),
        ..Default::default()
    };
    for _ in 0..args.warmup {
        client.call(&topics::ECHO, &ping, timeout).await?;
    }
    let mut echo = Vec::with_capacity(calls);
    for _ in 0..calls {
        let t0 = Instant::now();
        let rep = client.call(&topics::ECHO, &ping, timeout).await?;
        echo.push(t0.elapsed().as_nanos() as u64);
        sink += rep.text.len() as f64;
    }
    let echo = stats("baseline: empty echo service", echo);

    let mut up = Vec::with_capacity(calls);
    for i in 0..calls {
        let req = UpdateRequest {
            header: Header {
                stamp_ns: 1_000_000 + i as i64,
                ..Header::default()
            },
            joints: vec![JointUpdate {
                joint: "left_elbow".into(),
                value: -1.0 + (i % 100) as f64 * 0.01,
            }],
            ..Default::default()
        };
        let t0 = Instant::now();
        let rep = client.call(&topics::DR_UPDATE, &req, timeout).await?;
        up.push(t0.elapsed().as_nanos() as u64);
        sink += rep.applied as f64;
    }
    let up = stats("dr/update (1 joint, published)", up);

    println!(
        "deep_representation bench_dr: in-process, {} lookups per row, world -> left_fingertip ({} edges, 13 joints)",
        local.lookups, local.chain_edges
    );
    println!(
        "{:<42} {:>10} {:>10} {:>11} {:>10}",
        "measure", "p50 ns", "p99 ns", "mean ns", "max ns"
    );
    for r in local.rows() {
        println!(
            "{:<42} {:>10} {:>10} {:>11.1} {:>10}",
            r.name, r.p50, r.p99, r.mean, r.max
        );
    }
    println!();
    println!(
        "over the bus: {calls} calls each, one at a time, through a local zenoh router (client sessions, tcp loopback)"
    );
    println!(
        "{:<42} {:>10} {:>10} {:>11} {:>10}",
        "service call", "p50 us", "p99 us", "mean us", "max us"
    );
    let bus_row = |r: &Row| {
        println!(
            "{:<42} {:>10.1} {:>10.1} {:>11.1} {:>10.1}",
            r.name,
            us(r.p50),
            us(r.p99),
            r.mean / 1000.0,
            us(r.max)
        )
    };
    bus_row(&tf);
    bus_row(&up);
    bus_row(&echo);
    let verdict = if us(tf.p50) < BUS_TRANSFORM_TARGET_P50_US {
        "met"
    } else {
        "MISSED"
    };
    println!(
        "target: dr/transform p50 under {BUS_TRANSFORM_TARGET_P50_US} us: {verdict} (checksum {:.3})",
        sink + local.checksum
    );
    println!(
        "{{\"transform_lookup_p50_ns\": {}, \"transform_lookup_p99_ns\": {}, \"transform_lookup_at_time_p50_ns\": {}, \"fk13_p50_ns\": {}, \"fork_p50_ns\": {}, \"whatif_p50_ns\": {}, \"bus_transform_query_p50_us\": {:.1}, \"bus_transform_query_p99_us\": {:.1}, \"bus_transform_query_mean_us\": {:.1}, \"bus_update_p50_us\": {:.1}, \"bus_update_p99_us\": {:.1}, \"bus_echo_baseline_p50_us\": {:.1}, \"bus_calls\": {}, \"lookups\": {}, \"bus_transform_target_p50_us\": {}}}",
        local.latest.p50,
        local.latest.p99,
        local.at_time.p50,
        local.fk13.p50,
        local.fork.p50,
        local.whatif.p50,
        us(tf.p50),
        us(tf.p99),
        tf.mean / 1000.0,
        us(up.p50),
        us(up.p99),
        us(echo.p50),
        calls,
        local.lookups,
        BUS_TRANSFORM_TARGET_P50_US
    );
    Ok(())
}
