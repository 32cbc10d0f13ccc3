//! What an array hears in a reverberant room: the image-source method (Allen & Berkley, 1979)
//! in a shoebox room, for tests and simulators.
//!
//! [`ShoeboxRoom`] is a rectangular room whose six walls absorb the same share of the sound's
//! energy; [`ShoeboxRoom::rir`] is the impulse response from a point source to a point microphone
//! in it, [`ShoeboxRoom::render`] what each microphone of an array hears of several talkers.
//!
//! It is built to agree sample by sample with pyroomacoustics' `ShoeBox` with image sources only
//! (no air absorption, no ray tracing), which the crate's tests check it against: the same
//! inversion of Sabine's formula, the same fractional delays ([`FRAC_DELAY_TAPS`]-tap
//! Hann-windowed sinc), the same global delay ([`RIR_DELAY_SAMPLES`]) and the same
//! [`HIGH_PASS_HZ`] high-pass filter. One convention differs: a path of `r` metres has the
//! free-field amplitude `1 / (4 π r)` here, where pyroomacoustics leaves out the `4 π`.

use std::f64::consts::PI;

use rustfft::{FftPlanner, num_complex::Complex};

use super::sim::RoomError;
use super::{ArrayError, ArrayGeometry, SPEED_OF_SOUND_M_S};

/// The length of the windowed sinc that places each reflection between samples (taps; odd).
/// pyroomacoustics' default (`frac_delay_length`).
pub const FRAC_DELAY_TAPS: usize = 81;

/// How late every impulse response (and so every rendered channel) is, in samples, on top of the
/// time sound takes to travel: the half-length of the fractional-delay filter, so that a path of
/// zero length would still fit its whole filter after sample 0. pyroomacoustics' global delay.
pub const RIR_DELAY_SAMPLES: usize = FRAC_DELAY_TAPS / 2;

/// The cut-off of the high-pass filter applied to every impulse response (Hz; second-order
/// Butterworth, run forwards and backwards, so zero-phase and fourth-order in effect).
///
/// Every image contributes a positive pulse, so the late tail, where thousands of images land in
/// each sample, rides on a slowly varying positive offset that real rooms do not have (Allen &
/// Berkley point it out). Left in, that offset makes the decay look far slower than the walls'
/// absorption implies. pyroomacoustics removes it with this filter by default; so does this
/// module.
pub const HIGH_PASS_HZ: f64 = 10.0;

/// The most orders of reflections a room may ask for: about 36 million images, some 3 billion
/// filter taps per impulse response.
pub const MAX_ORDER: usize = 300;

/// The closest a source may be to a microphone (m): closer, a point source is no model of a
/// talker, and the amplitude `1 / (4 π r)` grows without bound.
const MIN_DISTANCE_M: f64 = 0.01;

/// A rectangular room, from the corner at the origin to `dims_m`, in the room's own frame
/// (metres; z up). Every wall absorbs the same share of the energy of the sound that hits it and
/// reflects the rest specularly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShoeboxRoom {
    /// Length, width and height (m), all finite and positive.
    pub dims_m: [f64; 3],
    /// The share of the energy every wall absorbs at each reflection, from 0 (a perfect mirror)
    /// to 1 (anechoic). Each reflection scales the amplitude by `(1 - absorption).sqrt()`.
    pub absorption: f64,
    /// The most reflections a path may have: images up to this order are summed, the later
    /// ones left out. Up to [`MAX_ORDER`].
    pub max_order: usize,
}

/// A talker in a [`ShoeboxRoom`]: where it is and what it says.
#[derive(Debug, Clone, Copy)]
pub struct RoomSource<'a> {
    /// Its position in the room's frame (m).
    pub position_m: [f64; 3],
    /// Its signal, mono, at the rate of the array that listens (any unit: the channels are in
    /// the same unit, as heard at the microphones).
    pub signal: &'a [f64],
}

impl ShoeboxRoom {
    /// A room of `dims_m` (m) whose walls absorb `absorption` (0 to 1) of the energy, summing
    /// images up to `max_order` reflections. Checked as [`ShoeboxRoom::rir`] would check it.
    pub fn new(dims_m: [f64; 3], absorption: f64, max_order: usize) -> Result<Self, RoomError> {
        let room = Self {
            dims_m,
            absorption,
            max_order,
        };
        room.check()?;
        Ok(room)
    }

