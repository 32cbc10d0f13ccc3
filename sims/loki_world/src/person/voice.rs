//! Her voice: room noise streamed in real time, with her sentences mixed in, onto the bus or
//! into a sound server's sink.

use super::{PULSE_BUFFER, RATE_HZ};
use audio::signal::{self as pcm, NoiseKind, NoiseRng};
use interfaces::msg::speech::AudioChunk;
use std::time::Duration;
use tokio::sync::{mpsc, oneshot};

/// Chunk length (samples: 100 ms).
const CHUNK: usize = 1_600;

/// A speech job for the audio task: samples to mix in, and who to tell when they are out.
pub(super) type SpeechJob = (Vec<i16>, oneshot::Sender<()>);

/// Where [`audio_stream`] puts its chunks.
pub(super) enum AudioOut {
    Bus(interfaces::RecentPublisher<AudioChunk>),
    /// To the thread that writes them into the sound server.
    Pulse(std::sync::mpsc::SyncSender<Vec<i16>>),
}

/// Open the room's `sink` and start the thread that plays what the returned sender gets. A
/// chunk the server does not take in time is dropped and logged (the person's voice would
/// stutter: the test fails on its own expectations, with the log saying why).
pub(super) fn into_room(
    server: Option<String>,
    sink: &str,
) -> anyhow::Result<std::sync::mpsc::SyncSender<Vec<i16>>> {
    let mut playback = pulse::Playback::open(
        server.as_deref(),
        sink,
        RATE_HZ,
        1,
        PULSE_BUFFER,
        "person's voice",
    )?;
    tracing::info!("the person speaks into the sound server's sink {sink:?}");
    let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<i16>>(10);
    std::thread::Builder::new()
        .name("person-voice".into())
        .spawn(move || {
            while let Ok(chunk) = rx.recv() {
                if let Err(e) = playback.write(&chunk) {
                    tracing::warn!("the person's voice cannot reach the room: {e}");
                    return;
                }
            }
        })?;
    Ok(tx)
}

/// Room noise in real time, with speech mixed in when there is some.
pub(super) async fn audio_stream(
    out: AudioOut,
    mut speech: mpsc::Receiver<SpeechJob>,
    noise_power: f64,
    seed: u64,
) {
    let mut rng = NoiseRng::new(seed);
    // A continuous stream in real time, as a microphone gives it or a sound server's sink takes
    // it: chunks missed by a late wake-up are caught up (Burst), so the stream never runs short.
    #[expect(
        clippy::disallowed_methods,
        reason = "the room's sound is a continuous real-time stream, as a microphone or a sound server paces it"
    )]
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Burst);
    // Current sentence: samples, position, who to tell at the end.
    let mut current: Option<(Vec<i16>, usize, oneshot::Sender<()>)> = None;
    loop {
        tick.tick().await;
        if current.is_none()
            && let Ok((s, done)) = speech.try_recv()
        {
            // A little silence before and after the words, as people leave.
            current = Some((s, 0, done));
        }
        let noise = pcm::noise(CHUNK, NoiseKind::White, noise_power, &mut rng);
        let mut chunk: Vec<i16> = noise
            .iter()
            .map(|x| x.clamp(-32768.0, 32767.0) as i16)
            .collect();
        let mut finished = false;
        if let Some((s, pos, _)) = current.as_mut() {
            for (k, c) in chunk.iter_mut().enumerate() {
                if let Some(v) = s.get(*pos + k) {
                    *c = (*c as i32 + *v as i32).clamp(-32768, 32767) as i16;
                }
            }
            *pos += CHUNK;
            finished = *pos >= s.len();
        }
        if finished && let Some((_, _, done)) = current.take() {
            let _ = done.send(());
        }
        match &out {
            AudioOut::Bus(p) => {
                if let Err(e) = p.publish(&mut AudioChunk::mono(RATE_HZ, &chunk)).await {
                    tracing::warn!("cannot publish audio/in: {e}");
                }
            }
            AudioOut::Pulse(tx) => match tx.try_send(chunk) {
                Ok(()) => {}
                Err(std::sync::mpsc::TrySendError::Full(_)) => {
                    tracing::warn!(
                        "the sound server is not taking the person's voice: a chunk is dropped"
                    );
                }
                Err(std::sync::mpsc::TrySendError::Disconnected(_)) => {
                    tracing::warn!("the person's voice stopped: its sound server is gone");
                    return;
                }
            },
        }
    }
}
