//! The speech generator's loop: `speech/say` in; `speech/speaking` and `audio/out` out, the
//! audio paced in real time. See the crate doc for the queue rules and the audio format.

use crate::queue::{Event, SpeechQueue};
use audio::synth::{self, Voice};
use audio::wav::{self, Pcm};
use interfaces::clock::Moment;
use interfaces::msg::speech::{AudioChunk, SayRequest, SpeakingEvent, SpeakingState};
use interfaces::node::{Component, Interface};
use interfaces::{Bus, Shutdown, topics};
use std::path::PathBuf;
use std::time::Duration;

/// The speech generator's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// espeak-ng voice (`espeak-ng --voices=en`).
    #[arg(long, default_value = "en-us")]
    pub voice: String,
    /// Speaking rate, words per minute (80-450).
    #[arg(long, default_value_t = 160)]
    pub speed_wpm: u32,
    /// Pitch, 0-99.
    #[arg(long, default_value_t = 50)]
    pub pitch: u8,
    /// Also write every utterance as `<id>.wav` (16 kHz mono) into this folder.
    #[arg(long)]
    pub wav_dir: Option<PathBuf>,
    /// Requests that may wait; beyond, the least important newest is dropped.
    #[arg(long, default_value_t = 16)]
    pub queue_capacity: usize,
    /// Length of the `audio/out` chunks (ms).
    #[arg(long, default_value_t = 100)]
    pub chunk_ms: u32,
}

/// The `speech_generator` component.
#[derive(Debug)]
pub struct SpeechGenerator;

impl Component for SpeechGenerator {
    const NAME: &'static str = "speech_generator";
    const ABOUT: &'static str = "Text to speech with espeak-ng.";
    type Config = Config;
    type Prepared = Config;

    fn interface(_: &Config) -> Interface {
        Interface::new(Self::NAME)
            .subscribes(&topics::SPEECH_SAY)
            .publishes(&topics::SPEECH_SPEAKING)
            .publishes(&topics::AUDIO_OUT)
    }

    fn prepare(config: Config) -> anyhow::Result<Config> {
        Ok(config)
    }

    async fn run(bus: Bus, config: Config, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, config, shutdown).await
    }
}

const RATE_HZ: u32 = 16_000;

struct Current {
    req: SayRequest,
    samples: Vec<i16>,
    pos: usize,
    /// When its first chunk went out, on the component's clock (which paces the rest).
    started: Moment,
}

fn event(req: &SayRequest, state: SpeakingState, duration_s: f64, detail: &str) -> SpeakingEvent {
    SpeakingEvent {
        header: Default::default(),
        id: req.id,
        text: req.text.clone(),
        state,
        duration_s,
        detail: detail.to_string(),
    }
}

/// Speak every request of `speech/say` until `shutdown`.
pub async fn run(bus: Bus, config: Config, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let voice = Voice {
        voice: config.voice.clone(),
        speed_wpm: config.speed_wpm,
        pitch: config.pitch,
    };
    let wav_dir = config.wav_dir.clone();
    let capacity = config.queue_capacity;
    let chunk = (RATE_HZ as usize * config.chunk_ms.clamp(10, 1000) as usize) / 1000;
    if let Some(d) = &wav_dir {
        std::fs::create_dir_all(d)?;
    }
    let say = bus.subscriber(&topics::SPEECH_SAY).await?;
    let speaking = bus.publisher(&topics::SPEECH_SPEAKING).await?;
    let audio = bus.publisher(&topics::AUDIO_OUT).await?;
    // The audio is paced on the component's clock, so a replay or a virtual clock drives it.
    let clock = bus.clock().clone();
    let mut queue = SpeechQueue::new(capacity);
    let mut current: Option<Current> = None;
    loop {
        // Start the next utterance when idle.
        if current.is_none()
            && let Some(req) = queue.start_next()
        {
            if req.text.trim().is_empty() {
                // Nothing to say: an urgent one of these only silences the robot (the player
                // talked over it), which pushing it into the queue already did.
                tracing::info!(id = req.id, "nothing to say ({:?})", req.priority);
                speaking
                    .publish(&mut event(
                        &req,
                        SpeakingState::Finished,
                        0.0,
                        "nothing to say",
                    ))
                    .await?;
                queue.done();
                continue;
            }
            let text = req.text.clone();
            let v = voice.clone();
            let synth =
                tokio::task::spawn_blocking(move || synth::synthesize_16k(&text, &v)).await?;
            match synth {
                Ok(samples) => {
                    let dur = samples.len() as f64 / RATE_HZ as f64;
                    if let Some(d) = &wav_dir {
                        let pcm = Pcm {
                            sample_rate_hz: RATE_HZ,
                            channels: 1,
                            samples: samples.clone(),
                        };
                        if let Err(e) =
                            std::fs::write(d.join(format!("{}.wav", req.id)), wav::encode(&pcm))
                        {
                            tracing::warn!("cannot write the utterance's WAV: {e}");
                        }
                    }
                    tracing::info!(id = req.id, "saying {:?} ({dur:.2} s)", req.text);
                    speaking
                        .publish(&mut event(&req, SpeakingState::Started, dur, ""))
                        .await?;
                    current = Some(Current {
                        req,
                        samples,
                        pos: 0,
                        started: clock.now(),
                    });
                }
                Err(e) => {
                    tracing::warn!(id = req.id, "cannot say {:?}: {e}", req.text);
                    bus.counters().incr("synth_failures");
                    speaking
                        .publish(&mut event(&req, SpeakingState::Failed, 0.0, &e.to_string()))
                        .await?;
                    queue.done();
                    continue;
                }
            }
        }
        let next_chunk_at = current
            .as_ref()
            .map(|c| c.started + Duration::from_secs_f64(c.pos as f64 / RATE_HZ as f64));
        tokio::select! {
            r = say.recv() => {
                let req = r?;
                for ev in queue.push(req) {
                    match ev {
                        Event::Queued(r) => {
                            speaking.publish(&mut event(&r, SpeakingState::Queued, 0.0, "")).await?;
                        }
                        Event::Again(r) => {
                            bus.counters().incr("said_once_sent_again");
                            tracing::info!(id = r.id, "{:?} sent again while it is queued or being said: said once", r.text);
                        }
                        Event::Dropped(r) => {
                            bus.counters().incr("dropped_queue_full");
                            speaking.publish(&mut event(&r, SpeakingState::Dropped, 0.0, "queue full")).await?;
                        }
                        Event::Interrupt(r) => {
                            if let Some(c) = current.take() {
                                let said = c.pos as f64 / RATE_HZ as f64;
                                tracing::info!(id = r.id, "interrupted after {said:.2} s");
                                speaking.publish(&mut event(&c.req, SpeakingState::Interrupted, said, "urgent request")).await?;
                            }
                        }
                    }
                }
            }
            _ = async {
                match next_chunk_at {
                    Some(t) => clock.sleep_until(t).await,
                    None => std::future::pending::<()>().await,
                }
            } => {
                if let Some(c) = current.as_mut() {
                    let end = (c.pos + chunk).min(c.samples.len());
                    let mut msg = AudioChunk::mono(RATE_HZ, &c.samples[c.pos..end]);
                    audio.publish(&mut msg).await?;
                    c.pos = end;
                    if c.pos >= c.samples.len() {
                        let dur = c.samples.len() as f64 / RATE_HZ as f64;
                        speaking.publish(&mut event(&c.req, SpeakingState::Finished, dur, "")).await?;
                        current = None;
                        queue.done();
                    }
                }
            }
            _ = shutdown.wait() => return Ok(()),
        }
    }
}
