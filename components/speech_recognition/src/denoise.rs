//! Speech enhancement before decoding: a streaming Wiener filter on the short-time spectrum.
//!
//! The acoustic model was trained on fairly clean speech; broadband noise (a fan, a room, the
//! simulated white noise of the tests) fills the high-frequency bands where the consonants of
//! "touch", "stop" or "kick" live, and the decoder hears other words. The filter lowers each
//! frequency bin by the Wiener gain of its estimated signal-to-noise ratio before the audio
//! reaches PocketSphinx.
//!
//! Frames: 512 samples (32 ms at 16 kHz), hop 256, square-root Hann windows for analysis and
//! synthesis (their product sums to one at 50 % overlap, so a gain of 1 gives the input back).
//! Output lags input by 256 samples (16 ms); [`Denoiser::flush`] returns the rest.
//!
//! Per bin `k` of frame `t`, with `N_k` the noise power, `|X_k|²` the noisy power:
//!
//! ```text
//!   γ = |X_k|² / N_k                                           a posteriori SNR
//!   ξ = α · G_k(t−1)² · γ(t−1) + (1 − α) · max(γ − 1, 0)       a priori SNR ("decision directed")
//!   G_k = max(ξ / (1 + ξ), g_min)
//! ```
//!
//! The decision-directed ξ (Ephraim and Malah) smooths the gain over time, which keeps the
//! "musical noise" of plain spectral subtraction low; the floor `g_min` keeps some noise, which
//! the recognizer tolerates better than holes in the spectrum.
//!
//! The noise power comes from audio known to be noise ([`Denoiser::set_noise`]: the recognizer
//! gives it the end-pointer's pre-roll, the quiet before the speech started) and is then tracked
//! in frames whose power is close to it.

/// Frame length (samples).
pub const N: usize = 512;
/// Hop (samples): also the filter's delay.
pub const HOP: usize = N / 2;
const BINS: usize = N / 2 + 1;

/// Filter settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenoiseConfig {
    /// Decision-directed smoothing `α` (0..1).
    pub alpha: f64,
    /// Gain floor `g_min` (linear amplitude, e.g. 0.1 = −20 dB).
    pub gain_floor: f64,
    /// Over-subtraction: the noise power is multiplied by this in `γ`.
    pub over_subtraction: f64,
}

impl Default for DenoiseConfig {
    fn default() -> Self {
        Self {
            alpha: 0.98,
            gain_floor: 0.1,
            over_subtraction: 1.0,
        }
    }
}

/// The streaming filter. Feed any chunk sizes; without a noise estimate it passes audio through
/// (delayed by [`HOP`]).
#[derive(Debug, Clone)]
pub struct Denoiser {
    cfg: DenoiseConfig,
    window: Vec<f64>,
    /// Last `N` input samples (the analysis frame), oldest first.
    frame: Vec<f64>,
    /// Samples since the last frame.
    fresh: usize,
    /// Overlap-add accumulator (`N` samples; the first `HOP` are complete after each frame).
    ola: Vec<f64>,
    noise: Option<Vec<f64>>,
    prev_gain2_gamma: Vec<f64>,
    /// Whether the first frame was processed (its first hop lies before the input's start).
    primed: bool,
    samples_in: u64,
    samples_out: u64,
}

impl Denoiser {
    pub fn new(cfg: DenoiseConfig) -> Self {
        let window = (0..N)
            .map(|i| (0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / N as f64).cos()).sqrt())
            .collect();
        Self {
            cfg,
            window,
            frame: vec![0.0; N],
            fresh: HOP,
            ola: vec![0.0; N],
            noise: None,
            prev_gain2_gamma: vec![0.0; BINS],
            primed: false,
            samples_in: 0,
            samples_out: 0,
        }
    }

    /// Whether a noise estimate is set.
    pub fn has_noise(&self) -> bool {
        self.noise.is_some()
    }

    /// Estimate the noise power spectrum from `samples` known to be noise (at least one frame;
    /// shorter input leaves the estimate as it was). Resets the gain smoothing.
    pub fn set_noise(&mut self, samples: &[i16]) {
        let mut acc = vec![0.0; BINS];
        let mut n = 0;
        let mut start = 0;
        while start + N <= samples.len() {
            let spec = self.power_spectrum(&samples[start..start + N]);
            for (a, p) in acc.iter_mut().zip(&spec) {
                *a += p;
            }
            n += 1;
            start += HOP;
        }
        if n == 0 {
            return;
        }
        self.noise = Some(acc.into_iter().map(|a| (a / n as f64).max(1e-3)).collect());
        self.prev_gain2_gamma = vec![0.0; BINS];
    }

    fn power_spectrum(&self, x: &[i16]) -> Vec<f64> {
        let mut re: Vec<f64> = x
            .iter()
            .zip(&self.window)
            .map(|(&s, w)| s as f64 * w)
            .collect();
        let mut im = vec![0.0; N];
        fft(&mut re, &mut im, false);
        (0..BINS).map(|k| re[k] * re[k] + im[k] * im[k]).collect()
    }

    /// Filter `samples`; returns the filtered samples available so far (lagging by [`HOP`]).
    pub fn push(&mut self, samples: &[i16]) -> Vec<i16> {
        let mut out = Vec::with_capacity(samples.len() + HOP);
        self.samples_in += samples.len() as u64;
        for &s in samples {
            self.frame.rotate_left(1);
            self.frame[N - 1] = s as f64;
            self.fresh -= 1;
            if self.fresh == 0 {
                self.fresh = HOP;
                self.process_frame(&mut out);
            }
        }
        self.samples_out += out.len() as u64;
        out
    }

    /// End of stream: the delayed samples, the last frame padded with zeros.
    pub fn flush(&mut self) -> Vec<i16> {
        // Samples in but not out yet (the delay plus those since the last frame): zeros push them
        // through the accumulator.
        let owed = (self.samples_in - self.samples_out) as usize;
        let (samples_in, samples_out) = (self.samples_in, self.samples_out);
        let mut out = Vec::with_capacity(owed);
        while out.len() < owed {
            out.extend(self.push(&[0i16; HOP]));
        }
        out.truncate(owed);
        self.samples_in = samples_in;
        self.samples_out = samples_out + owed as u64;
        out
    }

    fn process_frame(&mut self, out: &mut Vec<i16>) {
        let mut re: Vec<f64> = self
            .frame
            .iter()
            .zip(&self.window)
            .map(|(s, w)| s * w)
            .collect();
        let mut im = vec![0.0; N];
        fft(&mut re, &mut im, false);
        if let Some(noise) = &self.noise {
            let a = self.cfg.alpha;
            for k in 0..BINS {
                let p = re[k] * re[k] + im[k] * im[k];
                let nk = noise[k] * self.cfg.over_subtraction;
                let gamma = p / nk;
                let xi = a * self.prev_gain2_gamma[k] + (1.0 - a) * (gamma - 1.0).max(0.0);
                let g = (xi / (1.0 + xi)).max(self.cfg.gain_floor);
                self.prev_gain2_gamma[k] = g * g * gamma;
                re[k] *= g;
                im[k] *= g;
                if k > 0 && k < N / 2 {
                    re[N - k] *= g;
                    im[N - k] *= g;
                }
            }
        }
        fft(&mut re, &mut im, true);
        for ((o, r), w) in self.ola.iter_mut().zip(&re).zip(&self.window) {
            *o += r * w;
        }
        if self.primed {
            out.extend(
                self.ola[..HOP]
                    .iter()
                    .map(|&x| x.round().clamp(-32768.0, 32767.0) as i16),
            );
        }
        self.primed = true;
        self.ola.rotate_left(HOP);
        for x in &mut self.ola[N - HOP..] {
            *x = 0.0;
        }
    }
}

