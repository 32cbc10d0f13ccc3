//! `audio/in` to the decoder thread: each chunk checked (a chunk of the wrong format is dropped
//! and counted), beamformed when it comes from a microphone array ([`crate::beam`]), judged
//! against the talk key in push-to-talk mode ([`crate::talk`]), and queued for the decoder in a
//! queue bounded by its duration (a chunk the decoder is too far behind for is dropped and
//! counted). Also where the beam listens, paced for `speech/listening`.

use crate::beam::LiveBeam;
use crate::talk::{KeyNews, TalkGate};
use crate::vad::RATE_HZ;
use interfaces::Bus;
use interfaces::clock::Moment;
use interfaces::msg::speech::{AudioChunk, ListeningDirection, TalkKey};

/// The audio that may wait for the decoder (s), whatever the chunks' length (20 ms from
/// `audio_io`, 100 ms from the simulated person): the longest utterance and its decoding.
pub const DECODER_BACKLOG_S: f64 = 10.0;

/// A block for the decoder: its samples, when it arrived (the component's clock), when its
/// first sample was heard (ns, the microphone's time), and whose sound it is.
pub(crate) type Queued = (Vec<i16>, Moment, i64, Whose);

/// Whose sound a block is, as far as the component knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Whose {
    /// Nothing says: the end-pointer judges.
    Unknown,
    /// Someone else's: from another direction ([`crate::beam`]), or heard while the talk key
    /// was up ([`crate::talk`]).
    Elsewhere,
    /// The person's: heard while she held the talk key.
    Hers,
}

/// The most chunks that may wait for the decoder, however short: 10 s of 2.5 ms chunks.
const DECODER_BACKLOG_CHUNKS: usize = 4000;

