//! Signal helpers on mono signed 16-bit PCM: resampling, power, noise (white, brown, fan), babble
//! of competing talkers, mixing at a chosen signal-to-noise ratio, reverberation by a synthetic
//! room impulse response, gain with clipping, DC removal.
//!
//! Fan noise, babble, mixing and the room simulation assume 16 kHz.
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
    /// A ventilation or computer fan: white noise low-passed (2-pole, 400-700 Hz) with a weaker
    /// flat part, plus a blade-pass tone (90-180 Hz) and its 2nd to 4th harmonics whose level
    /// wobbles by 4 % at about 1 Hz. Cut-off, tone, wobble and phases come from the generator.
    Fan,
}

/// `n` samples of noise with power `power_fs` (full-scale units).
pub fn noise(n: usize, kind: NoiseKind, power_fs: f64, rng: &mut NoiseRng) -> Vec<f64> {
    let v: Vec<f64> = match kind {
        NoiseKind::White => (0..n).map(|_| rng.gaussian()).collect(),
        NoiseKind::Brown => {
            let mut y = 0.0;
            (0..n)
                .map(|_| {
                    y = 0.95 * y + rng.gaussian();
                    y
                })
                .collect()
        }
        NoiseKind::Fan => FanParams::draw(rng).generate(n, rng),
    };
    scaled_to_power(&v, power_fs)
}

