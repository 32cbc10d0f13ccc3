//! Beamformers: one enhanced channel out of an array's channels, frame by frame in the frequency
//! domain, stream-wise ([`super::stft`]).

use rustfft::num_complex::Complex;

use super::geometry::unit;
use super::linalg::HermitianSolver;
use super::stft::{BINS, FRAME, HOP, StftStream, Synthesizer};
use super::{ArrayError, ArrayGeometry, Multichannel, direction};

/// The steering vectors towards `direction` (a unit vector), bin after bin (`0..BINS`), each
/// with one element per microphone: `exp(j ω p·d / c)`, the phase by which a plane wave from
/// there leads at the microphone at `p`, so that `Σ conj(a) X / M` puts the channels back in step.
fn steering(geometry: &ArrayGeometry, direction: [f64; 3]) -> Vec<Complex<f64>> {
    let rate = f64::from(geometry.sample_rate_hz());
    let delays = geometry.delays_s(direction);
    (0..BINS)
        .flat_map(|k| {
            let omega = 2.0 * std::f64::consts::PI * k as f64 * rate / FRAME as f64;
            delays
                .iter()
                .map(move |&t| Complex::from_polar(1.0, -omega * t))
        })
        .collect()
}

/// `direction` as a unit vector, or the error naming it.
fn checked(direction: [f64; 3]) -> Result<[f64; 3], ArrayError> {
    unit(direction).ok_or(ArrayError::BadDirection(direction))
}

/// Delay-and-sum weights: the steering vectors over the number of microphones.
fn delay_and_sum_weights(steering: &[Complex<f64>], mics: usize) -> Vec<Complex<f64>> {
    let gain = 1.0 / mics as f64;
    steering.iter().map(|a| a * gain).collect()
}

/// The output spectrum `Y[k] = Σ_m conj(w[k][m]) X_m[k]` into `y` (bins `0..BINS`).
fn apply(weights: &[Complex<f64>], spectra: &[Vec<Complex<f64>>], y: &mut [Complex<f64>]) {
    let mics = spectra.len();
    for (k, (y, w)) in y.iter_mut().zip(weights.chunks_exact(mics)).enumerate() {
        *y = w.iter().zip(spectra).map(|(w, x)| w.conj() * x[k]).sum();
    }
}

/// The delay-and-sum beamformer: each channel delayed (by a fractional delay, in the frequency
/// domain) so that a plane wave from the steering direction lines up, then the channels
/// averaged. A sound from the steering direction passes unchanged (as heard at the array's
/// origin); others are attenuated, little at low frequencies where the array is small against
/// the wavelength.
///
/// Stream-wise: each call gives as many output samples as its input has per channel, whatever
/// the chunk sizes, [`DelayAndSum::latency_samples`] late.
#[derive(Clone)]
pub struct DelayAndSum {
    stream: StftStream,
    weights: Vec<Complex<f64>>,
}

impl DelayAndSum {
    /// A beamformer for the array `geometry`, steered straight ahead (azimuth 0, elevation 0).
    pub fn new(geometry: &ArrayGeometry) -> Self {
        let weights = delay_and_sum_weights(
            &steering(geometry, direction(0.0, 0.0)),
            geometry.channels(),
        );
        Self {
            stream: StftStream::new(geometry),
            weights,
        }
    }

    /// Steers it towards `direction` (a vector towards the source in the array frame, see
    /// [`super::direction`]; any length but zero). It takes effect from the next frame
    /// ([`DelayAndSum::latency_samples`] apply to it as to the sound).
    pub fn steer(&mut self, direction: [f64; 3]) -> Result<(), ArrayError> {
        let geometry = self.stream.geometry();
        self.weights = delay_and_sum_weights(
            &steering(geometry, checked(direction)?),
            geometry.channels(),
        );
        Ok(())
    }

    /// Beamforms `input` into `out` (cleared first, then as many samples as `input` has per
    /// channel, in the input's units: full-scale 16-bit units for interleaved `i16`).
    pub fn process(
        &mut self,
        input: Multichannel<'_>,
        out: &mut Vec<f32>,
    ) -> Result<(), ArrayError> {
        let weights = &self.weights;
        self.stream
            .process(input, out, |spectra, y| apply(weights, spectra, y))
    }

    /// How late the output is against the input (samples at the geometry's rate).
    pub fn latency_samples(&self) -> usize {
        Synthesizer::LATENCY
    }
}

/// The minimum-variance distortionless-response (MVDR) beamformer: per frequency, the weights
/// that pass a plane wave from the steering direction unchanged and let through as little as
/// possible of the noise, `w = R⁻¹a / (aᴴR⁻¹a)`, with `R` the noise's covariance across
/// microphones. It can put a deep null on a directional interferer (a fan, a television, another
/// talker) where delay-and-sum only attenuates it a little.
///
/// `R` is learned, per frequency bin, by exponential averaging (time constant
/// [`Mvdr::NOISE_TIME_CONSTANT_S`]) over the frames of the calls the caller marks as target
/// silent, and loaded on its diagonal by [`Mvdr::DIAGONAL_LOADING`] of its trace so that a small
/// error in the array's geometry or the steering does not cancel the target. Until
/// [`Mvdr::MIN_NOISE_FRAMES`] such frames were seen it works as [`DelayAndSum`].
///
/// Stream-wise as [`DelayAndSum`], with the same latency.
#[derive(Clone)]
pub struct Mvdr {
    stream: StftStream,
    noise: NoiseModel,
}

