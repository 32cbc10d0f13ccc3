//! Where a sound comes from: the steered response power with phase transform (SRP-PHAT) over a
//! grid of azimuths, from the generalized cross-correlations (GCC-PHAT) of all microphone pairs.

use std::{ops::Range, sync::Arc};

use rustfft::{Fft, FftPlanner, num_complex::Complex};

use super::geometry::dot;
use super::stft::{Analyzer, BINS, FRAME, HOP};
use super::{ArrayError, ArrayGeometry, Multichannel, SPEED_OF_SOUND_M_S, direction};

/// How finely the cross-correlations are interpolated (times the sample rate).
const UPSAMPLE: usize = 8;
/// The band used (Hz): below it, rumble and the array's small size make phases meaningless.
const LOW_HZ: f64 = 100.0;
/// How far above the noise floor a frame's energy must be to count (dB).
const ACTIVE_DB: f64 = 3.0;
/// How fast the noise floor may rise while there is sound over it (dB per second).
const FLOOR_RISE_DB_PER_S: f64 = 3.0;
/// How far (a fraction, in dB) the noise floor moves towards a background frame's energy.
const FLOOR_FOLLOW: f64 = 0.2;
/// The weight of a new frame's energy in the smoothed energy.
const ENERGY_SMOOTHING: f64 = 0.5;
/// The first frames of sound of a stream, which only set the noise floor (the loudest of their
/// smoothed energies): the very first is partly the silence before the stream.
const WARM_UP_FRAMES: usize = 8;

/// Where a block's dominant sound came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Localization {
    /// The azimuth of the source (radians in (-π, π], 0 straight ahead, positive to the left). For
    /// a linear array, the frontal one of the two mirror images it cannot tell apart.
    pub azimuth_rad: f64,
    /// The steered response power there, normalized to 1 for a single source heard by every
    /// microphone pair in phase at every frequency of every frame used, and about 0 for sound
    /// that is not coherent across the array (diffuse noise).
    pub power: f64,
    /// How far the peak rises above the mean of the azimuth map, as a fraction of the way from
    /// that mean to a perfect peak of 1 (0 to 1).
    pub confidence: f64,
}

/// The SRP-PHAT localizer: over each block of audio given to [`SrpPhat::locate`] (100-200 ms is
/// a good size), the frames louder than the noise floor by 3 dB are cut into frequency bins
/// (100 Hz to Nyquist), each microphone pair's cross-spectrum is whitened (PHAT: only its phase
/// is kept) and summed, and the azimuth whose time differences of arrival best fit all pairs
/// wins. Sources are taken to be far and in the horizontal plane of the array frame.
///
/// The noise floor is learned from the stream itself, never an absolute level. Frames count
/// when their energy (smoothed over about three frames) is 3 dB over the floor. The floor starts
/// at the loudest of the stream's first 8 frames of sound (about 130 ms at 16 kHz); a frame that
/// does not count moves it a fifth of the way (in dB) to its energy, so it settles on the
/// background's typical level within about 100 ms; under sound that counts, it rises by at most
/// 3 dB a second. So a steady background (a fan, a room's hum) is not reported, and a talker is
/// once they are 3 dB louder than it. Digital silence (exact zeros) neither counts nor moves the
/// floor.
///
/// A linear array cannot tell a source from its mirror image across the array's line (for an
/// array along y: front from back); its localizations are folded to the frontal image (the one
/// with the larger x).
#[derive(Clone)]
pub struct SrpPhat {
    analyzer: Analyzer,
    accumulator: Accumulator,
    azimuths: Vec<f64>,
    /// For each azimuth, each pair's time difference of arrival (upsampled samples).
    lags: Vec<f64>,
    ifft: Arc<dyn Fft<f64>>,
    gcc: Vec<Complex<f64>>,
    scratch: Vec<Complex<f64>>,
    /// For a linear array, the azimuth of its line in the horizontal plane (radians).
    line_azimuth: Option<f64>,
}

