//! The microphone's threads: the capture loop onto the bus loop, the microphone as it is beside
//! the echo canceller, and the double-talk detector between them.

use super::Heard;
use super::devices::{gone, open_capture, published_channels, reopen};
use super::shared::{Loops, Played};
use crate::double_talk::{self, DoubleTalk};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The microphone as it is (the canceller's master source), for the double-talk detector: what
/// it hears, with when, until `stop`. A failure is retried every `--reopen-s` without a word
/// beyond a log line: the detector then takes everything heard while the robot speaks for the
/// robot's, which is safe.
pub(super) fn raw_microphone_loop(
    loops: &Loops,
    stop: &AtomicBool,
    tx: &std::sync::mpsc::SyncSender<(i64, Vec<i16>)>,
) {
    let config = loops.config;
    let open = || {
        pulse::Capture::open(
            config.server(),
            &config.source,
            config.rate_hz,
            1,
            config.chunk_frames(),
            "robot microphone, as heard (double-talk detection)",
        )
    };
    let mut capture = match open() {
        Ok(c) => c,
        Err(e) => {
            tracing::warn!(
                "cannot open the microphone {:?} beside the echo canceller: {e}; until it opens, \
                 what is heard while the robot speaks is taken for the robot's voice",
                config.source
            );
            match reopen(config, loops.clock, stop, open) {
                Some(c) => c,
                None => return,
            }
        }
    };
    let mut samples = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        match capture.read(&mut samples) {
            Ok(()) => {
                let latency = capture.latency_us().unwrap_or(0);
                let t = loops.voice.heard_ns(samples.len(), config.rate_hz, latency);
                match tx.try_send((t, std::mem::take(&mut samples))) {
                    Ok(()) => {}
                    Err(std::sync::mpsc::TrySendError::Full(_)) => {
                        loops.counters.incr("double_talk_microphone_overruns");
                    }
                    Err(std::sync::mpsc::TrySendError::Disconnected(_)) => return,
                }
            }
            Err(e) => {
                tracing::warn!(
                    "lost the microphone {:?} beside the echo canceller: {e}; opening it again",
                    config.source
                );
                match reopen(config, loops.clock, stop, open) {
                    Some(c) => capture = c,
                    None => return,
                }
            }
        }
    }
}

/// The double-talk detector of the capture thread, and what it is fed: the microphone's frames
/// and what the speaker played.
pub(super) struct Detector {
    dt: DoubleTalk,
    raw: std::sync::mpsc::Receiver<(i64, Vec<i16>)>,
    played: std::sync::mpsc::Receiver<Played>,
    /// The time of the end of the microphone's last frame given to `dt`.
    raw_until_ns: i64,
    /// The canceller's output held back (first sample's time, samples), while the robot's voice
    /// may be in the room, until the microphone's frames of the next `holdback_ns` are known.
    held: std::collections::VecDeque<(i64, Vec<i16>)>,
    /// The counters `echo_suppressed_frames`, `double_talk_frames` and
    /// `double_talk_unheld_frames`.
    suppressed: Arc<std::sync::atomic::AtomicU64>,
    player: Arc<std::sync::atomic::AtomicU64>,
    unheld: Arc<std::sync::atomic::AtomicU64>,
}

impl Detector {
    pub(super) fn new(
        raw: std::sync::mpsc::Receiver<(i64, Vec<i16>)>,
        played: std::sync::mpsc::Receiver<Played>,
        counters: &interfaces::bus::Counters,
    ) -> Self {
        Self {
            dt: DoubleTalk::new(double_talk::Config::default()),
            raw,
            played,
            raw_until_ns: i64::MIN,
            held: Default::default(),
            suppressed: counters.counter("echo_suppressed_frames"),
            player: counters.counter("double_talk_frames"),
            unheld: counters.counter("double_talk_unheld_frames"),
        }
    }

