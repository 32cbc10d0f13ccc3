//! The speaker's thread: the robot's voice written to the server slice by slice, cut, paused and
//! resumed as the bus loop says, and the speaker reopened when it is lost.

use super::devices::gone;
use super::shared::Loops;
use super::{Ctl, Play};
use interfaces::clock::Moment;
use interfaces::msg::speech::AudioChunk;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// The speaker's stream and what this thread knows of it.
struct Speaker {
    stream: pulse::Playback,
    /// When what was written so far has played (this thread's count, without the device's own
    /// latency), on the devices' time line ([`super::shared::VoiceClock`]); `None` before the
    /// first chunk, after a cut and while paused.
    queued_until: Option<Instant>,
    /// Whether a sentence is under way (a chunk written, and the generator has not said it
    /// ended): a chunk of it that finds the queue empty came too late, an under-run.
    in_sentence: bool,
    /// The last samples written (interleaved), enough to cover the server's buffer: what a
    /// pause takes back from the server is played from here when the robot goes on.
    recent: std::collections::VecDeque<i16>,
    /// While paused: the samples to play when the robot goes on (what the server had not
    /// played, then what came since).
    held: Option<Vec<i16>>,
}

/// The playback thread's state: the speaker (opened for the format of the chunks that come),
/// and what the bus loop said.
struct Player<'a> {
    loops: &'a Loops<'a>,
    ctl: &'a std::sync::mpsc::Receiver<Ctl>,
    speaker: Option<Speaker>,
    /// After a failure, the next attempt to open the speaker is not before this (on the
    /// component's clock).
    retry_at: Moment,
    lost: bool,
    /// The echo canceller's generation the last stream was opened on.
    generation: u64,
    buffer: Duration,
    /// Chunks numbered up to this were cut: they are not played.
    cut_upto: u64,
}

/// Play what the bus loop sends until it hangs up.
///
/// The server starts a stream only once it holds `--playback-buffer-ms` of it, and the speech
/// generator sends its chunks in real time: so the first chunk of a sentence is preceded by
/// enough silence to fill that buffer at once. The sentence starts at once (after the silence),
/// short sounds play without waiting for more, and the buffer keeps its cushion against late
/// chunks for the whole sentence. Audio is written in slices of [`SLICE`], and the bus loop's
/// control messages (cut, pause, go on) are looked at between two slices: a write that waits for
/// room in the server's buffer never holds them up for longer than a slice.
pub(super) fn playback_loop(
    loops: &Loops,
    rx: &std::sync::mpsc::Receiver<Play>,
    ctl: &std::sync::mpsc::Receiver<Ctl>,
) {
    let mut p = Player {
        loops,
        ctl,
        speaker: None,
        retry_at: loops.clock.now(),
        lost: false,
        generation: 0,
        buffer: Duration::from_millis(u64::from(loops.config.playback_buffer_ms)),
        cut_upto: 0,
    };
    loop {
        p.control(&mut Vec::new());
        if p.loops.presence.sink_missing.load(Ordering::Relaxed) && p.speaker.is_some() {
            let e = gone(pulse::Kind::Sink, &p.loops.config.sink);
            p.failed(&e);
        }
        let cmd = match rx.recv_timeout(SLICE) {
            Ok(cmd) => cmd,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return,
        };
        match cmd {
            Play::SentenceEnded => {
                if let Some(s) = p.speaker.as_mut() {
                    s.in_sentence = false;
                }
            }
            Play::Chunk(seq, _) if seq <= p.cut_upto => {}
            Play::Chunk(_, chunk) => p.chunk(&chunk),
        }
    }
}

/// How much is written to the server at once.
const SLICE: Duration = Duration::from_millis(20);