impl SrpPhat {
    /// A localizer for the array `geometry` that tries the azimuths of `azimuths_rad`, e.g.
    /// [`SrpPhat::default_grid`]. An empty grid or a non-finite azimuth is an error.
    pub fn new(geometry: &ArrayGeometry, azimuths_rad: Vec<f64>) -> Result<Self, ArrayError> {
        if azimuths_rad.is_empty() || azimuths_rad.iter().any(|a| !a.is_finite()) {
            return Err(ArrayError::BadGrid);
        }
        let rate = f64::from(geometry.sample_rate_hz());
        let pairs: Vec<(usize, usize)> = geometry.pairs().collect();
        let samples_per_s = rate * UPSAMPLE as f64;
        let lags = azimuths_rad
            .iter()
            .flat_map(|&az| {
                let d = direction(az, 0.0);
                pairs.iter().map(move |&(i, j)| {
                    // The cross-spectrum X_i X_j* has the phase ω (p_i - p_j)·d / c: its
                    // correlation peaks at the lag -(p_i - p_j)·d / c.
                    let lead_s =
                        (dot(geometry.mic(i), d) - dot(geometry.mic(j), d)) / SPEED_OF_SOUND_M_S;
                    -lead_s * samples_per_s
                })
            })
            .collect();
        let low = (LOW_HZ * FRAME as f64 / rate).ceil() as usize;
        let ifft = FftPlanner::new().plan_fft_inverse(FRAME * UPSAMPLE);
        let line_azimuth = geometry.linear_axis().and_then(|u| {
            let horizontal = u[0].hypot(u[1]);
            (horizontal > 1e-6).then(|| u[1].atan2(u[0]))
        });
        Ok(Self {
            analyzer: Analyzer::new(geometry),
            accumulator: Accumulator {
                band: low.max(1)..BINS - 1,
                cross: vec![Complex::default(); pairs.len() * BINS],
                pairs,
                active_frames: 0,
                energy: 0.0,
                floor: 0.0,
                sound_frames: 0,
                floor_rise: 10f64.powf(FLOOR_RISE_DB_PER_S / 10.0 * HOP as f64 / rate),
            },
            azimuths: azimuths_rad,
            lags,
            scratch: vec![Complex::default(); ifft.get_inplace_scratch_len()],
            gcc: vec![Complex::default(); FRAME * UPSAMPLE],
            ifft,
            line_azimuth,
        })
    }

    /// One-degree steps over [-180°, 180°) (radians). For a linear array along y, the steps over
    /// [-90°, 90°] give the same localizations for half the work.
    pub fn default_grid() -> Vec<f64> {
        (-180..180).map(|deg| f64::from(deg).to_radians()).collect()
    }

    /// Where the dominant sound of `block` comes from; nothing when none of its frames is above
    /// the noise floor (silence, or only the steady background). Frames straddling two blocks
    /// count in the second.
    pub fn locate(&mut self, block: Multichannel<'_>) -> Result<Option<Localization>, ArrayError> {
        let accumulator = &mut self.accumulator;
        accumulator.start_block();
        self.analyzer
            .push(block, |spectra| accumulator.add_frame(spectra))?;
        if accumulator.active_frames == 0 {
            return Ok(None);
        }
        let mut map = vec![0.0; self.azimuths.len()];
        let pairs = accumulator.pairs.len();
        for (p, cross) in accumulator.cross.chunks_exact(BINS).enumerate() {
            // The one-sided inverse transform: its real part is the cross-correlation, each bin
            // counting at most 1 per frame.
            self.gcc.fill(Complex::default());
            let band = accumulator.band.clone();
            self.gcc[band.clone()].copy_from_slice(&cross[band]);
            self.ifft
                .process_with_scratch(&mut self.gcc, &mut self.scratch);
            for (value, lags) in map.iter_mut().zip(self.lags.chunks_exact(pairs)) {
                *value += interpolate(&self.gcc, lags[p]);
            }
        }
        let norm = (accumulator.active_frames * accumulator.band.len() * pairs) as f64;
        map.iter_mut().for_each(|v| *v /= norm);
        let Some((best, &power)) = map.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
            return Ok(None);
        };
        let mean = map.iter().sum::<f64>() / map.len() as f64;
        let confidence = ((power - mean) / (1.0 - mean).max(1e-12)).clamp(0.0, 1.0);
        Ok(Some(Localization {
            azimuth_rad: self.frontal(self.azimuths[best]),
            power,
            confidence,
        }))
    }

    /// `azimuth` wrapped into (-π, π] and, for a linear array, folded to the frontal one of it
    /// and its mirror image across the array's line.
    fn frontal(&self, azimuth: f64) -> f64 {
        let candidate = match self.line_azimuth {
            Some(line) => {
                let mirror = 2.0 * line - azimuth;
                if mirror.cos() > azimuth.cos() + 1e-9 {
                    mirror
                } else {
                    azimuth
                }
            }
            None => azimuth,
        };
        let wrapped = candidate.sin().atan2(candidate.cos());
        if wrapped <= -std::f64::consts::PI {
            std::f64::consts::PI
        } else {
            wrapped
        }
    }
}

