//! The speech recognition component: 16 kHz mono audio in (`audio/in`, or `--wav FILE`),
//! `speech/utterance` out. See the crate doc.
//!
//! Every utterance is also printed on stdout as one line `utterance {json}`.

use crate::beam::LiveBeam;
use crate::confidence::ConfidenceConfig;
use crate::heard;
use crate::intake::{DecoderQueue, ListeningPacer, Whose, feed, hear_key, next_key};
use crate::model::{AcousticModel, AdaptedOn, adapted_model_dir, adapted_on};
use crate::talk::TalkGate;
use crate::vad::{RATE_HZ, VadConfig};
use crate::{Recognized, Recognizer, RecognizerConfig};
use interfaces::clock::Moment;
use interfaces::liveliness::Readers;
use interfaces::msg::command::Game;
use interfaces::msg::speech::{Utterance, VoiceActivity, VoiceState};
use interfaces::node::{Component, Interface};
use interfaces::outbox::{Offered, Outbox};
use interfaces::{Bus, Shutdown, topics};
use std::path::PathBuf;
use std::time::Duration;

/// The recognizer's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Which game's commands to listen for (`touch` or `coach`).
    #[arg(long, default_value = "touch")]
    pub game: String,
    /// JSGF grammar file (default: the shipped `grammars/<game>.gram`).
    #[arg(long)]
    pub grammar: Option<PathBuf>,
    /// Decode this WAV file (16-bit PCM; other rates are resampled to 16 kHz, channels mixed),
    /// publish its utterances, and exit.
    #[arg(long)]
    pub wav: Option<PathBuf>,
    /// The audio's channels are the microphones of this array (audio/in from `audio_io
    /// --array`, or the `--wav` file's), beamformed into one channel before decoding. A name in
    /// `models/arrays/` (kinect_v1, circular_4, circular_6, laptop_2; found under ./models, else
    /// built in) or a geometry file of its own. audio/in chunks with another channel count are
    /// mixed into one, counted as `array_channel_mismatch`. Empty: one microphone, as without
    /// the flag (a manifest's default).
    #[arg(long, value_name = "NAME|FILE")]
    pub array: Option<String>,
    /// With `--array`: where the talker is, in the array's frame (degrees; 0 straight ahead,
    /// positive to the left). Without it, on audio/in the beam listens straight ahead (where
    /// the robot looks, for an array on its head); on a `--wav` file the localizer picks the
    /// loudest talker of the file.
    #[arg(
        long,
        requires = "array",
        allow_hyphen_values = true,
        value_name = "DEG"
    )]
    pub target_azimuth_deg: Option<f64>,
    /// With `--array` on audio/in: the deep representation's frame the array's geometry is
    /// given in (Loki's Kinect: `head_rgbd_link`). The beam then listens to the person the deep
    /// representation holds (`--listen-to`), wherever the robot's head and the person move,
    /// and to the loudest talker the localizer finds when it knows nobody.
    #[arg(long, requires = "array", conflicts_with_all = ["target_azimuth_deg", "wav"], value_name = "FRAME")]
    pub array_frame: Option<String>,
    /// With `--array-frame`: the deep representation's nodes to listen to, the first it knows
    /// first (comma-separated): the player, else the hand holding the ball.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "player,ball",
        value_name = "NODES"
    )]
    pub listen_to: Vec<String>,
    /// End-pointer: dB above the noise floor that starts speech.
    #[arg(long, default_value_t = VadConfig::default().start_db)]
    pub start_db: f64,
    /// End-pointer: silence that ends an utterance (s).
    #[arg(long, default_value_t = VadConfig::default().hangover_s)]
    pub hangover_s: f64,
    /// Confidence: acoustic scale of the N-best softmax (smaller spreads the confidence over
    /// competing sentences; see the library's `confidence` module).
    /// Default: the calibration of the acoustic model in use.
    #[arg(long)]
    pub confidence_scale: Option<f64>,
    /// Confidence: garbage penalty in nats per 10 ms frame (larger favours the commands).
    /// Default: the calibration of the acoustic model in use.
    #[arg(long)]
    pub garbage_penalty: Option<f64>,
    /// Noise settings for the decoder: wider beams, no PocketSphinx voice detection (the
    /// end-pointer's cut is decoded whole). `--noise-robust false` for PocketSphinx's defaults.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub noise_robust: bool,
    /// Remove background noise before decoding (Wiener filter, noise taken from the quiet
    /// before each utterance). Off by default: the acoustic model is not adapted to its output.
    #[arg(long)]
    pub denoise: bool,
    /// Acoustic model: `stock` (Debian's en-us), `adapted` (the one `speech_model` built), or a
    /// PocketSphinx model folder. Default (or `auto`): `$ROBOCOG_ACOUSTIC_MODEL`, else the
    /// adapted model when `speech_model` built it on recordings of people, else the stock model
    /// (a model adapted on the synthesized voices hears people worse than the stock one).
    #[arg(long, value_name = "auto|stock|adapted|DIR")]
    pub acoustic_model: Option<String>,
    /// Filler words of the garbage model that catches out-of-grammar speech, one per line
    /// (default: the shipped `grammars/filler.words`).
    #[arg(long)]
    pub fillers: Option<PathBuf>,
    /// The components that act on `speech/utterance` (comma-separated; the shipped graphs name
    /// `dialogs`). While none of them subscribes to it (the dialog is restarting), what is heard
    /// is held and goes out as soon as one is back; what was heard in the 2 s before the last
    /// one went is sent again with its stamp. Empty (the default): nobody is waited for.
    #[arg(long, value_delimiter = ',')]
    pub utterance_readers: Vec<String>,
    /// How long a held utterance waits for a reader before it is dropped (s).
    #[arg(long, default_value_t = 15.0)]
    pub hold_s: f64,
    /// The component's state folder (from the launcher, ROBOCOG_STATE_DIR): how far the stream
    /// was heard is kept there, and a restarted recognizer catches up on what was said while it
    /// was down (see `heard`). None: it starts from the live stream.
    #[arg(long, env = "ROBOCOG_STATE_DIR")]
    pub state_dir: Option<PathBuf>,
    /// Push-to-talk: only what is heard while the operator holds the talk key (`speech/talk`:
    /// the command panel's "Hold to talk" button, or V held on its page) is speech; the rest is
    /// the room's and never opens an utterance. For halls where everyone talks (a RoboCup
    /// field), with a headset microphone.
    #[arg(long, default_value_t = false, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub push_to_talk: bool,
}

