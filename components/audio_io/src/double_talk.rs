//! Telling the player's voice from what the echo canceller leaves of the robot's (double-talk
//! detection), and taking that residue out of `audio/in` (residual echo suppression).
//!
//! The sound server's canceller removes most of the robot's voice from the microphone, but not
//! all of it: while it adapts (the robot's first second of speech through it), and in bursts
//! after, what it lets through is loud enough for the recognizer's end-pointer and decodes as
//! commands. Only this process knows both sides: the microphone as it was (the canceller's
//! master source, captured on a stream of its own) and what the canceller made of it. Frame by
//! frame (10 ms), while the robot's voice may be in the room:
//!
//! - **How much the canceller removes** (its echo return loss enhancement, ERLE): the microphone's
//!   level minus the canceller output's, over frames where the robot is loud in the microphone.
//!   Its upper quartile over the last [`Config::erle_window_s`] of such frames tells whether the canceller
//!   has converged: at least [`Config::armed_erle_db`], and the player may talk over the robot
//!   (*armed*). Until then (and again if it falls under, the room changed), everything heard
//!   while the robot speaks is taken out: gating, the safe fallback.
//! - **The player talks** (double talk) when the canceller took out of a frame at least
//!   [`Config::near_end_db`] less than it takes out of the robot's voice (that ERLE): what
//!   is left is louder than the robot's residue can be, so it is not the robot's. (The canceller
//!   itself attenuates the player while the robot speaks, by 20 dB and more in WebRTC's, so
//!   the output is not compared with the microphone's level directly.) Only frames where the
//!   microphone hears something loud count (the canceller's noise suppression takes 20 dB out
//!   of a quiet room too), and only a run of them: [`Config::onset_frames`] of the last
//!   [`Config::onset_window`], since what the canceller lets through of the robot comes in
//!   bursts of a few frames, as loud against the microphone as the player's first syllable.
//!   Then the frames pass whole until [`Config::hold_s`] after the last such frame: the
//!   player's voice keeps its soft syllables, and loses its first tens of milliseconds.
//! - **Anything else is the robot's residue**: attenuated down to the canceller output's noise
//!   floor, so the recognizer's own floor keeps following the room (digital silence would drag
//!   it down, and the room's noise would then start an utterance when the robot stops).
//!
//! When the robot is silent (nothing played for [`Config::tail_s`]) every frame passes. Times
//! are nanoseconds on one clock shared by the two capture streams and the playback thread: a
//! frame's time is when its first sample was heard.

use std::collections::VecDeque;

/// Level of digital silence (dBFS).
pub const SILENCE_DB: f64 = -120.0;

/// The detector's thresholds.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Frame length (samples of one channel).
    pub frame: usize,
    /// Frame length (ns).
    pub frame_ns: i64,
    /// A frame the canceller took at least this much less out of than its ERLE is the
    /// player's (dB).
    pub near_end_db: f64,
    /// The canceller's ERLE (upper quartile) at which the player may talk over the robot (dB).
    pub armed_erle_db: f64,
    /// How much of the robot's loud frames the ERLE covers (s).
    pub erle_window_s: f64,
    /// Loud frames needed before the first judgement (s).
    pub erle_min_s: f64,
    /// The robot is loud in the microphone when it is at least this over the microphone's floor
    /// (dB) and over [`Self::loud_min_dbfs`].
    pub loud_over_floor_db: f64,
    pub loud_min_dbfs: f64,
    /// Frames like the player's among the last `onset_window` that make the player speak.
    pub onset_frames: usize,
    pub onset_window: usize,
    /// How long the frames after one of the player's pass whole (s).
    pub hold_s: f64,
    /// How far the microphone's frames are looked at around the output's (ns before, ns after):
    /// the canceller's own delay, and the two streams' timing.
    pub window_before_ns: i64,
    pub window_after_ns: i64,
    /// How fast the floors rise (dB/s; they fall at once).
    pub floor_rise_db_per_s: f64,
    /// How long after the last sample played the robot's voice may still be in the room (s): the
    /// server's and the device's latency, and the room's reverberation.
    pub tail_s: f64,
}