    /// The room of `dims_m` (m) that reverberates for `rt60_s` (s, the time sound takes to fade
    /// by 60 dB) by Sabine's formula, as pyroomacoustics' `inverse_sabine` makes it: the
    /// absorption `24 ln(10) V / (c S RT60)` (V the volume, S the walls' area), and the order
    /// that takes in every image closer than `c RT60`, the radius of the largest sphere that fits
    /// in the diamond-shaped pile of images of that order.
    ///
    /// An image-source room decays at the rate of Sabine's formula only roughly (its sound field
    /// is not diffuse): in the tests, in a 6 x 5 x 3 m room, a T20 (high-passed response) 1 to
    /// 8 % short of 0.3 s and 8 to 11 % over 0.6 s, depending on where source and microphone are.
    ///
    /// Errors: dimensions that are not finite and positive, an RT60 that is not, an RT60 too
    /// short for the room (the walls would have to absorb more than all the energy), an RT60 so
    /// long that it would take more than [`MAX_ORDER`] orders.
    pub fn for_rt60(dims_m: [f64; 3], rt60_s: f64) -> Result<Self, RoomError> {
        check_dims(dims_m)?;
        if !(rt60_s.is_finite() && rt60_s > 0.0) {
            return Err(RoomError::BadRt60(rt60_s));
        }
        let [x, y, z] = dims_m;
        let volume = x * y * z;
        let surface = 2.0 * (x * y + x * z + y * z);
        let absorption = 24.0 * 10f64.ln() * volume / (SPEED_OF_SOUND_M_S * surface * rt60_s);
        if absorption > 1.0 {
            return Err(RoomError::Rt60TooShort {
                dims_m,
                rt60_s,
                absorption,
            });
        }
        // The distance from the source's room to the nearest edge of the diamond of images of
        // order N grows by one of these per order: the smallest over the three pairs of sides.
        let radius = [(x, y), (x, z), (y, z)]
            .iter()
            .map(|&(a, b)| a * b / (a * a + b * b).sqrt())
            .fold(f64::INFINITY, f64::min);
        let order = (SPEED_OF_SOUND_M_S * rt60_s / radius - 1.0).ceil().max(0.0);
        if order > MAX_ORDER as f64 {
            return Err(RoomError::OrderTooHigh {
                max_order: order as usize,
                limit: MAX_ORDER,
            });
        }
        Self::new(dims_m, absorption, order as usize)
    }

    /// The reverberation time Sabine's formula gives the room (s): what [`ShoeboxRoom::for_rt60`]
    /// inverts.
    pub fn sabine_rt60_s(&self) -> f64 {
        let [x, y, z] = self.dims_m;
        let surface = 2.0 * (x * y + x * z + y * z);
        24.0 * 10f64.ln() * x * y * z / (SPEED_OF_SOUND_M_S * surface * self.absorption)
    }

    /// The room impulse response from a point source at `source_m` to a point microphone at
    /// `mic_m` (both in the room's frame, m, inside the room, at least 1 cm apart), sampled at
    /// `rate_hz`: [`ShoeboxRoom::image_rir`] high-passed at [`HIGH_PASS_HZ`] (zero-phase, as
    /// pyroomacoustics does by default). Its length and delay are those of `image_rir`.
    pub fn rir(
        &self,
        source_m: [f64; 3],
        mic_m: [f64; 3],
        rate_hz: f64,
    ) -> Result<Vec<f64>, RoomError> {
        let rir = self.image_rir(source_m, mic_m, rate_hz)?;
        Ok(high_pass(&rir, rate_hz))
    }

