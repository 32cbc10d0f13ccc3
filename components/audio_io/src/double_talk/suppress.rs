//! Residual echo suppression: the canceller's output cut where the robot's voice may be, to
//! noise at the room's level, and the player's frames passed whole.

use super::levels::{frame_time, level_db, samples_per_frame};
use super::{DoubleTalk, Outcome, ROOM_S};

impl DoubleTalk {
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
