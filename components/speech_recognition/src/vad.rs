//! Voice activity detection and end-pointing: cuts utterances out of a continuous 16 kHz mono
//! stream.
//!
//! The stream is cut into 10 ms frames (160 samples). A frame's level is its power in dB relative
//! to full scale (dBFS), smoothed over the last three frames. A background level (noise floor)
//! follows the quietest recent frames: it falls at once to a quieter frame and rises by
//! `floor_rise_db_per_s` otherwise (slower during speech). A frame is *loud* when its level is at
//! least `start_db` above the floor and above `min_level_dbfs` (and over the background's own
//! swings, below).
//!
//! - An utterance **starts** after `start_frames` consecutive loud frames; it begins `preroll_s`
//!   before the first of them (soft onsets are kept).
//! - It **ends** when no frame has been loud (with `start_db - hysteresis_db`) for `hangover_s`;
//!   `tail_s` of the quiet after the last loud frame is kept.
//! - It is **cut** at `max_utterance_s` (marked `forced`), and dropped if the loud part lasted
//!   less than `min_speech_s` (a click, a cough).
//!
//! **The background's swings.** The floor follows the quietest frames, but a noise's 10 ms
//! levels swing around its mean: white noise's by a dB or two, a fan's (its power is
//! low-frequency) by 5 dB and more, so under a fan the floor sits so far below most frames that
//! the fan itself is loud and an utterance never ends. The detector therefore also keeps the
//! levels of the last `background_s` of frames heard outside utterances (not the loud run that
//! opens one, which is the utterance's; but those of an utterance cut at `max_utterance_s` or
//! dropped as too short, which were the background too), and a frame is loud only if it is also
//! `background_margin_db` over their 90th percentile (less `hysteresis_db` while an utterance is
//! open). Over white noise the floor decides; over a fan, this threshold.
//!
//! **Background talk.** Other people talking in the room (babble) swings by 10 dB and more from
//! one syllable to the next. When the background's spread (90th minus 20th percentile) is at
//! least `background_spread_db` and most of it is loud over the floor (talk goes on; the
//! reverberation of a room after speech dies away), the background is talk: the threshold over
//! its 90th percentile lets a command said over it (louder than it, as a person speaking to the
//! robot is) start an utterance and not the talk, and such an utterance keeps only
//! `talk_margin_s` of the talk before and after it (the pre-roll and the tail are talk, which a
//! decoder would take for words). It is marked [`Segment::over_talk`].
//!
//! **Sound from elsewhere.** A caller that knows where sounds come from (a microphone array's
//! localizer, [`crate::beam`]) marks what comes from elsewhere than the person's direction
//! ([`Vad::set_elsewhere`]): those frames are never loud (they neither open nor stretch an
//! utterance, and are the background's), however loud they are. A caller that knows the person
//! is speaking (push-to-talk, [`crate::talk`]) says so ([`Vad::set_hers`]): then the background's
//! threshold does not keep her from opening an utterance, only the floor does; what she says
//! under a hall's talk as loud as she is still opens one.
//!
//! Times are sample indices on the stream (from 0), so the caller turns them into seconds.

use std::collections::VecDeque;

/// Samples per second the detector expects.
pub const RATE_HZ: u32 = 16_000;
/// Samples per frame (10 ms).
pub const FRAME: usize = 160;

/// End-pointing thresholds (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct VadConfig {
    pub start_db: f64,
    pub hysteresis_db: f64,
    pub min_level_dbfs: f64,
    pub start_frames: usize,
    pub preroll_s: f64,
    pub hangover_s: f64,
    pub tail_s: f64,
    pub min_speech_s: f64,
    pub max_utterance_s: f64,
    pub floor_rise_db_per_s: f64,
    pub background_s: f64,
    pub background_spread_db: f64,
    pub background_margin_db: f64,
    pub talk_margin_s: f64,
}

