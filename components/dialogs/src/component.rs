//! The dialogs component: `speech/utterance`, `game/answer` and `speech/speaking` in;
//! `game/command` and `speech/say` out, around the [`Dialog`] machine.

use crate::machine::{Action, Dialog, DialogConfig, Heard};
use interfaces::msg::command::{CommandSource, GameCommand};
use interfaces::msg::speech::{SayRequest, SpeakingState};
use interfaces::node::{Component, Interface};
use interfaces::{Bus, Shutdown, topics};
use std::path::PathBuf;
use std::time::Duration;

/// The dialog's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// TOML file with the dialog settings (`high`, `low`, `answer_timeout_s`, `repeat_after`,
    /// `repeat_window_s`, `echo_guard_s`); flags override it.
    #[arg(long)]
    pub settings: Option<PathBuf>,
    /// Confidence at or above which a command is accepted at once.
    #[arg(long)]
    pub high: Option<f64>,
    /// Confidence below which an utterance is ignored.
    #[arg(long)]
    pub low: Option<f64>,
    /// How long to wait for a yes or no (s).
    #[arg(long)]
    pub answer_timeout_s: Option<f64>,
    /// The components that carry out `game/command` (comma-separated; empty: none). While none
    /// of them subscribes to it (one is restarting), a command is held, the robot says "One
    /// moment, please.", and the command goes out as soon as one is back.
    #[arg(long, value_delimiter = ',', default_value = "executive")]
    pub command_readers: Vec<String>,
    /// How long a held command waits for a reader before it is dropped, the person told so (s).
    #[arg(long, default_value_t = 15.0)]
    pub hold_s: f64,
}

/// What the dialog does with a command nobody reads yet.
#[derive(Debug, Clone, PartialEq)]
pub struct Hold {
    /// The components that carry out `game/command` (empty: never hold).
    pub readers: Vec<String>,
    /// How long a command is held at most.
    pub max: Duration,
}

/// What the robot says when it holds a command for a reader that is restarting.
pub const HOLDING: &str = "One moment, please.";
/// What it says when a held command waited too long and was dropped.
pub const HOLD_EXPIRED: &str = "Sorry, I could not do that. Please say it again.";
/// At most this many commands are held; older ones are dropped first.
const HELD_MAX: usize = 8;

/// The dialog's settings: the `--settings` file, then the flags over it, checked.
pub fn settings(args: &Config) -> anyhow::Result<DialogConfig> {
    let mut cfg = match &args.settings {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", p.display()))?;
            toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?
        }
        None => DialogConfig::default(),
    };
    if let Some(x) = args.high {
        cfg.high = x;
    }
    if let Some(x) = args.low {
        cfg.low = x;
    }
    if let Some(x) = args.answer_timeout_s {
        cfg.answer_timeout_s = x;
    }
    cfg.validate()?;
    Ok(cfg)
}

/// The `dialogs` component.
#[derive(Debug)]
pub struct Dialogs;

impl Component for Dialogs {
    const NAME: &'static str = "dialogs";
    const ABOUT: &'static str = "Confidence handling and the \"Did you say ...?\" loop.";
    type Config = Config;
    type Prepared = (DialogConfig, Hold);

    fn interface(_: &Config) -> Interface {
        Interface::new(Self::NAME)
            .subscribes(&topics::SPEECH_UTTERANCE)
            .subscribes(&topics::GAME_ANSWER)
            .subscribes(&topics::SPEECH_SPEAKING)
            .publishes(&topics::GAME_COMMAND)
            .publishes(&topics::SPEECH_SAY)
    }

    /// Read and check the settings before joining the bus.
    fn prepare(config: Config) -> anyhow::Result<(DialogConfig, Hold)> {
        anyhow::ensure!(
            config.hold_s.is_finite() && config.hold_s >= 0.0,
            "--hold-s must be a number of seconds >= 0, got {}",
            config.hold_s
        );
        let hold = Hold {
            readers: config
                .command_readers
                .iter()
                .map(|r| r.trim().to_string())
                .filter(|r| !r.is_empty())
                .collect(),
            max: Duration::from_secs_f64(config.hold_s),
        };
        Ok((settings(&config)?, hold))
    }

    async fn run(
        bus: Bus,
        prepared: (DialogConfig, Hold),
        shutdown: Shutdown,
    ) -> anyhow::Result<()> {
        let (cfg, hold) = prepared;
        run(bus, cfg, hold, shutdown).await
    }
}