/// The queue of audio (one channel, 16 kHz) to the decoder thread, bounded by its duration: a
/// chunk that would take it over [`DECODER_BACKLOG_S`] (or [`DECODER_BACKLOG_CHUNKS`]) is
/// dropped and counted.
pub(crate) struct DecoderQueue {
    tx: std::sync::mpsc::SyncSender<Queued>,
    /// Samples sent and not yet taken by the decoder.
    queued: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

impl DecoderQueue {
    pub(crate) fn new() -> (Self, DecoderInbox) {
        let (tx, rx) = std::sync::mpsc::sync_channel(DECODER_BACKLOG_CHUNKS);
        let queued = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        (
            Self {
                tx,
                queued: queued.clone(),
            },
            DecoderInbox { rx, queued },
        )
    }
}

/// The decoder thread's end of a [`DecoderQueue`].
pub(crate) struct DecoderInbox {
    rx: std::sync::mpsc::Receiver<Queued>,
    queued: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

impl DecoderInbox {
    /// The next chunk, blocking; `None` once the queue's sender is gone.
    pub(crate) fn recv(&self) -> Option<Queued> {
        let chunk = self.rx.recv().ok()?;
        self.queued
            .fetch_sub(chunk.0.len(), std::sync::atomic::Ordering::Relaxed);
        Some(chunk)
    }
}

/// `speech/listening` at most this often (ns of the audio's time), but at once when a sound is
/// placed elsewhere or back.
const LISTENING_EVERY_NS: i64 = 200_000_000;

/// Paces `speech/listening` (see [`LISTENING_EVERY_NS`]).
#[derive(Debug, Default)]
pub(crate) struct ListeningPacer {
    last_ns: Option<i64>,
    last_elsewhere: bool,
}

impl ListeningPacer {
    /// Whether `m` goes out.
    pub(crate) fn due(&mut self, m: &ListeningDirection) -> bool {
        let at = m.header.stamp_ns;
        let due = m.elsewhere != self.last_elsewhere
            || self
                .last_ns
                .is_none_or(|last| at < last || at - last >= LISTENING_EVERY_NS);
        if due {
            self.last_ns = Some(at);
            self.last_elsewhere = m.elsewhere;
        }
        due
    }
}

/// One chunk of `audio/in` to the decoder: one of the wrong format, or one the decoder has no
/// room for, is dropped and counted. With push-to-talk (`talk`), what was heard while the key
/// was up goes as sound from elsewhere. Returns, for the beam's blocks, where the beam listened
/// and where their sound came from.
pub(crate) fn feed(
    bus: &Bus,
    audio_tx: &DecoderQueue,
    beam: &mut Option<LiveBeam>,
    talk: &mut Option<TalkGate>,
    chunk: AudioChunk,
) -> anyhow::Result<Vec<ListeningDirection>> {
    let mut listening = Vec::new();
    let channels = usize::from(chunk.channels);
    let reason = if chunk.sample_rate_hz != RATE_HZ {
        Some("wrong_rate")
    } else if channels == 0 {
        Some("no_channels")
    } else if !chunk.pcm_s16le.len().is_multiple_of(2 * channels) {
        Some("partial_frame")
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
                "dropped audio chunk ({reason}: {} Hz, {} channels, {} bytes; want {RATE_HZ} Hz s16le, whole frames), {} so far",
                chunk.sample_rate_hz,
                chunk.channels,
                chunk.pcm_s16le.len(),
                n + 1
            );
        }
        return Ok(listening);
    }
    let Some(samples) = chunk.samples() else {
        return Ok(listening);
    };
    let blocks = match beam {
        Some(beam) if channels > 1 => {
            let blocks = beam.push(&samples, channels, chunk.header.stamp_ns);
            if blocks.iter().any(|h| !h.beamformed) {
                let n = bus
                    .counters()
                    .counter("array_channel_mismatch")
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if n.is_power_of_two() || n == 0 {
                    tracing::warn!(
                        "an audio/in chunk of {channels} channels, the array {} has {} microphones: mixed into one channel, not beamformed ({} so far)",
                        beam.name(),
                        beam.channels(),
                        n + 1
                    );
                }
            }
            listening.extend(
                blocks
                    .iter()
                    .filter(|h| h.beamformed)
                    .map(|h| ListeningDirection {
                        header: interfaces::Header {
                            stamp_ns: h.stamp_ns,
                            frame_id: beam.name().to_string(),
                            ..Default::default()
                        },
                        beam_azimuth_rad: beam.azimuth_rad(),
                        listening_to: beam.current_aim().label().to_string(),
                        located: h.located_rad.is_some(),
                        talker_azimuth_rad: h.located_rad.unwrap_or(0.0),
                        elsewhere: h.elsewhere,
                    }),
            );
            let elsewhere = blocks.iter().filter(|h| h.elsewhere).count() as u64;
            bus.counters()
                .counter("array_blocks_elsewhere")
                .fetch_add(elsewhere, std::sync::atomic::Ordering::Relaxed);
            blocks
                .into_iter()
                .map(|h| (h.samples, h.stamp_ns, h.elsewhere))
                .collect()
        }
        _ if channels > 1 => {
            let n = bus
                .counters()
                .counter("audio_mixed_to_mono")
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if n == 0 {
                tracing::info!(
                    "audio/in has {channels} channels: mixed into one (with --array <its geometry> the recognizer beamforms them)"
                );
            }
            vec![(
                audio::wav::mix_to_mono(&samples, channels),
                chunk.header.stamp_ns,
                false,
            )]
        }
        _ => vec![(samples, chunk.header.stamp_ns, false)],
    };
    for (samples, stamp_ns, elsewhere) in blocks {
        let key = talk.as_mut().map(|gate| {
            let expired = gate.expired;
            let half_ns = samples.len() as i64 * 500_000_000 / i64::from(RATE_HZ);
            let held = gate.held_at(stamp_ns + half_ns);
            if gate.expired > expired {
                bus.counters().incr("talk_key_expired");
                tracing::warn!(
                    "the talk key was held and then not heard of for {:.1} s (the panel or its \
                     page is gone?): taken as released",
                    interfaces::msg::speech::TALK_KEY_EXPIRY_S
                );
            }
            held
        });
        let whose = match (elsewhere, key) {
            (true, _) => Whose::Elsewhere,
            (false, None) => Whose::Unknown,
            (false, Some(true)) => Whose::Hers,
            (false, Some(false)) => {
                bus.counters().incr("talk_blocks_outside_key");
                Whose::Elsewhere
            }
        };
        queue(bus, audio_tx, samples, stamp_ns, whose)?;
    }
    Ok(listening)
}

