//! Telling the player's voice from the robot's own (double-talk detection), and taking what the
//! echo canceller leaves of the robot's out of `audio/in` (residual echo suppression).
//!
//! The sound server's canceller removes most of the robot's voice from the microphone, but not
//! all of it: while it adapts, and in bursts after, what it lets through is loud enough for the
//! recognizer's end-pointer and decodes as commands. Its output alone cannot tell such a burst
//! from the player's first syllable over the robot: both are speech the canceller left in. So the
//! detector looks at the microphone as it is instead (the canceller's master source, captured on
//! a stream of its own) beside what the robot played (the reference), both as levels of 10 ms
//! frames on one clock:
//!
//! - **The echo path.** How long the robot's voice takes from the playback stream to the
//!   microphone, and how much louder or quieter it arrives there: the delay that best lines up
//!   the microphone's levels with the reference's (their correlation, over the last
//!   [`Config::path_window_s`] of the robot's speech, lags from [`Config::min_delay_ms`] to
//!   [`Config::max_delay_ms`]), and the median level difference at that delay. Measured again
//!   every [`Config::path_every_s`] of the robot's speech; a measure whose correlation is under
//!   [`Config::min_correlation`] (the player spoke through most of it) is not taken.
//! - **The echo a frame may hold**: the loudest of the reference's recent frames at that delay
//!   plus the gain, [`Config::jitter_frames`] either side at full level (the streams' timing,
//!   early or late), a frame further back than that counting less by the room's decay (its
//!   reverberation). The decay is
//!   measured with the path: the fastest of [`Config::decays_db_per_s`] under which the
//!   microphone, while the robot speaks, stands at most [`Config::fit_db`] over the echo so
//!   predicted in 99 % of the frames; the slowest when none does.
//! - **The player speaks** when the microphone is louder than that echo by the margin (3 dB
//!   over that 99th percentile, within [`Config::margin_db`]) and over its own floor, in
//!   [`Config::onset_frames`] of the last
//!   [`Config::onset_window`] frames. What the canceller let through does not enter into it:
//!   it is in the canceller's output, not in the microphone's excess over the echo. But a busy
//!   machine's timing can shift the robot's voice on the microphone against the played
//!   reference by more than the slack, and the end of its own word then stands over the echo
//!   predicted for it; so she is taken only once **the canceller's output confirms her**
//!   ([`Config::confirm_db`]): one of its frames near her onset stands over what the canceller
//!   leaves of the robot lately, and over the room. The canceller runs on the sound server's
//!   clock, where the robot's word is taken out as ever. The canceller's output is held back
//!   [`Config::confirm_s`] more for it ([`DoubleTalk::holdback_ns`]).
//! - **Or the canceller's output shows her** ([`DoubleTalk::canceller`]): where the robot is
//!   heard, and the canceller takes [`Config::min_erle_db`] or more out of the robot lately
//!   (the median over [`Config::residual_window_s`]), its output stands within
//!   [`Config::player_share_db`] of the microphone, in [`Config::canceller_onset_frames`] of
//!   the last [`Config::onset_window`]. That is the player as loud at the microphone as the
//!   robot's echo, whom the first test misses when a busy machine's timing makes the echo a
//!   frame may hold too large.
//! - **Her frames are the microphone as it is** ([`Config::pass_microphone`]), from
//!   [`Config::lookback_s`] before the first until [`Config::hold_s`] after the last (and on
//!   until she pauses, once the robot's voice has died away): while the robot speaks, the
//!   canceller's suppressor takes tens of dB out of her too, her first sounds above all.
//! - **Otherwise, while the robot's voice may be in the room**, the canceller's output is
//!   replaced with noise at the room's level (its output's where the robot is not heard):
//!   not digital silence, which would drag the recognizer's floor down (the room's noise would
//!   then start an utterance when the robot stops), and not the output scaled down, whose
//!   swings the recognizer took for people talking. Before the echo
//!   path is known (the robot's first words), everything heard while it speaks is cut: gating.
//!
//! Times are nanoseconds on the clock shared by the capture streams and the playback thread; a
//! frame's index is its time in frames (10 ms).

use std::collections::VecDeque;

/// Level of digital silence (dBFS).
pub const SILENCE_DB: f64 = -120.0;

/// How much of the room the comfort noise's level is taken over (s).
const ROOM_S: f64 = 3.0;

/// The detector's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Frame length (ns).
    pub frame_ns: i64,
    /// Reference frames quieter than this are no voice (dBFS).
    pub voice_min_dbfs: f64,
    /// The echo path's delays looked at (ms).
    pub min_delay_ms: i64,
    pub max_delay_ms: i64,
    /// The robot's speech the echo path is measured over (s), and how often (s of it).
    pub path_window_s: f64,
    pub path_every_s: f64,
    /// The correlation of the levels under which a measure is not taken.
    pub min_correlation: f64,
    /// How fast the room's echo of a frame may die away (dB/s), fastest first.
    pub decays_db_per_s: [f64; 4],
    /// How far over the predicted echo the microphone may stand, in 99 % of the robot's frames,
    /// for a decay to fit (dB).
    pub fit_db: f64,
    /// Frames either side of the delay a frame's echo may fall on (at full level; the room's
    /// decay counts from there).
    pub jitter_frames: i64,
    /// The least and the most the microphone must stand over the echo it may hold for a frame
    /// to be the player's (dB).
    pub margin_db: (f64, f64),
    /// ... and over the microphone's floor (dB).
    pub over_floor_db: f64,
    /// Frames like the player's among the last `onset_window` that make the player speak.
    pub onset_frames: usize,
    pub onset_window: usize,
    /// How long after the player's last frame the canceller's output passes whole (s).
    pub hold_s: f64,
    /// ... and how long before the first (s): her first sounds, heard before they were known
    /// to be hers. The caller holds the canceller's output back this long.
    pub lookback_s: f64,
    /// How long after the reference's last voiced frame its echo may still be in the room (s),
    /// beyond the echo path's delay.
    pub tail_s: f64,
    /// How fast the floors rise (dB/s; they fall at once).
    pub floor_rise_db_per_s: f64,
    /// Whether the player's frames over the robot are the microphone as it is rather than the
    /// canceller's output (see [`DoubleTalk::process`]).
    pub pass_microphone: bool,
    /// How much the canceller takes out of the robot is judged over this much of its speech
    /// (s)...
    pub residual_window_s: f64,
    /// ... and its output tells the player only when that is at least this (dB, the median
    /// over that window: an adapted canceller)...
    pub min_erle_db: f64,
    /// ... when it stands at most this far under the microphone (dB): once its suppressor lets
    /// her through, the canceller passes the player nearly whole (4-8 dB under a microphone
    /// that also holds the robot's echo), while its leaks stand 10-15 dB under the microphone.
    pub player_share_db: f64,
    /// Frames of the canceller's output like the player's among the last `onset_window` that
    /// make the player speak (its leaks come in bursts of a frame or two).
    pub canceller_onset_frames: usize,
    /// The player heard on the microphone alone (over the robot's echo) is taken only once the
    /// canceller's output confirms her: one of its frames, from `confirm_before_frames` before
    /// her onset to `confirm_s` after, stands this far over what the canceller leaves of the
    /// robot lately (dB over the median of its residue; while that is not known, she is taken
    /// at once), and [`Config::over_floor_db`] over the room as the canceller passes it.
    /// `None`: she is taken at once.
    pub confirm_db: Option<f64>,
    pub confirm_before_frames: i64,
    pub confirm_s: f64,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            frame_ns: 10_000_000,
            voice_min_dbfs: -70.0,
            min_delay_ms: -50,
            max_delay_ms: 500,
            path_window_s: 3.0,
            path_every_s: 1.0,
            min_correlation: 0.6,
            decays_db_per_s: [400.0, 200.0, 120.0, 60.0],
            fit_db: 3.0,
            jitter_frames: 4,
            margin_db: (4.0, 10.0),
            over_floor_db: 10.0,
            onset_frames: 2,
            onset_window: 4,
            hold_s: 0.3,
            lookback_s: 0.08,
            tail_s: 0.3,
            floor_rise_db_per_s: 3.0,
            pass_microphone: true,
            residual_window_s: 3.0,
            min_erle_db: 20.0,
            player_share_db: 8.0,
            canceller_onset_frames: 3,
            confirm_db: Some(10.0),
            confirm_before_frames: 8,
            confirm_s: 0.1,
        }
    }
}

