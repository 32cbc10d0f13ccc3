//! `scripts/bench bus`, second part: the bus between two machines, against the raw link.
//!
//! The script makes two network namespaces joined by a veth pair (machines A and B) and runs
//! this one binary in them with a role each:
//!
//! - `--role router`: one machine's zenoh router, configured as `robocog launch` and `robocog
//!   agent` configure it (`interfaces::router::machine_router_config`):
//!   listens on loopback for its components and on the machine's endpoint (`tcp/` or `tls/`
//!   `<ip>:<port>`) for the other router, and dials the other machine's endpoint. With
//!   `--tls-dir`, mutual TLS and the graph's access control.
//!   Prints `ready` once it listens, then runs until killed (or `--max-secs`).
//! - `--role echo` (machine B, a client of B's router): sends every `Ping` of `bench/ping` back
//!   on `bench/pong`, counts the `Counter64` of `bench/count` and reports (count, time from the
//!   first to the last) on `bench/count_report` once it has them all (or after 5 s of silence).
//! - `--role probe` (machine A, a client of A's router): ping-pong of 64 B, 4 KiB and 64 KiB
//!   `Ping`s through the two routers (one-way = round trip / 2, p50 and p99), then 8-byte
//!   `Counter64` messages as fast as it can publish them, counted by the echo. Prints one JSON
//!   object.
//! - `--role tcp-echo` / `--role tcp-probe`: the floor, plain TCP between the two machines'
//!   addresses over the same veth (`TCP_NODELAY`): ping-pong of the same payloads (a 4-byte
//!   length and the bytes, echoed whole), and one-way 8-byte messages counted by the echo, one
//!   `write` each (the floor of the throughput), then 1024 to a `write` (what the link carries
//!   when batched, as zenoh batches). The probe prints one JSON object.
//! - `--role report`: reads the JSON of the same-host bench and of the runs above, prints the
//!   tables and, last, one JSON object with every figure.
//!
//! Shared memory is off everywhere (routers and clients): the namespaces share the host's
//! memory, two machines do not. Multicast scouting (and gossip) is off everywhere.
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark measures and paces on the wall clock"
)]

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use interfaces::msg::std_msgs::{Counter64, Ping};
use interfaces::router::{MachineRouter, TlsFiles, machine_router_config};
use interfaces::{Bus, ConnectArgs, topics};
use serde_json::{Map, Value};
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The payload sizes of the latency rows, with their labels (table, JSON keys).
const SIZES: [(&str, &str, usize); 3] = [
    ("64 B", "64b", 64),
    ("4 KiB", "4kib", 4096),
    ("64 KiB", "64kib", 65536),
];
/// How long a round trip (or a reply) may take before the run fails.
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Role {
    Router,
    Echo,
    Probe,
    TcpEcho,
    TcpProbe,
    Report,
}

/// The bus between two machines (network namespaces), and the raw link under it.
#[derive(Debug, Parser)]
struct Cli {
    #[arg(long, value_enum)]
    role: Role,
    /// router: its endpoints (loopback, then the machine's); tcp-echo: `<ip>:<port>`.
    #[arg(long, value_delimiter = ',')]
    listen: Vec<String>,
    /// router: the other machines' endpoints; echo, probe: the local router; tcp-probe:
    /// `<ip>:<port>` of the tcp-echo.
    #[arg(long, value_delimiter = ',')]
    connect: Vec<String>,
    /// The bus namespace of the echo and the probe.
    #[arg(long, default_value = "bench-machines")]
    namespace: String,
    /// router: the folder of ca.pem, <machine>.pem, <machine>.key (mutual TLS between routers).
    #[arg(long)]
    tls_dir: Option<PathBuf>,
    /// router: this machine's name (its certificate's).
    #[arg(long, default_value = "a")]
    machine: String,
    /// router: every machine of the graph (the common names the access control lets in).
    #[arg(long, value_delimiter = ',', default_value = "a,b")]
    machines: Vec<String>,
    /// Fewer samples (a tenth).
    #[arg(long)]
    quick: bool,
    /// Servers (router, echo, tcp-echo) exit after this long, whatever happens.
    #[arg(long, default_value_t = 1800)]
    max_secs: u64,
    /// report: the same-host bench's output (its last line is its JSON object).
    #[arg(long)]
    same_host: Option<PathBuf>,
    /// report: the tcp-probe's JSON.
    #[arg(long)]
    floor: Option<PathBuf>,
    /// report: the probe's JSON, routers joined over tcp.
    #[arg(long)]
    bus: Option<PathBuf>,
    /// report: the probe's JSON, routers joined over mutual TLS.
    #[arg(long)]
    bus_tls: Option<PathBuf>,
}