    /// The room impulse response by the image-source method alone (no high-pass): every image
    /// of the source up to [`ShoeboxRoom::max_order`] reflections, at distance `r` with `n`
    /// reflections, adds a pulse of amplitude `(1 - absorption).sqrt()^n / (4 π r)` arriving
    /// `r / c` seconds ([`SPEED_OF_SOUND_M_S`]) plus [`RIR_DELAY_SAMPLES`] samples after sample 0,
    /// placed between samples by a sinc at the exact arrival, cut to [`FRAC_DELAY_TAPS`] taps by a
    /// Hann window centred on the sample at or before the arrival. The response runs to a little past the last image's filter,
    /// as pyroomacoustics' does (`ceil(t_max rate + RIR_DELAY_SAMPLES + 1) + 1` samples, `t_max`
    /// the latest arrival with the delay). A source's signal convolved with it is what the
    /// microphone hears, in the signal's unit: `1 / (4 π)` of it at 1 m in free field.
    pub fn image_rir(
        &self,
        source_m: [f64; 3],
        mic_m: [f64; 3],
        rate_hz: f64,
    ) -> Result<Vec<f64>, RoomError> {
        self.check()?;
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(ArrayError::BadRate(rate_hz).into());
        }
        self.check_inside("source".to_owned(), source_m)?;
        self.check_inside("microphone".to_owned(), mic_m)?;
        if distance(source_m, mic_m) < MIN_DISTANCE_M {
            return Err(RoomError::SameSpot {
                source_m,
                mic_m,
                min_m: MIN_DISTANCE_M,
            });
        }
        let window = hann();
        let half = RIR_DELAY_SAMPLES as f64;
        let transmission = (1.0 - self.absorption).sqrt();
        let gains: Vec<f64> = std::iter::successors(Some(1.0), |g| Some(g * transmission))
            .take(self.max_order + 1)
            .collect();
        let order = self.max_order as i64;
        let mut rir = Vec::new();
        let mut latest = 0.0f64;
        // The images are the points of the L1 ball of radius max_order in the lattice of
        // mirrored rooms: `n[d]` rooms away along axis d, reflected `|n[d]|` times off its walls.
        for nz in -order..=order {
            let ny_max = order - nz.abs();
            for ny in -ny_max..=ny_max {
                let nx_max = ny_max - ny.abs();
                for nx in -nx_max..=nx_max {
                    let n = [nx, ny, nz];
                    let image: [f64; 3] = std::array::from_fn(|d| {
                        // An odd number of reflections mirrors the source within its room.
                        let within = if n[d] % 2 == 0 {
                            source_m[d]
                        } else {
                            self.dims_m[d] - source_m[d]
                        };
                        n[d] as f64 * self.dims_m[d] + within
                    });
                    let r = distance(image, mic_m);
                    let reflections = (nx.abs() + ny.abs() + nz.abs()) as usize;
                    let amplitude = gains[reflections] / (4.0 * PI * r);
                    let arrival = r / SPEED_OF_SOUND_M_S * rate_hz + half;
                    latest = latest.max(arrival);
                    add_pulse(&mut rir, arrival, amplitude, &window);
                }
            }
        }
        let len = (latest + half + 1.0).ceil() as usize + 1;
        rir.resize(len.max(rir.len()), 0.0);
        Ok(rir)
    }

    /// What each microphone of `geometry` hears of `sources` in the room (one channel per
    /// microphone, in channel order, at the geometry's rate): each source's signal convolved with
    /// its impulse response ([`ShoeboxRoom::rir`]) to that microphone, summed over the sources.
    ///
    /// The array's frame (x forward, y left, z up) has its origin at `centre_m` (room frame, m)
    /// and is turned by `yaw_rad` about the vertical (0: forward is the room's +x, positive
    /// towards +y). Every channel has the length of the longest of the full convolutions (a
    /// source's signal length plus its longest impulse response's, less one); a sound at sample `k` of a signal reaches a microphone `r`
    /// metres away at sample `k + r / c * rate + RIR_DELAY_SAMPLES` (fractional). The convolutions
    /// are done by FFT; memory grows as (sources + 1) x the channels' length rounded up to a
    /// power of two, in complex numbers.
    pub fn render(
        &self,
        geometry: &ArrayGeometry,
        centre_m: [f64; 3],
        yaw_rad: f64,
        sources: &[RoomSource<'_>],
    ) -> Result<Vec<Vec<f64>>, RoomError> {
        let rate_hz = f64::from(geometry.sample_rate_hz());
        let (sin, cos) = yaw_rad.sin_cos();
        let mics: Vec<[f64; 3]> = geometry
            .mics()
            .iter()
            .map(|p| {
                [
                    centre_m[0] + cos * p[0] - sin * p[1],
                    centre_m[1] + sin * p[0] + cos * p[1],
                    centre_m[2] + p[2],
                ]
            })
            .collect();
        // Checked up front so that the error names which microphone or source is out.
        for (i, &m) in mics.iter().enumerate() {
            self.check_inside(format!("microphone {i} of the array"), m)?;
        }
        for (i, s) in sources.iter().enumerate() {
            self.check_inside(format!("source {i}"), s.position_m)?;
        }
        let talking: Vec<&RoomSource<'_>> =
            sources.iter().filter(|s| !s.signal.is_empty()).collect();
        // rirs[source][mic]
        let rirs: Vec<Vec<Vec<f64>>> = talking
            .iter()
            .map(|s| {
                mics.iter()
                    .map(|&m| self.rir(s.position_m, m, rate_hz))
                    .collect()
            })
            .collect::<Result<_, _>>()?;
        let len = talking
            .iter()
            .zip(&rirs)
            .map(|(s, r)| s.signal.len() + r.iter().map(Vec::len).max().unwrap_or(1) - 1)
            .max()
            .unwrap_or(0);
        if len == 0 {
            return Ok(vec![Vec::new(); mics.len()]);
        }
        // A circular convolution this long is the linear one: nothing wraps around.
        let size = len.next_power_of_two();
        let mut planner = FftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(size);
        let ifft = planner.plan_fft_inverse(size);
        let spectrum = |x: &[f64]| {
            let mut s: Vec<Complex<f64>> = x
                .iter()
                .map(|&v| Complex::new(v, 0.0))
                .chain(std::iter::repeat(Complex::default()))
                .take(size)
                .collect();
            fft.process(&mut s);
            s
        };
        let signals: Vec<Vec<Complex<f64>>> = talking.iter().map(|s| spectrum(s.signal)).collect();
        Ok((0..mics.len())
            .map(|m| {
                let mut sum = vec![Complex::default(); size];
                for (signal, rirs) in signals.iter().zip(&rirs) {
                    for ((acc, x), h) in sum.iter_mut().zip(signal).zip(spectrum(&rirs[m])) {
                        *acc += x * h;
                    }
                }
                ifft.process(&mut sum);
                sum.iter().take(len).map(|c| c.re / size as f64).collect()
            })
            .collect())
    }

    fn check(&self) -> Result<(), RoomError> {
        check_dims(self.dims_m)?;
        if !(0.0..=1.0).contains(&self.absorption) {
            return Err(RoomError::BadAbsorption(self.absorption));
        }
        if self.max_order > MAX_ORDER {
            return Err(RoomError::OrderTooHigh {
                max_order: self.max_order,
                limit: MAX_ORDER,
            });
        }
        Ok(())
    }

    /// Strictly inside: a point on a wall coincides with its own image.
    fn check_inside(&self, what: String, position_m: [f64; 3]) -> Result<(), RoomError> {
        let inside = position_m
            .iter()
            .zip(self.dims_m)
            .all(|(&p, l)| p > 0.0 && p < l);
        if inside {
            Ok(())
        } else {
            Err(RoomError::Outside {
                what,
                position_m,
                dims_m: self.dims_m,
            })
        }
    }
}

