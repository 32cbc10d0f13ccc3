//! What an array hears: the channels a far source gives, for tests and simulators.

use rustfft::{FftPlanner, num_complex::Complex};

use super::geometry::unit;
use super::{ArrayError, ArrayGeometry};

/// Samples of margin past the signal and the largest delay, for the tails of the fractional
/// delays to die out in rather than wrap around onto the signal.
const MARGIN: usize = 1024;

/// The channels of `geometry` (one per microphone, in channel order, each as long as `mono`) for
/// a plane wave from `direction` (a vector towards the source in the array frame, any length but
/// zero, see [`super::direction`]) carrying `mono` (sampled at `sample_rate_hz`, usually the
/// geometry's rate) as it passes the origin of the array frame. Each microphone hears it
/// [`ArrayGeometry::delays_s`] early or late, delayed exactly (a linear phase in the frequency
/// domain, so fractional delays are exact for a band-limited signal). Before the wave's start the
/// microphones that hear it early already have its first samples.
pub fn render_plane_wave(
    geometry: &ArrayGeometry,
    mono: &[f64],
    direction: [f64; 3],
    sample_rate_hz: f64,
) -> Result<Vec<Vec<f64>>, ArrayError> {
    let direction = unit(direction).ok_or(ArrayError::BadDirection(direction))?;
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(ArrayError::BadRate(sample_rate_hz));
    }
    if mono.is_empty() {
        return Ok(vec![Vec::new(); geometry.channels()]);
    }
    let delays = geometry.delays_s(direction);
    let longest = delays.iter().fold(0.0, |m: f64, d| m.max(d.abs()));
    let size =
        (mono.len() + (longest * sample_rate_hz).ceil() as usize + MARGIN).next_power_of_two();
    let mut planner = FftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(size);
    let ifft = planner.plan_fft_inverse(size);
    let mut spectrum: Vec<Complex<f64>> = mono
        .iter()
        .map(|&x| Complex::new(x, 0.0))
        .chain(std::iter::repeat(Complex::default()))
        .take(size)
        .collect();
    fft.process(&mut spectrum);
    let half = size / 2;
    Ok(delays
        .iter()
        .map(|&delay| {
            let mut channel: Vec<Complex<f64>> = spectrum
                .iter()
                .enumerate()
                .map(|(k, &x)| {
                    // Signed frequency of bin k (cycles per sample); the Nyquist bin is delayed
                    // by its real part only, as a real signal's must be.
                    let f = if k < half {
                        k as f64
                    } else {
                        k as f64 - size as f64
                    } / size as f64;
                    let phase = -2.0 * std::f64::consts::PI * f * delay * sample_rate_hz;
                    if k == half {
                        x * phase.cos()
                    } else {
                        x * Complex::from_polar(1.0, phase)
                    }
                })
                .collect();
            ifft.process(&mut channel);
            channel
                .iter()
                .take(mono.len())
                .map(|c| c.re / size as f64)
                .collect()
        })
        .collect())
}
