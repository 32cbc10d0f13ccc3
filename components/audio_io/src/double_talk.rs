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

mod config;
mod levels;
mod path;
mod suppress;

pub use config::Config;
use levels::{Floor, Levels, Tail, frames};
pub use levels::{SILENCE_DB, level_db};
use std::collections::VecDeque;

/// How much of the room the comfort noise's level is taken over (s).
const ROOM_S: f64 = 3.0;

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
}

#[cfg(test)]
mod tests;