impl Cli {
    /// Round trips per payload size, and warm-up round trips before them.
    fn samples(&self) -> (usize, usize) {
        if self.quick { (200, 20) } else { (2000, 200) }
    }
    /// 8-byte messages sent one way for the throughput.
    fn messages(&self) -> u64 {
        if self.quick { 50_000 } else { 500_000 }
    }
}

fn pct(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// p50 and p99 of one-way latencies (µs).
fn summarise(mut one_way_us: Vec<f64>) -> (f64, f64) {
    one_way_us.sort_by(|a, b| a.total_cmp(b));
    (pct(&one_way_us, 0.5), pct(&one_way_us, 0.99))
}

fn announce_ready(what: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "ready {what}")?;
    out.flush()?;
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The bus: routers, echo, probe.

/// A machine's router, configured as `robocog::machines::router_config` does (plus shared
/// memory off: two machines share none).
async fn router(cli: &Cli) -> anyhow::Result<()> {
    let [local_listen, endpoint] = cli.listen.as_slice() else {
        anyhow::bail!("--listen takes two endpoints: loopback, then the machine's");
    };
    let tls = cli
        .tls_dir
        .as_ref()
        .map(|dir| TlsFiles::in_folder(dir, &cli.machine));
    if let Some(p) = tls.as_ref().and_then(|t| t.missing().first().copied()) {
        bail!("missing {}", p.display());
    }
    // The configuration `robocog launch` and `robocog agent` give a machine's router.
    let mut config = machine_router_config(&MachineRouter {
        local_listen: local_listen.clone(),
        endpoint: endpoint.clone(),
        peers: cli.connect.clone(),
        tls,
        machines: cli.machines.clone(),
        namespace: cli.namespace.clone(),
        ros2_domain: None,
    })?;
    // Two namespaces share /dev/shm, two machines do not.
    config
        .insert_json5("transport/shared_memory/enabled", "false")
        .map_err(|e| anyhow::anyhow!("router shared memory: {e}"))?;
    let session = zenoh::open(config)
        .await
        .map_err(|e| anyhow::anyhow!("cannot start the router on {:?}: {e}", cli.listen))?;
    let locators: Vec<String> = session
        .info()
        .locators()
        .await
        .into_iter()
        .map(|l| l.to_string())
        .collect();
    eprintln!(
        "router {}: listening on {}",
        cli.machine,
        locators.join(", ")
    );
    announce_ready(&locators.join(","))?;
    tokio::time::sleep(Duration::from_secs(cli.max_secs)).await;
    Ok(())
}

/// A client of the local router, shared memory off.
async fn open_bus(cli: &Cli, name: &str) -> anyhow::Result<Bus> {
    let endpoint = cli
        .connect
        .first()
        .context("--connect <the local router's endpoint> is needed")?;
    let mut args = ConnectArgs::to_router(endpoint, &cli.namespace);
    args.no_shm = true;
    Ok(Bus::open(&args, name).await?)
}

async fn echo(cli: &Cli) -> anyhow::Result<()> {
    let bus = open_bus(cli, "bench-machines-echo").await?;
    let pings = bus.subscriber(&topics::BENCH_PING).await?;
    let pongs = bus.publisher(&topics::BENCH_PONG).await?;
    let counts = bus
        .subscriber_named::<Counter64>(topics::BENCH_COUNT.name(), 65536)
        .await?;
    let report = bus.publisher(&topics::BENCH_COUNT_REPORT).await?;
    let expected = cli.messages();
    let pinger = tokio::spawn(async move {
        while let Ok(mut m) = pings.recv().await {
            if let Err(e) = pongs.publish(&mut m).await {
                eprintln!("echo: cannot send a pong back: {e}");
                return;
            }
        }
    });
    let counter = tokio::spawn(async move {
        loop {
            // The first message of a run, then every other until all are in or 5 s of silence.
            let Ok(_) = counts.recv().await else { return };
            let start = Instant::now();
            let mut last = start;
            let mut got = 1u64;
            while got < expected {
                match counts.recv_timeout(Duration::from_secs(5)).await {
                    Ok(Some(_)) => {
                        got += 1;
                        last = Instant::now();
                    }
                    _ => break,
                }
            }
            let mut m = Ping {
                sent_ns: last.duration_since(start).as_nanos() as u64,
                data: got.to_le_bytes().to_vec(),
                ..Default::default()
            };
            if let Err(e) = report.publish(&mut m).await {
                eprintln!("echo: cannot report the count: {e}");
                return;
            }
        }
    });
    announce_ready("echo")?;
    tokio::select! {
        _ = tokio::time::sleep(Duration::from_secs(cli.max_secs)) => {}
        r = pinger => r?,
        r = counter => r?,
    }
    Ok(())
}

/// The probe's ping-pong: pings carry a sequence number in `sent_ns`; pongs of earlier pings
/// (a late answer to the wait for the route) are skipped.
struct Pinger {
    out: interfaces::Publisher<Ping>,
    back: interfaces::Subscriber<Ping>,
    seq: u64,
}

impl Pinger {
    /// One-way latency (µs) of one round trip of `ping`, or `None` when no answer came in
    /// `wait`.
    async fn once(&mut self, ping: &mut Ping, wait: Duration) -> anyhow::Result<Option<f64>> {
        self.seq += 1;
        ping.sent_ns = self.seq;
        let t = Instant::now();
        self.out.publish(ping).await?;
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            match tokio::time::timeout_at(deadline, self.back.recv()).await {
                Err(_) => return Ok(None),
                Ok(pong) => {
                    let pong = pong?;
                    if pong.sent_ns == self.seq {
                        anyhow::ensure!(pong.data.len() == ping.data.len(), "echo of wrong size");
                        return Ok(Some(t.elapsed().as_secs_f64() * 1e6 / 2.0));
                    }
                }
            }
        }
    }
}