impl Config {
    /// The array `--array` names, if it names one (empty: one microphone).
    fn array_name(&self) -> Option<&str> {
        self.array
            .as_deref()
            .map(str::trim)
            .filter(|a| !a.is_empty())
    }
}

/// The `speech_recognition` component.
#[derive(Debug)]
pub struct SpeechRecognition;

/// A loaded recognizer, and the file to decode instead of `audio/in` if any.
pub struct Prepared {
    pub recognizer: Recognizer,
    pub wav: Option<PathBuf>,
    /// The array the file's channels come from (`--array`), and the talker's azimuth (rad).
    pub array: Option<(audio::array::ArrayGeometry, Option<f64>)>,
    /// Where the beam is steered from: the deep representation (`--array-frame`).
    pub steer: Option<crate::steer::DrAim>,
    /// Who acts on `speech/utterance` (empty: nobody is waited for).
    pub readers: Vec<String>,
    /// How long an utterance is held for them at most.
    pub hold: Duration,
    /// Where how far the stream was heard is kept.
    pub state_dir: Option<PathBuf>,
    /// Only what is heard while the talk key is held is speech (`--push-to-talk`).
    pub push_to_talk: bool,
}

impl Component for SpeechRecognition {
    const NAME: &'static str = "speech_recognition";
    const ABOUT: &'static str = "Grammar-constrained speech recognition (PocketSphinx).";
    type Config = Config;
    type Prepared = Prepared;

    fn interface(config: &Config) -> Interface {
        let mut i = Interface::new(Self::NAME)
            .subscribes(&topics::AUDIO_IN)
            .publishes(&topics::SPEECH_UTTERANCE)
            .publishes(&topics::SPEECH_ACTIVITY);
        if config.array_name().is_some() && config.wav.is_none() {
            i = i.publishes(&topics::SPEECH_LISTENING);
            if config.array_frame.is_some() {
                i = i.calls(&topics::DR_TRANSFORM);
            }
        }
        if config.push_to_talk {
            i.subscribes(&topics::SPEECH_TALK)
        } else {
            i
        }
    }