/// Run the dialog on the bus until `shutdown`.
pub async fn run(
    bus: Bus,
    cfg: DialogConfig,
    hold: Hold,
    mut shutdown: Shutdown,
) -> anyhow::Result<()> {
    tracing::info!(
        high = cfg.high,
        low = cfg.low,
        timeout_s = cfg.answer_timeout_s,
        "dialog thresholds"
    );
    let mut dialog = Dialog::new(cfg)?;
    let utterances = bus.subscriber(&topics::SPEECH_UTTERANCE).await?;
    let answers = bus.subscriber(&topics::GAME_ANSWER).await?;
    let speaking = bus.subscriber(&topics::SPEECH_SPEAKING).await?;
    let commands = bus.publisher(&topics::GAME_COMMAND).await?;
    let say = bus.publisher(&topics::SPEECH_SAY).await?;
    let mut readers = interfaces::liveliness::Readers::watch(&bus, &topics::GAME_COMMAND).await?;
    // Commands waiting for a reader of game/command, with when they were held.
    let mut held: std::collections::VecDeque<(GameCommand, interfaces::clock::Moment)> =
        Default::default();
    // Time is the component's clock (the system's, or a replay's with `--clock bus`): the
    // answer time-out and the echo guard run on it.
    let clock = bus.clock().clone();
    let mut tick = clock.interval(Duration::from_millis(100));
    let mut say_id: u64 = (std::process::id() as u64) << 32;
    loop {
        let now = || clock.now().as_duration().as_secs_f64();
        let actions = tokio::select! {
            u = utterances.recv() => {
                let u = u?;
                tracing::info!("heard {:?} (confidence {:.2}, {:?})", u.text, u.confidence, u.command);
                dialog.heard(now(), Heard { game: u.game, text: u.text, confidence: u.confidence, command: u.command })
            }
            a = answers.recv() => dialog.panel_answer(now(), a?.yes),
            s = speaking.recv() => {
                let s = s?;
                match s.state {
                    SpeakingState::Started => dialog.robot_started_speaking(now(), s.duration_s),
                    SpeakingState::Finished | SpeakingState::Interrupted | SpeakingState::Failed => {
                        dialog.robot_speaking(now(), false)
                    }
                    SpeakingState::Queued | SpeakingState::Dropped => {}
                }
                vec![]
            }
            _ = tick.tick() => dialog.tick(now()),
            _ = readers.changed() => vec![],
            _ = shutdown.wait() => return Ok(()),
        };
        let reader_present = hold.readers.is_empty() || readers.any_of(&hold.readers);
        let mut lines: Vec<&'static str> = Vec::new();
        // Held commands go out, in order, once a reader is back; too old, they are dropped.
        if reader_present {
            while let Some((mut msg, since)) = held.pop_front() {
                tracing::info!(
                    "carrying out {:?}, held {:.1} s while nobody read {}",
                    msg.command,
                    clock.elapsed(since).as_secs_f64(),
                    topics::GAME_COMMAND.name()
                );
                bus.counters().incr("commands_released");
                msg.header = Default::default();
                commands.publish(&mut msg).await?;
            }
        }
        while held
            .front()
            .is_some_and(|(_, since)| clock.elapsed(*since) > hold.max)
        {
            if let Some((msg, _)) = held.pop_front() {
                tracing::warn!(
                    "dropped {:?}: none of {:?} read {} within {:.0} s",
                    msg.command,
                    hold.readers,
                    topics::GAME_COMMAND.name(),
                    hold.max.as_secs_f64()
                );
                bus.counters().incr("commands_dropped_no_reader");
                if !lines.contains(&HOLD_EXPIRED) {
                    lines.push(HOLD_EXPIRED);
                }
            }
        }
        for a in actions {
            match a {
                Action::Publish(c) => {
                    tracing::info!(
                        "command {:?} (confidence {:.2}, confirmed {})",
                        c.command,
                        c.confidence,
                        c.confirmed
                    );
                    let mut msg = GameCommand {
                        header: Default::default(),
                        game: c.game,
                        command: c.command,
                        source: CommandSource::Voice,
                        text: c.text,
                        confidence: c.confidence,
                        confirmed: c.confirmed,
                    };
                    if reader_present {
                        commands.publish(&mut msg).await?;
                    } else {
                        tracing::warn!(
                            "none of {:?} reads {} (restarting?): holding {:?} for up to {:.0} s",
                            hold.readers,
                            topics::GAME_COMMAND.name(),
                            msg.command,
                            hold.max.as_secs_f64()
                        );
                        bus.counters().incr("commands_held");
                        if held.is_empty() {
                            lines.push(HOLDING);
                        }
                        if held.len() == HELD_MAX {
                            held.pop_front();
                            bus.counters().incr("commands_dropped_no_reader");
                        }
                        held.push_back((msg, clock.now()));
                    }
                }
                Action::Say { text, priority } => {
                    say_id += 1;
                    tracing::info!("saying {text:?}");
                    say.publish(&mut SayRequest {
                        header: Default::default(),
                        id: say_id,
                        text,
                        priority,
                    })
                    .await?;
                }
                Action::Ignored(r) => {
                    tracing::info!("ignored: {r:?}");
                    bus.counters().incr(&format!("ignored/{r:?}"));
                }
                Action::Dropped(c) => {
                    tracing::info!("dropped {c:?}");
                    bus.counters().incr("dropped");
                }
            }
        }
        for text in lines {
            say_id += 1;
            tracing::info!("saying {text:?}");
            say.publish(&mut SayRequest {
                header: Default::default(),
                id: say_id,
                text: text.into(),
                priority: interfaces::msg::speech::Priority::High,
            })
            .await?;
        }
    }
}
