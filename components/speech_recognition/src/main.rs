//! The speech recognition component: 16 kHz mono audio in (`audio/in`, or `--wav FILE`),
//! `speech/utterance` out. See the library doc.
//!
//! Every utterance is also printed on stdout as one line `utterance {json}`.

use clap::Parser;
use interfaces::msg::command::Game;
use interfaces::msg::speech::Utterance;
use interfaces::node::{self, Interface, NodeArgs};
use interfaces::topics;
use speech_recognition::confidence::ConfidenceConfig;
use speech_recognition::model::{AcousticModel, adapted_model_dir};
use speech_recognition::vad::{RATE_HZ, VadConfig};
use speech_recognition::{Recognized, Recognizer, RecognizerConfig};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Grammar-constrained speech recognition (PocketSphinx).
#[derive(Debug, Parser)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// Which game's commands to listen for (`touch` or `coach`).
    #[arg(long, default_value = "touch")]
    game: String,
    /// JSGF grammar file (default: the shipped `grammars/<game>.gram`).
    #[arg(long)]
    grammar: Option<PathBuf>,
    /// Decode this WAV file (16-bit PCM; other rates are resampled to 16 kHz, channels mixed),
    /// publish its utterances, and exit.
    #[arg(long)]
    wav: Option<PathBuf>,
    /// End-pointer: dB above the noise floor that starts speech.
    #[arg(long, default_value_t = VadConfig::default().start_db)]
    start_db: f64,
    /// End-pointer: silence that ends an utterance (s).
    #[arg(long, default_value_t = VadConfig::default().hangover_s)]
    hangover_s: f64,
    /// Confidence: acoustic scale of the N-best softmax (smaller spreads the confidence over
    /// competing sentences; see the library's `confidence` module).
    #[arg(long, default_value_t = ConfidenceConfig::default().acoustic_scale)]
    confidence_scale: f64,
    /// Confidence: garbage penalty in nats per 10 ms frame (larger favours the commands).
    #[arg(long, default_value_t = ConfidenceConfig::default().garbage_penalty)]
    garbage_penalty: f64,
    /// Noise settings for the decoder: wider beams, no PocketSphinx voice detection (the
    /// end-pointer's cut is decoded whole). `--noise-robust false` for PocketSphinx's defaults.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set, value_name = "BOOL")]
    noise_robust: bool,
    /// Remove background noise before decoding (Wiener filter, noise taken from the quiet
    /// before each utterance). Off by default: the acoustic model is not adapted to its output.
    #[arg(long)]
    denoise: bool,
    /// Acoustic model: a PocketSphinx model folder, or `stock` (Debian's en-us). Default:
    /// `$ROBOCOG_ACOUSTIC_MODEL`, else the adapted model built by `speech_model` when there is
    /// one, else the stock model.
    #[arg(long, value_name = "DIR|stock")]
    acoustic_model: Option<String>,
    /// Filler words of the garbage model that catches out-of-grammar speech, one per line
    /// (default: the shipped `grammars/filler.words`).
    #[arg(long)]
    fillers: Option<PathBuf>,
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

