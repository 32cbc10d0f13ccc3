//! The `loki_world` binary: the simulated person of the touch-the-ball game. See the library.

use clap::Parser;
use interfaces::node::{self, Interface, NodeArgs};
use interfaces::topics;
use loki_world::person::{self, PersonConfig};
use loki_world::scenario::Scenario;
use std::process::ExitCode;

/// The simulated person and ball of the touch-the-ball game: plays a scenario (speaks commands
/// into `audio/in`, moves the ball on `sim/ball`) and checks what the robot does. Exits 0 when
/// the scenario completes, 1 at the first expectation not met (naming the step and what was
/// seen instead).
#[derive(Debug, Parser)]
#[command(name = "loki_world")]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// A built-in scenario (still, moving, out_of_view, unreachable, confirm_yes, bench,
    /// tracker_restart) or a TOML
    /// file.
    #[arg(long, default_value = "still")]
    scenario: String,
    /// `sim/ball` rate (Hz).
    #[arg(long, default_value_t = 60.0)]
    ball_rate_hz: f64,
    /// The robot's hand frame in the DR (the hand centre of the reaching arm).
    #[arg(long, default_value = "left_hand_center")]
    hand_frame: String,
    /// The robot's head camera optical frame in the DR.
    #[arg(long, default_value = "head_rgbd_optical_frame")]
    camera_frame: String,
    /// Seconds of room noise before the first step.
    #[arg(long, default_value_t = 2.0)]
    settle_s: f64,
    /// Seed of the room noise.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Check the scenario and print its steps, then exit.
    #[arg(long)]
    check: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let interface = Interface::new("loki_world")
        .publishes(&topics::SIM_BALL)
        .publishes(&topics::AUDIO_IN)
        .subscribes(&topics::SPEECH_SPEAKING)
        .subscribes(&topics::EXECUTIVE_TRANSITIONS)
        .subscribes(&topics::BODY_REACH_STATUS)
        .subscribes(&topics::VISION_BALL_EVENTS)
        .calls(&topics::DR_TRANSFORM);
    if args.node.describe {
        return node::run(args.node, interface, |_, _| async { Ok(()) });
    }
    let scenario = match Scenario::load(&args.scenario) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("loki_world: {e}");
            return ExitCode::FAILURE;
        }
    };
    if args.check {
        println!(
            "{}: {} ({} steps)",
            scenario.name,
            scenario.description,
            scenario.steps.len()
        );
        for (i, s) in scenario.steps.iter().enumerate() {
            println!("{:3}. {s:?}", i + 1);
        }
        return ExitCode::SUCCESS;
    }
    if !(args.ball_rate_hz.is_finite() && args.ball_rate_hz > 0.0 && args.ball_rate_hz <= 1000.0) {
        eprintln!("loki_world: --ball-rate-hz must be in (0, 1000]");
        return ExitCode::FAILURE;
    }
    let cfg = PersonConfig {
        scenario,
        ball_rate_hz: args.ball_rate_hz,
        hand_frame: args.hand_frame,
        camera_frame: args.camera_frame,
        settle_s: args.settle_s.clamp(0.0, 60.0),
        seed: args.seed,
    };
    node::run(args.node, interface, move |bus, shutdown| async move {
        let name = cfg.scenario.name.clone();
        let o = person::run(bus, cfg, shutdown).await?;
        println!(
            "person: scenario {name:?} completed: {} steps in {:.1} s{}",
            o.steps,
            o.duration_s,
            o.closest_hand_to_ball_m
                .map(|d| format!("; closest hand to ball surface {:.1} cm", d * 100.0))
                .unwrap_or_default()
        );
        // One machine-readable line for benchmarks: each expectation's delay after its action, and
        // that action.
        println!("person: timings {}", serde_json::to_string(&o.timings)?);
        Ok(())
    })
}