    /// A chunk of the canceller's output heard at `t_ns`; the chunks held back long enough,
    /// the robot's residue in them taken out, with when their first samples were heard.
    fn process(&mut self, loops: &Loops, t_ns: i64, samples: Vec<i16>) -> Vec<(i64, Vec<i16>)> {
        let rate = loops.config.rate_hz;
        let ns = |n: usize, rate: u32| n as i64 * 1_000_000_000 / i64::from(rate.max(1));
        while let Ok(p) = self.played.try_recv() {
            match p {
                Played::Voice(t, r, mono) => self.dt.reference(t, r, &mono),
                Played::DroppedFrom(t) => self.dt.reference_dropped_from(t),
            }
        }
        // The microphone's frames up to this chunk's end: they were heard at the same time (the
        // canceller's output comes later), but their thread may not have run yet, on a busy
        // machine for tens of milliseconds. (Not waited for when that stream is not
        // delivering: lost, or not open yet.)
        let end = t_ns + ns(samples.len(), rate);
        let delivering = self.raw_until_ns > t_ns - 500_000_000;
        let deadline = loops.voice.now() + Duration::from_millis(if delivering { 100 } else { 0 });
        loop {
            while let Ok((t, raw)) = self.raw.try_recv() {
                self.raw_until_ns = t + ns(raw.len(), rate);
                self.dt.mic(t, rate, &raw);
            }
            if self.raw_until_ns >= end || loops.voice.now() >= deadline {
                break;
            }
            #[expect(
                clippy::disallowed_methods,
                reason = "waits on this device thread for the microphone's own thread, which runs in real time"
            )]
            std::thread::sleep(Duration::from_millis(2));
        }
        self.dt.canceller(t_ns, rate, &samples);
        self.held.push_back((t_ns, samples));
        let lookback = self.dt.holdback_ns();
        let mut ready = Vec::new();
        // Held back only while the robot's voice may be in the room, where the player's first
        // sounds may come before they are known to be hers.
        while self.held.front().is_some_and(|(t, s)| {
            t + ns(s.len(), rate) + lookback <= end || !self.dt.robot_may_be_heard(*t)
        }) {
            let Some((t, mut s)) = self.held.pop_front() else {
                break;
            };
            let o = self.dt.process(t, rate, &mut s);
            self.suppressed
                .fetch_add(u64::from(o.suppressed_frames), Ordering::Relaxed);
            self.player
                .fetch_add(u64::from(o.player_frames), Ordering::Relaxed);
            if o.unheld_frames > 0 {
                let before = self
                    .unheld
                    .fetch_add(u64::from(o.unheld_frames), Ordering::Relaxed);
                if before == 0 {
                    tracing::warn!(
                        "the player's frames at {t} ns passed as the canceller left them: the \
                         microphone's samples of their time were not held (a gap in its stream \
                         or a rate change); counted as double_talk_unheld_frames"
                    );
                }
            }
            ready.push((t, s));
        }
        if let Some(p) = self.dt.path_changed() {
            tracing::info!(
                "the robot's voice reaches the microphone {} ms after it is played, {:+.0} dB \
                 (levels correlated {:.2}), and dies away at {:.0} dB/s: the player can talk \
                 over it {:.0} dB louder than that",
                p.delay_frames * 10,
                p.gain_db,
                p.correlation,
                p.decay_db_per_s,
                p.margin_db
            );
        }
        ready
    }
}

/// Read the microphone until `stop`, reopening it when it fails; with a detector, the robot's
/// voice the canceller left in is taken out first.
pub(super) fn capture_loop(
    (mut capture, mut generation): (pulse::Capture, u64),
    loops: &Loops,
    stop: &AtomicBool,
    tx: &tokio::sync::mpsc::Sender<Heard>,
    mut detector: Option<Detector>,
) {
    let Loops {
        config,
        echo,
        presence,
        counters,
        ..
    } = *loops;
    let mut samples = Vec::new();
    let mut publish = published_channels(&capture, echo.array(), counters);
    while !stop.load(Ordering::Relaxed) {
        let read = match capture.read(&mut samples) {
            Ok(()) if presence.source_missing.load(Ordering::Relaxed) => {
                Err(gone(pulse::Kind::Source, &config.source))
            }
            other => other,
        };
        match read {
            Ok(()) => {
                counters.incr("capture_chunks");
                let latency = capture.latency_us().unwrap_or(0);
                let chunks = match detector.as_mut() {
                    Some(d) => {
                        let t = loops.voice.heard_ns(samples.len(), config.rate_hz, latency);
                        let ready = d.process(loops, t, std::mem::take(&mut samples));
                        if d.dt.player_started() {
                            counters.incr("double_talk_onsets");
                            let _ = tx.try_send(Heard::PlayerOverRobot);
                        }
                        // Held back: how long their last samples waited by now.
                        let now = loops.voice.ns(loops.voice.now());
                        ready
                            .into_iter()
                            .map(|(t, s)| {
                                let end = t + s.len() as i64 * 1_000_000_000
                                    / i64::from(config.rate_hz.max(1));
                                (s, u64::try_from((now - end) / 1000).unwrap_or(0))
                            })
                            .collect()
                    }
                    None if u16::from(capture.channels()) == publish => {
                        vec![(std::mem::take(&mut samples), latency)]
                    }
                    None => vec![(
                        audio::wav::mix_to_mono(&samples, usize::from(capture.channels())),
                        latency,
                    )],
                };
                for (chunk, waited_us) in chunks {
                    match tx.try_send(Heard::Chunk(chunk, publish, waited_us)) {
                        Ok(()) => {}
                        Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {
                            counters.incr("capture_overruns");
                        }
                        Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => return,
                    }
                }
            }
            Err(e) => {
                if tx.blocking_send(Heard::Lost(e.to_string())).is_err() {
                    return;
                }
                let open = || {
                    if presence.source_missing.load(Ordering::Relaxed) {
                        Err(gone(pulse::Kind::Source, &config.source))
                    } else {
                        open_capture(config, echo, Some(generation))
                    }
                };
                let Some(again) = reopen(config, loops.clock, stop, open) else {
                    return;
                };
                (capture, generation) = again;
                publish = published_channels(&capture, echo.array(), counters);
                if tx.blocking_send(Heard::Back).is_err() {
                    return;
                }
            }
        }
    }
}
