#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: measures real UDP and bus latency on the wall clock"
)]
//! `scripts/bench coach`: the bridge's two hot paths on loopback, measured end to end.
//!
//! In one process: a router (as `robocog launch` hosts it), the bridge's `run` on its own bus
//! session, and this program playing both the operator (a bus client) and the robot (UDP
//! sockets on 127.0.0.2).
//! - command: `nao/command` published on the bus -> the 11-byte packet received at the robot;
//! - debug: a 356-byte debug packet sent by the robot -> `nao/world_model` received on the bus.
//!
//! The issue names no peer program; as a floor, the same run measures a bare UDP hop on
//! loopback (send -> receive), which no bridge can beat. Targets: p99 under 1 ms for each path.

use interfaces::{Bus, ConnectArgs, topics};
use nao_bridge::component::{Config, run};
use spl::encode_debug;
use spl::types::*;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() as f64 - 1.0) * p).round() as usize]
}

fn free_port() -> anyhow::Result<u16> {
    Ok(UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port())
}

fn robot_model() -> NaoLocalModel {
    NaoLocalModel {
        header: Default::default(),
        player_number: 2,
        team_number: 19,
        fallen: false,
        pose: FieldPose {
            x_mm: -1000.0,
            y_mm: 200.0,
            theta_rad: 0.3,
        },
        ball_age_s: 0.1,
        ball: FieldPoint::new(500.0, -300.0),
        role: PlayerRole::Controlled,
        obstacles_seen: 1,
        obstacles: vec![NaoObstacle {
            kind: ObstacleKind::Opponent,
            center: FieldPoint::new(2000.0, 0.0),
            last_seen_ms: 1000,
        }],
        message_budget: 1000,
        secs_remaining: 80,
        arm_contact: [false; 2],
        arm_push_direction: [0; 2],
        arm_last_contact_ms: [0; 2],
        time_since_whistle_ms: 0,
        whistle: WhistleState::NotDetected,
        team_ball: FieldPoint::new(500.0, -300.0),
        team_ball_velocity: FieldPoint::new(0.0, 0.0),
        battery: 0.9,
        cpu_temperature_c: 50.0,
        referee_gesture: 0,
    }
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() -> anyhow::Result<()> {
    let n: usize = std::env::args()
        .skip_while(|a| a != "--n")
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let (_router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0").await?;
    let ns = format!("bench-coach-{}", std::process::id());
    let args = ConnectArgs::to_router(&endpoint, &ns);
    let (debug_port, gc_port) = (free_port()?, free_port()?);
    let robot = UdpSocket::bind("127.0.0.2:0")?;
    robot.set_read_timeout(Some(Duration::from_secs(2)))?;
    let command_port = robot.local_addr()?.port();
    let config = Config {
        controlled: "127.0.0.2".parse()?,
        teammate: None,
        command_port,
        listen: "127.0.0.1".parse()?,
        debug_port,
        gamecontroller_port: gc_port,
        team_number: 19,
        link_timeout_s: 5.0,
        dr_updates: false,
        propose_via: Default::default(),
    };
    let bridge_bus = Bus::open(&args, "nao_bridge").await?;
    let (stop, shutdown) = interfaces::Shutdown::new();
    let bridge = tokio::spawn(run(bridge_bus, config, shutdown));
    let bus = Bus::open(&args, "bench-operator").await?;
    let commands = bus.publisher(&topics::NAO_COMMAND).await?;
    let world = bus.subscriber(&topics::NAO_WORLD_MODEL).await?;
    tokio::time::sleep(Duration::from_millis(500)).await;

    // Path 1: bus command -> UDP packet at the robot.
    let mut cmd_us = Vec::with_capacity(n);
    let mut buf = [0u8; 64];
    for i in 0..n + 50 {
        let mut c = NaoCommand {
            body: NaoBody::GoToPosition,
            target: FieldPoint::new(i as f32, 0.0),
            source: "bench".into(),
            ..Default::default()
        };
        let t = Instant::now();
        commands.publish(&mut c).await?;
        let r = tokio::task::block_in_place(|| robot.recv_from(&mut buf));
        let dt = t.elapsed();
        let (len, _) =
            r.map_err(|e| anyhow::anyhow!("command {i} never reached the robot: {e}"))?;
        anyhow::ensure!(len == 11, "the robot got {len} bytes");
        if i >= 50 {
            cmd_us.push(dt.as_secs_f64() * 1e6);
        }
    }

    // Path 2: debug packet at the bridge -> world model on the bus.
    let packet = encode_debug(&robot_model()).map_err(|e| anyhow::anyhow!("{e}"))?;
    let bridge_debug = ("127.0.0.1", debug_port);
    let mut dbg_us = Vec::with_capacity(n);
    for i in 0..n + 50 {
        let t = Instant::now();
        robot.send_to(&packet, bridge_debug)?;
        tokio::time::timeout(Duration::from_secs(2), world.recv())
            .await
            .map_err(|_| anyhow::anyhow!("no world model for debug packet {i}"))??;
        if i >= 50 {
            dbg_us.push(t.elapsed().as_secs_f64() * 1e6);
        }
    }

    // Floor: one bare UDP hop on loopback.
    let rx = UdpSocket::bind("127.0.0.1:0")?;
    rx.set_read_timeout(Some(Duration::from_secs(2)))?;
    let to = rx.local_addr()?;
    let mut udp_us = Vec::with_capacity(n);
    for _ in 0..n {
        let t = Instant::now();
        robot.send_to(&packet, to)?;
        rx.recv_from(&mut [0u8; 512])?;
        udp_us.push(t.elapsed().as_secs_f64() * 1e6);
    }
    let _ = stop.send(true);
    let _ = bridge.await;

    let (c50, c99) = (pct(&mut cmd_us, 0.5), pct(&mut cmd_us, 0.99));
    let (d50, d99) = (pct(&mut dbg_us, 0.5), pct(&mut dbg_us, 0.99));
    let (u50, u99) = (pct(&mut udp_us, 0.5), pct(&mut udp_us, 0.99));
    println!();
    println!("| path ({n} samples) | p50 µs | p99 µs | target p99 |");
    println!("|---|---:|---:|---:|");
    println!("| bus command -> UDP packet at the robot | {c50:.1} | {c99:.1} | < 1000 |");
    println!(
        "| debug packet at the bridge -> world model on the bus | {d50:.1} | {d99:.1} | < 1000 |"
    );
    println!("| floor: bare UDP hop on loopback | {u50:.1} | {u99:.1} | |");
    println!(
        "targets: command p99 under 1 ms ({}), debug-to-world-model p99 under 1 ms ({})",
        if c99 < 1000.0 { "met" } else { "NOT met" },
        if d99 < 1000.0 { "met" } else { "NOT met" }
    );
    println!(
        "{}",
        serde_json::json!({
            "command_to_udp_p50_us": c50, "command_to_udp_p99_us": c99,
            "debug_to_world_model_p50_us": d50, "debug_to_world_model_p99_us": d99,
            "udp_floor_p50_us": u50, "udp_floor_p99_us": u99,
            "ratio_command_p50_over_udp_floor": c50 / u50, "ratio_debug_p50_over_udp_floor": d50 / u50,
        })
    );
    Ok(())
}