impl Default for VadConfig {
    fn default() -> Self {
        Self {
            start_db: 5.0,
            hysteresis_db: 2.0,
            min_level_dbfs: -65.0,
            start_frames: 4,
            preroll_s: 0.25,
            hangover_s: 0.25,
            tail_s: 0.2,
            min_speech_s: 0.08,
            // The longest command of the games, said slowly ("robot please go to the ball and
            // dribble" at 130 words a minute), lasts 3.5 s: speech running on past this is
            // talk in the room, not a command (and becomes its background, see the module doc).
            max_utterance_s: 5.0,
            floor_rise_db_per_s: 2.0,
            background_s: 3.0,
            background_spread_db: 7.0,
            background_margin_db: 3.0,
            talk_margin_s: 0.08,
        }
    }
}

/// One utterance cut from the stream.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// First and one-past-last sample on the stream.
    pub start_sample: u64,
    pub end_sample: u64,
    pub samples: Vec<i16>,
    /// Cut at `max_utterance_s` rather than ended by silence.
    pub forced: bool,
    /// Samples at the start that were heard before the speech started (the pre-roll without its
    /// loud frames): background, usable as a noise estimate.
    pub lead_len: usize,
    /// Cut over other people's talk (the background was speech-like when it opened, see the
    /// module doc).
    pub over_talk: bool,
}

impl Segment {
    pub fn start_s(&self) -> f64 {
        self.start_sample as f64 / RATE_HZ as f64
    }
    pub fn end_s(&self) -> f64 {
        self.end_sample as f64 / RATE_HZ as f64
    }
}

#[derive(Debug)]
struct Open {
    start_sample: u64,
    samples: Vec<i16>,
    /// Samples in `samples` up to the end of the last loud frame.
    last_loud_len: usize,
    loud_frames: usize,
    quiet_frames: usize,
    lead_len: usize,
    /// The smoothed level of each frame since it opened (dBFS): the background's, if it turns
    /// out to be no utterance.
    levels: Vec<f64>,
    /// The background's threshold when it opened (see [`Vad::background_threshold`]).
    threshold: Option<f64>,
    /// Whether the background was talk when it opened (see [`Vad::background_is_talk`]).
    over_talk: bool,
}

/// The end-pointer; feed it any chunk sizes.
#[derive(Debug)]
pub struct Vad {
    cfg: VadConfig,
    pending: Vec<i16>,
    /// Recent frames kept for the pre-roll, oldest first.
    history: VecDeque<Vec<i16>>,
    levels: VecDeque<f64>,
    floor_db: Option<f64>,
    /// Whether the stream began with digital silence (before any floor was set).
    silence_first: bool,
    /// After digital silence, the levels of the room's first frames (see [`SETTLE_FRAMES`]).
    settling: Vec<f64>,
    loud_run: usize,
    /// The levels of the loud frames of `loud_run`: the background's if the run ends before it
    /// opens an utterance, the utterance's if it opens one.
    run_levels: Vec<f64>,
    open: Option<Open>,
    /// Stream position of the first sample of `pending`.
    pos: u64,
    /// Smoothed levels of the last `background_s` of frames heard outside utterances (dBFS),
    /// oldest first, and the same sorted.
    background: VecDeque<f64>,
    background_sorted: Vec<f64>,
    /// Utterances dropped as too short.
    pub dropped_short: u64,
    /// Whether what is heard now comes from elsewhere than the person (see the module doc).
    elsewhere: bool,
    /// Whether what is heard now is known to be the person's (see the module doc).
    hers: bool,
}

/// The level of a frame of digital silence (exact zeros), in dBFS.
const SILENCE_DBFS: f64 = -100.0;
/// The loudest first frame after digital silence still taken for the room's noise (dBFS); a
/// louder one is a sound.
const QUIET_ROOM_DBFS: f64 = -40.0;

/// Power of a frame in dBFS (−100 for digital silence).
/// The room's frames after digital silence whose median is the first floor (50 ms).
const SETTLE_FRAMES: usize = 5;

/// Exact zeros in a row (2 ms) that make a frame partly digital silence: a room's noise, or
/// speech, never holds a sample at exactly zero for so long.
const PARTLY_SILENT_RUN: usize = 32;

/// Whether `frame` holds `run` exact zeros in a row.
fn has_zero_run(frame: &[i16], run: usize) -> bool {
    let mut n = 0;
    for &s in frame {
        n = if s == 0 { n + 1 } else { 0 };
        if n >= run {
            return true;
        }
    }
    false
}