/// In-place radix-2 complex FFT of length `N` (inverse scaled by 1/N).
fn fft(re: &mut [f64], im: &mut [f64], inverse: bool) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = 2.0 * std::f64::consts::PI / len as f64 * if inverse { 1.0 } else { -1.0 };
        let (wr, wi) = (ang.cos(), ang.sin());
        for start in (0..n).step_by(len) {
            let (mut cr, mut ci) = (1.0, 0.0);
            for k in 0..len / 2 {
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * cr - im[b] * ci;
                let ti = re[b] * ci + im[b] * cr;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
                let nr = cr * wr - ci * wi;
                ci = cr * wi + ci * wr;
                cr = nr;
            }
        }
        len <<= 1;
    }
    if inverse {
        for (r, i) in re.iter_mut().zip(im.iter_mut()) {
            *r /= n as f64;
            *i /= n as f64;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use audio::signal::{NoiseKind, NoiseRng, noise};

    fn tone(n: usize, amp: f64) -> Vec<i16> {
        (0..n)
            .map(|i| (amp * (2.0 * std::f64::consts::PI * 440.0 * i as f64 / 16000.0).sin()) as i16)
            .collect()
    }

    fn power(x: &[i16]) -> f64 {
        x.iter().map(|&s| (s as f64).powi(2)).sum::<f64>() / x.len().max(1) as f64
    }

    #[test]
    fn without_noise_estimate_it_gives_the_input_back_in_any_chunks() {
        let x = tone(5000, 8000.0);
        let mut d = Denoiser::new(DenoiseConfig::default());
        let mut y = vec![];
        for c in x.chunks(333) {
            y.extend(d.push(c));
        }
        y.extend(d.flush());
        assert_eq!(y.len(), x.len());
        let err = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (*a as i32 - *b as i32).abs())
            .max()
            .unwrap();
        // The first half frame has only half a window of support.
        let err_mid = x[HOP..]
            .iter()
            .zip(&y[HOP..])
            .map(|(a, b)| (*a as i32 - *b as i32).abs())
            .max()
            .unwrap();
        assert!(err_mid <= 1, "{err_mid} (all {err})");
        // Shorter than a hop, and nothing at all.
        let mut d = Denoiser::new(DenoiseConfig::default());
        let mut y = d.push(&x[..100]);
        y.extend(d.flush());
        assert_eq!(y.len(), 100);
        let mut d = Denoiser::new(DenoiseConfig::default());
        assert!(d.flush().is_empty());
    }

    #[test]
    fn white_noise_is_lowered_and_a_tone_in_it_kept() {
        let n = noise(32000, NoiseKind::White, 1.0e6, &mut NoiseRng::new(3));
        let noisy: Vec<i16> = n.iter().map(|&v| v.round() as i16).collect();
        let mut d = Denoiser::new(DenoiseConfig::default());
        d.set_noise(&noisy[..8000]);
        assert!(d.has_noise());
        let t = tone(16000, 6000.0);
        let mix: Vec<i16> = noisy[16000..]
            .iter()
            .zip(&t)
            .map(|(a, b)| a.saturating_add(*b))
            .collect();
        let mut y = d.push(&noisy[8000..16000]);
        let noise_out = power(&y[2000..]);
        y = d.push(&mix);
        y.extend(d.flush());
        // Noise alone: at least 15 dB lower.
        assert!(noise_out < power(&noisy[8000..16000]) / 30.0, "{noise_out}");
        // The tone's power survives within 3 dB (the Wiener gain lowers the bins at the edges of
        // its spectral peak, where the noise is comparable).
        let out_tone = power(&y[4000..]);
        let ratio = out_tone / power(&t);
        assert!(ratio > 0.5 && ratio < 1.4, "{ratio}");
    }
}