/// A frame's level (dBFS; [`SILENCE_DB`] for digital silence).
pub fn level_db(frame: &[i16]) -> f64 {
    if frame.is_empty() {
        return SILENCE_DB;
    }
    let p = frame.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / frame.len() as f64;
    if p <= 0.0 {
        SILENCE_DB
    } else {
        (10.0 * (p / (32768.0 * 32768.0)).log10()).max(SILENCE_DB)
    }
}

/// A level that falls at once to a quieter frame and rises slowly otherwise.
#[derive(Debug, Clone, Copy, Default)]
struct Floor {
    db: Option<f64>,
}

impl Floor {
    /// The floor after a frame at `level` (digital silence, a stream not started yet, leaves
    /// it: it is no measure of the room).
    fn update(&mut self, level: f64, rise_db: f64) -> f64 {
        if level <= SILENCE_DB {
            return self.db.unwrap_or(SILENCE_DB);
        }
        let db = match self.db {
            Some(f) if level >= f => f + rise_db.min(level - f),
            _ => level,
        };
        self.db = Some(db);
        db
    }
}

/// The microphone's last samples, contiguous, the first heard at `start_ns`.
#[derive(Debug, Default)]
struct Tail {
    start_ns: i64,
    rate_hz: u32,
    samples: VecDeque<i16>,
}

impl Tail {
    /// Streams' times jitter by their latency's estimate: a chunk that starts within this of
    /// where the last ended follows it (ns).
    const SLACK_NS: i64 = 20_000_000;

    fn ns(&self, n: usize) -> i64 {
        n as i64 * 1_000_000_000 / i64::from(self.rate_hz.max(1))
    }

    /// Samples heard from `t_ns` on, keeping the last `keep_ns`.
    fn push(&mut self, t_ns: i64, rate_hz: u32, samples: &[i16], keep_ns: i64) {
        let end = self.start_ns + self.ns(self.samples.len());
        if self.rate_hz != rate_hz || self.samples.is_empty() || (t_ns - end).abs() > Self::SLACK_NS
        {
            self.samples.clear();
            self.start_ns = t_ns;
            self.rate_hz = rate_hz;
        }
        self.samples.extend(samples);
        let keep = (keep_ns as i128 * i128::from(rate_hz) / 1_000_000_000) as usize;
        let excess = self.samples.len().saturating_sub(keep);
        self.samples.drain(..excess);
        self.start_ns += self.ns(excess);
    }

    /// The samples heard from `t_ns` on into `out`, if all of them are held.
    fn copy(&self, t_ns: i64, rate_hz: u32, out: &mut [i16]) -> bool {
        if rate_hz != self.rate_hz || t_ns < self.start_ns {
            return false;
        }
        let from = ((t_ns - self.start_ns) as i128 * i128::from(rate_hz) / 1_000_000_000) as usize;
        if from + out.len() > self.samples.len() {
            return false;
        }
        for (o, s) in out.iter_mut().zip(self.samples.range(from..)) {
            *o = *s;
        }
        true
    }
}

/// How the robot's voice reaches the microphone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EchoPath {
    /// From the reference's clock to the microphone's (frames, may be negative).
    pub delay_frames: i64,
    /// The microphone's level minus the reference's (dB).
    pub gain_db: f64,
    /// The correlation of the levels at that delay.
    pub correlation: f64,
    /// How fast the room's echo of a frame dies away (dB/s).
    pub decay_db_per_s: f64,
    /// How far over the predicted echo a frame of the player's must stand (dB).
    pub margin_db: f64,
}

/// What the detector did to one chunk of the canceller's output.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Outcome {
    /// Frames heard while the robot's voice may be in the room.
    pub robot_frames: u32,
    /// Of those, frames passed whole as the player's.
    pub player_frames: u32,
    /// Frames cut as the robot's.
    pub suppressed_frames: u32,
    /// Player's frames passed as the canceller's output, the microphone's samples of their time
    /// not held (a gap in its stream, a rate change): with [`Config::pass_microphone`], each is
    /// her voice as the canceller left it.
    pub unheld_frames: u32,
}

/// Frame levels by index, the newest last, at most `keep` of them.
#[derive(Debug, Default)]
struct Levels {
    frames: VecDeque<(i64, f64)>,
}

impl Levels {
    fn push(&mut self, index: i64, level: f64, keep: usize) {
        // A frame that comes again (streams overlap by rounding) keeps the louder level.
        if let Some(last) = self.frames.back_mut()
            && last.0 >= index
        {
            if last.0 == index {
                last.1 = last.1.max(level);
            }
            return;
        }
        self.frames.push_back((index, level));
        while self.frames.len() > keep {
            self.frames.pop_front();
        }
    }

    /// The level at `index`, if that frame is held.
    fn at(&self, index: i64) -> Option<f64> {
        let first = self.frames.front()?.0;
        // Frames are mostly consecutive: look where it should be, then search.
        let guess = usize::try_from(index - first).ok()?;
        if let Some(&(i, l)) = self.frames.get(guess)
            && i == index
        {
            return Some(l);
        }
        self.frames
            .binary_search_by_key(&index, |&(i, _)| i)
            .ok()
            .map(|k| self.frames[k].1)
    }

    fn last_index(&self) -> Option<i64> {
        self.frames.back().map(|&(i, _)| i)
    }

    /// Drop the frames from `index` on.
    fn truncate_from(&mut self, index: i64) {
        while self.frames.back().is_some_and(|&(i, _)| i >= index) {
            self.frames.pop_back();
        }
    }
}