pub fn level_dbfs(frame: &[i16]) -> f64 {
    if frame.is_empty() {
        return -100.0;
    }
    let p = frame
        .iter()
        .map(|&s| {
            let x = s as f64 / 32768.0;
            x * x
        })
        .sum::<f64>()
        / frame.len() as f64;
    (10.0 * p.max(1e-10).log10()).max(-100.0)
}

impl Vad {
    pub fn new(cfg: VadConfig) -> Self {
        Self {
            cfg,
            pending: Vec::new(),
            history: VecDeque::new(),
            levels: VecDeque::new(),
            floor_db: None,
            silence_first: false,
            settling: Vec::new(),
            loud_run: 0,
            run_levels: Vec::new(),
            open: None,
            pos: 0,
            background: VecDeque::new(),
            background_sorted: Vec::new(),
            dropped_short: 0,
            elsewhere: false,
            hers: false,
        }
    }

    /// Whether the frames pushed from now on come from elsewhere than the person (someone
    /// else's, see the module doc), until said otherwise.
    pub fn set_elsewhere(&mut self, elsewhere: bool) {
        self.elsewhere = elsewhere;
    }

    /// Whether the frames pushed from now on are known to be the person's (a talk key is held):
    /// an utterance opens on the floor alone, the background's threshold aside, until said
    /// otherwise.
    pub fn set_hers(&mut self, hers: bool) {
        self.hers = hers;
    }

    /// Add a frame's smoothed level to the background (digital silence too: a room that fell
    /// silent has no talk in it any more).
    fn hear_background(&mut self, level: f64) {
        let cap = Self::frames(self.cfg.background_s).max(1);
        while self.background.len() >= cap {
            if let Some(old) = self.background.pop_front()
                && let Ok(i) = self
                    .background_sorted
                    .binary_search_by(|x| x.total_cmp(&old))
            {
                self.background_sorted.remove(i);
            }
        }
        self.background.push_back(level);
        let i = self
            .background_sorted
            .partition_point(|x| x.total_cmp(&level).is_lt());
        self.background_sorted.insert(i, level);
    }

    /// The `p` quantile of the background's levels (dBFS), once `min_s` of background was
    /// heard.
    fn background_quantile(&self, p: f64, min_s: f64) -> Option<f64> {
        let b = &self.background_sorted;
        (!b.is_empty() && b.len() >= Self::frames(min_s))
            .then(|| b[((b.len() - 1) as f64 * p).round() as usize])
    }

    /// The level a frame must reach to stand out of the background's own swings (dBFS):
    /// `background_margin_db` over its 90th percentile (see the module doc); `None` before
    /// 100 ms of background was heard.
    pub fn background_threshold(&self) -> Option<f64> {
        Some(self.background_quantile(0.9, 0.1)? + self.cfg.background_margin_db)
    }

    /// Whether the background is other people's talk (see the module doc): `None` before a
    /// second of background was heard.
    pub fn background_is_talk(&self) -> Option<bool> {
        let b = &self.background_sorted;
        let (low, high) = (
            self.background_quantile(0.2, 1.0)?,
            self.background_quantile(0.9, 1.0)?,
        );
        // Talk goes on: most of it is loud over the floor. A room that rang after speech (its
        // reverberation decaying into quiet) or a few loud sounds in steady noise is not talk.
        let floor = self.floor_db?;
        let loud = b.len() - b.partition_point(|&x| x < floor + self.cfg.start_db);
        Some(high - low >= self.cfg.background_spread_db && loud * 2 >= b.len())
    }

    /// Whether an utterance is under way.
    pub fn in_speech(&self) -> bool {
        self.open.is_some()
    }

    /// The utterance under way, if any: its first stream sample and the samples of it that will
    /// certainly be part of the cut segment (up to the last loud frame plus `tail_s`; later
    /// samples belong to it only if speech resumes). A recognizer can decode these while the
    /// person still speaks; the segment that [`Vad::push`] returns at the end starts with them.
    /// Also the length of its background lead ([`Segment::lead_len`]).
    pub fn open_prefix(&self) -> Option<(u64, &[i16], usize)> {
        let open = self.open.as_ref()?;
        let keep = (open.last_loud_len + self.tail_frames(open) * FRAME).min(open.samples.len());
        Some((open.start_sample, &open.samples[..keep], open.lead_len))
    }