impl Player<'_> {
    /// Act on the control messages that came; `rest` is what the caller has not written yet of
    /// what it is writing (a pause holds it, a cut drops it). Whether to stop writing.
    fn control(&mut self, rest: &mut Vec<i16>) -> bool {
        let mut stop = false;
        while let Ok(c) = self.ctl.try_recv() {
            match c {
                Ctl::Cut(upto) => {
                    self.cut_upto = self.cut_upto.max(upto);
                    rest.clear();
                    stop = true;
                    self.cut();
                }
                Ctl::Pause => {
                    let taken = std::mem::take(rest);
                    stop = true;
                    self.pause(taken);
                }
                Ctl::Resume => self.resume(),
            }
        }
        stop
    }

    fn failed(&mut self, e: &pulse::Error) {
        let config = self.loops.config;
        tracing::warn!(
            "lost the speaker {:?}: {e}; opening it again every {} s",
            config.sink,
            config.reopen_s
        );
        self.loops.counters.incr("speaker_lost");
        self.speaker = None;
        self.lost = true;
        self.retry_at = self.loops.clock.now() + Duration::from_secs_f64(config.reopen_s);
    }

    /// Drop what is queued and held: the sentence was interrupted.
    fn cut(&mut self) {
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        let playing = s.queued_until.take().is_some();
        let held = s.held.take().is_some();
        if playing || held {
            s.in_sentence = false;
            self.loops.counters.incr("playback_cut");
            self.loops.voice.stopped(self.loops.counters);
            if let Err(e) = s.stream.flush() {
                self.failed(&e);
            }
        }
    }

    /// Stop playing at once, keeping what was not played (and `unwritten`) for [`Self::resume`].
    fn pause(&mut self, unwritten: Vec<i16>) {
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        if let Some(held) = s.held.as_mut() {
            held.extend(unwritten);
            return;
        }
        if s.queued_until.is_none() && unwritten.is_empty() {
            return;
        }
        // What the server holds and has not played yet, taken back.
        let queued_us = s.stream.latency_us().unwrap_or(0);
        self.loops.voice.stopped(self.loops.counters);
        if let Err(e) = s.stream.flush() {
            self.failed(&e);
            return;
        }
        let channels = usize::from(s.stream.channels());
        let frames = (queued_us as f64 * 1e-6 * f64::from(s.stream.rate_hz())) as usize;
        let n = (frames * channels).min(s.recent.len());
        let mut held: Vec<i16> = s.recent.iter().skip(s.recent.len() - n).copied().collect();
        held.extend(unwritten);
        s.recent.clear();
        s.queued_until = None;
        s.held = Some(held);
        self.loops.counters.incr("playback_paused");
    }

    /// Go on with what a pause held.
    fn resume(&mut self) {
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        let Some(held) = s.held.take() else {
            return;
        };
        // The server's buffer is empty: it starts again like a sentence (not an under-run).
        s.in_sentence = false;
        if !held.is_empty() {
            self.write(held);
        }
    }

    /// A chunk of the robot's voice: played, or held while paused.
    fn chunk(&mut self, chunk: &AudioChunk) {
        let counters = self.loops.counters;
        let (Some(samples), Ok(channels)) = (chunk.samples(), u8::try_from(chunk.channels)) else {
            counters.incr("playback_malformed");
            return;
        };
        if channels == 0
            || chunk.sample_rate_hz == 0
            || !samples.len().is_multiple_of(channels as usize)
        {
            counters.incr("playback_malformed");
            return;
        }
        // (Re)open the speaker for this chunk's format.
        let fits = self.speaker.as_ref().is_some_and(|s| {
            s.stream.rate_hz() == chunk.sample_rate_hz && s.stream.channels() == channels
        });
        if !fits && !self.open(chunk.sample_rate_hz, channels) {
            counters.incr("playback_dropped_device_lost");
            return;
        }
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        if let Some(held) = s.held.as_mut() {
            held.extend(samples);
            return;
        }
        self.write(samples);
    }

    /// Open the speaker for a format (closing the one open, after it played what it holds).
    fn open(&mut self, rate_hz: u32, channels: u8) -> bool {
        let config = self.loops.config;
        if let Some(mut old) = self.speaker.take()
            && old.queued_until.is_some_and(|t| t > self.loops.voice.now())
        {
            let _ = old.stream.drain();
        }
        if self.loops.clock.now() < self.retry_at
            || self.loops.presence.sink_missing.load(Ordering::Relaxed)
        {
            return false;
        }
        let failed = self.lost.then_some(self.generation);
        let opened = self.loops.echo.devices(failed).and_then(|(_, sink, g)| {
            self.generation = g;
            pulse::Playback::open(
                config.server(),
                &sink,
                rate_hz,
                channels,
                self.buffer,
                "robot voice",
            )
        });
        match opened {
            Ok(stream) => {
                if self.lost {
                    tracing::info!("the speaker {:?} is back", config.sink);
                    self.lost = false;
                }
                self.speaker = Some(Speaker {
                    stream,
                    queued_until: None,
                    in_sentence: false,
                    recent: Default::default(),
                    held: None,
                });
                true
            }
            Err(e) => {
                if !self.lost {
                    tracing::warn!(
                        "cannot open the speaker {:?}: {e}; the robot's voice is dropped until \
                         it opens (tried every {} s)",
                        config.sink,
                        config.reopen_s
                    );
                    self.loops.counters.incr("speaker_lost");
                    self.lost = true;
                }
                self.retry_at = self.loops.clock.now() + Duration::from_secs_f64(config.reopen_s);
                false
            }
        }
    }

    /// Write samples of the open speaker's format, slice by slice, a sentence's start padded
    /// with silence; a control message between two slices may stop it.
    fn write(&mut self, samples: Vec<i16>) {
        let counters = self.loops.counters;
        let buffer = self.buffer;
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        let (rate, channels) = (s.stream.rate_hz(), usize::from(s.stream.channels()));
        let duration = |n: usize| Duration::from_secs_f64((n / channels) as f64 / f64::from(rate));
        let now = self.loops.voice.now();
        let (mut until, mut data) = match s.queued_until {
            Some(until) if until > now => (until, samples),
            _ => {
                if s.in_sentence {
                    counters.incr("playback_underruns");
                    tracing::debug!("the speaker ran dry in the middle of a sentence");
                }
                // A sentence starts: silence first, up to the server's start threshold.
                let pad = buffer.saturating_sub(duration(samples.len()));
                let frames = (pad.as_secs_f64() * f64::from(rate)) as usize;
                let mut padded = vec![0i16; frames * channels];
                padded.extend(samples);
                (now, padded)
            }
        };
        s.in_sentence = true;
        counters.incr("playback_chunks");
        let slice = ((SLICE.as_secs_f64() * f64::from(rate)) as usize).max(1) * channels;
        let keep = ((buffer + SLICE * 5).as_secs_f64() * f64::from(rate)) as usize * channels;
        while !data.is_empty() {
            let mut rest = data.split_off(slice.min(data.len()));
            let Some(s) = self.speaker.as_mut() else {
                return;
            };
            if let Err(e) = s.stream.write(&data) {
                self.failed(&e);
                return;
            }
            let now = self.loops.voice.now();
            let starts = until.max(now);
            until = starts + duration(data.len());
            s.queued_until = Some(until);
            // When the slice plays, as the server says (it knows of late writes and of the
            // device's own delay; a busy machine's count of what was written does not).
            let plays = s
                .stream
                .latency_us()
                .and_then(|l| (now + Duration::from_micros(l)).checked_sub(duration(data.len())))
                .unwrap_or(starts);
            self.loops
                .voice
                .played(plays, (rate, channels), &data, self.loops.counters);
            s.recent.extend(data.iter().copied());
            let excess = s.recent.len().saturating_sub(keep);
            s.recent.drain(..excess);
            if self.control(&mut rest) {
                return;
            }
            data = rest;
        }
    }
}
