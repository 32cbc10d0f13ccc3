//! The dialogs component: `speech/utterance`, `game/answer` and `speech/speaking` in;
//! `game/command` and `speech/say` out, around the [`Dialog`] machine.

use crate::machine::{Action, Dialog, DialogConfig, Heard};
use interfaces::msg::command::{CommandSource, GameCommand};
use interfaces::msg::speech::{SayRequest, SpeakingState, VoiceState};
use interfaces::node::{Component, Interface};
use interfaces::outbox::{Offered, Outbox};
use interfaces::{Bus, Shutdown, topics};
use std::path::PathBuf;
use std::time::Duration;

/// The dialog's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// TOML file with the dialog settings (`high`, `low`, `answer_timeout_s`, `repeat_after`,
    /// `repeat_window_s`, `echo_guard_s`, `barge_in`); flags override it.
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
    /// Let the player talk over the robot: a sure command heard while it speaks silences it and
    /// is carried out. Only for a microphone with the robot's voice taken out (`audio_io
    /// --echo-cancel webrtc`); otherwise what is heard while the robot speaks is ignored.
    #[arg(long, value_name = "true|false")]
    pub barge_in: Option<bool>,
    /// The components that carry out `game/command` (comma-separated; empty: none). While none
    /// of them subscribes to it (one is restarting), a command is held, the robot says "One
    /// moment, please.", and the command goes out as soon as one is back. The commands sent in
    /// the 2 s before the last reader went are sent again with their stamps (it may have died
    /// before acting on them; the Executive knows the ones it did).
    #[arg(long, value_delimiter = ',', default_value = "executive")]
    pub command_readers: Vec<String>,
    /// How long a held command waits for a reader before it is dropped, the person told so (s).
    #[arg(long, default_value_t = 15.0)]
    pub hold_s: f64,
    /// The components that hear the person (readers of `audio/in`; comma-separated, empty:
    /// none). When the last of them goes away (it is restarting), the robot says "I can't hear
    /// you for a moment. Please wait.", and "I can hear you again." once one is back.
    #[arg(long, value_delimiter = ',', default_value = "speech_recognition")]
    pub recognizers: Vec<String>,
    /// The components that capture the microphone (writers of `audio/in`; comma-separated,
    /// empty: not watched). While none of them publishes it (the microphone is lost and
    /// `audio_io` withdrew its publisher), the robot says it cannot hear, as for a recognizer.
    #[arg(long, value_delimiter = ',', default_value = "")]
    pub microphones: Vec<String>,
}

/// What the dialog does with a command nobody reads yet.
#[derive(Debug, Clone, PartialEq)]
pub struct Hold {
    /// The components that carry out `game/command` (empty: never hold).
    pub readers: Vec<String>,
    /// How long a command is held at most.
    pub max: Duration,
    /// The components that hear the person (empty: the dialog never says it cannot hear).
    pub recognizers: Vec<String>,
    /// The components that capture the microphone (empty: not watched).
    pub microphones: Vec<String>,
}

/// Whether the person can be heard. Once a recognizer was there, its going away is said
/// ([`CANNOT_HEAR`]) when it has been gone [`UNHEARD_GRACE_S`], and its return ([`HEAR_AGAIN`]);
/// a dialog that never saw one says nothing.
#[derive(Debug, Default)]
pub struct Hearing {
    seen: bool,
    deaf: bool,
    /// Since when (s) nothing has heard the person, not said yet.
    gone_since: Option<f64>,
}

/// How long (s) nothing must have heard the person before the robot says so. The launcher's
/// word that the graph stops reaches the dialog on a path of its own, and may come a few
/// milliseconds after the recognizer's leaving; a recognizer restarted by the launcher takes
/// longer than this to come back.
pub const UNHEARD_GRACE_S: f64 = 0.5;

impl Hearing {
    /// At `now` (s), with a recognizer `present`: what to say, if anything. Called again while
    /// it is not present (on every tick), so that its absence is said once it has lasted.
    pub fn update(&mut self, now: f64, present: bool) -> Option<&'static str> {
        if present {
            self.seen = true;
            self.gone_since = None;
            return std::mem::take(&mut self.deaf).then_some(HEAR_AGAIN);
        }
        if !self.seen || self.deaf {
            return None;
        }
        let since = *self.gone_since.get_or_insert(now);
        (now - since >= UNHEARD_GRACE_S).then(|| {
            self.deaf = true;
            self.gone_since = None;
            CANNOT_HEAR
        })
    }
}

