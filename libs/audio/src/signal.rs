//! Signal helpers on mono signed 16-bit PCM: resampling, power, noise, mixing at a chosen
//! signal-to-noise ratio, gain with clipping.
//!
//! Power is the mean of squared samples in full-scale units (a sample of 32768 is 1.0); SNR in dB
//! is `10 log10(P_speech / P_noise)`, with `P_speech` measured over the whole speech signal given.

/// Resample by windowed-sinc interpolation (Hann window, 16 zero crossings each side, cut-off at
/// the lower Nyquist frequency, so downsampling does not alias).
pub fn resample(samples: &[i16], from_hz: u32, to_hz: u32) -> Vec<i16> {
    if from_hz == to_hz || samples.is_empty() || from_hz == 0 || to_hz == 0 {
        return samples.to_vec();
    }
    let ratio = to_hz as f64 / from_hz as f64;
    let cutoff = ratio.min(1.0); // fraction of the input Nyquist
    const ZEROS: f64 = 16.0;
    let half = (ZEROS / cutoff).ceil() as i64;
    let n_out = ((samples.len() as f64) * ratio).floor() as usize;
    let mut out = Vec::with_capacity(n_out);
    for j in 0..n_out {
        let t = j as f64 / ratio; // position in input samples
        let center = t.floor() as i64;
        let mut acc = 0.0;
        for k in (center - half + 1)..=(center + half) {
            if k < 0 || k as usize >= samples.len() {
                continue;
            }
            let x = t - k as f64;
            let arg = x * cutoff;
            let sinc = if arg.abs() < 1e-9 {
                1.0
            } else {
                (std::f64::consts::PI * arg).sin() / (std::f64::consts::PI * arg)
            };
            let w = 0.5 + 0.5 * (std::f64::consts::PI * x / (half as f64)).cos();
            acc += samples[k as usize] as f64 * sinc * cutoff * w;
        }
        out.push(acc.round().clamp(-32768.0, 32767.0) as i16);
    }
    out
}

/// Mean power in full-scale units (0 for no samples).
pub fn power(samples: &[i16]) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    samples
        .iter()
        .map(|&s| {
            let x = s as f64 / 32768.0;
            x * x
        })
        .sum::<f64>()
        / samples.len() as f64
}

/// Power of the loud part of a signal: frames of 10 ms at 16 kHz whose power is within 30 dB of
/// the loudest frame. Used as `P_speech` so that pauses inside an utterance do not count.
pub fn active_power(samples: &[i16]) -> f64 {
    let frames: Vec<f64> = samples.chunks(160).map(power).collect();
    let max = frames.iter().cloned().fold(0.0, f64::max);
    let active: Vec<f64> = frames.into_iter().filter(|&p| p > max * 1e-3).collect();
    if active.is_empty() {
        0.0
    } else {
        active.iter().sum::<f64>() / active.len() as f64
    }
}

/// A deterministic pseudo-random generator (xorshift64*), so tests and benchmarks repeat.
#[derive(Debug, Clone)]
pub struct NoiseRng(u64);

impl NoiseRng {
    pub fn new(seed: u64) -> Self {
        Self(seed.max(1))
    }
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal (Box-Muller).
    pub fn gaussian(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
    }
}

/// Kinds of background noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseKind {
    /// Flat spectrum.
    White,
    /// Low-passed (one-pole, 0.95) white noise: a rumble like a fan or a crowd's murmur.
    Brown,
}

/// `n` samples of noise with power `power_fs` (full-scale units).
pub fn noise(n: usize, kind: NoiseKind, power_fs: f64, rng: &mut NoiseRng) -> Vec<f64> {
    let mut v: Vec<f64> = Vec::with_capacity(n);
    let mut y = 0.0;
    for _ in 0..n {
        let g = rng.gaussian();
        let x = match kind {
            NoiseKind::White => g,
            NoiseKind::Brown => {
                y = 0.95 * y + g;
                y
            }
        };
        v.push(x);
    }
    let p = if n == 0 {
        1.0
    } else {
        v.iter().map(|x| x * x).sum::<f64>() / n as f64
    };
    let gain = if p > 0.0 { (power_fs / p).sqrt() } else { 0.0 };
    v.iter().map(|x| x * gain * 32768.0).collect()
}

/// Place `speech` after `lead_s` of noise, followed by `trail_s` of noise, at 16 kHz, with the
/// noise scaled so the speech's active power over the noise power is `snr_db`. The result is
/// clipped to 16 bits. `snr_db = f64::INFINITY` adds silence instead of noise.
pub fn mix_at_snr(
    speech: &[i16],
    snr_db: f64,
    kind: NoiseKind,
    lead_s: f64,
    trail_s: f64,
    rng: &mut NoiseRng,
) -> Vec<i16> {
    let lead = (lead_s * 16_000.0) as usize;
    let trail = (trail_s * 16_000.0) as usize;
    let n = lead + speech.len() + trail;
    let noise_power = if snr_db.is_finite() {
        active_power(speech) / 10f64.powf(snr_db / 10.0)
    } else {
        0.0
    };
    let nz = noise(n, kind, noise_power, rng);
    (0..n)
        .map(|i| {
            let s = if i >= lead && i < lead + speech.len() {
                speech[i - lead] as f64
            } else {
                0.0
            };
            (s + nz[i]).round().clamp(-32768.0, 32767.0) as i16
        })
        .collect()
}