impl Config {
    /// The defaults for a stream of `rate_hz`.
    pub fn at(rate_hz: u32) -> Self {
        Self {
            frame: (rate_hz as usize / 100).max(1),
            frame_ns: 10_000_000,
            near_end_db: 15.0,
            armed_erle_db: 25.0,
            erle_window_s: 3.0,
            erle_min_s: 0.5,
            loud_over_floor_db: 20.0,
            loud_min_dbfs: -60.0,
            onset_frames: 6,
            onset_window: 8,
            hold_s: 0.3,
            window_before_ns: 60_000_000,
            window_after_ns: 30_000_000,
            floor_rise_db_per_s: 3.0,
            tail_s: 0.3,
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
#[derive(Debug, Clone, Copy)]
struct Floor {
    db: Option<f64>,
}

impl Floor {
    fn update(&mut self, level: f64, rise_db: f64) -> f64 {
        let db = match self.db {
            Some(f) if level >= f => f + rise_db.min(level - f),
            _ => level,
        };
        self.db = Some(db);
        db
    }
}

/// When the robot's voice may be in the room: from the first sample written of what it is
/// saying to [`Config::tail_s`] after the last has played (ns on the shared clock).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RobotVoice {
    pub from_ns: i64,
    pub until_ns: i64,
}

impl RobotVoice {
    fn at(&self, t_ns: i64) -> bool {
        t_ns >= self.from_ns && t_ns < self.until_ns
    }
}

/// What the detector did to one chunk.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Outcome {
    /// Frames heard while the robot's voice may be in the room.
    pub robot_frames: u32,
    /// Of those, frames taken for the player's voice (passed whole).
    pub player_frames: u32,
    /// Frames attenuated as the robot's residue.
    pub suppressed_frames: u32,
}

/// A change of whether the player may talk over the robot, with the canceller's ERLE (dB).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Armed {
    Yes(f64),
    No(f64),
}

/// The detector and suppressor of one microphone (see the module doc).
#[derive(Debug)]
pub struct DoubleTalk {
    cfg: Config,
    /// The microphone's frames: time and level, oldest first.
    mic: VecDeque<(i64, f64)>,
    mic_floor: Floor,
    out_floor: Floor,
    /// ERLE of the robot's loud frames (dB), oldest first.
    erle: VecDeque<f64>,
    armed: bool,
    /// The player's frames pass until then.
    hold_until_ns: i64,
    /// Whether each of the last frames heard with the robot was like the player's, newest last.
    recent: VecDeque<bool>,
    /// The gain at the end of the last frame (a frame's gain ramps from it: no clicks).
    gain: f64,
    /// A change of `armed` not yet taken by [`Self::armed_changed`].
    changed: Option<Armed>,
}

impl DoubleTalk {
    pub fn new(cfg: Config) -> Self {
        Self {
            cfg,
            mic: VecDeque::new(),
            mic_floor: Floor { db: None },
            out_floor: Floor { db: None },
            erle: VecDeque::new(),
            armed: false,
            hold_until_ns: i64::MIN,
            recent: VecDeque::new(),
            gain: 1.0,
            changed: None,
        }
    }

    pub fn config(&self) -> &Config {
        &self.cfg
    }

    fn rise_per_frame(&self) -> f64 {
        self.cfg.floor_rise_db_per_s * self.cfg.frame_ns as f64 * 1e-9
    }

    /// A chunk of the microphone as it was (mono), its first sample heard at `t_ns`.
    pub fn mic(&mut self, t_ns: i64, samples: &[i16]) {
        let rise = self.rise_per_frame();
        for (i, f) in samples.chunks(self.cfg.frame).enumerate() {
            let l = level_db(f);
            self.mic_floor.update(l, rise);
            self.mic.push_back((t_ns + i as i64 * self.cfg.frame_ns, l));
        }
        // Two seconds are far more than the canceller's delay.
        let keep = 200;
        while self.mic.len() > keep {
            self.mic.pop_front();
        }
    }

