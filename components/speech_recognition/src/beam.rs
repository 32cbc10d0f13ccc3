//! Hearing through a microphone array on the live stream: `audio/in` chunks whose channels are
//! the array's microphones (`audio_io --array`) beamformed, chunk by chunk, into the one channel
//! the end-pointer and the decoder take, with the same delay-and-sum beamformer as `--wav
//! --array` ([`crate::array_wav`]).
//!
//! The beam listens at a fixed azimuth of the array's own frame (`--target-azimuth-deg`, 0 by
//! default: straight ahead). On a robot whose array is on its head (Loki's Kinect), straight ahead
//! is where the robot looks, and the robot looks at the person it plays with while she speaks.
//!
//! A chunk that does not fit the array (another channel count: a source that lost channels, or
//! the wrong one) is mixed into one channel and goes on, counted; the beam takes up again with
//! the next chunk that fits.

use audio::array::{ArrayError, ArrayGeometry, DelayAndSum, Multichannel, direction};

/// One chunk as the recognizer hears it.
#[derive(Debug, Clone, PartialEq)]
pub struct Heard {
    /// The one channel.
    pub samples: Vec<i16>,
    /// Whether it came out of the beam (`false`: the chunk's channels were mixed).
    pub beamformed: bool,
}

/// The beam on the live stream.
#[derive(Clone)]
pub struct LiveBeam {
    geometry: ArrayGeometry,
    beam: DelayAndSum,
    azimuth_rad: f64,
    out: Vec<f32>,
}

impl std::fmt::Debug for LiveBeam {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveBeam")
            .field("array", &self.geometry.name())
            .field("azimuth_deg", &self.azimuth_rad.to_degrees())
            .finish()
    }
}

impl LiveBeam {
    /// A beam of the array `geometry` listening at `azimuth_rad` (the array's frame).
    pub fn new(geometry: &ArrayGeometry, azimuth_rad: f64) -> Result<Self, ArrayError> {
        let mut beam = DelayAndSum::new(geometry);
        beam.steer(direction(azimuth_rad, 0.0))?;
        Ok(Self {
            geometry: geometry.clone(),
            beam,
            azimuth_rad,
            out: Vec::new(),
        })
    }

    /// The array's microphones: the channel count a chunk must have to be beamformed.
    pub fn channels(&self) -> usize {
        self.geometry.channels()
    }

    /// The array's name.
    pub fn name(&self) -> &str {
        self.geometry.name()
    }

    /// Where it listens (rad, the array's frame).
    pub fn azimuth_rad(&self) -> f64 {
        self.azimuth_rad
    }

    /// How much later than the microphones the beam's output is (ns): a chunk's stamp minus
    /// this is when what its output holds was heard.
    pub fn latency_ns(&self) -> i64 {
        let rate = i64::from(self.geometry.sample_rate_hz().max(1));
        self.beam.latency_samples() as i64 * 1_000_000_000 / rate
    }

    /// A chunk of `channels` interleaved channels (`samples.len()` a whole number of frames)
    /// into one channel: beamformed when its channels are the array's, else mixed.
    pub fn push(&mut self, samples: &[i16], channels: usize) -> Heard {
        if channels == self.channels()
            && self
                .beam
                .process(Multichannel::Interleaved(samples), &mut self.out)
                .is_ok()
        {
            return Heard {
                samples: self
                    .out
                    .iter()
                    .map(|&x| x.round().clamp(-32768.0, 32767.0) as i16)
                    .collect(),
                beamformed: true,
            };
        }
        Heard {
            samples: audio::wav::mix_to_mono(samples, channels),
            beamformed: false,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use audio::array::sim::render_plane_wave;

    fn interleave(channels: &[Vec<f64>]) -> Vec<i16> {
        let n = channels[0].len();
        (0..n)
            .flat_map(|i| channels.iter().map(move |c| c[i].round() as i16))
            .collect()
    }

    fn rms(x: &[i16]) -> f64 {
        (x.iter().map(|&v| f64::from(v).powi(2)).sum::<f64>() / x.len().max(1) as f64).sqrt()
    }

    /// A 2 kHz tone from straight ahead passes the beam steered there, in chunks of any size,
    /// and is taken down when it comes from the side; chunks of another channel count are
    /// mixed, not lost.
    #[test]
    fn the_beam_passes_its_direction_in_chunks_and_mixes_what_does_not_fit() {
        let g = ArrayGeometry::builtin("circular_6").unwrap();
        let n = 16_000;
        let tone: Vec<f64> = (0..n)
            .map(|i| 8000.0 * (2.0 * std::f64::consts::PI * 2000.0 * i as f64 / 16_000.0).sin())
            .collect();
        let heard = |deg: f64| {
            let ch = render_plane_wave(&g, &tone, direction(f64::to_radians(deg), 0.0), 16_000.0)
                .unwrap();
            let mut beam = LiveBeam::new(&g, 0.0).unwrap();
            let pcm = interleave(&ch);
            let mut out = Vec::new();
            let (mut at, mut k) = (0, 0);
            while at < pcm.len() {
                let size = [160, 320, 97, 1600][k % 4] * 6;
                let chunk = &pcm[at..(at + size).min(pcm.len())];
                let h = beam.push(chunk, 6);
                assert!(h.beamformed);
                assert_eq!(h.samples.len(), chunk.len() / 6);
                out.extend(h.samples);
                (at, k) = (at + size, k + 1);
            }
            rms(&out[4000..])
        };
        let ahead = heard(0.0);
        let side = heard(90.0);
        assert!(
            (ahead / (8000.0 / 2f64.sqrt()) - 1.0).abs() < 0.1,
            "ahead {ahead:.0}"
        );
        assert!(side < 0.5 * ahead, "ahead {ahead:.0}, side {side:.0}");

        let mut beam = LiveBeam::new(&g, 0.0).unwrap();
        let h = beam.push(&[100, 300, -50, 50], 2);
        assert!(!h.beamformed);
        assert_eq!(h.samples, [200, 0]);
        assert!(beam.latency_ns() > 0);
    }
}
