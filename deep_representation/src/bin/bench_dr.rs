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
//! 3. Under a flood: while a foreign zenoh client (no caller attachment) sends valid and
//!    malformed `dr/transform` queries with `--flood-in-flight` outstanding, and a robocog
//!    component floods the same service with as many calls at a time, the game's client calls
//!    `dr/transform` one call at a time for `--flood-s` seconds: its p50/p99 against the quiet
//!    figures of 2., what the service refused or dropped per caller (its `service_busy/...` and
//!    `service_expired/...` counters), and how long after the flood stopped its last query was
//!    settled (answered, refused or timed out).
//!
//! Run: `scripts/bench.d/dr.sh`, or `cargo run --release -p deep_representation --bin bench_dr --
//! [--calls 5000] [--lookups 200000]`. The last line printed is one JSON object (units in the
//! keys).
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: it times calls over a real bus on the wall's monotonic clock"
)]

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use clap::Parser;
use deep_representation::service::{self, Scene, ServiceConfig};
use interfaces::bus::BusOptions;
use interfaces::msg::dr::{JointUpdate, TransformRequest, UpdateRequest};
use interfaces::msg::std_msgs::Text;
use interfaces::router::open_router;
use interfaces::{Bus, ConnectArgs, Header, Message, topics};
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
    /// Seconds of the flood (0: no flood measured).
    #[arg(long, default_value_t = 10.0)]
    flood_s: f64,
    /// Queries each flooding client keeps outstanding.
    #[arg(long, default_value_t = 256)]
    flood_in_flight: usize,
    /// Only the flood, beside a running graph: the router it joins (with `--namespace`); its
    /// `deep_representation` is the one flooded, its counters read from `diagnostics`.
    #[arg(long, requires = "namespace")]
    beside: Option<String>,
    /// The running graph's namespace (with `--beside`).
    #[arg(long)]
    namespace: Option<String>,
}

/// Target of the game's `dr/transform` p99 under the flood (ms).
const FLOOD_GAME_TARGET_P99_MS: f64 = 20.0;

/// Target of the bus transform query (median, µs).
const BUS_TRANSFORM_TARGET_P50_US: f64 = 200.0;