    /// How much speech (loud frames, s) the utterance under way holds so far.
    pub fn open_loud_s(&self) -> Option<f64> {
        let open = self.open.as_ref()?;
        Some((open.loud_frames * FRAME) as f64 / RATE_HZ as f64)
    }

    /// The current noise floor estimate (dBFS).
    pub fn floor_dbfs(&self) -> Option<f64> {
        self.floor_db
    }

    /// The quiet kept after an utterance's last loud frame (frames): less over talk.
    fn tail_frames(&self, open: &Open) -> usize {
        Self::frames(if open.over_talk {
            self.cfg.talk_margin_s
        } else {
            self.cfg.tail_s
        })
    }

    fn frames(s: f64) -> usize {
        (s * RATE_HZ as f64 / FRAME as f64).round() as usize
    }

    /// Feed samples; returns the utterances that ended in them.
    pub fn push(&mut self, samples: &[i16]) -> Vec<Segment> {
        self.pending.extend_from_slice(samples);
        let mut out = Vec::new();
        let n = self.pending.len() / FRAME;
        let frames: Vec<Vec<i16>> = self.pending[..n * FRAME]
            .chunks_exact(FRAME)
            .map(<[i16]>::to_vec)
            .collect();
        self.pending.drain(..n * FRAME);
        for f in frames {
            if let Some(s) = self.frame(f) {
                out.push(s);
            }
            self.pos += FRAME as u64;
        }
        out
    }

    /// End of stream: close an open utterance (with what was heard so far).
    pub fn flush(&mut self) -> Option<Segment> {
        let open = self.open.take()?;
        self.close(open, false)
    }

    fn close(&mut self, mut open: Open, forced: bool) -> Option<Segment> {
        self.loud_run = 0;
        if (open.loud_frames as f64) * (FRAME as f64) / (RATE_HZ as f64) < self.cfg.min_speech_s {
            self.dropped_short += 1;
            for &l in &open.levels {
                self.hear_background(l);
            }
            return None;
        }
        if forced {
            // Talk that never paused: the room's, not a command to the robot.
            let levels = std::mem::take(&mut open.levels);
            for l in levels {
                self.hear_background(l);
            }
        }
        if !forced {
            let keep =
                (open.last_loud_len + self.tail_frames(&open) * FRAME).min(open.samples.len());
            open.samples.truncate(keep);
        }
        Some(Segment {
            start_sample: open.start_sample,
            end_sample: open.start_sample + open.samples.len() as u64,
            samples: open.samples,
            forced,
            lead_len: open.lead_len,
            over_talk: open.over_talk,
        })
    }