/// The detector and suppressor of one microphone (see the module doc).
#[derive(Debug)]
pub struct DoubleTalk {
    cfg: Config,
    /// The robot's voice as played, and the microphone as it is.
    reference: Levels,
    mic: Levels,
    /// The microphone's samples, for the player's frames.
    tail: Tail,
    mic_floor: Floor,
    out_floor: Floor,
    /// The canceller's output where the robot is not heard, its levels over the last [`ROOM_S`]
    /// (dBFS), newest last: the room as the recognizer hears it.
    room: VecDeque<f64>,
    /// The last reference frame with voice.
    last_voiced: Option<i64>,
    path: Option<EchoPath>,
    /// Voiced reference frames since the echo path was last measured.
    voiced_since_measure: usize,
    /// Whether each of the last microphone frames heard with the robot was like the player's.
    recent: VecDeque<bool>,
    /// ... and each of the last frames of the canceller's output.
    recent_out: VecDeque<bool>,
    /// How far under the microphone the canceller's output stood in the robot's recent frames
    /// (dB), the newest last.
    residual: VecDeque<f64>,
    /// How much the canceller takes out of the robot lately (dB; the median of `residual`),
    /// once it has heard a second of it.
    erle: Option<f64>,
    /// The canceller's frames (indices) that stood `confirm_db` over its residue, newest last.
    shown: VecDeque<i64>,
    /// The player heard on the microphone, not yet confirmed by the canceller's output: when.
    pending_ns: Option<i64>,
    /// The canceller's output passes whole from and until then (ns).
    hold_from_ns: i64,
    hold_until_ns: i64,
    /// The comfort noise's generator ([`Self::comfort`]).
    noise: audio::signal::NoiseRng,
    /// A new echo path not yet taken by [`Self::path_changed`].
    changed: Option<EchoPath>,
    /// The player started speaking over the robot, not yet taken by [`Self::player_started`].
    started: bool,
}

impl DoubleTalk {
    pub fn new(cfg: Config) -> Self {
        Self {
            cfg,
            reference: Levels::default(),
            mic: Levels::default(),
            tail: Tail::default(),
            mic_floor: Floor::default(),
            out_floor: Floor::default(),
            room: VecDeque::new(),
            last_voiced: None,
            path: None,
            voiced_since_measure: 0,
            recent: VecDeque::new(),
            recent_out: VecDeque::new(),
            residual: VecDeque::new(),
            erle: None,
            shown: VecDeque::new(),
            pending_ns: None,
            hold_from_ns: i64::MIN,
            hold_until_ns: i64::MIN,
            noise: audio::signal::NoiseRng::new(0x9E37_79B9_7F4A_7C15),
            changed: None,
            started: false,
        }
    }

    /// Whether the player started speaking over the robot since the last call: the robot may
    /// yield at once, before the recognizer has heard enough to say speech started.
    pub fn player_started(&mut self) -> bool {
        std::mem::take(&mut self.started)
    }

    fn index(&self, t_ns: i64) -> i64 {
        t_ns.div_euclid(self.cfg.frame_ns)
    }

    fn rise(&self) -> f64 {
        self.cfg.floor_rise_db_per_s * self.cfg.frame_ns as f64 * 1e-9
    }

    fn keep(&self) -> usize {
        let s = self.cfg.path_window_s + self.cfg.max_delay_ms as f64 * 1e-3 + 1.0;
        (s * 1e9 / self.cfg.frame_ns as f64) as usize
    }

    fn frames_of(&self, s: f64) -> usize {
        (s * 1e9 / self.cfg.frame_ns as f64).round() as usize
    }

    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// The echo path, once measured.
    pub fn path(&self) -> Option<EchoPath> {
        self.path
    }

    /// The echo path when it was first measured or moved by more than a frame, once.
    pub fn path_changed(&mut self) -> Option<EchoPath> {
        self.changed.take()
    }

    /// What the robot played (mono, `rate_hz`), its first sample playing at `t_ns`.
    pub fn reference(&mut self, t_ns: i64, rate_hz: u32, samples: &[i16]) {
        let keep = self.keep();
        for (t, f) in frames(t_ns, rate_hz, self.cfg.frame_ns, samples) {
            let i = self.index(t);
            let l = level_db(f);
            self.reference.push(i, l, keep);
            if l >= self.cfg.voice_min_dbfs {
                self.last_voiced = Some(i);
                self.voiced_since_measure += 1;
            }
        }
        if self.voiced_since_measure >= self.frames_of(self.cfg.path_every_s) {
            self.voiced_since_measure = 0;
            self.measure_path();
        }
    }

    /// What the robot had queued from `t_ns` on was thrown away (a pause or a cut): it never
    /// plays.
    pub fn reference_dropped_from(&mut self, t_ns: i64) {
        let i = self.index(t_ns);
        self.reference.truncate_from(i);
        if self.last_voiced.is_some_and(|v| v >= i) {
            self.last_voiced = self.reference.last_index().map(|l| l.min(i - 1));
        }
    }

    /// How long the caller holds the canceller's output back while the robot's voice may be in
    /// the room (ns): [`Config::lookback_s`], and [`Config::confirm_s`] more while a player heard
    /// on the microphone may wait for the canceller's output to confirm her.
    pub fn holdback_ns(&self) -> i64 {
        let confirm = match self.cfg.confirm_db {
            Some(_) => self.cfg.confirm_s,
            None => 0.0,
        };
        ((self.cfg.lookback_s + confirm) * 1e9) as i64
    }

    /// Whether the robot's voice may be in the room at `t_ns` on the microphone's clock: the
    /// canceller's output of that time is held back [`Config::lookback_s`] only then.
    pub fn robot_may_be_heard(&self, t_ns: i64) -> bool {
        self.robot_at(self.index(t_ns))
    }

    /// Whether the robot's voice may be in the room at frame `i` of the microphone.
    fn robot_at(&self, i: i64) -> bool {
        let Some(v) = self.last_voiced else {
            return false;
        };
        let (delay, after) = match self.path {
            Some(p) => (p.delay_frames, self.frames_of(self.cfg.tail_s) as i64),
            // Not measured: as far as it could be.
            None => (
                0,
                (self.cfg.max_delay_ms * 1_000_000 / self.cfg.frame_ns)
                    + self.frames_of(self.cfg.tail_s) as i64,
            ),
        };
        let first = self.reference.frames.front().map_or(i64::MAX, |f| f.0);
        i >= first + delay.min(0) && i <= v + delay + after
    }

    /// The loudest echo of the robot frame `i` of the microphone may hold (dBFS).
    fn echo_at(&self, i: i64, path: EchoPath) -> f64 {
        let decay = path.decay_db_per_s * self.cfg.frame_ns as f64 * 1e-9;
        let back = self.frames_of(self.cfg.tail_s) as i64;
        let mut echo = SILENCE_DB;
        let jitter = self.cfg.jitter_frames;
        for j in -jitter..=back + jitter {
            if let Some(r) = self.reference.at(i - path.delay_frames - j) {
                // The streams' timing may put a frame `jitter` either side of the delay: its
                // echo fades only from there.
                let fade = decay * (j - jitter).max(0) as f64;
                echo = echo.max(r + path.gain_db - fade);
            }
        }
        echo
    }