fn main() -> ExitCode {
    let args = Args::parse();
    let interface = Interface::new("speech_recognition")
        .subscribes(&topics::AUDIO_IN)
        .publishes(&topics::SPEECH_UTTERANCE);
    let setup = || -> anyhow::Result<Recognizer> {
        let game = Game::from_name(&args.game)
            .ok_or_else(|| anyhow::anyhow!("unknown game {:?} (touch or coach)", args.game))?;
        let grammar = args.grammar.clone().unwrap_or_else(|| {
            speech_recognition::grammar::grammar_dir().join(format!("{}.gram", game.name()))
        });
        let acoustic_model = AcousticModel::resolve(args.acoustic_model.as_deref())?;
        let cfg = RecognizerConfig {
            acoustic_model,
            vad: VadConfig {
                start_db: args.start_db,
                hangover_s: args.hangover_s,
                ..VadConfig::default()
            },
            confidence: ConfidenceConfig {
                acoustic_scale: args.confidence_scale,
                garbage_penalty: args.garbage_penalty,
                ..ConfidenceConfig::default()
            },
            fillers: Some(
                args.fillers
                    .clone()
                    .unwrap_or_else(speech_recognition::garbage::filler_file),
            ),
            noise_robust: args.noise_robust,
            denoise: args
                .denoise
                .then(speech_recognition::denoise::DenoiseConfig::default),
            ..RecognizerConfig::default()
        };
        Ok(Recognizer::new(game, &grammar, cfg)?)
    };
    let recognizer = if args.node.describe {
        None
    } else {
        match setup() {
            Ok(r) => Some(r),
            Err(e) => {
                eprintln!("speech_recognition: {e:#}");
                return ExitCode::FAILURE;
            }
        }
    };
    let wav = args.wav.clone();
    node::run(args.node, interface, move |bus, mut shutdown| async move {
        let Some(mut recognizer) = recognizer else {
            return Ok(());
        };
        let out = bus.publisher(&topics::SPEECH_UTTERANCE).await?;
        let model = &recognizer.config().acoustic_model;
        if model.stock {
            tracing::warn!(
                "acoustic model: {}; no adapted model at {} (build it with `speech_model`): noisy commands are recognized much worse",
                model.describe(),
                adapted_model_dir().display()
            );
        } else {
            tracing::info!("acoustic model: {}", model.describe());
        }
        tracing::info!(game = recognizer.game().name(), grammar = %recognizer.grammar().origin.display(), "listening");
        if let Some(path) = wav {
            let bytes = std::fs::read(&path)
                .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
            let pcm = audio::wav::parse(&bytes)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            let samples = audio::signal::resample(&pcm.to_mono(), pcm.sample_rate_hz, RATE_HZ);
            let (results, rec) = tokio::task::spawn_blocking(move || {
                let mut v = recognizer.push(&samples)?;
                v.extend(recognizer.flush()?);
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
            tokio::time::sleep(std::time::Duration::from_millis(200)).await;
            return Ok(());
        }
        // The decoder blocks for a fraction of a second per utterance: it runs on its own thread.
        let (audio_tx, audio_rx) = std::sync::mpsc::channel::<(Vec<i16>, Instant)>();
        let (res_tx, mut res_rx) =
            tokio::sync::mpsc::unbounded_channel::<anyhow::Result<(Recognized, Instant)>>();
        std::thread::Builder::new()
            .name("decoder".into())
            .spawn(move || {
                while let Ok((samples, arrived)) = audio_rx.recv() {
                    match recognizer.push(&samples) {
                        Ok(v) => {
                            for r in v {
                                if res_tx.send(Ok((r, arrived))).is_err() {
                                    return;
                                }
                            }
                        }
                        Err(e) => {
                            let _ = res_tx.send(Err(e.into()));
                            return;
                        }
                    }
                }
            })?;
        let audio = bus.subscriber(&topics::AUDIO_IN).await?;
        loop {
            tokio::select! {
                chunk = audio.recv() => {
                    let chunk = chunk?;
                    let reason = if chunk.sample_rate_hz != RATE_HZ {
                        Some("wrong_rate")
                    } else if chunk.channels != 1 {
                        Some("not_mono")
                    } else if chunk.pcm_s16le.len() % 2 != 0 {
                        Some("odd_bytes")
                    } else if chunk.pcm_s16le.is_empty() {
                        Some("empty")
                    } else {
                        None
                    };
                    if let Some(reason) = reason {
                        let c = bus.counters().counter(&format!("audio_dropped/{reason}"));
                        let n = c.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if n.is_power_of_two() || n == 0 {
                            tracing::warn!(
                                "dropped audio chunk ({reason}: {} Hz, {} channels, {} bytes; want {RATE_HZ} Hz mono s16le), {} so far",
                                chunk.sample_rate_hz, chunk.channels, chunk.pcm_s16le.len(), n + 1
                            );
                        }
                        continue;
                    }
                    let Some(samples) = chunk.samples() else { continue };
                    if audio_tx.send((samples, Instant::now())).is_err() {
                        anyhow::bail!("the decoder thread stopped");
                    }
                }
                r = res_rx.recv() => {
                    let Some(r) = r else { anyhow::bail!("the decoder thread stopped") };
                    let (r, arrived) = r?;
                    let mut msg = to_msg(&r, arrived.elapsed().as_secs_f64());
                    tracing::info!("heard {:?} (confidence {:.2}, {:?}, {:.2}-{:.2} s)", r.text, r.confidence, r.command, r.start_s, r.end_s);
                    print(&msg);
                    out.publish(&mut msg).await?;
                }
                _ = shutdown.wait() => return Ok(()),
            }
        }
    })
}