/// A talk key message into the push-to-talk gate, logged as the key goes down and up.
pub(crate) fn hear_key(bus: &Bus, gate: &mut TalkGate, key: &TalkKey) {
    match gate.key(key) {
        KeyNews::Pressed => tracing::info!("talk key down ({})", key.source),
        KeyNews::Released => tracing::info!("talk key up ({})", key.source),
        KeyNews::Same => {}
        KeyNews::Dropped => {
            let n = bus
                .counters()
                .counter("talk_key_dropped")
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if n.is_power_of_two() || n == 0 {
                tracing::warn!(
                    "dropped a talk key message from {:?} stamped {} ns: older than the last one, \
                     or over a minute off the microphone's time (is that machine's clock \
                     right?); {} so far",
                    key.source,
                    key.header.stamp_ns,
                    n + 1
                );
            }
        }
    }
}

/// One block of one channel to the decoder, or dropped and counted when it is too far behind.
fn queue(
    bus: &Bus,
    audio_tx: &DecoderQueue,
    samples: Vec<i16>,
    stamp_ns: i64,
    whose: Whose,
) -> anyhow::Result<()> {
    let limit = (DECODER_BACKLOG_S * f64::from(RATE_HZ)) as usize;
    let queued = audio_tx.queued.load(std::sync::atomic::Ordering::Relaxed);
    let n = samples.len();
    // Counted before it is sent: the decoder may take it (and count it out) at once.
    let full = queued + n > limit || {
        audio_tx
            .queued
            .fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        match audio_tx
            .tx
            .try_send((samples, bus.clock().now(), stamp_ns, whose))
        {
            Ok(()) => false,
            Err(std::sync::mpsc::TrySendError::Full(_)) => {
                audio_tx
                    .queued
                    .fetch_sub(n, std::sync::atomic::Ordering::Relaxed);
                true
            }
            Err(std::sync::mpsc::TrySendError::Disconnected(_)) => {
                anyhow::bail!("the decoder thread stopped")
            }
        }
    };
    if full {
        let c = bus.counters().counter("audio_dropped/decoder_behind");
        let k = c.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        if k.is_power_of_two() || k == 0 {
            tracing::warn!(
                "the decoder is {:.1} s behind: dropped an audio chunk, {} so far",
                queued as f64 / f64::from(RATE_HZ),
                k + 1
            );
        }
    }
    Ok(())
}

/// The next talk key message; never, without push-to-talk.
pub(crate) async fn next_key(
    keys: Option<&interfaces::Subscriber<TalkKey>>,
) -> Result<TalkKey, interfaces::BusError> {
    match keys {
        Some(keys) => keys.recv().await,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(at_ms: i64, elsewhere: bool) -> ListeningDirection {
        ListeningDirection {
            header: interfaces::Header {
                stamp_ns: 1_800_000_000_000_000_000 + at_ms * 1_000_000,
                ..Default::default()
            },
            located: true,
            elsewhere,
            ..Default::default()
        }
    }

    #[test]
    fn where_it_listens_goes_out_five_times_a_second_and_at_once_when_a_talker_moves() {
        let mut p = ListeningPacer::default();
        let sent: Vec<i64> = (0..20)
            .map(|k| k * 100)
            .filter(|&at| p.due(&block(at, false)))
            .collect();
        assert_eq!(sent, [0, 200, 400, 600, 800, 1000, 1200, 1400, 1600, 1800]);
        // Someone else starts, and stops: both said at once.
        assert!(p.due(&block(1900, true)));
        assert!(!p.due(&block(2000, true)));
        assert!(p.due(&block(2050, false)));
        // A stream that starts again earlier (a restarted microphone) is not held back.
        assert!(p.due(&block(100, false)));
    }
}