    /// The microphone as it is (mono, `rate_hz`), its first sample heard at `t_ns`.
    pub fn mic(&mut self, t_ns: i64, rate_hz: u32, samples: &[i16]) {
        let keep = self.keep();
        let rise = self.rise();
        if self.cfg.pass_microphone {
            let keep_ns = self.holdback_ns() + 1_000_000_000;
            self.tail.push(t_ns, rate_hz, samples, keep_ns);
        }
        let hold_ns = (self.cfg.hold_s * 1e9) as i64;
        for (t, f) in frames(t_ns, rate_hz, self.cfg.frame_ns, samples) {
            let i = self.index(t);
            let l = level_db(f);
            let floor = self.mic_floor.update(l, rise);
            self.mic.push(i, l, keep);
            if !self.robot_at(i) {
                self.recent.clear();
                // The player goes on after the robot's voice died away: her words stay on one
                // signal until she pauses.
                if t < self.hold_until_ns && l >= floor + self.cfg.over_floor_db {
                    self.hold_until_ns = t + hold_ns;
                }
                continue;
            }
            let echo = self.path.map(|p| (self.echo_at(i, p), p.margin_db));
            let like_player = echo.is_some_and(|(echo, margin)| {
                l >= echo + margin && l >= floor + self.cfg.over_floor_db
            });
            tracing::trace!(
                i,
                mic = format!("{l:.1}"),
                echo = format!("{:.1}", echo.map_or(f64::NAN, |e| e.0)),
                like_player,
                holding = t < self.hold_until_ns,
                "microphone frame"
            );
            self.player_frame(t, like_player, false);
        }
    }

    /// The canceller's output as it arrives (mono, `rate_hz`, its first sample heard at
    /// `t_ns`), before [`Self::process`] is given it. The player shows there too: where the
    /// robot's echo is as loud as she is, the microphone stands no higher than the echo it may
    /// hold, but an adapted canceller passes her nearly whole while it takes most of the robot
    /// out (see [`Config::player_share_db`]).
    pub fn canceller(&mut self, t_ns: i64, rate_hz: u32, samples: &[i16]) {
        let keep = self.frames_of(self.cfg.residual_window_s);
        // The room's noise as the microphone hears it: the canceller's own output sinks to
        // digital silence where it suppresses, no measure of the room.
        let Some(floor) = self.mic_floor.db else {
            return;
        };
        // How much the canceller takes out of the robot lately (the median of its residuals
        // before this chunk, which neither its leaks nor a player it missed move much); none
        // yet, it has not adapted.
        let erle = (self.residual.len() >= self.frames_of(1.0)).then(|| {
            let mut r: Vec<f64> = self.residual.iter().copied().collect();
            r.sort_by(f64::total_cmp);
            -r[r.len() / 2]
        });
        self.erle = erle;
        for (t, f) in frames(t_ns, rate_hz, self.cfg.frame_ns, samples) {
            let i = self.index(t);
            let l = level_db(f);
            // The microphone's frame of the same time, heard (not a stream's silent start).
            let mic = self.mic.at(i).filter(|&m| m > SILENCE_DB);
            let (Some(path), Some(mic)) = (self.path.filter(|_| self.robot_at(i)), mic) else {
                self.recent_out.clear();
                continue;
            };
            // Only where the robot is heard: elsewhere the microphone tells her apart.
            let audible = self.echo_at(i, path) >= floor + self.cfg.over_floor_db;
            let share = l - mic;
            let like_player = audible
                && erle.is_some_and(|e| e >= self.cfg.min_erle_db)
                && share >= -self.cfg.player_share_db
                && l >= floor + self.cfg.over_floor_db;
            let holding = t < self.hold_until_ns;
            tracing::trace!(
                i,
                out = format!("{l:.1}"),
                mic = format!("{mic:.1}"),
                erle = format!("{:.1}", erle.unwrap_or(f64::NAN)),
                like_player,
                "canceller's output"
            );
            if audible && !holding {
                self.residual.push_back(share);
                while self.residual.len() > keep {
                    self.residual.pop_front();
                }
            }
            // More than the robot's residue, and more than the room (whose noise, left where
            // the microphone holds little of the robot, stands close to the microphone's).
            if let (Some(e), Some(db)) = (erle, self.cfg.confirm_db)
                && share >= -e + db
                && self
                    .out_floor
                    .db
                    .is_none_or(|room| l >= room + self.cfg.over_floor_db)
            {
                self.shown.push_back(i);
                while self.shown.len() > 64 {
                    self.shown.pop_front();
                }
            }
            self.confirm(i);
            self.player_frame(t, like_player, true);
        }
    }

    /// Whether the canceller's output showed more than the robot's residue near the
    /// microphone's onset at frame `onset` (see [`Config::confirm_db`]), as far as it is known.
    fn shown_near(&self, onset: i64) -> bool {
        let after = self.frames_of(self.cfg.confirm_s) as i64;
        self.shown
            .iter()
            .any(|&i| i >= onset - self.cfg.confirm_before_frames && i <= onset + after)
    }

    /// The canceller's frame `i` is known: a player heard on the microphone and waiting is
    /// taken when the canceller's output showed her, or dropped when it did not in time.
    fn confirm(&mut self, i: i64) {
        let Some(t) = self.pending_ns else {
            return;
        };
        let onset = self.index(t);
        if self.shown_near(onset) {
            self.pending_ns = None;
            self.start(
                t,
                "on the microphone, over the robot's echo, and in the canceller's output",
            );
            self.hold_until_ns = self.hold_until_ns.max(t + (self.cfg.hold_s * 1e9) as i64);
        } else if i > onset + self.frames_of(self.cfg.confirm_s) as i64 {
            self.pending_ns = None;
            tracing::debug!(
                frame = onset,
                "not the player: heard on the microphone over the robot's echo, but the \
                 canceller's output showed nothing over the robot's residue"
            );
        }
    }

    /// The player starts over the robot at `t` (heard `how`): her frames pass from
    /// [`Config::lookback_s`] before.
    fn start(&mut self, t: i64, how: &str) {
        tracing::debug!(
            frame = self.index(t),
            "the player starts over the robot: heard {how}"
        );
        self.started = true;
        self.hold_from_ns = t - (self.cfg.lookback_s * 1e9) as i64;
    }