fn us(ns: u64) -> f64 {
    ns as f64 / 1000.0
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if let (Some(endpoint), Some(ns)) = (&args.beside, &args.namespace) {
        return beside(endpoint, ns, &args).await;
    }
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

    let flood = if args.flood_s > 0.0 {
        let counters = server.counters().clone();
        Some(
            flood(
                &connect,
                move || async move { counters.snapshot() },
                &client,
                &query,
                Duration::from_secs_f64(args.flood_s),
                args.flood_in_flight.max(1),
            )
            .await?,
        )
    } else {
        None
    };

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
    if let Some(f) = &flood {
        f.print();
    }
    let verdict = if us(tf.p50) < BUS_TRANSFORM_TARGET_P50_US {
        "met"
    } else {
        "MISSED"
    };
    println!(
        "target: dr/transform p50 under {BUS_TRANSFORM_TARGET_P50_US} us: {verdict} (checksum {:.3})",
        sink + local.checksum
    );
    let flood_json = flood.as_ref().map_or(String::new(), Flood::json);
    println!(
        "{{\"transform_lookup_p50_ns\": {}, \"transform_lookup_p99_ns\": {}, \"transform_lookup_at_time_p50_ns\": {}, \"fk13_p50_ns\": {}, \"fork_p50_ns\": {}, \"whatif_p50_ns\": {}, \"bus_transform_query_p50_us\": {:.1}, \"bus_transform_query_p99_us\": {:.1}, \"bus_transform_query_mean_us\": {:.1}, \"bus_update_p50_us\": {:.1}, \"bus_update_p99_us\": {:.1}, \"bus_echo_baseline_p50_us\": {:.1}, \"bus_calls\": {}, \"lookups\": {}, \"bus_transform_target_p50_us\": {}{flood_json}}}",
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

/// What the flood measurement found.
struct Flood {
    seconds: f64,
    game: Row,
    game_failed: u64,
    foreign_sent: u64,
    foreign_replied: u64,
    component_sent: u64,
    component_answered: u64,
    component_refused: u64,
    busy: u64,
    expired: u64,
    settled_after_stop_ms: f64,
    counters: Vec<(String, u64)>,
}

impl Flood {
    fn p99_ms(&self) -> f64 {
        self.game.p99 as f64 / 1e6
    }

    fn print(&self) {
        println!();
        println!(
            "under a flood of dr/transform for {:.0} s: a foreign zenoh client and a robocog component, each with queries outstanding without pause",
            self.seconds
        );
        println!(
            "{:<42} {:>10} {:>10} {:>11} {:>10}",
            "the game's calls", "p50 us", "p99 us", "mean us", "max us"
        );
        println!(
            "{:<42} {:>10.1} {:>10.1} {:>11.1} {:>10.1}",
            self.game.name,
            us(self.game.p50),
            us(self.game.p99),
            self.game.mean / 1000.0,
            us(self.game.max)
        );
        println!(
            "the game's calls that failed: {}; foreign queries sent {}, replied to {} (an answer or a refusal); the component's calls {}, answered {}, refused {}",
            self.game_failed,
            self.foreign_sent,
            self.foreign_replied,
            self.component_sent,
            self.component_answered,
            self.component_refused
        );
        println!(
            "the service's counters: {}",
            self.counters
                .iter()
                .map(|(k, v)| format!("{k} = {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        println!(
            "after the flood stopped, its last query settled in {:.0} ms",
            self.settled_after_stop_ms
        );
        let verdict = if self.game_failed == 0 && self.p99_ms() < FLOOD_GAME_TARGET_P99_MS {
            "met"
        } else {
            "MISSED"
        };
        println!(
            "target: the game's dr/transform p99 under the flood below {FLOOD_GAME_TARGET_P99_MS} ms, none failed: {verdict}"
        );
    }

    fn json(&self) -> String {
        format!(
            ", \"flood_s\": {:.1}, \"flood_game_transform_p50_us\": {:.1}, \"flood_game_transform_p99_us\": {:.1}, \"flood_game_calls\": {}, \"flood_game_failed\": {}, \"flood_foreign_sent\": {}, \"flood_component_sent\": {}, \"flood_busy_refused\": {}, \"flood_expired_dropped\": {}, \"flood_settled_after_stop_ms\": {:.0}, \"flood_game_target_p99_ms\": {}",
            self.seconds,
            us(self.game.p50),
            us(self.game.p99),
            self.game.count,
            self.game_failed,
            self.foreign_sent,
            self.component_sent,
            self.busy,
            self.expired,
            self.settled_after_stop_ms,
            FLOOD_GAME_TARGET_P99_MS
        )
    }
}

/// The flood beside a running graph (`--beside`): the same measure against its DR, whose
/// counters come from its `diagnostics`.
async fn beside(endpoint: &str, ns: &str, args: &Args) -> anyhow::Result<()> {
    let connect = ConnectArgs::to_router(endpoint, ns);
    // The graph's launcher opens its router as it starts.
    let deadline = Instant::now() + Duration::from_secs(120);
    let game = loop {
        match Bus::open(&connect, "bench_dr").await {
            Ok(bus) => break bus,
            Err(e) if Instant::now() < deadline => {
                eprintln!("waiting for the graph's router: {e}");
                tokio::time::sleep(Duration::from_millis(500)).await;
            }
            Err(e) => anyhow::bail!("the graph's router never came within 120 s: {e}"),
        }
    };
    let diagnostics = game.subscriber(&topics::DIAGNOSTICS).await?;
    let query = TransformRequest {
        target: "world".into(),
        source: "left_fingertip".into(),
        ..Default::default()
    };
    while game
        .call(&topics::DR_TRANSFORM, &query, Duration::from_secs(2))
        .await
        .is_err()
    {
        anyhow::ensure!(
            Instant::now() < deadline,
            "the graph's dr/transform never answered within 120 s"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let counters = || async {
        // The DR's newest counters, published after the flood (every second or so).
        while diagnostics.try_recv().is_some() {}
        let mut latest = Vec::new();
        let until = Instant::now() + Duration::from_secs(5);
        while Instant::now() < until {
            match diagnostics.recv_timeout(Duration::from_millis(500)).await {
                Ok(Some(d)) if d.component == "deep_representation" => {
                    latest = d.counters.into_iter().map(|c| (c.name, c.value)).collect();
                    break;
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
        latest
    };
    let f = flood(
        &connect,
        counters,
        &game,
        &query,
        Duration::from_secs_f64(args.flood_s.max(1.0)),
        args.flood_in_flight.max(1),
    )
    .await?;
    f.print();
    println!("{{{}}}", f.json().trim_start_matches(", "));
    Ok(())
}

/// The game's `dr/transform` calls while two clients flood the service (see the module docs);
/// `counters` gives the service's counters after it.
async fn flood<C, F>(
    connect: &ConnectArgs,
    counters: C,
    game: &Bus,
    query: &TransformRequest,
    seconds: Duration,
    in_flight: usize,
) -> anyhow::Result<Flood>
where
    C: FnOnce() -> F,
    F: std::future::Future<Output = Vec<(String, u64)>>,
{
    let stop = Arc::new(AtomicBool::new(false));
    let foreign_sent = Arc::new(AtomicU64::new(0));
    let foreign_replied = Arc::new(AtomicU64::new(0));
    let component_sent = Arc::new(AtomicU64::new(0));
    let component_answered = Arc::new(AtomicU64::new(0));
    let component_refused = Arc::new(AtomicU64::new(0));
    let mut workers = tokio::task::JoinSet::new();

    // The foreign client: its own session, plain zenoh queries, half of them not CDR at all.
    let foreign = Bus::open(connect, "foreign").await?;
    let key = interfaces::topic::service_key(&connect.namespace, topics::DR_TRANSFORM.name());
    let valid = interfaces::codec::encode(query, TransformRequest::TYPE_NAME)?;
    for w in 0..in_flight {
        let (session, key, valid) = (foreign.session().clone(), key.clone(), valid.clone());
        let (stop, sent, answered) = (stop.clone(), foreign_sent.clone(), foreign_replied.clone());
        workers.spawn(async move {
            let mut i = w;
            while !stop.load(Ordering::Relaxed) {
                let payload = if i % 2 == 0 {
                    valid.clone()
                } else {
                    vec![0xde, 0xad, 0xbe, 0xef, i as u8]
                };
                i += 1;
                sent.fetch_add(1, Ordering::Relaxed);
                let Ok(replies) = session
                    .get(&key)
                    .payload(payload)
                    .timeout(Duration::from_secs(2))
                    .await
                else {
                    continue;
                };
                while let Ok(reply) = replies.recv_async().await {
                    if reply.result().is_ok() {
                        answered.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        });
    }
    // A robocog component flooding with well-formed calls: its own share, refused when full.
    let flooder = Bus::open(connect, "flooder").await?;
    for _ in 0..in_flight {
        let (bus, query) = (flooder.clone(), query.clone());
        let (stop, sent, answered, refused) = (
            stop.clone(),
            component_sent.clone(),
            component_answered.clone(),
            component_refused.clone(),
        );
        workers.spawn(async move {
            while !stop.load(Ordering::Relaxed) {
                sent.fetch_add(1, Ordering::Relaxed);
                match bus
                    .call(&topics::DR_TRANSFORM, &query, Duration::from_secs(2))
                    .await
                {
                    Ok(_) => answered.fetch_add(1, Ordering::Relaxed),
                    Err(_) => refused.fetch_add(1, Ordering::Relaxed),
                };
            }
        });
    }

    // The game's calls, one at a time, while it lasts.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let mut times = Vec::new();
    let mut failed = 0;
    let start = Instant::now();
    while start.elapsed() < seconds {
        let t0 = Instant::now();
        match game
            .call(&topics::DR_TRANSFORM, query, Duration::from_secs(2))
            .await
        {
            Ok(_) => times.push(t0.elapsed().as_nanos() as u64),
            Err(_) => failed += 1,
        }
    }
    stop.store(true, Ordering::Relaxed);
    let stopped = Instant::now();
    while workers.join_next().await.is_some() {}
    let settled_after_stop_ms = stopped.elapsed().as_secs_f64() * 1e3;

    let counters: Vec<(String, u64)> = counters()
        .await
        .into_iter()
        .filter(|(k, v)| k.contains("dr/transform") && *v > 0)
        .collect();
    let sum = |prefix: &str| {
        counters
            .iter()
            .filter(|(k, _)| k.starts_with(prefix))
            .map(|(_, v)| v)
            .sum()
    };
    Ok(Flood {
        seconds: seconds.as_secs_f64(),
        game: stats("dr/transform, the game's client", times),
        game_failed: failed,
        foreign_sent: foreign_sent.load(Ordering::Relaxed),
        foreign_replied: foreign_replied.load(Ordering::Relaxed),
        component_sent: component_sent.load(Ordering::Relaxed),
        component_answered: component_answered.load(Ordering::Relaxed),
        component_refused: component_refused.load(Ordering::Relaxed),
        busy: sum("service_busy/"),
        expired: sum("service_expired/"),
        settled_after_stop_ms,
        counters,
    })
}