    /// The microphone's loudest frame around `t_ns`, if it heard any there.
    fn mic_around(&self, t_ns: i64) -> Option<f64> {
        let (from, to) = (
            t_ns - self.cfg.window_before_ns,
            t_ns + self.cfg.window_after_ns,
        );
        self.mic
            .iter()
            .rev()
            .skip_while(|(t, _)| *t > to)
            .take_while(|(t, _)| *t >= from)
            .map(|&(_, l)| l)
            .reduce(f64::max)
    }

    /// The canceller's ERLE now (dB): the upper quartile over the robot's recent loud frames
    /// (the player's frames among them, which the canceller leaves in, pull a median down).
    pub fn erle_db(&self) -> Option<f64> {
        let min = (self.cfg.erle_min_s * 1e9 / self.cfg.frame_ns as f64) as usize;
        if self.erle.len() < min.max(1) {
            return None;
        }
        let mut v: Vec<f64> = self.erle.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        Some(v[v.len() * 3 / 4])
    }

    /// Whether the player may talk over the robot now.
    pub fn armed(&self) -> bool {
        self.armed
    }

    /// The last change of [`Self::armed`], once.
    pub fn armed_changed(&mut self) -> Option<Armed> {
        self.changed.take()
    }

    /// A chunk of the canceller's output (mono), its first sample heard at `t_ns`, while the
    /// robot's voice is `robot`: the robot's residue in it attenuated in place.
    pub fn process(&mut self, t_ns: i64, samples: &mut [i16], robot: RobotVoice) -> Outcome {
        let mut outcome = Outcome::default();
        let rise = self.rise_per_frame();
        let frame = self.cfg.frame;
        let window = (self.cfg.erle_window_s * 1e9 / self.cfg.frame_ns as f64) as usize;
        for (i, f) in samples.chunks_mut(frame).enumerate() {
            let t = t_ns + i as i64 * self.cfg.frame_ns;
            let out = level_db(f);
            let floor = self.out_floor.update(out, rise);
            if !robot.at(t) {
                tracing::trace!(
                    t_ms = t / 1_000_000,
                    out = format!("{out:.1}"),
                    floor = format!("{floor:.1}"),
                    "frame without the robot"
                );
                self.ramp(f, 1.0);
                continue;
            }
            outcome.robot_frames += 1;
            let mic = self.mic_around(t);
            let mic_floor = self.mic_floor.db.unwrap_or(SILENCE_DB);
            let loud = mic.filter(|&m| {
                m >= self.cfg.loud_min_dbfs && m >= mic_floor + self.cfg.loud_over_floor_db
            });
            if let Some(m) = loud {
                self.erle.push_back(m - out);
                while self.erle.len() > window.max(1) {
                    self.erle.pop_front();
                }
                self.judge();
            }
            let like_player = self.armed
                && loud
                    .zip(self.erle_db())
                    .is_some_and(|(m, erle)| m - out < erle - self.cfg.near_end_db);
            self.recent.push_back(like_player);
            while self.recent.len() > self.cfg.onset_window.max(1) {
                self.recent.pop_front();
            }
            let run = self.recent.iter().filter(|&&p| p).count();
            let holding = t < self.hold_until_ns;
            let player = like_player && (holding || run >= self.cfg.onset_frames);
            if player {
                self.hold_until_ns = t + (self.cfg.hold_s * 1e9) as i64;
            }
            tracing::trace!(
                t_ms = t / 1_000_000,
                out = format!("{out:.1}"),
                mic = format!("{:.1}", mic.unwrap_or(f64::NAN)),
                floor = format!("{floor:.1}"),
                armed = self.armed,
                player,
                "frame"
            );
            if self.armed && t < self.hold_until_ns {
                outcome.player_frames += 1;
                self.ramp(f, 1.0);
            } else {
                outcome.suppressed_frames += 1;
                let gain = 10f64.powf((floor - out) / 20.0).min(1.0);
                self.ramp(f, gain);
            }
        }
        outcome
    }