    /// A frame at `t` of the microphone (`canceller`: of the canceller's output) like the
    /// player's or not: she starts speaking when [`Config::onset_frames`] (of the canceller's:
    /// [`Config::canceller_onset_frames`]) of the last [`Config::onset_window`] of the one or
    /// the other are, and her frames then pass (from [`Config::lookback_s`] before) until
    /// [`Config::hold_s`] after the last.
    fn player_frame(&mut self, t: i64, like_player: bool, canceller: bool) {
        let window = self.cfg.onset_window.max(1);
        let recent = match canceller {
            true => &mut self.recent_out,
            false => &mut self.recent,
        };
        recent.push_back(like_player);
        while recent.len() > window {
            recent.pop_front();
        }
        let run = recent.iter().filter(|&&p| p).count();
        let holding = t < self.hold_until_ns;
        let onset = match canceller {
            true => self.cfg.canceller_onset_frames,
            false => self.cfg.onset_frames,
        };
        if like_player && (holding || run >= onset) {
            if !holding {
                if canceller {
                    self.pending_ns = None;
                    self.start(t, "in the canceller's output");
                } else if self.cfg.confirm_db.is_none()
                    || self.erle.is_none()
                    || self.shown_near(self.index(t))
                {
                    self.pending_ns = None;
                    self.start(t, "on the microphone, over the robot's echo");
                } else {
                    // A busy machine's timing can put the robot's own words over the echo
                    // predicted for them: the canceller, on the server's clock, tells.
                    let window = self.frames_of(self.cfg.confirm_s) as i64;
                    if self
                        .pending_ns
                        .is_none_or(|p| self.index(t) - self.index(p) > window)
                    {
                        self.pending_ns = Some(t);
                    }
                    return;
                }
            }
            self.hold_until_ns = self.hold_until_ns.max(t + (self.cfg.hold_s * 1e9) as i64);
        }
    }

    /// Measure the echo path on the recent frames (see the module doc).
    fn measure_path(&mut self) {
        let window = self.frames_of(self.cfg.path_window_s) as i64;
        let (Some(last_mic), Some(last_ref)) = (self.mic.last_index(), self.reference.last_index())
        else {
            return;
        };
        let lo = self.cfg.min_delay_ms * 1_000_000 / self.cfg.frame_ns;
        let hi = self.cfg.max_delay_ms * 1_000_000 / self.cfg.frame_ns;
        let mut best: Option<EchoPath> = None;
        for d in lo..=hi {
            // Pairs (reference, microphone) over the reference's voiced frames.
            let mut pairs = Vec::new();
            let end = last_ref.min(last_mic - d);
            for r in (end - window)..=end {
                let (Some(x), Some(y)) = (self.reference.at(r), self.mic.at(r + d)) else {
                    continue;
                };
                if x >= self.cfg.voice_min_dbfs {
                    pairs.push((x, y));
                }
            }
            if pairs.len() < self.frames_of(self.cfg.path_every_s) / 2 {
                continue;
            }
            let c = correlation(&pairs);
            if best.is_none_or(|b| c > b.correlation) {
                let mut diff: Vec<f64> = pairs.iter().map(|(x, y)| y - x).collect();
                diff.sort_by(f64::total_cmp);
                best = Some(EchoPath {
                    delay_frames: d,
                    gain_db: diff[diff.len() / 2],
                    correlation: c,
                    decay_db_per_s: self.cfg.decays_db_per_s[3],
                    margin_db: self.cfg.margin_db.1,
                });
            }
        }
        let Some(mut best) = best.filter(|b| b.correlation >= self.cfg.min_correlation) else {
            return;
        };
        // The room's decay and the margin: how far over the echo so predicted the microphone
        // stands while the robot speaks (99th percentile over the window's voiced frames: the
        // ends of its words, where a timing error shows, count).
        let end = last_ref.min(last_mic - best.delay_frames);
        let over = |path: EchoPath| {
            let mut e: Vec<f64> = ((end - window)..=end)
                .filter(|&r| {
                    self.reference
                        .at(r)
                        .is_some_and(|x| x >= self.cfg.voice_min_dbfs)
                })
                .filter_map(|r| {
                    let i = r + path.delay_frames;
                    self.mic.at(i).map(|y| y - self.echo_at(i, path))
                })
                .collect();
            e.sort_by(f64::total_cmp);
            e.get(e.len() * 99 / 100).copied().unwrap_or(f64::INFINITY)
        };
        let fits: Vec<(f64, f64)> = self
            .cfg
            .decays_db_per_s
            .iter()
            .map(|&decay_db_per_s| {
                let p95 = over(EchoPath {
                    decay_db_per_s,
                    ..best
                });
                (decay_db_per_s, p95)
            })
            .collect();
        let (decay, p95) = fits
            .iter()
            .copied()
            .find(|&(_, p95)| p95 <= self.cfg.fit_db)
            .unwrap_or(fits[fits.len() - 1]);
        best.decay_db_per_s = decay;
        let (lo, hi) = self.cfg.margin_db;
        best.margin_db = (p95 + 3.0).clamp(lo, hi);
        let moved = self
            .path
            .is_none_or(|p| (p.delay_frames - best.delay_frames).abs() > 1);
        self.path = Some(best);
        if moved {
            self.changed = Some(best);
        }
    }

    /// A chunk of the canceller's output (mono, `rate_hz`), its first sample heard at `t_ns`:
    /// the robot's residue in it cut in place, and the player's frames replaced by the
    /// microphone's (with [`Config::pass_microphone`], where the microphone's are held).
    pub fn process(&mut self, t_ns: i64, rate_hz: u32, samples: &mut [i16]) -> Outcome {
        let rise = self.rise();
        let mut outcome = Outcome::default();
        let per_frame = samples_per_frame(rate_hz, self.cfg.frame_ns);
        for (k, f) in samples.chunks_mut(per_frame).enumerate() {
            let t = frame_time(t_ns, rate_hz, k * per_frame);
            let out = level_db(f);
            let robot = self.robot_at(self.index(t));
            // The room's floor and level, measured where the robot is not heard: while it
            // speaks, the canceller's suppressor takes the room's noise down with its voice.
            let floor = match self.out_floor.db {
                Some(db) if robot => db,
                _ => self.out_floor.update(out, rise),
            };
            if !robot {
                let keep = self.frames_of(ROOM_S);
                self.room.push_back(out);
                while self.room.len() > keep {
                    self.room.pop_front();
                }
            }
            let passed = t >= self.hold_from_ns && t < self.hold_until_ns;
            if passed && self.cfg.pass_microphone && !self.tail.copy(t, rate_hz, f) {
                outcome.unheld_frames += 1;
            }
            if !robot {
                continue;
            }
            outcome.robot_frames += 1;
            if passed {
                outcome.player_frames += 1;
            } else {
                outcome.suppressed_frames += 1;
                let level = self.room_level().unwrap_or(floor);
                self.comfort(f, level);
            }
        }
        outcome
    }

    /// The room's level as the canceller passes it where the robot is not heard: the 20th
    /// percentile of its frames there over the last [`ROOM_S`] (the player's words, if she spoke
    /// lately, stand over it). `None` before any.
    fn room_level(&self) -> Option<f64> {
        if self.room.is_empty() {
            return None;
        }
        let mut v: Vec<f64> = self.room.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        Some(v[v.len() / 5])
    }

    /// Replace a frame with noise at `level_db`, the room's level (digital silence while the
    /// room has been heard only as that): what is cut of the robot's voice sounds like the room
    /// without it, steady. The canceller's output while the robot speaks swings by tens of dB
    /// from frame to frame (its suppressor takes the room's noise down with the voice, in
    /// bursts); scaled down to its floor, it still stood far under the room's, and the
    /// recognizer's end-pointer took those swings for people talking behind the player. Nor
    /// the room's floor (its quietest frames): 8 dB under the room in the test's, a step the
    /// end-pointer took for talk when the robot started speaking.
    fn comfort(&mut self, f: &mut [i16], level_db: f64) {
        let amplitude = 3f64.sqrt() * 32768.0 * 10f64.powf(level_db / 20.0);
        for x in f.iter_mut() {
            // Uniform noise, whose RMS is its amplitude over the root of 3.
            let u = self.noise.uniform() * 2.0 - 1.0;
            *x = (u * amplitude)
                .round()
                .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16;
        }
    }
}

