//! The streams as frames: their levels, a level's floor, the levels kept by frame index, the
//! microphone's last samples, and the arithmetic of frame times and of correlation.

use std::collections::VecDeque;

/// Level of digital silence (dBFS).
pub const SILENCE_DB: f64 = -120.0;

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
pub(super) struct Floor {
    pub(super) db: Option<f64>,
}

impl Floor {
    /// The floor after a frame at `level` (digital silence, a stream not started yet, leaves
    /// it: it is no measure of the room).
    pub(super) fn update(&mut self, level: f64, rise_db: f64) -> f64 {
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
pub(super) struct Tail {
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
    pub(super) fn push(&mut self, t_ns: i64, rate_hz: u32, samples: &[i16], keep_ns: i64) {
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
    pub(super) fn copy(&self, t_ns: i64, rate_hz: u32, out: &mut [i16]) -> bool {
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

/// Frame levels by index, the newest last, at most `keep` of them.
#[derive(Debug, Default)]
pub(super) struct Levels {
    pub(super) frames: VecDeque<(i64, f64)>,
}

impl Levels {
    pub(super) fn push(&mut self, index: i64, level: f64, keep: usize) {
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
    pub(super) fn at(&self, index: i64) -> Option<f64> {
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

    pub(super) fn last_index(&self) -> Option<i64> {
        self.frames.back().map(|&(i, _)| i)
    }

    /// Drop the frames from `index` on.
    pub(super) fn truncate_from(&mut self, index: i64) {
        while self.frames.back().is_some_and(|&(i, _)| i >= index) {
            self.frames.pop_back();
        }
    }
}

/// Samples in a frame of `frame_ns` at `rate_hz` (at least one).
pub(super) fn samples_per_frame(rate_hz: u32, frame_ns: i64) -> usize {
    (rate_hz as usize * frame_ns as usize / 1_000_000_000).max(1)
}

/// When sample `n` of a stream whose first sample is heard at `t_ns` is heard.
pub(super) fn frame_time(t_ns: i64, rate_hz: u32, n: usize) -> i64 {
    t_ns + n as i64 * 1_000_000_000 / i64::from(rate_hz.max(1))
}

/// The frames of `samples` (`rate_hz`, the first heard at `t_ns`), each with when it is heard.
pub(super) fn frames(
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
pub(super) fn correlation(pairs: &[(f64, f64)]) -> f64 {
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