    /// Load the grammar and the acoustic model (seconds) before joining the bus.
    fn prepare(config: Config) -> anyhow::Result<Prepared> {
        anyhow::ensure!(
            config.hold_s.is_finite() && config.hold_s >= 0.0,
            "--hold-s must be a number of seconds >= 0, got {}",
            config.hold_s
        );
        anyhow::ensure!(
            !(config.push_to_talk && config.wav.is_some()),
            "--push-to-talk listens to audio/in while the talk key is held; a --wav file has no \
             key: decode it without --push-to-talk"
        );
        let array = match config.array_name() {
            Some(name) => {
                let geometry = audio::array::ArrayGeometry::by_name_or_path(
                    name,
                    std::path::Path::new("models"),
                )
                .map_err(|e| anyhow::anyhow!("--array {name}: {e}"))?;
                anyhow::ensure!(
                    geometry.sample_rate_hz() == RATE_HZ,
                    "--array {name}: the geometry is for {} Hz; the recognizer hears at {RATE_HZ} Hz",
                    geometry.sample_rate_hz()
                );
                if let Some(deg) = config.target_azimuth_deg {
                    anyhow::ensure!(
                        deg.is_finite(),
                        "--target-azimuth-deg must be a number of degrees, got {deg}"
                    );
                }
                Some((geometry, config.target_azimuth_deg.map(f64::to_radians)))
            }
            None => None,
        };
        let steer = match (&config.array_frame, &array) {
            (Some(frame), Some(_)) => {
                let nodes: Vec<String> = config
                    .listen_to
                    .iter()
                    .map(|n| n.trim().to_string())
                    .filter(|n| !n.is_empty())
                    .collect();
                anyhow::ensure!(
                    !frame.trim().is_empty(),
                    "--array-frame must name a frame of the deep representation"
                );
                anyhow::ensure!(
                    !nodes.is_empty(),
                    "--listen-to must name at least one node of the deep representation \
                     (player, ball, ...)"
                );
                Some(crate::steer::DrAim {
                    frame: frame.trim().to_string(),
                    nodes,
                })
            }
            _ => None,
        };
        Ok(Prepared {
            recognizer: recognizer(&config)?,
            wav: config.wav,
            array,
            steer,
            readers: config
                .utterance_readers
                .iter()
                .map(|r| r.trim().to_string())
                .filter(|r| !r.is_empty())
                .collect(),
            hold: Duration::from_secs_f64(config.hold_s),
            state_dir: config.state_dir,
            push_to_talk: config.push_to_talk,
        })
    }