fn check_dims(dims_m: [f64; 3]) -> Result<(), RoomError> {
    if dims_m.iter().all(|d| d.is_finite() && *d > 0.0) {
        Ok(())
    } else {
        Err(RoomError::BadDimensions(dims_m))
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The Hann window of the fractional-delay filter, zero at both ends (pyroomacoustics' own).
fn hann() -> [f64; FRAC_DELAY_TAPS] {
    std::array::from_fn(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / (FRAC_DELAY_TAPS - 1) as f64).cos())
}

/// Adds to `rir` a pulse of `amplitude` arriving at `arrival` (samples, at least
/// [`RIR_DELAY_SAMPLES`]): the windowed sinc `w[k] sinc(k - half - frac)` on the samples
/// `floor(arrival) - half + k`, growing `rir` as needed.
fn add_pulse(rir: &mut Vec<f64>, arrival: f64, amplitude: f64, window: &[f64; FRAC_DELAY_TAPS]) {
    let whole = arrival.floor();
    let frac = arrival - whole;
    let start = whole as usize - RIR_DELAY_SAMPLES;
    if rir.len() < start + FRAC_DELAY_TAPS {
        rir.resize(start + FRAC_DELAY_TAPS, 0.0);
    }
    // sin(π (m - frac)) is -(-1)^m sin(π frac) for a whole m: one sine per pulse, not per tap
    // (m = k - half has the parity of k, half being even).
    let sine = (PI * frac).sin();
    for (k, (out, w)) in rir[start..start + FRAC_DELAY_TAPS]
        .iter_mut()
        .zip(window)
        .enumerate()
    {
        let x = k as f64 - RIR_DELAY_SAMPLES as f64 - frac;
        let sinc = if x == 0.0 {
            1.0
        } else if k % 2 == 0 {
            -sine / (PI * x)
        } else {
            sine / (PI * x)
        };
        *out += amplitude * w * sinc;
    }
}

/// `x` through a second-order Butterworth high-pass at [`HIGH_PASS_HZ`], forwards then backwards
/// (zero-phase), with the ends extended by odd reflection and the filter started in its steady
/// state, exactly as scipy's `sosfiltfilt` (the filter pyroomacoustics applies) does it.
fn high_pass(x: &[f64], rate_hz: f64) -> Vec<f64> {
    // sosfiltfilt's default padding for one second-order section: 3 x (2 x 1 + 1) samples.
    const PAD: usize = 9;
    if x.len() <= PAD {
        // Never so for an impulse response, which is longer than its delay alone.
        return x.to_vec();
    }
    // The bilinear transform of the analog Butterworth high-pass, pre-warped at the cut-off.
    let k = (PI * HIGH_PASS_HZ / rate_hz).tan();
    let norm = 1.0 + std::f64::consts::SQRT_2 * k + k * k;
    let b = [1.0 / norm, -2.0 / norm, 1.0 / norm];
    let a = [
        2.0 * (k * k - 1.0) / norm,
        (1.0 - std::f64::consts::SQRT_2 * k + k * k) / norm,
    ];
    // The filter's state for a constant input of 1 (scipy's lfilter_zi), for a start without a
    // transient.
    let z0 = (b[1] - a[0] * b[0] + b[2] - a[1] * b[0]) / (1.0 + a[0] + a[1]);
    let steady = [z0, b[2] - a[1] * b[0] - a[1] * z0];
    let filter = |signal: &mut [f64]| {
        let first = signal[0];
        let mut z = steady.map(|s| s * first);
        for v in signal.iter_mut() {
            let input = *v;
            let y = b[0] * input + z[0];
            z[0] = b[1] * input - a[0] * y + z[1];
            z[1] = b[2] * input - a[1] * y;
            *v = y;
        }
    };
    let (head, tail) = (x[0], x[x.len() - 1]);
    let mut padded: Vec<f64> = (1..=PAD)
        .rev()
        .map(|i| 2.0 * head - x[i])
        .chain(x.iter().copied())
        .chain((2..PAD + 2).map(|i| 2.0 * tail - x[x.len() - i]))
        .collect();
    filter(&mut padded);
    padded.reverse();
    filter(&mut padded);
    padded.reverse();
    padded[PAD..padded.len() - PAD].to_vec()
}

#[cfg(test)]
mod tests {
    use super::*;

    const RATE: f64 = 16_000.0;

    fn energy(x: &[f64]) -> f64 {
        x.iter().map(|v| v * v).sum()
    }

    /// T20: the time the Schroeder backward integral of `rir` takes to fall by 60 dB, from the
    /// least-squares line through its -5 to -25 dB part (ISO 3382).
    fn t20_s(rir: &[f64], rate_hz: f64) -> f64 {
        let mut edc: Vec<f64> = rir
            .iter()
            .rev()
            .scan(0.0, |acc, v| {
                *acc += v * v;
                Some(*acc)
            })
            .collect();
        edc.reverse();
        let db: Vec<f64> = edc.iter().map(|e| 10.0 * (e / edc[0]).log10()).collect();
        let from = db.iter().position(|&d| d <= -5.0).unwrap();
        let to = db.iter().position(|&d| d <= -25.0).unwrap();
        let n = (to - from) as f64;
        let ts: Vec<f64> = (from..to).map(|i| i as f64 / rate_hz).collect();
        let (mt, md) = (
            ts.iter().sum::<f64>() / n,
            db[from..to].iter().sum::<f64>() / n,
        );
        let slope = ts
            .iter()
            .zip(&db[from..to])
            .map(|(t, d)| (t - mt) * (d - md))
            .sum::<f64>()
            / ts.iter().map(|t| (t - mt).powi(2)).sum::<f64>();
        -60.0 / slope
    }

    #[test]
    fn for_rt60_inverts_sabine_as_pyroomacoustics_does() {
        // pyroomacoustics 0.10.1: inverse_sabine(0.3, [6, 5, 3]) = (0.3836043470210822, 40).
        let room = ShoeboxRoom::for_rt60([6.0, 5.0, 3.0], 0.3).unwrap();
        assert!((room.absorption - 0.383_604_347_021_082_2).abs() < 1e-12);
        assert_eq!(room.max_order, 40);
        assert!((room.sabine_rt60_s() - 0.3).abs() < 1e-12);
        assert_eq!(
            ShoeboxRoom::for_rt60([6.0, 5.0, 3.0], 0.6)
                .unwrap()
                .max_order,
            80
        );
    }

    #[test]
    fn the_direct_path_arrives_at_distance_over_c() {
        let (source, mic) = ([1.3, 3.7, 1.6], [4.1, 1.2, 1.1]);
        let d = distance(source, mic);
        let expected = d / SPEED_OF_SOUND_M_S * RATE + RIR_DELAY_SAMPLES as f64;
        let anechoic = ShoeboxRoom::new([6.0, 5.0, 3.0], 0.5, 0).unwrap();
        let direct = anechoic.image_rir(source, mic, RATE).unwrap();
        let peak = |h: &[f64]| {
            (0..h.len())
                .max_by(|&i, &j| h[i].abs().total_cmp(&h[j].abs()))
                .unwrap()
        };
        assert!((peak(&direct) as f64 - expected).abs() <= 1.0);
        // The windowed sinc keeps the pulse's area: 1 / (4 π r).
        let area: f64 = direct.iter().sum();
        assert!((area * 4.0 * PI * d - 1.0).abs() < 0.01, "{area}");
        let reverberant = ShoeboxRoom::for_rt60([6.0, 5.0, 3.0], 0.4).unwrap();
        let h = reverberant.rir(source, mic, RATE).unwrap();
        assert!((peak(&h) as f64 - expected).abs() <= 1.0);
    }

    #[test]
    fn energy_decays_at_the_rate_the_rt60_implies() {
        // Three source-microphone pairs of a 6 x 5 x 3 m room, as ISO 3382 measures a room at
        // several positions.
        let pairs = [
            ([3.0, 2.5, 1.2], [1.5, 3.6, 1.6]),
            ([4.2, 1.8, 1.3], [2.0, 3.0, 1.7]),
            ([1.0, 1.0, 1.0], [5.0, 4.0, 2.0]),
        ];
        for rt60 in [0.3, 0.6] {
            let room = ShoeboxRoom::for_rt60([6.0, 5.0, 3.0], rt60).unwrap();
            for (source, mic) in pairs {
                let t20 = t20_s(&room.rir(source, mic, RATE).unwrap(), RATE);
                println!("RT60 {rt60} s, source {source:?}, mic {mic:?}: T20 {t20:.3} s");
                assert!(
                    (t20 / rt60 - 1.0).abs() < 0.15,
                    "RT60 {rt60} s: T20 {t20:.3} s"
                );
            }
        }
    }

    #[test]
    fn render_is_each_source_through_its_rir_summed() {
        let room = ShoeboxRoom::new([5.0, 4.0, 3.0], 0.4, 6).unwrap();
        let geometry = ArrayGeometry::builtin("circular_4").unwrap();
        let (centre, yaw) = ([2.0, 1.5, 1.2], std::f64::consts::FRAC_PI_2);
        let click = [0.0, 0.0, 1.0];
        let noise: Vec<f64> = (0..300).map(|i| ((i * 7919) % 113) as f64 - 56.0).collect();
        let sources = [
            RoomSource {
                position_m: [4.0, 3.0, 1.6],
                signal: &click,
            },
            RoomSource {
                position_m: [1.0, 3.2, 1.0],
                signal: &noise,
            },
        ];
        let channels = room.render(&geometry, centre, yaw, &sources).unwrap();
        assert_eq!(channels.len(), geometry.channels());
        let rate = f64::from(geometry.sample_rate_hz());
        for (m, channel) in channels.iter().enumerate() {
            // Turned a quarter turn left: the array's forward (x) is the room's +y.
            let p = geometry.mic(m);
            let at = [centre[0] - p[1], centre[1] + p[0], centre[2] + p[2]];
            let (h0, h1) = (
                room.rir(sources[0].position_m, at, rate).unwrap(),
                room.rir(sources[1].position_m, at, rate).unwrap(),
            );
            let mut expected = vec![0.0; channel.len()];
            for (i, v) in h0.iter().enumerate() {
                expected[i + 2] += v;
            }
            for (i, x) in noise.iter().enumerate() {
                for (j, v) in h1.iter().enumerate() {
                    expected[i + j] += x * v;
                }
            }
            // Every channel is as long as the longest (which may be another microphone's).
            assert_eq!(channel.len(), channels[0].len());
            assert!(channel.len() >= (3 + h0.len()).max(noise.len() + h1.len()) - 1);
            let error = energy(
                &channel
                    .iter()
                    .zip(&expected)
                    .map(|(a, b)| a - b)
                    .collect::<Vec<_>>(),
            );
            assert!(error < 1e-20 * energy(&expected), "channel {m}");
        }
        let silent = room.render(&geometry, centre, yaw, &[]).unwrap();
        assert!(silent.iter().all(Vec::is_empty));
    }

    #[test]
    fn impossible_rooms_and_positions_are_errors() {
        use RoomError as E;
        let room = |dims| ShoeboxRoom::for_rt60(dims, 0.5);
        assert!(matches!(room([0.0, 5.0, 3.0]), Err(E::BadDimensions(_))));
        assert!(matches!(room([6.0, -5.0, 3.0]), Err(E::BadDimensions(_))));
        assert!(matches!(
            room([6.0, 5.0, f64::NAN]),
            Err(E::BadDimensions(_))
        ));
        assert!(matches!(
            room([f64::INFINITY, 5.0, 3.0]),
            Err(E::BadDimensions(_))
        ));
        for rt60 in [0.0, -0.3, f64::NAN, f64::INFINITY] {
            let r = ShoeboxRoom::for_rt60([6.0, 5.0, 3.0], rt60);
            assert!(matches!(r, Err(E::BadRt60(_))), "{rt60}");
        }
        // A 20 m hall cannot die away in 50 ms: its walls would absorb more than all.
        let short = ShoeboxRoom::for_rt60([20.0, 20.0, 20.0], 0.05);
        assert!(matches!(short, Err(E::Rt60TooShort { absorption, .. }) if absorption > 1.0));
        assert!(matches!(
            ShoeboxRoom::for_rt60([3.0, 3.0, 2.5], 5.0),
            Err(E::OrderTooHigh { .. })
        ));
        assert!(matches!(
            ShoeboxRoom::new([6.0, 5.0, 3.0], 1.2, 5),
            Err(E::BadAbsorption(_))
        ));
        assert!(matches!(
            ShoeboxRoom::new([6.0, 5.0, 3.0], -0.1, 5),
            Err(E::BadAbsorption(_))
        ));
        let good = ShoeboxRoom::new([6.0, 5.0, 3.0], 0.3, 3).unwrap();
        let inside = [3.0, 2.0, 1.5];
        for outside in [
            [6.5, 2.0, 1.0],
            [1.0, -0.1, 1.0],
            [1.0, 2.0, 3.0],
            [f64::NAN, 1.0, 1.0],
        ] {
            assert!(matches!(
                good.rir(outside, inside, RATE),
                Err(E::Outside { .. })
            ));
            assert!(matches!(
                good.rir(inside, outside, RATE),
                Err(E::Outside { .. })
            ));
        }
        assert!(matches!(
            good.rir(inside, inside, RATE),
            Err(E::SameSpot { .. })
        ));
        assert!(matches!(
            good.rir(inside, [1.0, 1.0, 1.0], 0.0),
            Err(E::Array(ArrayError::BadRate(_)))
        ));
        let geometry = ArrayGeometry::builtin("kinect_v1").unwrap();
        // The bar along y, 5 cm from the wall: its microphone 7.6 cm to the right is out.
        let near_wall = good.render(&geometry, [3.0, 0.05, 1.0], 0.0, &[]);
        assert!(
            matches!(&near_wall, Err(E::Outside { what, .. }) if what == "microphone 2 of the array"),
            "{near_wall:?}"
        );
    }
}
