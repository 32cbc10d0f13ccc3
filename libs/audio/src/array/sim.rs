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

/// A room of talkers as an array hears it (plane waves, no reverberation), for tests and
/// simulators: the player says `phrases` one after the other, `gap_s` apart, after `lead_s`
/// where only the others talk; the others chat all along, each `under_db` under the player's
/// average speech level; every microphone has a little noise of its own.
#[derive(Debug, Clone)]
pub struct TalkersRoom<'a> {
    pub player: crate::synth::Voice,
    pub phrases: &'a [&'a str],
    /// Where the player is (rad, the array's frame; elevation 0).
    pub player_azimuth_rad: f64,
    /// The others, each with where they are (rad) and what they keep saying in turn.
    pub others: Vec<(crate::synth::Voice, f64, Vec<&'a str>)>,
    pub under_db: f64,
    pub lead_s: f64,
    pub gap_s: f64,
    /// RMS of each microphone's own noise (16-bit units).
    pub mic_noise: f64,
    pub seed: u64,
}

/// What [`TalkersRoom::render`] gives: the array's recording and where each phrase starts.
#[derive(Debug, Clone)]
pub struct RenderedRoom {
    /// The array's channels, interleaved, at 16 kHz.
    pub pcm: crate::wav::Pcm,
    /// The first sample (per channel) of each of the player's phrases.
    pub starts: Vec<usize>,
}

/// Why a room could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RoomError {
    #[error(transparent)]
    Synth(#[from] crate::synth::SynthError),
    #[error(transparent)]
    Array(#[from] ArrayError),
}

impl TalkersRoom<'_> {
    /// The array `geometry`'s recording of the room (at 16 kHz, whatever the geometry's rate).
    pub fn render(&self, geometry: &ArrayGeometry) -> Result<RenderedRoom, RoomError> {
        use crate::signal::{NoiseRng, active_power};
        use crate::synth::{synthesize_16k, talker};
        const RATE: f64 = 16_000.0;
        let said: Vec<Vec<i16>> = self
            .phrases
            .iter()
            .map(|p| synthesize_16k(p, &self.player))
            .collect::<Result<_, _>>()?;
        let (lead, gap) = (
            (self.lead_s.max(0.0) * RATE) as usize,
            (self.gap_s.max(0.0) * RATE) as usize,
        );
        let mut starts = Vec::with_capacity(said.len());
        let mut n = lead;
        for s in &said {
            starts.push(n);
            n += s.len() + gap;
        }
        let mut track = vec![0.0; n];
        for (s, &at) in said.iter().zip(&starts) {
            for (k, &x) in s.iter().enumerate() {
                track[at + k] = f64::from(x);
            }
        }
        let mut channels = render_plane_wave(
            geometry,
            &track,
            super::direction(self.player_azimuth_rad, 0.0),
            RATE,
        )?;
        let level = said.iter().map(|s| active_power(s)).sum::<f64>() / said.len().max(1) as f64;
        let gain = 10f64.powf(-self.under_db / 20.0);
        for (k, (voice, azimuth, sentences)) in self.others.iter().enumerate() {
            let talk = talker(voice, sentences, k)?;
            let scale = gain * (level / active_power(&talk).max(1e-9)).sqrt();
            let other: Vec<f64> = (0..n)
                .map(|i| f64::from(talk[i % talk.len()]) * scale)
                .collect();
            let heard = render_plane_wave(geometry, &other, super::direction(*azimuth, 0.0), RATE)?;
            for (c, h) in channels.iter_mut().zip(heard) {
                for (x, y) in c.iter_mut().zip(h) {
                    *x += y;
                }
            }
        }
        let mut rng = NoiseRng::new(self.seed);
        let samples = (0..n)
            .flat_map(|i| channels.iter().map(move |c| c[i]).collect::<Vec<_>>())
            .map(|x| {
                (x + self.mic_noise * rng.gaussian())
                    .round()
                    .clamp(-32768.0, 32767.0) as i16
            })
            .collect();
        Ok(RenderedRoom {
            pcm: crate::wav::Pcm {
                sample_rate_hz: RATE as u32,
                channels: geometry.channels() as u16,
                samples,
            },
            starts,
        })
    }
}