    async fn run(bus: Bus, prepared: Prepared, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}

/// The recognizer the flags describe.
pub fn recognizer(config: &Config) -> anyhow::Result<Recognizer> {
    let game = Game::from_name(&config.game)
        .ok_or_else(|| anyhow::anyhow!("unknown game {:?} (touch or coach)", config.game))?;
    let grammar = config
        .grammar
        .clone()
        .unwrap_or_else(|| crate::grammar::grammar_dir().join(format!("{}.gram", game.name())));
    let acoustic_model = AcousticModel::resolve(config.acoustic_model.as_deref())?;
    let fitted = RecognizerConfig::for_model(acoustic_model);
    let cfg = RecognizerConfig {
        vad: VadConfig {
            start_db: config.start_db,
            hangover_s: config.hangover_s,
            ..VadConfig::default()
        },
        confidence: ConfidenceConfig {
            acoustic_scale: config
                .confidence_scale
                .unwrap_or(fitted.confidence.acoustic_scale),
            garbage_penalty: config
                .garbage_penalty
                .unwrap_or(fitted.confidence.garbage_penalty),
            ..fitted.confidence
        },
        fillers: Some(
            config
                .fillers
                .clone()
                .unwrap_or_else(crate::garbage::filler_file),
        ),
        noise_robust: config.noise_robust,
        denoise: config.denoise.then(crate::denoise::DenoiseConfig::default),
        ..fitted
    };
    Ok(Recognizer::new(game, &grammar, cfg)?)
}

fn to_msg(r: &Recognized, latency_s: f64) -> Utterance {
    Utterance {
        header: Default::default(),
        game: r.game,
        text: r.text.clone(),
        confidence: r.confidence,
        command: r.command,
        in_grammar: r.command != interfaces::msg::command::Command::None,
        stream_start_s: r.start_s,
        stream_end_s: r.end_s,
        decode_duration_s: r.decode_s,
        latency_s,
    }
}

fn print(msg: &Utterance) {
    if let Ok(j) = serde_json::to_string(msg) {
        println!("utterance {j}");
    }
}

/// How much speech an utterance holds before `speech/activity` says it started (s).
pub const SUSTAINED_SPEECH_S: f64 = 0.15;

/// What the decoder thread hands the bus loop.
enum Decoded {
    /// The end-pointer opened, ended or dropped an utterance (at that stream time, s).
    Activity(VoiceState, f64),
    /// Every chunk up to the one stamped this (ns) is heard: no speech is open.
    Heard(i64),
    /// An utterance decoded, from audio that arrived then (on the component's clock), its end
    /// in the chunk stamped this (ns, the microphone's time).
    Utterance(Recognized, Moment, i64),
}

/// How long a restarted recognizer waits for the microphone's kept audio.
const CATCH_UP_WAIT: Duration = Duration::from_secs(2);
/// A gap between the mark and the first kept chunk longer than this is audio lost.
const CHUNK_GAP_NS: i64 = 500_000_000;

/// Says which acoustic model decodes, and what else is there and why it is not used.
fn log_model(model: &AcousticModel) {
    let cached = adapted_model_dir();
    match (model.stock, adapted_on(&cached)) {
        (false, _) => tracing::info!("acoustic model: {}", model.describe()),
        (true, Some(AdaptedOn::Recordings)) => tracing::info!(
            "acoustic model: {}, as asked (--acoustic-model or ROBOCOG_ACOUSTIC_MODEL); the model adapted on recordings at {} is not used",
            model.describe(),
            cached.display()
        ),
        (true, Some(AdaptedOn::Synthesized)) => tracing::info!(
            "acoustic model: {}; the model adapted on espeak-ng's voices at {} is used only when asked for (--acoustic-model adapted): it hears those voices, not people",
            model.describe(),
            cached.display()
        ),
        (true, None) => tracing::info!("acoustic model: {}", model.describe()),
    }
}

/// Decode `--wav` and return, or listen on `audio/in` until `shutdown`.
pub async fn run(bus: Bus, prepared: Prepared, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let mut recognizer = prepared.recognizer;
    let out = bus.publisher(&topics::SPEECH_UTTERANCE).await?;
    let activity = bus.publisher(&topics::SPEECH_ACTIVITY).await?;
    log_model(&recognizer.config().acoustic_model);
    tracing::info!(game = recognizer.game().name(), grammar = %recognizer.grammar().origin.display(), "listening");
    if let Some(path) = prepared.wav {
        let bytes = std::fs::read(&path)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
        let pcm =
            audio::wav::parse(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        // The blocks the recognizer hears, each with whether it came from elsewhere.
        let heard = match &prepared.array {
            None => vec![crate::beam::Heard {
                samples: audio::signal::resample(&pcm.to_mono(), pcm.sample_rate_hz, RATE_HZ),
                stamp_ns: 0,
                beamformed: false,
                located_rad: None,
                elsewhere: false,
            }],
            Some((geometry, azimuth)) => {
                let b = crate::array_wav::beamform(&pcm, geometry, *azimuth)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
                tracing::info!(
                    "{}: {} microphones of {}, listening at {:.0} degrees ({})",
                    path.display(),
                    geometry.channels(),
                    geometry.name(),
                    b.azimuth_rad.to_degrees(),
                    if b.located {
                        format!(
                            "the loudest talker: a sound in {} of {} blocks",
                            b.blocks_located, b.blocks
                        )
                    } else {
                        "as given".to_string()
                    }
                );
                let (elsewhere, blocks) = b.elsewhere();
                tracing::info!(
                    "{}: {elsewhere} of {blocks} blocks of 100 ms came from elsewhere",
                    path.display()
                );
                b.heard
            }
        };
        let (results, rec) = tokio::task::spawn_blocking(move || {
            let v = crate::array_wav::decode(&mut recognizer, &heard)?;
            anyhow::Ok((v, recognizer))
        })
        .await??;
        drop(rec);
        for r in &results {
            let mut msg = to_msg(r, r.decode_s);
            print(&msg);
            out.publish(&mut msg).await?;
        }
        tracing::info!("{}: {} utterances", path.display(), results.len());
        // Let the last samples leave before the session closes.
        #[expect(
            clippy::disallowed_methods,
            reason = "lets the transport send the last messages before the session closes: network time, and no clock need drive an offline --wav decode"
        )]
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
        return Ok(());
    }
    // The decoder blocks for a fraction of a second per utterance: it runs on its own thread.
    // Bounded both ways: audio the decoder is more than DECODER_BACKLOG_S behind on is
    // dropped and counted (`audio_dropped/decoder_behind`), and the decoder waits for this
    // loop to take its results.
    let (audio_tx, audio_rx) = DecoderQueue::new();
    let preroll_ns = (recognizer.config().vad.preroll_s.max(0.0) * 1e9) as i64;
    let (res_tx, mut res_rx) = tokio::sync::mpsc::channel::<anyhow::Result<Decoded>>(16);
    std::thread::Builder::new()
        .name("decoder".into())
        .spawn(move || {
            let mut heard_s = 0.0;
            // The start of the utterance whose speech was announced.
            let mut announced: Option<f64> = None;
            while let Some((samples, arrived, stamp_ns, whose)) = audio_rx.recv() {
                let dropped_before = recognizer.dropped_short();
                heard_s += samples.len() as f64 / f64::from(RATE_HZ);
                recognizer.set_hers(whose == Whose::Hers);
                match recognizer.push_from(&samples, whose == Whose::Elsewhere) {
                    Ok(v) => {
                        let dropped = recognizer.dropped_short() > dropped_before;
                        let mut events = Vec::new();
                        for r in v {
                            events.push(Decoded::Activity(VoiceState::Ended, r.end_s));
                            events.push(Decoded::Utterance(r, arrived, stamp_ns));
                        }
                        if dropped {
                            events.push(Decoded::Activity(VoiceState::Dropped, heard_s));
                        }
                        // Speech that has gone on long enough not to be a click, a cough or
                        // what an echo canceller lets through of the robot as it adapts.
                        if let Some((start, loud_s)) = recognizer.speech_open()
                            && loud_s >= SUSTAINED_SPEECH_S
                            && announced != Some(start)
                        {
                            announced = Some(start);
                            events.push(Decoded::Activity(VoiceState::Started, start));
                        }
                        if recognizer.speech_open().is_none() {
                            events.push(Decoded::Heard(stamp_ns));
                        }
                        for e in events {
                            if res_tx.blocking_send(Ok(e)).is_err() {
                                return;
                            }
                        }
                    }
                    Err(e) => {
                        let _ = res_tx.blocking_send(Err(e.into()));
                        return;
                    }
                }
            }
        })?;
    let mut beam = match &prepared.array {
        Some((geometry, azimuth)) => {
            let beam = LiveBeam::new(geometry, azimuth.unwrap_or(0.0))?;
            match &prepared.steer {
                None => tracing::info!(
                    "audio/in from the {} microphones of the array {}: listening at {:.0} degrees of its frame",
                    beam.channels(),
                    beam.name(),
                    beam.azimuth_rad().to_degrees()
                ),
                Some(dr) => tracing::info!(
                    "audio/in from the {} microphones of the array {} (frame {}): listening to \
                     {} as the deep representation places them, else to the loudest talker",
                    beam.channels(),
                    beam.name(),
                    dr.frame,
                    dr.nodes.join(" or ")
                ),
            }
            Some(beam)
        }
        None => None,
    };
    // The deep representation steers the beam (`--array-frame`): asked at the newest audio's
    // time, its answers applied from the next chunk on.
    let newest_audio_ns = std::sync::Arc::new(std::sync::atomic::AtomicI64::new(0));
    let aim = match (&prepared.steer, beam.is_some()) {
        (Some(dr), true) => {
            let (tx, rx) = tokio::sync::watch::channel(crate::beam::Aim::Loudest);
            tokio::spawn(crate::steer::run(
                bus.clone(),
                dr.clone(),
                newest_audio_ns.clone(),
                tx,
                shutdown.clone(),
            ));
            Some(rx)
        }
        _ => None,
    };
    let audio = bus.subscriber(&topics::AUDIO_IN).await?;
    let listening = if beam.is_some() {
        Some(bus.publisher(&topics::SPEECH_LISTENING).await?)
    } else {
        None
    };
    let mut pacer = ListeningPacer::default();
    let (mut talk, talk_keys) = if prepared.push_to_talk {
        tracing::info!(
            "push-to-talk: only what is heard while the talk key is held ({}: the panel's \
             \"Hold to talk\" button, or V held on its page) is speech",
            topics::SPEECH_TALK.name()
        );
        (
            Some(TalkGate::new()),
            Some(bus.subscriber(&topics::SPEECH_TALK).await?),
        )
    } else {
        (None, None)
    };
    // A restart: what was said while this recognizer was down, from the microphone's kept audio.
    let mut keeper = prepared.state_dir.as_deref().map(heard::Keeper::new);
    let mut fed_until_ns = i64::MIN;
    // An utterance was decoded since the mark was last offered: the next is written at once.
    let mut decoded = false;
    if let Some(mark) = prepared.state_dir.as_deref().and_then(heard::load) {
        // From a VAD pre-roll before the mark: a word whose first frames had not opened speech
        // yet is heard whole (what lies before is silence, or the last utterance's hang-over).
        let after = mark.saturating_sub(preroll_ns);
        // Without the kept audio (no microphone keeps it, the bus failed), the live stream.
        let missed = match bus.recent(&topics::AUDIO_IN, after, CATCH_UP_WAIT).await {
            Ok(missed) => missed,
            Err(e) => {
                tracing::warn!(
                    "restarted: cannot ask the microphone for what was said meanwhile ({e}); \
                     listening from now on"
                );
                Vec::new()
            }
        };
        let seconds: f64 = missed
            .iter()
            .map(|c| c.pcm_s16le.len() as f64 / 2.0 / f64::from(c.sample_rate_hz.max(1)))
            .sum();
        match missed.first() {
            Some(first) if first.header.stamp_ns - after > CHUNK_GAP_NS => tracing::warn!(
                "restarted: {:.1} s of audio said while this recognizer was down is no longer \
                 kept by the microphone and was lost; catching up on the {seconds:.1} s kept",
                (first.header.stamp_ns - after) as f64 / 1e9
            ),
            Some(_) => tracing::info!(
                "restarted: catching up on {seconds:.1} s of audio said while this recognizer \
                 was down"
            ),
            None => tracing::info!("restarted: nothing was said while this recognizer was down"),
        }
        for chunk in missed {
            fed_until_ns = fed_until_ns.max(chunk.header.stamp_ns);
            // Where it listened then is old news: not published.
            feed(&bus, &audio_tx, &mut beam, &mut talk, chunk)?;
        }
    }
    // What is heard while the dialog restarts waits for it (see `interfaces::outbox`).
    let mut readers = Readers::watch(&bus, &topics::SPEECH_UTTERANCE).await?;
    let mut outbox: Outbox<Utterance> = Outbox::new(bus.clock().clone(), prepared.hold);
    let mut tick = bus.clock().interval(Duration::from_millis(250));
    loop {
        let present = prepared.readers.is_empty() || readers.any_of(&prepared.readers);
        for r in outbox.readers(present) {
            tracing::info!(
                "sending {:?}, held {:.1} s while nobody read {}{}",
                r.msg.text,
                r.waited.as_secs_f64(),
                topics::SPEECH_UTTERANCE.name(),
                if r.again {
                    " (again: its reader went just after it)"
                } else {
                    ""
                }
            );
            bus.counters().incr("utterances_released");
            out.publish(&mut r.msg.clone()).await?;
        }
        for r in outbox.expire() {
            bus.counters().incr("utterances_dropped_no_reader");
            tracing::warn!(
                "dropped {:?}: none of {:?} read {} within {:.0} s",
                r.msg.text,
                prepared.readers,
                topics::SPEECH_UTTERANCE.name(),
                prepared.hold.as_secs_f64()
            );
        }
        tokio::select! {
            _ = readers.changed() => {}
            _ = tick.tick() => {}
            chunk = audio.recv() => {
                let chunk = chunk?;
                // Already fed from the microphone's kept audio, as this recognizer caught up.
                if chunk.header.stamp_ns <= fed_until_ns {
                    continue;
                }
                if let (Some(b), Some(aim)) = (beam.as_mut(), aim.as_ref()) {
                    newest_audio_ns.store(chunk.header.stamp_ns, std::sync::atomic::Ordering::Relaxed);
                    b.aim(aim.borrow().clone());
                }
                for mut l in feed(&bus, &audio_tx, &mut beam, &mut talk, chunk)? {
                    if let Some(p) = listening.as_ref()
                        && pacer.due(&l)
                    {
                        p.publish(&mut l).await?;
                    }
                }
            }
            key = next_key(talk_keys.as_ref()) => {
                if let Some(gate) = talk.as_mut() {
                    hear_key(&bus, gate, &key?);
                }
            }
            r = res_rx.recv() => {
                let Some(r) = r else { anyhow::bail!("the decoder thread stopped") };
                let (r, arrived, said_ns) = match r? {
                    Decoded::Activity(state, stream_s) => {
                        tracing::debug!("voice activity: {state:?} at {stream_s:.2} s");
                        activity
                            .publish(&mut VoiceActivity { header: Default::default(), state, stream_s })
                            .await?;
                        continue;
                    }
                    Decoded::Heard(stamp_ns) => {
                        // Heard, unless an utterance still waits for its reader in the outbox.
                        if let Some(k) = keeper.as_mut()
                            && outbox.held() == 0
                        {
                            k.offer(stamp_ns, std::mem::take(&mut decoded));
                        }
                        continue;
                    }
                    Decoded::Utterance(r, arrived, stamp_ns) => (r, arrived, stamp_ns),
                };
                decoded = true;
                let mut msg = to_msg(&r, bus.clock().elapsed(arrived).as_secs_f64());
                // Stamped with when the words were said (the audio's time), not when they were
                // decoded: the dialog judges echo by it, and a recognizer that caught up after
                // a restart hands on words said before they arrive.
                msg.header.stamp_ns = said_ns;
                tracing::info!("heard {:?} (confidence {:.2}, {:?}, {:.2}-{:.2} s)", r.text, r.confidence, r.command, r.start_s, r.end_s);
                // Why it is as sure as it is (see `confidence`): the parts of the confidence.
                tracing::debug!(
                    "heard {:?}: in grammar {:.2} (against the garbage {:?}: {:+.2} nats/frame), \
                     N-best margin {}, estimated SNR {:.1} dB, over talk {}, cut at the longest {}",
                    r.text,
                    r.p_in_grammar,
                    r.garbage_text,
                    r.llr_per_frame,
                    r.margin_per_frame.map_or("none".into(), |m| format!("{m:.2} nats/frame")),
                    r.snr_db,
                    r.over_talk,
                    r.forced,
                );
                print(&msg);
                match outbox.offer(msg) {
                    Offered::Send(mut msg) => out.publish(&mut msg).await?,
                    Offered::Held { evicted, .. } => {
                        bus.counters().incr("utterances_held");
                        tracing::warn!(
                            "none of {:?} reads {} (restarting?): holding {:?} for up to {:.0} s",
                            prepared.readers,
                            topics::SPEECH_UTTERANCE.name(),
                            r.text,
                            prepared.hold.as_secs_f64()
                        );
                        if let Some(old) = evicted {
                            bus.counters().incr("utterances_dropped_no_reader");
                            tracing::warn!("dropped {:?}: too many held", old.msg.text);
                        }
                    }
                }
            }
            _ = shutdown.wait() => return Ok(()),
        }
    }
}