/// What the robot says when it holds a command for a reader that is restarting.
pub const HOLDING: &str = "One moment, please.";
/// An utterance stamped longer ago than this (s) is judged at its arrival: a restarted
/// recognizer catches up on at most what the microphone keeps (`topics::AUDIO_IN_KEPT`).
const SAID_AGE_MAX_S: f64 = 15.0;
/// What the robot says when nothing hears the person any more (the recognizer is restarting).
pub const CANNOT_HEAR: &str = "I can't hear you for a moment. Please wait.";
/// What it says when it hears the person again.
pub const HEAR_AGAIN: &str = "I can hear you again.";
/// What it says when a held command waited too long and was dropped.
pub const HOLD_EXPIRED: &str = "Sorry, I could not do that. Please say it again.";

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
    if let Some(x) = args.barge_in {
        cfg.barge_in = x;
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
            .subscribes(&topics::SPEECH_ACTIVITY)
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
        let names = |v: &[String]| -> Vec<String> {
            v.iter()
                .map(|r| r.trim().to_string())
                .filter(|r| !r.is_empty())
                .collect()
        };
        let hold = Hold {
            readers: names(&config.command_readers),
            max: Duration::from_secs_f64(config.hold_s),
            recognizers: names(&config.recognizers),
            microphones: names(&config.microphones),
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
        barge_in = cfg.barge_in,
        "dialog thresholds"
    );
    let mut dialog = Dialog::new(cfg)?;
    let utterances = bus.subscriber(&topics::SPEECH_UTTERANCE).await?;
    let answers = bus.subscriber(&topics::GAME_ANSWER).await?;
    let speaking = bus.subscriber(&topics::SPEECH_SPEAKING).await?;
    let activity = bus.subscriber(&topics::SPEECH_ACTIVITY).await?;
    let commands = bus.publisher(&topics::GAME_COMMAND).await?;
    let say = bus.publisher(&topics::SPEECH_SAY).await?;
    let mut readers = interfaces::liveliness::Readers::watch(&bus, &topics::GAME_COMMAND).await?;
    let mut ears = interfaces::liveliness::Readers::watch(&bus, &topics::AUDIO_IN).await?;
    let mut mics = interfaces::liveliness::Readers::watch_writers(&bus, &topics::AUDIO_IN).await?;
    let mut hearing = Hearing::default();
    // While the launcher stops the graph, the recognizer and the microphone leaving is no news
    // for the person (the launcher stops them before the dialog: they depend on it).
    let stopping = interfaces::liveliness::Stopping::watch(&bus).await?;
    let mut said_stopping = false;
    // Commands for the Executive while it restarts (see `interfaces::outbox`).
    let mut outbox: Outbox<GameCommand> = Outbox::new(bus.clock().clone(), hold.max);
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
                // When the words ended: the utterance's stamp is the audio's time (a restarted
                // recognizer catching up hands on words said before they arrive). A stamp older
                // than the microphone keeps audio is from a clock out of step with this one: the
                // arrival is taken instead.
                let age_s = (clock.now_ns() - u.header.stamp_ns).max(0) as f64 / 1e9;
                let said_s = (age_s <= SAID_AGE_MAX_S).then(|| now() - age_s);
                dialog.heard(now(), Heard { game: u.game, text: u.text, confidence: u.confidence, command: u.command, stamp_ns: u.header.stamp_ns, stream_start_s: u.stream_start_s, said_s })
            }
            a = answers.recv() => dialog.panel_answer(now(), a?.yes),
            s = speaking.recv() => {
                let s = s?;
                match s.state {
                    SpeakingState::Started => dialog.robot_started_speaking(now(), s.duration_s, &s.text),
                    SpeakingState::Finished | SpeakingState::Interrupted | SpeakingState::Failed => {
                        dialog.robot_speaking(now(), false)
                    }
                    SpeakingState::Queued | SpeakingState::Dropped => {}
                }
                vec![]
            }
            a = activity.recv() => {
                let a = a?;
                if a.state == VoiceState::Started {
                    dialog.speech_started(a.stream_s);
                }
                vec![]
            }
            _ = tick.tick() => dialog.tick(now()),
            _ = readers.changed() => vec![],
            _ = ears.changed() => vec![],
            _ = mics.changed() => vec![],
            _ = shutdown.wait() => return Ok(()),
        };
        let reader_present = hold.readers.is_empty() || readers.any_of(&hold.readers);
        let mut lines: Vec<&'static str> = Vec::new();
        let recognizer = ears.any_of(&hold.recognizers);
        let microphone = hold.microphones.is_empty() || mics.any_of(&hold.microphones);
        let heard = recognizer && microphone;
        if !heard && stopping.now() {
            if !std::mem::replace(&mut said_stopping, true) {
                tracing::info!(
                    "the graph is stopping: the recognizer or the microphone leaving is not said"
                );
            }
        } else if let Some(line) = hearing.update(now(), heard) {
            tracing::warn!(
                "{}",
                if line == CANNOT_HEAR && !recognizer {
                    format!(
                        "none of {:?} hears the person (restarting?)",
                        hold.recognizers
                    )
                } else if line == CANNOT_HEAR {
                    format!(
                        "none of {:?} captures the microphone (lost?)",
                        hold.microphones
                    )
                } else {
                    "the person is heard again".to_string()
                }
            );
            lines.push(line);
        }
        // Held commands go out, in order, once a reader is back; too old, they are dropped.
        for r in outbox.readers(reader_present) {
            tracing::info!(
                "carrying out {:?}, held {:.1} s while nobody read {}{}",
                r.msg.command,
                r.waited.as_secs_f64(),
                topics::GAME_COMMAND.name(),
                if r.again {
                    " (sent again: its reader went just after it)"
                } else {
                    ""
                }
            );
            bus.counters().incr("commands_released");
            commands.publish(&mut r.msg.clone()).await?;
        }
        for r in outbox.expire() {
            tracing::warn!(
                "dropped {:?}{}: none of {:?} read {} within {:.0} s",
                r.msg.command,
                if r.again { " (sent once already)" } else { "" },
                hold.readers,
                topics::GAME_COMMAND.name(),
                hold.max.as_secs_f64()
            );
            bus.counters().incr("commands_dropped_no_reader");
            if !r.again && !lines.contains(&HOLD_EXPIRED) {
                lines.push(HOLD_EXPIRED);
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
                    let msg = GameCommand {
                        // Stamped with when its words were heard: the same command if it comes
                        // again (see `interfaces::outbox`).
                        header: interfaces::Header {
                            stamp_ns: c.stamp_ns,
                            ..Default::default()
                        },
                        game: c.game,
                        command: c.command,
                        source: CommandSource::Voice,
                        text: c.text,
                        confidence: c.confidence,
                        confirmed: c.confirmed,
                    };
                    let command = msg.command;
                    match outbox.offer(msg) {
                        Offered::Send(mut msg) => commands.publish(&mut msg).await?,
                        Offered::Held { first, evicted } => {
                            tracing::warn!(
                                "none of {:?} reads {} (restarting?): holding {:?} for up to {:.0} s",
                                hold.readers,
                                topics::GAME_COMMAND.name(),
                                command,
                                hold.max.as_secs_f64()
                            );
                            bus.counters().incr("commands_held");
                            if first {
                                lines.push(HOLDING);
                            }
                            if let Some(old) = evicted {
                                tracing::warn!("dropped {:?}: too many held", old.msg.command);
                                bus.counters().incr("commands_dropped_no_reader");
                            }
                        }
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
                Action::Hush => {
                    say_id += 1;
                    tracing::info!("the player talks over the robot: silencing it");
                    bus.counters().incr("barge_ins");
                    say.publish(&mut SayRequest {
                        header: Default::default(),
                        id: say_id,
                        text: String::new(),
                        priority: interfaces::msg::speech::Priority::Urgent,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_robot_says_when_it_cannot_hear_and_when_it_hears_again() {
        let mut h = Hearing::default();
        assert_eq!(
            h.update(0.0, false),
            None,
            "never heard: nothing to say at start"
        );
        assert_eq!(h.update(0.1, true), None);
        assert_eq!(h.update(0.2, true), None);
        assert_eq!(h.update(1.0, false), None, "gone for less than the grace");
        assert_eq!(h.update(1.0 + UNHEARD_GRACE_S / 2.0, false), None);
        assert_eq!(h.update(1.0 + UNHEARD_GRACE_S, false), Some(CANNOT_HEAR));
        assert_eq!(h.update(2.0 + UNHEARD_GRACE_S, false), None, "said once");
        assert_eq!(h.update(3.0, true), Some(HEAR_AGAIN));
        assert_eq!(h.update(3.1, true), None);
    }

    #[test]
    fn a_recognizer_back_within_the_grace_is_not_spoken_of() {
        let mut h = Hearing::default();
        assert_eq!(h.update(0.0, true), None);
        assert_eq!(h.update(1.0, false), None);
        assert_eq!(h.update(1.0 + UNHEARD_GRACE_S * 0.9, true), None);
        // A later absence has its own grace, from its own start.
        assert_eq!(h.update(5.0, false), None);
        assert_eq!(h.update(5.0 + UNHEARD_GRACE_S * 0.9, false), None);
        assert_eq!(h.update(5.0 + UNHEARD_GRACE_S, false), Some(CANNOT_HEAR));
    }
}