async fn probe(cli: &Cli) -> anyhow::Result<()> {
    let bus = open_bus(cli, "bench-machines-probe").await?;
    let mut pinger = Pinger {
        out: bus.publisher(&topics::BENCH_PING).await?,
        back: bus.subscriber(&topics::BENCH_PONG).await?,
        seq: 0,
    };
    let reports = bus.subscriber(&topics::BENCH_COUNT_REPORT).await?;

    // The routers join each other and learn the echo's subscription: ping until it answers.
    let t0 = Instant::now();
    let mut small = Ping {
        data: vec![0xab; 64],
        ..Default::default()
    };
    loop {
        if pinger
            .once(&mut small, Duration::from_millis(250))
            .await?
            .is_some()
        {
            break;
        }
        if t0.elapsed() > Duration::from_secs(30) {
            bail!("no answer from the echo on the other machine after 30 s");
        }
    }
    eprintln!(
        "probe: the echo answers through both routers ({:.1} s after start)",
        t0.elapsed().as_secs_f64()
    );

    let mut json = Map::new();
    let (n, warm) = cli.samples();
    for (label, key, size) in SIZES {
        eprintln!("probe: latency {label} ({n} round trips, {warm} warm-up)...");
        let mut ping = Ping {
            data: vec![0xab; size],
            ..Default::default()
        };
        let mut one_way = Vec::with_capacity(n);
        for i in 0..n + warm {
            let us = pinger
                .once(&mut ping, REPLY_TIMEOUT)
                .await?
                .with_context(|| format!("a {label} ping got no answer in {REPLY_TIMEOUT:?}"))?;
            if i >= warm {
                one_way.push(us);
            }
        }
        let (p50, p99) = summarise(one_way);
        json.insert(format!("p50_us_{key}"), p50.into());
        json.insert(format!("p99_us_{key}"), p99.into());
    }

    let sent = cli.messages();
    eprintln!("probe: throughput ({sent} Counter64 messages one way)...");
    let counter = bus.publisher(&topics::BENCH_COUNT).await?;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let t = Instant::now();
    let mut m = Counter64::default();
    for i in 0..sent {
        m.value = i;
        counter.publish(&mut m).await?;
    }
    let send_s = t.elapsed().as_secs_f64();
    let report = reports
        .recv_timeout(Duration::from_secs(60))
        .await?
        .context("the echo did not report its count in 60 s")?;
    let got = u64::from_le_bytes(
        report
            .data
            .get(..8)
            .and_then(|b| b.try_into().ok())
            .context("a count report without its count")?,
    );
    let secs = (report.sent_ns as f64 / 1e9).max(1e-9);
    json.insert("throughput_msgs_per_s".into(), (got as f64 / secs).into());
    json.insert("throughput_sent".into(), sent.into());
    json.insert("throughput_received".into(), got.into());
    json.insert(
        "throughput_send_msgs_per_s".into(),
        (sent as f64 / send_s.max(1e-9)).into(),
    );
    println!("{}", Value::Object(json));
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// The floor: plain TCP over the same veth.

/// The first byte of a floor connection: ping-pong, or one-way throughput.
const TCP_PINGPONG: u8 = b'P';
const TCP_THROUGHPUT: u8 = b'T';

fn tcp_echo(cli: &Cli) -> anyhow::Result<()> {
    let addr = cli
        .listen
        .first()
        .context("--listen <ip>:<port> is needed")?;
    let listener = TcpListener::bind(addr).with_context(|| format!("cannot listen on {addr}"))?;
    eprintln!("tcp-echo: listening on {addr}");
    announce_ready(addr)?;
    let max = Duration::from_secs(cli.max_secs);
    std::thread::Builder::new()
        .name("max-secs".into())
        .spawn(move || {
            std::thread::sleep(max);
            std::process::exit(0);
        })?;
    for conn in listener.incoming() {
        let conn = conn?;
        std::thread::Builder::new()
            .name("tcp-echo".into())
            .spawn(move || {
                if let Err(e) = tcp_serve(conn) {
                    eprintln!("tcp-echo: {e:#}");
                }
            })?;
    }
    Ok(())
}

fn tcp_serve(mut conn: TcpStream) -> anyhow::Result<()> {
    conn.set_nodelay(true)?;
    let mut kind = [0u8; 1];
    conn.read_exact(&mut kind)?;
    match kind[0] {
        TCP_PINGPONG => {
            // [len u32 LE][len bytes], sent back whole in one write.
            let mut buf = Vec::new();
            loop {
                let mut len = [0u8; 4];
                match conn.read_exact(&mut len) {
                    Ok(()) => {}
                    Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(()),
                    Err(e) => return Err(e.into()),
                }
                let n = u32::from_le_bytes(len) as usize;
                buf.resize(4 + n, 0);
                buf[..4].copy_from_slice(&len);
                conn.read_exact(&mut buf[4..])?;
                conn.write_all(&buf)?;
            }
        }
        TCP_THROUGHPUT => {
            // [count u64 LE], then count 8-byte messages; answers [ns first..last, bytes/8].
            let mut count = [0u8; 8];
            conn.read_exact(&mut count)?;
            let want = u64::from_le_bytes(count) * 8;
            conn.set_read_timeout(Some(Duration::from_secs(5)))?;
            let mut buf = vec![0u8; 1 << 16];
            let (mut got, mut start, mut last) = (0u64, None, Instant::now());
            while got < want {
                match conn.read(&mut buf) {
                    Ok(0) | Err(_) => break,
                    Ok(n) => {
                        last = Instant::now();
                        start.get_or_insert(last);
                        got += n as u64;
                    }
                }
            }
            let ns = last.duration_since(start.unwrap_or(last)).as_nanos() as u64;
            let mut reply = ns.to_le_bytes().to_vec();
            reply.extend_from_slice(&(got / 8).to_le_bytes());
            conn.write_all(&reply)?;
            Ok(())
        }
        k => bail!("unknown connection kind {k}"),
    }
}

/// Connect to the tcp-echo, retrying for 10 s (it may still be starting).
fn tcp_connect(addr: &str, kind: u8) -> anyhow::Result<TcpStream> {
    let t0 = Instant::now();
    let mut conn = loop {
        match TcpStream::connect(addr) {
            Ok(c) => break c,
            Err(e) if t0.elapsed() > Duration::from_secs(10) => {
                return Err(e).with_context(|| format!("cannot connect to {addr}"));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(100)),
        }
    };
    conn.set_nodelay(true)?;
    conn.set_read_timeout(Some(REPLY_TIMEOUT))?;
    conn.write_all(&[kind])?;
    Ok(conn)
}

fn tcp_probe(cli: &Cli) -> anyhow::Result<()> {
    let addr = cli
        .connect
        .first()
        .context("--connect <ip>:<port> is needed")?;
    let mut json = Map::new();
    let (n, warm) = cli.samples();
    let mut conn = tcp_connect(addr, TCP_PINGPONG)?;
    for (label, key, size) in SIZES {
        eprintln!("tcp-probe: latency {label} ({n} round trips, {warm} warm-up)...");
        let mut frame = (size as u32).to_le_bytes().to_vec();
        frame.resize(4 + size, 0xab);
        let mut back = vec![0u8; 4 + size];
        let mut one_way = Vec::with_capacity(n);
        for i in 0..n + warm {
            let t = Instant::now();
            conn.write_all(&frame)?;
            conn.read_exact(&mut back)
                .with_context(|| format!("no answer to a {label} ping"))?;
            let us = t.elapsed().as_secs_f64() * 1e6 / 2.0;
            anyhow::ensure!(back[..4] == frame[..4], "echo of the wrong size");
            if i >= warm {
                one_way.push(us);
            }
        }
        let (p50, p99) = summarise(one_way);
        json.insert(format!("p50_us_{key}"), p50.into());
        json.insert(format!("p99_us_{key}"), p99.into());
    }
    drop(conn);

    let sent = cli.messages();
    eprintln!("tcp-probe: throughput ({sent} 8-byte messages one way, one write each)...");
    let (rate, got) = tcp_throughput(addr, sent, 1)?;
    json.insert("throughput_msgs_per_s".into(), rate.into());
    json.insert("throughput_sent".into(), sent.into());
    json.insert("throughput_received".into(), got.into());
    eprintln!("tcp-probe: throughput ({sent} 8-byte messages one way, {TCP_BATCH} to a write)...");
    let (rate, got) = tcp_throughput(addr, sent, TCP_BATCH)?;
    json.insert("batched_throughput_msgs_per_s".into(), rate.into());
    json.insert("batched_throughput_received".into(), got.into());
    println!("{}", Value::Object(json));
    Ok(())
}

/// Messages per write of the batched throughput floor (8 KiB writes).
const TCP_BATCH: u64 = 1024;

/// `sent` 8-byte messages one way, `batch` to a `write`, counted by the tcp-echo. Returns
/// (messages per second from the first to the last byte received, messages received).
fn tcp_throughput(addr: &str, sent: u64, batch: u64) -> anyhow::Result<(f64, u64)> {
    let mut conn = tcp_connect(addr, TCP_THROUGHPUT)?;
    conn.write_all(&sent.to_le_bytes())?;
    let mut buf = Vec::with_capacity(8 * batch as usize);
    let mut i = 0u64;
    while i < sent {
        buf.clear();
        let end = (i + batch).min(sent);
        for v in i..end {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        conn.write_all(&buf)?;
        i = end;
    }
    conn.set_read_timeout(Some(Duration::from_secs(60)))?;
    let mut reply = [0u8; 16];
    conn.read_exact(&mut reply)
        .context("the tcp-echo did not report its count")?;
    let (ns, got) = reply.split_at(8);
    let ns = u64::from_le_bytes(ns.try_into()?);
    let got = u64::from_le_bytes(got.try_into()?);
    Ok((got as f64 / (ns as f64 / 1e9).max(1e-9), got))
}

// ---------------------------------------------------------------------------------------------
// The report.

/// The JSON object on the last non-empty line of `path`.
fn last_json(path: &Path) -> anyhow::Result<Map<String, Value>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let line = text
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .with_context(|| format!("{} is empty", path.display()))?;
    match serde_json::from_str(line)
        .with_context(|| format!("the last line of {} is not JSON", path.display()))?
    {
        Value::Object(m) => Ok(m),
        _ => bail!("the last line of {} is not a JSON object", path.display()),
    }
}

fn num(m: &Map<String, Value>, key: &str) -> anyhow::Result<f64> {
    m.get(key)
        .and_then(Value::as_f64)
        .with_context(|| format!("no figure {key:?}"))
}

fn report(cli: &Cli) -> anyhow::Result<()> {
    let need = |p: &Option<PathBuf>, flag: &str| -> anyhow::Result<Map<String, Value>> {
        last_json(
            p.as_deref()
                .with_context(|| format!("--{flag} is needed"))?,
        )
    };
    let mut all = need(&cli.same_host, "same-host")?;
    let floor = need(&cli.floor, "floor")?;
    let bus = need(&cli.bus, "bus")?;
    let tls = cli.bus_tls.as_deref().map(last_json).transpose()?;

    let mut head = String::from(
        "| payload | veth floor p50 µs | veth floor p99 µs | bus, 2 routers (tcp) p50 µs | p99 µs | bus/floor p50 | bus/floor p99 |",
    );
    let mut rule = String::from("|---|---:|---:|---:|---:|---:|---:|");
    if tls.is_some() {
        head.push_str(" bus, 2 routers (mTLS) p50 µs | p99 µs | mTLS/floor p50 |");
        rule.push_str("---:|---:|---:|");
    }
    let mut rows = Vec::new();
    for (label, key, _) in SIZES {
        let (f50, f99) = (
            num(&floor, &format!("p50_us_{key}"))?,
            num(&floor, &format!("p99_us_{key}"))?,
        );
        let (b50, b99) = (
            num(&bus, &format!("p50_us_{key}"))?,
            num(&bus, &format!("p99_us_{key}"))?,
        );
        all.insert(format!("machines_floor_p50_us_{key}"), f50.into());
        all.insert(format!("machines_floor_p99_us_{key}"), f99.into());
        all.insert(format!("machines_p50_us_{key}"), b50.into());
        all.insert(format!("machines_p99_us_{key}"), b99.into());
        all.insert(format!("machines_ratio_p50_{key}"), (b50 / f50).into());
        all.insert(format!("machines_ratio_p99_{key}"), (b99 / f99).into());
        let mut row = format!(
            "| {label} | {f50:.1} | {f99:.1} | {b50:.1} | {b99:.1} | {:.2} | {:.2} |",
            b50 / f50,
            b99 / f99
        );
        if let Some(tls) = &tls {
            let (t50, t99) = (
                num(tls, &format!("p50_us_{key}"))?,
                num(tls, &format!("p99_us_{key}"))?,
            );
            all.insert(format!("machines_tls_p50_us_{key}"), t50.into());
            all.insert(format!("machines_tls_p99_us_{key}"), t99.into());
            all.insert(format!("machines_tls_ratio_p50_{key}"), (t50 / f50).into());
            row.push_str(&format!(" {t50:.1} | {t99:.1} | {:.2} |", t50 / f50));
        }
        rows.push(row);
    }
    let floor_tp = num(&floor, "throughput_msgs_per_s")?;
    let bus_tp = num(&bus, "throughput_msgs_per_s")?;
    let floor_batched_tp = num(&floor, "batched_throughput_msgs_per_s")?;
    all.insert(
        "machines_floor_throughput_msgs_per_s".into(),
        floor_tp.into(),
    );
    all.insert(
        "machines_floor_batched_throughput_msgs_per_s".into(),
        floor_batched_tp.into(),
    );
    all.insert("machines_throughput_msgs_per_s".into(), bus_tp.into());
    all.insert(
        "machines_ratio_throughput_bus_over_floor".into(),
        (bus_tp / floor_tp).into(),
    );
    let tls_tp = match &tls {
        Some(tls) => {
            let tp = num(tls, "throughput_msgs_per_s")?;
            all.insert("machines_tls_throughput_msgs_per_s".into(), tp.into());
            Some(tp)
        }
        None => None,
    };
    let lost = |m: &Map<String, Value>| -> String {
        let (s, r) = (num(m, "throughput_sent"), num(m, "throughput_received"));
        match (s, r) {
            (Ok(s), Ok(r)) if r < s => format!(" ({} of {} received)", r as u64, s as u64),
            _ => String::new(),
        }
    };

    println!();
    println!("Between two machines (two network namespaces joined by a veth pair, same host):");
    println!("one-way latency = round trip / 2; the bus goes probe -> router A -> router B ->");
    println!("echo and back; the floor is plain TCP (TCP_NODELAY) between the same two addresses.");
    println!();
    println!("{head}");
    println!("{rule}");
    for row in &rows {
        println!("{row}");
    }
    println!();
    println!("| one way, 8-byte messages, A to B | messages/s |");
    println!("|---|---:|");
    println!(
        "| veth floor: plain TCP, one write() per message | {floor_tp:.0}{} |",
        lost(&floor)
    );
    println!(
        "| veth, plain TCP, {TCP_BATCH} messages per write() (8 KiB): the link's capacity | {floor_batched_tp:.0} |"
    );
    println!(
        "| typed Counter64 through two routers (tcp link) | {bus_tp:.0}{} |",
        lost(&bus)
    );
    if let (Some(tp), Some(tls)) = (tls_tp, &tls) {
        println!(
            "| typed Counter64 through two routers (mTLS link) | {tp:.0}{} |",
            lost(tls)
        );
    }
    println!();
    println!("{}", Value::Object(all));
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.role {
        Role::TcpEcho => tcp_echo(&cli),
        Role::TcpProbe => tcp_probe(&cli),
        Role::Report => report(&cli),
        Role::Router | Role::Echo | Role::Probe => tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()?
            .block_on(async {
                match cli.role {
                    Role::Router => router(&cli).await,
                    Role::Echo => echo(&cli).await,
                    _ => probe(&cli).await,
                }
            }),
    }
}