/// The real part of `gcc` at the fractional, possibly negative index `lag` (circular), by linear
/// interpolation.
fn interpolate(gcc: &[Complex<f64>], lag: f64) -> f64 {
    let len = gcc.len();
    let at = lag.rem_euclid(len as f64);
    let below = at.floor();
    let frac = at - below;
    let i = below as usize % len;
    let j = (i + 1) % len;
    gcc[i].re * (1.0 - frac) + gcc[j].re * frac
}

/// The whitened cross-spectra of a block's active frames, and the noise floor.
#[derive(Clone)]
struct Accumulator {
    pairs: Vec<(usize, usize)>,
    /// The bins used.
    band: Range<usize>,
    /// Per pair, the sum of the frames' whitened cross-spectra (bins `0..BINS`).
    cross: Vec<Complex<f64>>,
    /// Frames of the current block above the floor.
    active_frames: usize,
    /// The frames' energy in the band, summed over channels, smoothed.
    energy: f64,
    /// The noise floor (as `energy`).
    floor: f64,
    /// Frames of sound seen, up to [`WARM_UP_FRAMES`].
    sound_frames: usize,
    /// The most the floor may rise in a frame (a factor).
    floor_rise: f64,
}

impl Accumulator {
    fn start_block(&mut self) {
        self.cross.fill(Complex::default());
        self.active_frames = 0;
    }

    fn add_frame(&mut self, spectra: &[Vec<Complex<f64>>]) {
        let energy: f64 = spectra
            .iter()
            .map(|x| {
                x[self.band.clone()]
                    .iter()
                    .map(|c| c.norm_sqr())
                    .sum::<f64>()
            })
            .sum();
        if !(energy > 0.0 && energy.is_finite()) {
            return;
        }
        self.energy = if self.sound_frames == 0 {
            energy
        } else {
            self.energy + (energy - self.energy) * ENERGY_SMOOTHING
        };
        if self.sound_frames < WARM_UP_FRAMES {
            self.sound_frames += 1;
            self.floor = self.floor.max(self.energy);
            return;
        }
        let active = self.energy > self.floor * 10f64.powf(ACTIVE_DB / 10.0);
        self.floor = if active {
            self.floor * self.floor_rise
        } else {
            self.floor * (self.energy / self.floor).powf(FLOOR_FOLLOW)
        };
        if !active {
            return;
        }
        self.active_frames += 1;
        for (&(i, j), cross) in self.pairs.iter().zip(self.cross.chunks_exact_mut(BINS)) {
            for k in self.band.clone() {
                let g = spectra[i][k] * spectra[j][k].conj();
                let magnitude = g.norm();
                if magnitude > f64::MIN_POSITIVE {
                    cross[k] += g / magnitude;
                }
            }
        }
    }
}
