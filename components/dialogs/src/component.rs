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
}

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
    type Prepared = DialogConfig;

    fn interface(_: &Config) -> Interface {
        Interface::new(Self::NAME)
            .subscribes(&topics::SPEECH_UTTERANCE)
            .subscribes(&topics::GAME_ANSWER)
            .subscribes(&topics::SPEECH_SPEAKING)
            .publishes(&topics::GAME_COMMAND)
            .publishes(&topics::SPEECH_SAY)
    }

    /// Read and check the settings before joining the bus.
    fn prepare(config: Config) -> anyhow::Result<DialogConfig> {
        settings(&config)
    }

    async fn run(bus: Bus, cfg: DialogConfig, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, cfg, shutdown).await
    }
}

/// Run the dialog on the bus until `shutdown`.
pub async fn run(bus: Bus, cfg: DialogConfig, mut shutdown: Shutdown) -> anyhow::Result<()> {
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
                match s?.state {
                    SpeakingState::Started => dialog.robot_speaking(now(), true),
                    SpeakingState::Finished | SpeakingState::Interrupted | SpeakingState::Failed => {
                        dialog.robot_speaking(now(), false)
                    }
                    SpeakingState::Queued | SpeakingState::Dropped => {}
                }
                vec![]
            }
            _ = tick.tick() => dialog.tick(now()),
            _ = shutdown.wait() => return Ok(()),
        };
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
                    commands.publish(&mut msg).await?;
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
    }
}