    /// Arm or disarm on the ERLE now.
    fn judge(&mut self) {
        let Some(erle) = self.erle_db() else {
            return;
        };
        let armed = erle >= self.cfg.armed_erle_db;
        if armed != self.armed {
            self.armed = armed;
            self.changed = Some(if armed {
                Armed::Yes(erle)
            } else {
                Armed::No(erle)
            });
        }
    }

    /// Scale a frame: a lower gain at once (the residue is cut from its first sample), a higher
    /// one going linearly from the last frame's (no click as the player comes in).
    fn ramp(&mut self, f: &mut [i16], gain: f64) {
        let from = self.gain.min(gain);
        self.gain = gain;
        if from == 1.0 && gain == 1.0 {
            return;
        }
        let n = f.len().max(1) as f64;
        for (k, x) in f.iter_mut().enumerate() {
            let g = from + (gain - from) * (k + 1) as f64 / n;
            *x = (f64::from(*x) * g).round() as i16;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: u32 = 16_000;
    const FRAME: usize = 160;
    const FRAME_NS: i64 = 10_000_000;

    /// A tone-like frame at `db` dBFS (a square wave of that power), phase `k`.
    fn frame_at(db: f64, k: usize) -> Vec<i16> {
        let a = 32768.0 * 10f64.powf(db / 20.0);
        (0..FRAME)
            .map(|i| if ((i + k) / 8).is_multiple_of(2) { a } else { -a } as i16)
            .collect()
    }

    /// Feed `n` frames: the microphone at `mic_db`, the canceller's output at `out_db`; the
    /// outcome summed and the output's levels after suppression.
    fn feed(
        d: &mut DoubleTalk,
        t0: i64,
        n: usize,
        mic_db: f64,
        out_db: f64,
        robot: RobotVoice,
    ) -> (Outcome, Vec<f64>) {
        let mut sum = Outcome::default();
        let mut levels = Vec::new();
        for k in 0..n {
            let t = t0 + k as i64 * FRAME_NS;
            d.mic(t, &frame_at(mic_db, k));
            let mut out = frame_at(out_db, k);
            let o = d.process(t, &mut out, robot);
            sum.robot_frames += o.robot_frames;
            sum.player_frames += o.player_frames;
            sum.suppressed_frames += o.suppressed_frames;
            levels.push(level_db(&out));
        }
        (sum, levels)
    }

    const ALWAYS: RobotVoice = RobotVoice {
        from_ns: i64::MIN,
        until_ns: i64::MAX,
    };

    #[test]
    fn without_the_robot_everything_passes() {
        let mut d = DoubleTalk::new(Config::at(RATE));
        let (o, levels) = feed(&mut d, 0, 50, -20.0, -20.0, RobotVoice::default());
        assert_eq!(o, Outcome::default());
        assert!(levels.iter().all(|l| (l - -20.0).abs() < 0.1), "{levels:?}");
    }

    #[test]
    fn until_the_canceller_has_converged_the_robots_voice_is_gated() {
        let mut d = DoubleTalk::new(Config::at(RATE));
        // The room's floor first: -70 dBFS.
        feed(&mut d, 0, 100, -70.0, -70.0, RobotVoice::default());
        // The robot speaks; the canceller has not adapted: its output is the microphone's.
        let (o, levels) = feed(&mut d, 100 * FRAME_NS, 100, -25.0, -26.0, ALWAYS);
        assert_eq!(o.suppressed_frames, 100, "{o:?}");
        assert!(!d.armed());
        // Brought down to the floor, not to digital silence.
        let last = levels[levels.len() - 1];
        // (It rises 3 dB a second while the robot speaks: a second of it here.)
        assert!((-71.0..-66.0).contains(&last), "{levels:?}");
    }

    #[test]
    fn once_converged_the_residue_is_suppressed_and_the_player_passes() {
        let mut d = DoubleTalk::new(Config::at(RATE));
        feed(&mut d, 0, 100, -90.0, -90.0, RobotVoice::default());
        // The robot alone: the canceller removes 40 dB.
        let (_, _) = feed(&mut d, 100 * FRAME_NS, 100, -25.0, -65.0, ALWAYS);
        assert!(d.armed(), "ERLE {:?}", d.erle_db());
        assert!(
            matches!(d.armed_changed(), Some(Armed::Yes(e)) if (e - 40.0).abs() < 0.5),
            "{:?}",
            d.erle_db()
        );
        assert_eq!(d.armed_changed(), None);
        let (o, levels) = feed(&mut d, 200 * FRAME_NS, 50, -25.0, -65.0, ALWAYS);
        assert_eq!(o.suppressed_frames, 50, "{o:?}");
        assert!(levels.iter().all(|&l| l < -80.0), "{levels:?}");
        // The player speaks over it, as loud; the canceller attenuates the player too, but far
        // less than the robot (by 18 dB).
        let (o, levels) = feed(&mut d, 250 * FRAME_NS, 30, -22.0, -40.0, ALWAYS);
        // From the sixth frame on (a run of six), whole after that frame's ramp.
        assert_eq!(o.player_frames, 25, "{o:?}");
        assert!(levels[..5].iter().all(|&l| l < -80.0), "{levels:?}");
        assert!(levels[6..].iter().all(|&l| l > -40.5), "{levels:?}");
        // Still armed: the player's frames are a tenth of the window.
        assert!(d.armed(), "ERLE {:?}", d.erle_db());
        // The player stops: held for hold_s, then the residue is taken out again.
        let (o, _) = feed(&mut d, 280 * FRAME_NS, 50, -25.0, -65.0, ALWAYS);
        // (The last of the player's frames and the 29 after it make the 0.3 s.)
        assert_eq!(o.player_frames, 29, "{o:?}");
        assert_eq!(o.suppressed_frames, 21, "{o:?}");
        // A burst of the robot's voice the canceller lets through, as loud against the
        // microphone as the player, for 50 ms: still the robot's.
        let (o, levels) = feed(&mut d, 330 * FRAME_NS, 5, -25.0, -40.0, ALWAYS);
        assert_eq!(o.suppressed_frames, 5, "{o:?}");
        assert!(levels.iter().all(|&l| l < -80.0), "{levels:?}");
        // A quiet room that the canceller's noise suppression takes 20 dB out of is no player.
        let (o, _) = feed(&mut d, 335 * FRAME_NS, 20, -85.0, -105.0, ALWAYS);
        assert_eq!(o.player_frames, 0, "{o:?}");
    }

    #[test]
    fn a_canceller_that_stops_removing_the_robot_is_disarmed() {
        let mut d = DoubleTalk::new(Config::at(RATE));
        feed(&mut d, 0, 100, -90.0, -90.0, RobotVoice::default());
        feed(&mut d, 100 * FRAME_NS, 100, -25.0, -65.0, ALWAYS);
        assert!(d.armed());
        d.armed_changed();
        // The room changed: the canceller removes 3 dB for four seconds.
        let (o, _) = feed(&mut d, 200 * FRAME_NS, 400, -25.0, -28.0, ALWAYS);
        assert!(!d.armed(), "ERLE {:?}", d.erle_db());
        assert!(matches!(d.armed_changed(), Some(Armed::No(_))));
        // Until disarmed the frames were taken for the player's; then gated.
        assert!(o.suppressed_frames > 50, "{o:?}");
    }

    #[test]
    fn the_robots_voice_ends_after_its_tail() {
        let voice = RobotVoice {
            from_ns: 10 * FRAME_NS,
            until_ns: 20 * FRAME_NS,
        };
        let mut d = DoubleTalk::new(Config::at(RATE));
        let (o, _) = feed(&mut d, 0, 30, -25.0, -25.0, voice);
        assert_eq!(o.robot_frames, 10);
        assert_eq!(o.suppressed_frames, 10);
    }

    #[test]
    fn levels_of_silence_and_full_scale() {
        assert_eq!(level_db(&[0; 160]), SILENCE_DB);
        assert_eq!(level_db(&[]), SILENCE_DB);
        assert!(level_db(&[i16::MIN; 160]).abs() < 1e-9);
    }
}
