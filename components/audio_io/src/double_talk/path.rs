//! The echo path: measuring how the robot's voice reaches the microphone, and the echo it
//! predicts a microphone frame may hold.

use super::levels::correlation;
use super::{DoubleTalk, EchoPath, SILENCE_DB};

impl DoubleTalk {
    /// The loudest echo of the robot frame `i` of the microphone may hold (dBFS).
    pub(super) fn echo_at(&self, i: i64, path: EchoPath) -> f64 {
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

    /// Measure the echo path on the recent frames (see the module doc).
    pub(super) fn measure_path(&mut self) {
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
}