/// Samples in a frame of `frame_ns` at `rate_hz` (at least one).
fn samples_per_frame(rate_hz: u32, frame_ns: i64) -> usize {
    (rate_hz as usize * frame_ns as usize / 1_000_000_000).max(1)
}

/// When sample `n` of a stream whose first sample is heard at `t_ns` is heard.
fn frame_time(t_ns: i64, rate_hz: u32, n: usize) -> i64 {
    t_ns + n as i64 * 1_000_000_000 / i64::from(rate_hz.max(1))
}

/// The frames of `samples` (`rate_hz`, the first heard at `t_ns`), each with when it is heard.
fn frames(
    t_ns: i64,
    rate_hz: u32,
    frame_ns: i64,
    samples: &[i16],
) -> impl Iterator<Item = (i64, &[i16])> {
    let per_frame = samples_per_frame(rate_hz, frame_ns);
    samples
        .chunks(per_frame)
        .enumerate()
        .map(move |(k, f)| (frame_time(t_ns, rate_hz, k * per_frame), f))
}

/// Pearson's correlation of the pairs (0 when either side does not vary).
fn correlation(pairs: &[(f64, f64)]) -> f64 {
    let n = pairs.len() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let (mx, my) = pairs
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in pairs {
        sxy += (x - mx) * (y - my);
        sxx += (x - mx).powi(2);
        syy += (y - my).powi(2);
    }
    if sxx <= 0.0 || syy <= 0.0 {
        0.0
    } else {
        sxy / (sxx * syy).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: u32 = 16_000;
    const FRAME: usize = 160;
    const FRAME_NS: i64 = 10_000_000;

    /// A frame at `db` dBFS (a square wave of that power), phase `k`.
    fn frame_at(db: f64, k: usize) -> Vec<i16> {
        let a = 32768.0 * 10f64.powf(db / 20.0);
        (0..FRAME)
            .map(|i| if ((i + k) / 8).is_multiple_of(2) { a } else { -a } as i16)
            .collect()
    }

    /// A voice-like envelope for frame `k`: syllables of 15 frames between -45 and -20 dBFS.
    fn voice(k: usize) -> f64 {
        let s = [-20.0, -24.0, -30.0, -45.0, -26.0, -21.0, -35.0, -28.0];
        s[(k / 15 + k * 7 / 11) % s.len()]
    }

    /// The room: the robot's voice played at frame `k` reaches the microphone `delay` frames
    /// later, `gain` dB louder, over a -70 dBFS floor; the canceller's output is the
    /// microphone's minus `erle` dB of the robot, and the player (levels by frame) as they are.
    struct Room {
        d: DoubleTalk,
        delay: usize,
        gain: f64,
        played: Vec<f64>,
        /// How much the canceller takes out of the player too (its suppressor, while the robot
        /// speaks; dB).
        player_loss_db: f64,
        /// The microphone's levels, frame by frame.
        heard: Vec<f64>,
        /// Frames the microphone's stream does not deliver (lost on the way).
        mic_lost: std::ops::Range<usize>,
        /// How much the canceller takes out of the room's noise while the robot speaks (dB).
        floor_loss_db: f64,
        /// How far the room's noise through the canceller dips in one frame of ten (dB): a
        /// suppressor releasing, a noise suppressor's swings.
        room_dip_db: f64,
    }

    impl Room {
        fn new(delay: usize, gain: f64) -> Self {
            Room {
                d: DoubleTalk::new(Config::default()),
                delay,
                gain,
                played: Vec::new(),
                player_loss_db: 0.0,
                heard: Vec::new(),
                mic_lost: 0..0,
                floor_loss_db: 0.0,
                room_dip_db: 0.0,
            }
        }

        /// `n` frames: the robot says `robot(k)` (None: silent), the player `player(k)`; the
        /// canceller takes `erle` dB out of the robot. The outcome and the output's levels.
        fn run(
            &mut self,
            n: usize,
            robot: impl Fn(usize) -> Option<f64>,
            player: impl Fn(usize) -> Option<f64>,
            erle: f64,
        ) -> (Outcome, Vec<f64>) {
            let mut sum = Outcome::default();
            let mut levels = Vec::new();
            for _ in 0..n {
                let k = self.played.len();
                let t = k as i64 * FRAME_NS;
                let r = robot(k).unwrap_or(SILENCE_DB);
                self.played.push(r);
                if robot(k).is_some() {
                    self.d.reference(t, RATE, &frame_at(r, k));
                }
                let echo = k
                    .checked_sub(self.delay)
                    .map_or(SILENCE_DB, |j| self.played[j] + self.gain);
                let p = player(k).unwrap_or(SILENCE_DB);
                let sum_db = |a: f64, b: f64, c: f64| {
                    10.0 * (10f64.powf(a / 10.0) + 10f64.powf(b / 10.0) + 10f64.powf(c / 10.0))
                        .log10()
                };
                let mic = sum_db(echo, p, -70.0);
                let room = if echo > SILENCE_DB {
                    -75.0 - self.floor_loss_db
                } else if k.is_multiple_of(10) {
                    -75.0 - self.room_dip_db
                } else {
                    -75.0
                };
                let out = sum_db(echo - erle, p - self.player_loss_db, room);
                self.heard.push(mic);
                if !self.mic_lost.contains(&k) {
                    self.d.mic(t, RATE, &frame_at(mic, k));
                }
                let mut o = frame_at(out, k);
                self.d.canceller(t, RATE, &o);
                let oc = self.d.process(t, RATE, &mut o);
                sum.robot_frames += oc.robot_frames;
                sum.player_frames += oc.player_frames;
                sum.suppressed_frames += oc.suppressed_frames;
                sum.unheld_frames += oc.unheld_frames;
                levels.push(level_db(&o));
            }
            (sum, levels)
        }
    }

    #[test]
    fn without_the_robot_everything_passes() {
        let mut room = Room::new(12, -3.0);
        let (o, levels) = room.run(100, |_| None, |k| Some(voice(k)), 0.0);
        assert_eq!(o, Outcome::default());
        assert!(levels.iter().all(|&l| l > -50.0), "{levels:?}");
    }

    #[test]
    fn the_echo_path_is_measured_and_the_robots_leaks_are_cut() {
        let mut room = Room::new(12, -3.0);
        // The robot's first words: the path is not known yet, everything is cut.
        let (o, levels) = room.run(80, |k| Some(voice(k)), |_| None, 5.0);
        assert_eq!(o.player_frames, 0, "{o:?}");
        assert!(levels[20..].iter().all(|&l| l < -65.0), "{levels:?}");
        // A second of speech: measured, 12 frames and -3 dB.
        room.run(40, |k| Some(voice(k)), |_| None, 5.0);
        let p = room.d.path().expect("the echo path");
        assert_eq!(p.delay_frames, 12, "{p:?}");
        assert!((p.gain_db + 3.0).abs() < 0.5, "{p:?}");
        // A room without reverberation: the fastest decay, the least margin.
        assert_eq!(p.decay_db_per_s, 400.0, "{p:?}");
        assert_eq!(p.margin_db, 4.0, "{p:?}");
        assert!(room.d.path_changed().is_some());
        // The canceller lets 25 dB through (a burst as loud as a player's voice): still cut.
        let (o, levels) = room.run(100, |k| Some(voice(k)), |_| None, 0.0);
        assert_eq!(o.player_frames, 0, "{o:?}");
        assert!(levels.iter().all(|&l| l < -65.0), "{levels:?}");
    }

    /// While the robot's voice is cut, the output is the room's own floor, steady, however far
    /// the canceller takes the room's noise down with the robot's voice and whatever it lets
    /// through: the recognizer's end-pointer must hear a quiet room, not talk.
    #[test]
    fn what_is_cut_of_the_robot_stands_steady_at_the_rooms_level() {
        let mut room = Room::new(12, -3.0);
        room.floor_loss_db = 30.0;
        // The room alone, through the canceller (-75 dBFS, as frames make it).
        let (_, levels) = room.run(50, |_| None, |_| None, 0.0);
        let floor = levels[49];
        assert!((floor + 75.0).abs() < 2.0, "{levels:?}");
        // Three seconds of the robot, then the room alone again.
        let cut = robot_speaks(&mut room, 30);
        assert_steady(&cut, floor, 1.5);
        let (_, after) = room.run(100, |_| None, |_| None, 40.0);
        assert!(after.iter().all(|&l| (l - floor).abs() < 1.5), "{after:?}");
    }

    /// Where the room's noise through the canceller dips now and then, what is cut of the robot
    /// stands at the room's usual level, not at its dips: a step down when the robot starts
    /// speaking is talk to the recognizer's end-pointer.
    #[test]
    fn what_is_cut_of_the_robot_stands_at_the_rooms_level_not_its_dips() {
        let mut room = Room::new(12, -3.0);
        room.room_dip_db = 15.0;
        room.floor_loss_db = 30.0;
        let (_, mut before) = room.run(300, |_| None, |_| None, 0.0);
        before.sort_by(f64::total_cmp);
        // -75 dBFS as frames make it (-76.3), the dips at -90.
        let usual = before[before.len() / 2];
        // Within 3 dB of the room's usual level, its dips 15 dB under it.
        let cut = robot_speaks(&mut room, 20);
        assert_steady(&cut, usual, 3.0);
    }

    /// The robot speaks `chunks` times 10 frames, the canceller taking 20 to 60 dB out of its
    /// voice (and `floor_loss_db` out of the room) and the detector hearing no player: the
    /// output's levels.
    fn robot_speaks(room: &mut Room, chunks: i32) -> Vec<f64> {
        let mut cut = Vec::new();
        for i in 0..chunks {
            let erle = 20.0 + f64::from(i * 17 % 41);
            let (o, levels) = room.run(10, |k| Some(voice(k)), |_| None, erle);
            assert_eq!(o.player_frames, 0, "{o:?}");
            cut.extend(levels);
        }
        cut
    }

    /// Every level from the echo's arrival (12 frames) on within `tolerance_db` of `level`.
    fn assert_steady(levels: &[f64], level: f64, tolerance_db: f64) {
        let off: Vec<f64> = levels[12..]
            .iter()
            .copied()
            .filter(|l| (l - level).abs() > tolerance_db)
            .collect();
        assert!(
            off.is_empty(),
            "frames off the room's level ({level:.1}): {off:?}"
        );
    }

    #[test]
    fn the_player_over_the_robot_passes_and_the_robots_tail_is_cut_after() {
        let mut room = Room::new(12, -3.0);
        room.run(200, |k| Some(voice(k)), |_| None, 20.0);
        assert!(room.d.path().is_some());
        // The player says something as loud as the robot, over it, for half a second.
        assert!(!room.d.player_started());
        let (o, levels) = room.run(50, |k| Some(voice(k)), |k| Some(voice(k + 5) + 3.0), 20.0);
        assert!(room.d.player_started());
        assert!(o.player_frames >= 40, "{o:?}");
        assert!(levels[10..].iter().all(|&l| l > -50.0), "{levels:?}");
        // The robot alone again: held for 0.3 s after the player's last loud frame, then cut.
        let (o, _) = room.run(60, |k| Some(voice(k)), |_| None, 20.0);
        assert!((15..=30).contains(&o.player_frames), "{o:?}");
        assert!(o.suppressed_frames >= 28, "{o:?}");
    }

    /// The player as loud at the microphone as the robot's echo: the microphone alone does not
    /// tell her apart, but the canceller's output stands far over what it leaves of the robot.
    #[test]
    fn the_player_as_loud_as_the_robot_shows_in_the_cancellers_output() {
        let mut room = Room::new(12, -3.0);
        // The microphone alone never tells her apart here.
        room.d.cfg.margin_db = (40.0, 40.0);
        room.run(400, |k| Some(voice(k)), |_| None, 25.0);
        assert!(room.d.path().is_some());
        // A leak: the canceller lets 13 dB more of the robot through, far over what it left
        // lately, but 12 dB under the microphone: the robot still.
        let (o, _) = room.run(30, |k| Some(voice(k)), |_| None, 12.0);
        assert!(!room.d.player_started(), "{o:?}");
        assert_eq!(o.player_frames, 0, "{o:?}");
        let (o, levels) = room.run(
            50,
            |k| Some(voice(k)),
            |k| Some(voice(k + 12 - 4) - 3.0),
            25.0,
        );
        assert!(room.d.player_started());
        assert!(o.player_frames >= 40, "{o:?}");
        assert!(levels[10..].iter().all(|&l| l > -50.0), "{levels:?}");
    }

    /// While the robot speaks, the canceller takes 30 dB out of the player too (and 45 out of
    /// the robot): the frames passed as hers are the microphone's, not the canceller's.
    #[test]
    fn the_players_frames_are_the_microphone_as_it_is() {
        let mut room = Room::new(12, -3.0);
        room.player_loss_db = 30.0;
        room.run(200, |k| Some(voice(k)), |_| None, 45.0);
        let (o, levels) = room.run(50, |k| Some(voice(k)), |k| Some(voice(k + 5) + 6.0), 45.0);
        assert!(o.player_frames >= 40, "{o:?}");
        assert_eq!(o.unheld_frames, 0, "{o:?}");
        let heard = &room.heard[room.heard.len() - 50..];
        for (k, (&out, &mic)) in levels.iter().zip(heard).enumerate().skip(10) {
            assert!(
                (out - mic).abs() < 0.5,
                "frame {k}: {out:.1} dBFS out, {mic:.1} heard"
            );
        }
    }

    /// A busy machine's timing: the robot's voice reaches the microphone 80 ms later than the
    /// echo path measured says, so the end of its word stands over the echo predicted for it,
    /// as a player would. The canceller (on the sound server's clock) took the word out as
    /// ever: without its word, the microphone alone takes the robot for her.
    #[test]
    fn the_robot_heard_late_on_the_microphone_is_not_the_player() {
        let word = |k: usize| (k % 40 < 15).then_some(-20.0);
        for confirm in [None, Some(10.0)] {
            let mut room = Room::new(12, -3.0);
            room.d.cfg.confirm_db = confirm;
            room.run(200, |k| Some(voice(k)), |_| None, 45.0);
            assert_eq!(room.d.path().map(|p| p.delay_frames), Some(12));
            room.delay = 20;
            let (o, _) = room.run(40, word, |_| None, 45.0);
            match confirm {
                None => assert!(room.d.player_started(), "the scenario: {o:?}"),
                Some(_) => {
                    assert!(!room.d.player_started(), "{o:?}");
                    assert_eq!(o.player_frames, 0, "{o:?}");
                }
            }
        }
    }

    /// The streams' timing puts the robot's voice on the microphone a few frames later than the
    /// echo path measured (30 ms, within [`Config::jitter_frames`]): the ends of its words are
    /// heard where the reference has fallen silent. They are its echo, not the player, even
    /// without the canceller's confirmation.
    #[test]
    fn the_robot_heard_a_few_frames_late_is_its_echo() {
        let word = |k: usize| (k % 40 < 15).then_some(-20.0);
        let mut room = Room::new(12, -3.0);
        room.d.cfg.confirm_db = None;
        room.run(200, |k| Some(voice(k)), |_| None, 45.0);
        assert_eq!(room.d.path().map(|p| p.delay_frames), Some(12));
        room.delay = 15;
        let (o, _) = room.run(120, word, |_| None, 45.0);
        assert!(!room.d.player_started(), "{o:?}");
        assert_eq!(o.player_frames, 0, "{o:?}");
    }

    /// Five frames of the microphone's stream lost while she speaks: those frames pass as the
    /// canceller left them, and are counted; the next ones are the microphone's again.
    #[test]
    fn the_players_frames_the_microphone_lost_are_counted() {
        let mut room = Room::new(12, -3.0);
        room.player_loss_db = 30.0;
        room.run(200, |k| Some(voice(k)), |_| None, 45.0);
        room.mic_lost = 230..235;
        let (o, levels) = room.run(50, |k| Some(voice(k)), |k| Some(voice(k + 5) + 6.0), 45.0);
        assert!(o.player_frames >= 40, "{o:?}");
        assert_eq!(o.unheld_frames, 5, "{o:?}");
        let heard = &room.heard[200..];
        for k in (10..50).filter(|k| !(30..35).contains(k)) {
            assert!((levels[k] - heard[k]).abs() < 0.5, "frame {k}");
        }
        // The canceller's output: 30 dB under her.
        assert!(levels[32] < heard[32] - 20.0, "{levels:?}");
    }

    #[test]
    fn the_microphones_tail_is_contiguous_and_starts_again_after_a_jump() {
        let mut tail = Tail::default();
        let ms = 1_000_000;
        let chunk: Vec<i16> = (0..320).collect();
        tail.push(0, RATE, &chunk, 1_000 * ms);
        // 1 ms late by the stream's latency estimate: still the next samples.
        let next: Vec<i16> = (320..640).collect();
        tail.push(21 * ms, RATE, &next, 1_000 * ms);
        let mut out = [0i16; 160];
        assert!(tail.copy(30 * ms, RATE, &mut out));
        assert_eq!(out[0], 480);
        // Not held: before the first, past the last, another rate.
        assert!(!tail.copy(-ms, RATE, &mut out));
        assert!(!tail.copy(35 * ms, RATE, &mut out));
        assert!(!tail.copy(0, 48_000, &mut out));
        // A jump of 100 ms: what was held is no longer next to it.
        tail.push(140 * ms, RATE, &chunk, 1_000 * ms);
        assert!(!tail.copy(30 * ms, RATE, &mut out));
        assert!(tail.copy(140 * ms, RATE, &mut out));
        assert_eq!(out[0], 0);
        // Only the last `keep_ns` are kept.
        for c in 0..10 {
            tail.push((160 + 20 * c) * ms, RATE, &chunk, 50 * ms);
        }
        assert!(!tail.copy(200 * ms, RATE, &mut out));
        assert!(tail.copy(320 * ms, RATE, &mut out));
    }

    #[test]
    fn a_pause_drops_what_was_queued_and_the_robot_ends_after_its_tail() {
        let mut room = Room::new(12, -3.0);
        room.run(200, |k| Some(voice(k)), |_| None, 20.0);
        // The robot falls silent: its echo and tail (12 + 30 frames) later, nothing is cut.
        let (o, _) = room.run(80, |_| None, |_| None, 20.0);
        assert!((40..=44).contains(&o.robot_frames), "{o:?}");
        // Queued audio thrown away before it played is no echo.
        room.d
            .reference(300 * FRAME_NS, RATE, &frame_at(-20.0, 0).repeat(50));
        room.d.reference_dropped_from(290 * FRAME_NS);
        assert!(!room.d.robot_at(400));
    }

    /// The microphone's stream starts in digital silence; the robot then speaks over a room
    /// that the microphone hears at -52 dBFS, falls silent, and writes its next sentence ahead
    /// of playing it, starting with the silence the speaker is primed with: meanwhile the
    /// microphone hears the room alone, which is no player (the floor is the room's, not the
    /// silence's).
    #[test]
    fn a_room_heard_after_digital_silence_is_no_player() {
        let mut d = DoubleTalk::new(Config::default());
        let t = |k: usize| k as i64 * FRAME_NS;
        for k in 0..200 {
            d.mic(t(k), RATE, &[0; FRAME]);
        }
        for k in 200..350 {
            d.reference(t(k), RATE, &frame_at(voice(k), k));
            d.mic(t(k), RATE, &frame_at(voice(k).max(-52.0), k));
        }
        assert!(d.path().is_some());
        for k in 350..400 {
            d.mic(t(k), RATE, &frame_at(-52.0, k));
        }
        assert!(!d.player_started());
        // The next sentence, written 200 ms ahead: 20 frames of silence, then the voice.
        d.reference(t(400), RATE, &[0; FRAME * 20]);
        let ahead: Vec<i16> = (420..470).flat_map(|k| frame_at(voice(k), k)).collect();
        d.reference(t(420), RATE, &ahead);
        for k in 400..420 {
            d.mic(t(k), RATE, &frame_at(-52.0, k));
        }
        assert!(!d.player_started());
    }

    #[test]
    fn levels_of_silence_and_full_scale() {
        assert_eq!(level_db(&[0; 160]), SILENCE_DB);
        assert_eq!(level_db(&[]), SILENCE_DB);
        assert!(level_db(&[i16::MIN; 160]).abs() < 1e-9);
    }

    #[test]
    fn correlation_of_lines() {
        let up: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 2.0 * i as f64)).collect();
        assert!((correlation(&up) - 1.0).abs() < 1e-9);
        let flat: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 3.0)).collect();
        assert_eq!(correlation(&flat), 0.0);
    }
}