impl Mvdr {
    /// The target-silent frames needed before the weights adapt (about 0.26 s at 16 kHz).
    pub const MIN_NOISE_FRAMES: usize = 16;
    /// The fraction of the trace of the noise covariance added to its diagonal.
    pub const DIAGONAL_LOADING: f64 = 0.01;
    /// The time constant of the noise covariance's exponential average (seconds of
    /// target-silent audio).
    pub const NOISE_TIME_CONSTANT_S: f64 = 1.0;

    /// A beamformer for the array `geometry`, steered straight ahead, with no noise learned yet.
    pub fn new(geometry: &ArrayGeometry) -> Self {
        let mics = geometry.channels();
        let steering = steering(geometry, direction(0.0, 0.0));
        let hop_s = HOP as f64 / f64::from(geometry.sample_rate_hz());
        Self {
            stream: StftStream::new(geometry),
            noise: NoiseModel {
                mics,
                weights: delay_and_sum_weights(&steering, mics),
                steering,
                covariance: vec![Complex::default(); BINS * mics * mics],
                frames: 0,
                forget: (-hop_s / Self::NOISE_TIME_CONSTANT_S).exp(),
                solver: HermitianSolver::new(mics),
                loaded: vec![Complex::default(); mics * mics],
            },
        }
    }

    /// Steers it towards `direction` (as [`DelayAndSum::steer`]); what it learned of the noise
    /// is kept.
    pub fn steer(&mut self, direction: [f64; 3]) -> Result<(), ArrayError> {
        self.noise.steering = steering(self.stream.geometry(), checked(direction)?);
        self.noise.update_weights();
        Ok(())
    }

    /// Beamforms `input` into `out` (as [`DelayAndSum::process`]). `target_active` says whether
    /// the target may be sounding in this chunk: when false, the frames the chunk completes
    /// update the noise covariance first. A frame spans the last 512 samples, so mark a chunk
    /// silent only once the target has been silent for that long (32 ms at 16 kHz): a target
    /// learned as noise is what MVDR cancels.
    pub fn process(
        &mut self,
        input: Multichannel<'_>,
        target_active: bool,
        out: &mut Vec<f32>,
    ) -> Result<(), ArrayError> {
        let noise = &mut self.noise;
        self.stream.process(input, out, |spectra, y| {
            if !target_active {
                noise.learn(spectra);
            }
            apply(&noise.weights, spectra, y);
        })
    }

    /// How late the output is against the input (samples at the geometry's rate).
    pub fn latency_samples(&self) -> usize {
        Synthesizer::LATENCY
    }

    /// How many target-silent frames it has learned the noise from.
    pub fn noise_frames(&self) -> usize {
        self.noise.frames
    }
}

/// The noise covariance of an [`Mvdr`] and the weights it gives.
#[derive(Clone)]
struct NoiseModel {
    mics: usize,
    /// Steering vectors, bin after bin.
    steering: Vec<Complex<f64>>,
    /// The weights in use, bin after bin.
    weights: Vec<Complex<f64>>,
    /// The noise covariance matrices, bin after bin, each `mics x mics` row-major.
    covariance: Vec<Complex<f64>>,
    /// Target-silent frames seen.
    frames: usize,
    /// The weight of the past in the exponential average, per frame.
    forget: f64,
    solver: HermitianSolver,
    /// A loaded covariance matrix (scratch).
    loaded: Vec<Complex<f64>>,
}

impl NoiseModel {
    /// Adds a target-silent frame to the covariance, and updates the weights.
    fn learn(&mut self, spectra: &[Vec<Complex<f64>>]) {
        let m = self.mics;
        let (old, new) = (self.forget, 1.0 - self.forget);
        for (k, r) in self.covariance.chunks_exact_mut(m * m).enumerate() {
            for i in 0..m {
                for j in 0..m {
                    let x = spectra[i][k] * spectra[j][k].conj();
                    r[i * m + j] = r[i * m + j] * old + x * new;
                }
            }
        }
        self.frames += 1;
        self.update_weights();
    }

    /// MVDR weights for every bin, or delay-and-sum ones until enough noise was seen (and in a
    /// bin where the noise gives no usable matrix, e.g. digital silence).
    fn update_weights(&mut self) {
        let m = self.mics;
        if self.frames < Mvdr::MIN_NOISE_FRAMES {
            self.weights = delay_and_sum_weights(&self.steering, m);
            return;
        }
        let das_gain = 1.0 / m as f64;
        for ((r, a), w) in self
            .covariance
            .chunks_exact(m * m)
            .zip(self.steering.chunks_exact(m))
            .zip(self.weights.chunks_exact_mut(m))
        {
            let trace: f64 = (0..m).map(|i| r[i * m + i].re).sum();
            let loading = Mvdr::DIAGONAL_LOADING * trace;
            self.loaded.copy_from_slice(r);
            for i in 0..m {
                self.loaded[i * m + i] += loading;
            }
            // w = R⁻¹a / (aᴴR⁻¹a); aᴴR⁻¹a is real and positive for a positive definite R.
            let solved = trace > 0.0 && self.solver.solve(&self.loaded, a, w);
            let gain: Complex<f64> = a.iter().zip(w.iter()).map(|(a, z)| a.conj() * z).sum();
            if solved && gain.re > 0.0 && gain.re.is_finite() {
                for z in w.iter_mut() {
                    *z /= gain.re;
                }
            } else {
                for (z, a) in w.iter_mut().zip(a) {
                    *z = a * das_gain;
                }
            }
        }
    }
}