    fn frame(&mut self, f: Vec<i16>) -> Option<Segment> {
        let raw = level_dbfs(&f);
        self.levels.push_back(raw);
        if self.levels.len() > 3 {
            self.levels.pop_front();
        }
        // Smooth in the power domain.
        let level = 10.0
            * (self
                .levels
                .iter()
                .map(|l| 10f64.powf(l / 10.0))
                .sum::<f64>()
                / self.levels.len() as f64)
                .log10();
        // Digital silence (exact zeros: a stream that has not started, a muted source, an empty
        // virtual room) is no measure of the room's noise: it never lowers the floor. A stream
        // that starts with it gets its floor from the first frame that is not silent when that
        // one is as quiet as a room (below QUIET_ROOM_DBFS); a louder one is a sound, heard
        // against silence. A stream that starts with sound sets the floor from it, as before
        // (it falls at once to the first quieter frame). A frame that is partly digital silence
        // (the sound starts or stops inside it) measures neither: its level is the sound's
        // diluted by zeros, and a floor set from it would sit under the room (the room's noise
        // starting after an echo canceller's first silent chunks would then be heard as speech).
        // Nor does the room's first frame alone: a sound server's stream can fade in, an echo
        // canceller's noise comes up over a few frames. So the floor after digital silence is
        // the median of the room's first SETTLE_FRAMES, none of them loud.
        let silent = raw <= SILENCE_DBFS;
        let partly_silent = !silent && has_zero_run(&f, PARTLY_SILENT_RUN);
        if silent && self.floor_db.is_none() {
            self.silence_first = true;
        }
        let settling = self.floor_db.is_none()
            && self.silence_first
            && !silent
            && !partly_silent
            && raw < QUIET_ROOM_DBFS;
        let floor = match self.floor_db {
            Some(f) => f,
            None if settling => {
                self.settling.push(raw);
                self.settling.iter().copied().fold(f64::MIN, f64::max)
            }
            None if !silent && !partly_silent && !self.silence_first => raw,
            None => SILENCE_DBFS,
        };
        let rise = self.cfg.floor_rise_db_per_s * FRAME as f64 / RATE_HZ as f64;
        let new_floor = if silent || (partly_silent && raw < floor) {
            floor
        } else if raw < floor {
            raw
        } else if self.open.is_some() {
            floor + rise * 0.25
        } else {
            floor + rise
        };
        if settling {
            if self.settling.len() >= SETTLE_FRAMES {
                let mut v = std::mem::take(&mut self.settling);
                v.sort_by(f64::total_cmp);
                self.floor_db = Some(v[v.len() / 2]);
            }
        } else if !((silent || partly_silent) && self.floor_db.is_none()) {
            self.floor_db = Some(new_floor);
        }
        let above = level - floor;
        // The background's threshold too: the one in force when the utterance opened, while it
        // is open.
        let (threshold, talk) = match &self.open {
            Some(open) => (open.threshold, open.over_talk),
            None => (
                self.background_threshold().filter(|_| !self.hers),
                self.background_is_talk().unwrap_or(false),
            ),
        };
        let loud = !self.elsewhere
            && level > self.cfg.min_level_dbfs
            && above >= self.cfg.start_db
            && threshold.is_none_or(|t| level >= t);
        let still_loud = !self.elsewhere
            && level > self.cfg.min_level_dbfs
            && above >= self.cfg.start_db - self.cfg.hysteresis_db
            && threshold.is_none_or(|t| level >= t - self.cfg.hysteresis_db);

        // Over talk, the pre-roll and the tail are talk too: the utterance keeps little of them.
        let preroll_s = if talk {
            self.cfg.talk_margin_s
        } else {
            self.cfg.preroll_s
        };
        let preroll = Self::frames(preroll_s).max(self.cfg.start_frames);
        match self.open.as_mut() {
            None => {
                if loud {
                    self.loud_run += 1;
                    self.run_levels.push(level);
                } else {
                    self.loud_run = 0;
                    for l in std::mem::take(&mut self.run_levels) {
                        self.hear_background(l);
                    }
                    self.hear_background(level);
                }
                self.history.push_back(f);
                while self.history.len() > preroll {
                    self.history.pop_front();
                }
                if self.loud_run >= self.cfg.start_frames {
                    let frames: Vec<Vec<i16>> = self.history.drain(..).collect();
                    let start_sample = self.pos + FRAME as u64 - (frames.len() * FRAME) as u64;
                    let samples: Vec<i16> = frames.concat();
                    let lead_len = samples.len().saturating_sub(self.loud_run * FRAME);
                    self.open = Some(Open {
                        start_sample,
                        lead_len,
                        last_loud_len: samples.len(),
                        samples,
                        loud_frames: self.loud_run,
                        quiet_frames: 0,
                        levels: std::mem::take(&mut self.run_levels),
                        threshold,
                        over_talk: talk,
                    });
                }
                None
            }
            Some(open) => {
                open.samples.extend_from_slice(&f);
                open.levels.push(level);
                if still_loud {
                    open.loud_frames += 1;
                    open.quiet_frames = 0;
                    open.last_loud_len = open.samples.len();
                } else {
                    open.quiet_frames += 1;
                }
                let too_long =
                    open.samples.len() as f64 / RATE_HZ as f64 >= self.cfg.max_utterance_s;
                let ended = open.quiet_frames >= Self::frames(self.cfg.hangover_s);
                if too_long || ended {
                    let open = self.open.take()?;
                    return self.close(open, too_long && !ended);
                }
                None
            }
        }
    }
}

#[cfg(test)]
mod tests;
