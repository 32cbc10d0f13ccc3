//! The simulated person as a component: plays a scenario (speaks commands into `audio/in`,
//! moves the ball on `sim/ball`) and checks what the robot does. Exits 0 when the scenario
//! completes, 1 at the first expectation not met (naming the step and what was seen instead).

use crate::person::{self, PersonConfig, VoiceOut};
use crate::scenario::Scenario;
use interfaces::node::{Component, Interface};
use interfaces::{Bus, Shutdown, topics};

/// The simulated person's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// A built-in scenario (`sims/loki_world/scenarios/`, by its name: still, moving,
    /// out_of_view, unreachable, beside, confirm_yes, barge_in, ...; a wrong name lists them
    /// all) or a TOML file.
    #[arg(long, default_value = "still")]
    pub scenario: String,
    /// `sim/ball` rate (Hz).
    #[arg(long, default_value_t = 60.0)]
    pub ball_rate_hz: f64,
    /// The robot's hand frame in the DR (the hand centre of the reaching arm).
    #[arg(long, default_value = "left_hand_center")]
    pub hand_frame: String,
    /// The robot's head camera optical frame in the DR.
    #[arg(long, default_value = "head_rgbd_optical_frame")]
    pub camera_frame: String,
    /// Seconds of room noise before the first step.
    #[arg(long, default_value_t = 2.0)]
    pub settle_s: f64,
    /// Seed of the room noise.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Play the scenario this many times, each time as a new visitor (the ball back at its start,
    /// what the last visitor saw forgotten); the robot starts a new game when greeted after
    /// the last one finished. For soak runs: `scripts/bench soak`.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub games: u32,
    /// Seconds between one visitor's last step and the next one's first.
    #[arg(long, default_value_t = 2.0)]
    pub visitor_gap_s: f64,
    /// Check the scenario and print its steps, then exit.
    #[arg(long)]
    pub check: bool,
    /// Where her voice goes: `bus`, straight onto audio/in; `pulse`, into a sound server's sink
    /// (the room) for the robot's microphone (`audio_io`) to capture.
    #[arg(long, value_enum, default_value_t = Voice::Bus)]
    pub voice: Voice,
    /// With `--voice pulse`: the sound server's address; empty: libpulse's usual one (which
    /// honours PULSE_SERVER).
    #[arg(long, default_value = "")]
    pub voice_server: String,
    /// With `--voice pulse`: the sink standing for the room.
    #[arg(long, default_value = "@DEFAULT_SINK@")]
    pub voice_sink: String,
}

/// `--voice`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Voice {
    Bus,
    Pulse,
}

/// The `loki_world` component.
#[derive(Debug)]
pub struct LokiWorld;

impl Component for LokiWorld {
    const NAME: &'static str = "loki_world";
    const ABOUT: &'static str = "The simulated person and ball of the touch-the-ball game: plays a \
        scenario (speaks commands into `audio/in`, moves the ball on `sim/ball`) and checks what \
        the robot does. Exits 0 when the scenario completes, 1 at the first expectation not met \
        (naming the step and what was seen instead).";
    type Config = Config;
    /// The person, and whether `--check` asked only for the scenario's steps.
    type Prepared = (PersonConfig, bool);

    fn interface(config: &Config) -> Interface {
        let i = Interface::new(Self::NAME).publishes(&topics::SIM_BALL);
        let i = match config.voice {
            Voice::Bus => i.publishes(&topics::AUDIO_IN),
            Voice::Pulse => i,
        };
        i.subscribes(&topics::SPEECH_SPEAKING)
            .subscribes(&topics::EXECUTIVE_TRANSITIONS)
            .subscribes(&topics::BODY_REACH_STATUS)
            .subscribes(&topics::VISION_BALL_EVENTS)
            .calls(&topics::DR_TRANSFORM)
    }

    /// Load and check the scenario.
    fn prepare(config: Config) -> anyhow::Result<(PersonConfig, bool)> {
        let scenario = Scenario::load(&config.scenario)?;
        if !(config.ball_rate_hz.is_finite()
            && config.ball_rate_hz > 0.0
            && config.ball_rate_hz <= 1000.0)
        {
            anyhow::bail!("--ball-rate-hz must be in (0, 1000]");
        }
        for (flag, v) in [
            ("--settle-s", config.settle_s),
            ("--visitor-gap-s", config.visitor_gap_s),
        ] {
            if !(v.is_finite() && (0.0..=600.0).contains(&v)) {
                anyhow::bail!("{flag} must be a number of seconds in [0, 600], not {v}");
            }
        }
        let voice_out = match config.voice {
            Voice::Bus => VoiceOut::Bus,
            Voice::Pulse => {
                let server = (!config.voice_server.is_empty()).then_some(config.voice_server);
                let devices = pulse::devices(server.as_deref())?;
                if !devices.has(pulse::Kind::Sink, &config.voice_sink) {
                    return Err(pulse::Error::NoSuchDevice {
                        kind: pulse::Kind::Sink,
                        name: config.voice_sink,
                        listing: devices.listing(pulse::Kind::Sink),
                    }
                    .into());
                }
                VoiceOut::Pulse {
                    server,
                    sink: config.voice_sink,
                }
            }
        };
        let person = PersonConfig {
            scenario,
            ball_rate_hz: config.ball_rate_hz,
            hand_frame: config.hand_frame,
            camera_frame: config.camera_frame,
            settle_s: config.settle_s,
            seed: config.seed,
            voice_out,
            games: config.games,
            visitor_gap_s: config.visitor_gap_s,
        };
        Ok((person, config.check))
    }

    /// `--check`: the scenario's steps on stdout, and no bus.
    fn without_bus((person, check): &(PersonConfig, bool)) -> Option<anyhow::Result<()>> {
        check.then(|| {
            let scenario = &person.scenario;
            println!(
                "{}: {} ({} steps)",
                scenario.name,
                scenario.description,
                scenario.steps.len()
            );
            for (i, s) in scenario.steps.iter().enumerate() {
                println!("{:3}. {s:?}", i + 1);
            }
            Ok(())
        })
    }

    async fn run(
        bus: Bus,
        (cfg, _): (PersonConfig, bool),
        shutdown: Shutdown,
    ) -> anyhow::Result<()> {
        let games = person::run(bus, cfg, shutdown).await?;
        if games.len() > 1 {
            let total: f64 = games.iter().map(|o| o.duration_s).sum();
            println!(
                "person: all {} games completed, {:.1} s of play",
                games.len(),
                total
            );
        }
        Ok(())
    }
}