/// `v` (full-scale units) scaled to power `power_fs`, in sample units (silence stays silence).
fn scaled_to_power(v: &[f64], power_fs: f64) -> Vec<f64> {
    let p = if v.is_empty() {
        1.0
    } else {
        v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64
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
    place_in_noise(speech, &nz, lead)
}

/// `speech` added to `nz` (sample units) from sample `lead` on, clipped to 16 bits; as long as
/// `nz`.
fn place_in_noise(speech: &[i16], nz: &[f64], lead: usize) -> Vec<i16> {
    nz.iter()
        .enumerate()
        .map(|(i, &z)| {
            let s = if i >= lead && i < lead + speech.len() {
                speech[i - lead] as f64
            } else {
                0.0
            };
            (s + z).round().clamp(-32768.0, 32767.0) as i16
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

/// Sample rate of fan noise, babble, mixing and the room simulation (Hz).
const RATE: f64 = 16_000.0;

/// The random parameters of a [`NoiseKind::Fan`] noise.
#[derive(Debug, Clone, Copy)]
struct FanParams {
    /// Cut-off of the 2-pole low-pass (Hz).
    cutoff_hz: f64,
    /// Blade-pass frequency (Hz).
    blade_hz: f64,
    /// Power of the blade-pass tone relative to the low-passed noise.
    tone_power: f64,
    /// Frequency of the level wobble (Hz).
    wobble_hz: f64,
    wobble_phase: f64,
    /// Phases of the tone and its harmonics.
    phases: [f64; 4],
}

impl FanParams {
    /// Amplitude of each harmonic (1st to 4th) relative to the blade-pass tone.
    const HARMONICS: [f64; 4] = [1.0, 0.5, 0.3, 0.2];
    /// Power of the flat part relative to the low-passed noise (-13 dB).
    const FLAT_POWER: f64 = 0.05;
    /// Depth of the level wobble.
    const WOBBLE: f64 = 0.04;

    fn draw(rng: &mut NoiseRng) -> Self {
        let tau = 2.0 * std::f64::consts::PI;
        Self {
            cutoff_hz: 400.0 + 300.0 * rng.uniform(),
            blade_hz: 90.0 + 90.0 * rng.uniform(),
            tone_power: 0.1 + 0.1 * rng.uniform(),
            wobble_hz: 0.7 + 0.6 * rng.uniform(),
            wobble_phase: tau * rng.uniform(),
            phases: [(); 4].map(|()| tau * rng.uniform()),
        }
    }

    /// `n` samples, not yet scaled to a power.
    fn generate(&self, n: usize, rng: &mut NoiseRng) -> Vec<f64> {
        let tau = 2.0 * std::f64::consts::PI;
        // Butterworth low-pass biquad (RBJ cookbook, Q = 1/sqrt 2).
        let w0 = tau * self.cutoff_hz / RATE;
        let alpha = w0.sin() / std::f64::consts::SQRT_2;
        let a0 = 1.0 + alpha;
        let b0 = (1.0 - w0.cos()) / 2.0 / a0;
        let b1 = (1.0 - w0.cos()) / a0;
        let a1 = -2.0 * w0.cos() / a0;
        let a2 = (1.0 - alpha) / a0;
        let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
        let mut low_pass = |x: f64| {
            let y = b0 * x + b1 * x1 + b0 * x2 - a1 * y1 - a2 * y2;
            (x2, x1, y2, y1) = (x1, x, y1, y);
            y
        };
        // Settle the filter (its time constant is well under 64 samples).
        for _ in 0..64 {
            low_pass(rng.gaussian());
        }
        let mut low = Vec::with_capacity(n);
        let mut flat = Vec::with_capacity(n);
        for _ in 0..n {
            low.push(low_pass(rng.gaussian()));
            flat.push(rng.gaussian());
        }
        let p_low = low.iter().map(|x| x * x).sum::<f64>() / n.max(1) as f64;
        let low_gain = if p_low > 0.0 { 1.0 / p_low.sqrt() } else { 0.0 };
        let flat_gain = Self::FLAT_POWER.sqrt();
        // A sine of amplitude a has power a^2 / 2.
        let tone_amp = (2.0 * self.tone_power).sqrt();
        low.iter()
            .zip(&flat)
            .enumerate()
            .map(|(i, (l, f))| {
                let t = i as f64 / RATE;
                let level = tone_amp
                    * (1.0 + Self::WOBBLE * (tau * self.wobble_hz * t + self.wobble_phase).sin());
                let tones: f64 = Self::HARMONICS
                    .iter()
                    .zip(self.phases)
                    .enumerate()
                    .map(|(h, (a, ph))| a * (tau * self.blade_hz * (h + 1) as f64 * t + ph).sin())
                    .sum();
                l * low_gain + f * flat_gain + level * tones
            })
            .collect()
    }
}

/// `n` samples of babble with power `power_fs` (full-scale units, as [`noise`]): the sum of the
/// `talkers`' speech (16 kHz, e.g. each talker's sentences concatenated), each scaled to the same
/// active power and looped from a random offset, so their pauses do not line up. Use 2 talkers
/// or more (a crowd from about 6); silent or empty talkers are skipped, and with none left the
/// result is silence.
pub fn babble(talkers: &[Vec<i16>], n: usize, power_fs: f64, rng: &mut NoiseRng) -> Vec<f64> {
    let mut v = vec![0.0; n];
    for talker in talkers {
        let offset = (rng.uniform() * talker.len() as f64) as usize;
        let p = active_power(talker);
        if p <= 0.0 {
            continue;
        }
        let gain = 1.0 / (p.sqrt() * 32768.0);
        for (x, &s) in v.iter_mut().zip(talker.iter().cycle().skip(offset)) {
            *x += s as f64 * gain;
        }
    }
    scaled_to_power(&v, power_fs)
}

/// Place `speech` after `lead_s` of `noise`, followed by `trail_s` of it, at 16 kHz, as
/// [`mix_at_snr`] does with a given noise (sample units, e.g. from [`noise`] or [`babble`]): its
/// first `lead + speech + trail` samples (repeated if it is shorter) are scaled so the speech's
/// active power over their power is `snr_db`. The result is clipped to 16 bits.
/// `snr_db = f64::INFINITY` (or a silent noise) adds silence instead of noise.
pub fn mix_with_noise(
    speech: &[i16],
    snr_db: f64,
    noise: &[f64],
    lead_s: f64,
    trail_s: f64,
) -> Vec<i16> {
    let lead = (lead_s * RATE) as usize;
    let trail = (trail_s * RATE) as usize;
    let n = lead + speech.len() + trail;
    let used: Vec<f64> = noise.iter().copied().cycle().take(n).collect();
    let p = if used.is_empty() {
        0.0
    } else {
        used.iter().map(|x| (x / 32768.0).powi(2)).sum::<f64>() / used.len() as f64
    };
    let gain = if snr_db.is_finite() && p > 0.0 {
        (active_power(speech) / 10f64.powf(snr_db / 10.0) / p).sqrt()
    } else {
        0.0
    };
    let mut nz: Vec<f64> = used.iter().map(|x| x * gain).collect();
    nz.resize(n, 0.0);
    place_in_noise(speech, &nz, lead)
}

/// A synthetic room impulse response at 16 kHz, `rt60_s` long (at least one sample): the direct
/// path (1.0 at sample 0), 5 to 10 early reflections in the first 50 ms (random delays, gains
/// falling with path length), and from 5-15 ms on a tail of Gaussian noise whose envelope falls
/// 60 dB in `rt60_s`. Its levels are those of a talker about 1.5 m away in a small room: the
/// direct-to-reverberant ratio is about +3 dB at 0.3 s and about -1 dB at 0.8 s. A
/// non-positive or non-finite `rt60_s` gives the direct path alone.
pub fn room_impulse_response(rt60_s: f64, rng: &mut NoiseRng) -> Vec<f64> {
    if !(rt60_s.is_finite() && rt60_s > 0.0) {
        return vec![1.0];
    }
    /// Distance of the talker (m) and speed of sound (m/s).
    const DISTANCE: f64 = 1.5;
    const SOUND_SPEED: f64 = 343.0;
    /// Amplitude of the tail's envelope at the direct path's time.
    const TAIL_LEVEL: f64 = 0.037;
    let len = ((rt60_s * RATE).round() as usize).max(1);
    let mut h = vec![0.0; len];
    h[0] = 1.0;
    // Amplitude envelope falling 60 dB (a factor of 1000) in rt60_s.
    let decay = |t: f64| 10f64.powf(-3.0 * t / rt60_s);
    let tail_start = 0.005 + 0.010 * rng.uniform();
    let fade = 0.005;
    for (i, x) in h.iter_mut().enumerate().skip((tail_start * RATE) as usize) {
        let t = i as f64 / RATE;
        let ramp = ((t - tail_start) / fade).clamp(0.0, 1.0);
        *x = TAIL_LEVEL * ramp * decay(t) * rng.gaussian();
    }
    let reflections = 5 + (rng.uniform() * 6.0) as usize;
    for _ in 0..reflections {
        let delay = 0.002 + 0.048 * rng.uniform();
        let absorption = 0.6 + 0.3 * rng.uniform();
        let gain = absorption * DISTANCE / (DISTANCE + SOUND_SPEED * delay) * decay(delay);
        if let Some(x) = h.get_mut((delay * RATE) as usize) {
            *x += gain;
        }
    }
    h
}

/// `samples` (16 kHz) in a room: convolved (by FFT) with a [`room_impulse_response`] for
/// `rt60_s`, so the result is the input followed by its reverberant tail (`rt60_s` minus one
/// sample longer), scaled so its active power equals the input's, clipped to 16 bits.
pub fn reverberate(samples: &[i16], rt60_s: f64, rng: &mut NoiseRng) -> Vec<i16> {
    let h = room_impulse_response(rt60_s, rng);
    let x: Vec<f64> = samples.iter().map(|&s| s as f64).collect();
    let y = convolve(&x, &h);
    let p = active_power_f64(&y);
    let gain = if p > 0.0 {
        (active_power(samples) * 32768.0 * 32768.0 / p).sqrt()
    } else {
        0.0
    };
    y.iter()
        .map(|v| (v * gain).round().clamp(-32768.0, 32767.0) as i16)
        .collect()
}

/// [`active_power`] of samples in sample units (not full-scale).
fn active_power_f64(samples: &[f64]) -> f64 {
    let frames: Vec<f64> = samples
        .chunks(160)
        .map(|c| c.iter().map(|x| x * x).sum::<f64>() / c.len() as f64)
        .collect();
    let max = frames.iter().cloned().fold(0.0, f64::max);
    let active: Vec<f64> = frames.into_iter().filter(|&p| p > max * 1e-3).collect();
    if active.is_empty() {
        0.0
    } else {
        active.iter().sum::<f64>() / active.len() as f64
    }
}

/// Linear convolution of `a` and `b` (`a.len() + b.len() - 1` samples; none if either is empty),
/// by one forward and one inverse FFT: both real signals share a complex transform.
fn convolve(a: &[f64], b: &[f64]) -> Vec<f64> {
    use rustfft::{FftPlanner, num_complex::Complex};
    if a.is_empty() || b.is_empty() {
        return Vec::new();
    }
    let len = a.len() + b.len() - 1;
    let size = len.next_power_of_two();
    let mut z = vec![Complex::new(0.0, 0.0); size];
    for (z, &x) in z.iter_mut().zip(a) {
        z.re = x;
    }
    for (z, &x) in z.iter_mut().zip(b) {
        z.im = x;
    }
    let mut planner = FftPlanner::<f64>::new();
    planner.plan_fft_forward(size).process(&mut z);
    // With z = a + ib: A[k] = (Z[k] + Z*[-k]) / 2, B[k] = (Z[k] - Z*[-k]) / 2i, so
    // A[k] B[k] = -i (Z[k]^2 - Z*[-k]^2) / 4.
    let mut c: Vec<Complex<f64>> = (0..size)
        .map(|k| {
            let zk = z[k];
            let zc = z[(size - k) % size].conj();
            (zk * zk - zc * zc) * Complex::new(0.0, -0.25)
        })
        .collect();
    planner.plan_fft_inverse(size).process(&mut c);
    c.iter().take(len).map(|v| v.re / size as f64).collect()
}

/// Removes a constant offset (DC) from a stream, as a cheap microphone or sound card adds: a
/// running mean with a time constant of a quarter second (a first-order high-pass below 1 Hz,
/// far under speech) is subtracted once it is large enough to matter (at least
/// [`DcRemover::MIN_OFFSET`], -54 dBFS). A stream with no offset passes unchanged, sample for
/// sample, so its digital silence stays exact zeros.
///
/// The mean starts from the stream's first 10 ms of sound when the offset dominates them (its
/// size at least their spread around it): an offset there from the start is removed at once,
/// rather than as a sound that decays over a second (which an end-pointer would take for the
/// room's noise, or for speech).
#[derive(Debug, Clone, Default)]
pub struct DcRemover {
    mean: f64,
    /// Whether the first 10 ms of sound were looked at.
    seeded: bool,
}

impl DcRemover {
    /// Time constant of the running mean (samples at 16 kHz: 0.25 s).
    pub const TAU_SAMPLES: f64 = 4000.0;
    /// The smallest offset removed (in sample units).
    pub const MIN_OFFSET: f64 = 64.0;
    /// The first samples of sound the mean may start from (10 ms at 16 kHz), and the fewest.
    const SEED: usize = 160;
    const MIN_SEED: usize = 32;

    /// `samples` without their offset, appended to `out` (cleared first).
    pub fn process(&mut self, samples: &[i16], out: &mut Vec<i16>) {
        out.clear();
        out.reserve(samples.len());
        match self.seed(samples) {
            // The digital silence before the first sound, then the sound from the seeded mean.
            Some((first, mean)) => {
                self.remove(&samples[..first], out);
                self.mean = mean;
                self.remove(&samples[first..], out);
            }
            None => self.remove(samples, out),
        }
    }

    fn remove(&mut self, samples: &[i16], out: &mut Vec<i16>) {
        for &s in samples {
            self.mean += (f64::from(s) - self.mean) / Self::TAU_SAMPLES;
            out.push(if self.mean.abs() < Self::MIN_OFFSET {
                s
            } else {
                (f64::from(s) - self.mean).round().clamp(-32768.0, 32767.0) as i16
            });
        }
    }

    /// Where the stream's first 10 ms of sound start in `samples` (digital silence before them
    /// skipped) and the mean to start from there, if the offset dominates them; nothing if the
    /// mean was started already, or is not to be (and again at the next chunk if this one holds
    /// too little sound to tell).
    fn seed(&mut self, samples: &[i16]) -> Option<(usize, f64)> {
        if self.seeded {
            return None;
        }
        let first = samples.iter().position(|&s| s != 0)?;
        let w = &samples[first..samples.len().min(first + Self::SEED)];
        if w.len() < Self::MIN_SEED {
            return None;
        }
        self.seeded = true;
        let n = w.len() as f64;
        let mean = w.iter().map(|&s| f64::from(s)).sum::<f64>() / n;
        let spread = (w
            .iter()
            .map(|&s| (f64::from(s) - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        (mean.abs() >= Self::MIN_OFFSET && mean.abs() >= spread).then_some((first, mean))
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
mod tests;