/// Multiply by `gain`, clipping at full scale (simulates an overdriven microphone).
pub fn gain_clipped(samples: &[i16], gain: f64) -> Vec<i16> {
    samples
        .iter()
        .map(|&s| (s as f64 * gain).round().clamp(-32768.0, 32767.0) as i16)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone(hz: f64, rate: u32, secs: f64) -> Vec<i16> {
        (0..(rate as f64 * secs) as usize)
            .map(|i| {
                (8000.0 * (2.0 * std::f64::consts::PI * hz * i as f64 / rate as f64).sin()) as i16
            })
            .collect()
    }

    #[test]
    fn resampling_keeps_in_band_tones_and_removes_aliases() {
        let a = resample(&tone(1000.0, 22050, 1.0), 22050, 16000);
        assert!((a.len() as i64 - 16000).abs() <= 1);
        // Power of a sine of amplitude 8000: (8000/32768)^2 / 2.
        let expect = (8000.0f64 / 32768.0).powi(2) / 2.0;
        let p = power(&a[500..15500]);
        assert!((p / expect - 1.0).abs() < 0.05, "{p} vs {expect}");
        // 10 kHz is above the new Nyquist (8 kHz): it must be filtered, not folded to 6 kHz.
        let b = resample(&tone(10_000.0, 22050, 1.0), 22050, 16000);
        assert!(power(&b[500..15500]) < expect * 0.01);
    }

    #[test]
    fn mixing_hits_the_requested_snr() {
        let speech = tone(440.0, 16000, 1.0);
        let mut rng = NoiseRng::new(7);
        for snr in [0.0, 10.0, 20.0] {
            let mixed = mix_at_snr(&speech, snr, NoiseKind::White, 0.5, 0.5, &mut rng);
            assert_eq!(mixed.len(), 32000);
            let noise_only = power(&mixed[..8000]);
            let measured = 10.0 * (active_power(&speech) / noise_only).log10();
            assert!(
                (measured - snr).abs() < 0.5,
                "asked {snr} dB, got {measured}"
            );
        }
        let clean = mix_at_snr(&speech, f64::INFINITY, NoiseKind::Brown, 0.1, 0.0, &mut rng);
        assert!(clean[..1600].iter().all(|&s| s == 0));
    }

    #[test]
    fn gain_clips_at_full_scale() {
        let c = gain_clipped(&[20000, -20000, 100], 4.0);
        assert_eq!(c, vec![32767, -32768, 400]);
    }
}

/// Removes a constant offset (DC) from a stream, as a cheap microphone or sound card adds: a
/// running mean with a time constant of a quarter second (a first-order high-pass below 1 Hz,
/// far under speech) is subtracted once it is large enough to matter (at least
/// [`DcRemover::MIN_OFFSET`], -54 dBFS). A stream with no offset passes unchanged, sample for
/// sample, so its digital silence stays exact zeros.
#[derive(Debug, Clone, Default)]
pub struct DcRemover {
    mean: f64,
}

impl DcRemover {
    /// Time constant of the running mean (samples at 16 kHz: 0.25 s).
    pub const TAU_SAMPLES: f64 = 4000.0;
    /// The smallest offset removed (in sample units).
    pub const MIN_OFFSET: f64 = 64.0;

    /// `samples` without their offset, appended to `out` (cleared first).
    pub fn process(&mut self, samples: &[i16], out: &mut Vec<i16>) {
        out.clear();
        out.reserve(samples.len());
        for &s in samples {
            self.mean += (f64::from(s) - self.mean) / Self::TAU_SAMPLES;
            out.push(if self.mean.abs() < Self::MIN_OFFSET {
                s
            } else {
                (f64::from(s) - self.mean).round().clamp(-32768.0, 32767.0) as i16
            });
        }
    }

    /// The offset it currently removes (sample units; 0 below [`DcRemover::MIN_OFFSET`]).
    pub fn offset(&self) -> f64 {
        if self.mean.abs() < Self::MIN_OFFSET {
            0.0
        } else {
            self.mean
        }
    }
}

#[cfg(test)]
mod dc_tests {
    use super::*;

    #[test]
    fn an_offset_is_removed_and_a_clean_stream_is_untouched() {
        let tone: Vec<i16> = (0..32_000)
            .map(|i| {
                (3000.0 * (i as f64 * 2.0 * std::f64::consts::PI * 200.0 / 16_000.0).sin()) as i16
            })
            .collect();
        let mut dc = DcRemover::default();
        let mut out = Vec::new();
        dc.process(&tone, &mut out);
        assert_eq!(out, tone, "no offset: unchanged");
        let silence = vec![0i16; 1600];
        dc.process(&silence, &mut out);
        assert!(out.iter().all(|&s| s == 0), "digital silence stays zeros");

        let offset: Vec<i16> = tone.iter().map(|&s| s + 4000).collect();
        let mut dc = DcRemover::default();
        dc.process(&offset, &mut out);
        // After a second (four time constants) the mean of the output is near zero and the tone
        // is intact.
        let tail = &out[16_000..];
        let mean = tail.iter().map(|&s| f64::from(s)).sum::<f64>() / tail.len() as f64;
        assert!(mean.abs() < 100.0, "mean {mean}");
        let peak = tail.iter().map(|&s| s.abs()).max().unwrap_or(0);
        assert!((2800..=3300).contains(&peak), "peak {peak}");
        assert!((dc.offset() - 4000.0).abs() < 100.0, "{}", dc.offset());
    }
}
