//! Hearing through a microphone array on the live stream: `audio/in` chunks whose channels are
//! the array's microphones (`audio_io --array`) beamformed, chunk by chunk, into the one channel
//! the end-pointer and the decoder take, with the same delay-and-sum beamformer as `--wav
//! --array` ([`crate::array_wav`]).
//!
//! The beam listens at a fixed azimuth of the array's own frame (`--target-azimuth-deg`, 0 by
//! default: straight ahead). On a robot whose array is on its head (Loki's Kinect), straight ahead
//! is where the robot looks, and the robot looks at the person it plays with while she speaks.
//!
//! The beam works on blocks of [`BLOCK_S`] (so the recognizer hears the array that much later).
//! The localizer (SRP-PHAT) places each block's dominant sound; a block whose sound comes from
//! more than [`HER_DIRECTION_DEG`] away from where the beam listens, [`HER_HOLD_S`] or more
//! after her last, is someone else's: the
//! end-pointer neither opens nor stretches an utterance on it ([`crate::vad::Vad::set_elsewhere`]),
//! however loud and however long the others talk.
//!
//! A chunk that does not fit the array (another channel count: a source that lost channels, or
//! the wrong one) is mixed into one channel and goes on, counted; the beam takes up again with
//! the next chunk that fits.

use audio::array::{ArrayError, ArrayGeometry, DelayAndSum, Multichannel, SrpPhat, direction};

/// The blocks (s) the localizer judges at once: a syllable of one talker.
pub const BLOCK_S: f64 = 0.1;

/// How far from where the beam listens a sound may come and still be hers (degrees): the
/// localizer's spread on one talker, with a margin.
pub const HER_DIRECTION_DEG: f64 = 30.0;

/// How long after a block placed at her the blocks placed elsewhere are still taken as hers
/// (s): within a command, between its syllables and in its weak sounds, the others' talk
/// dominates block after block (her words stand over it by a few dB only on average), and a
/// command cut there is lost; a pause between words is shorter than this.
pub const HER_HOLD_S: f64 = 0.3;

/// One block as the recognizer hears it.
#[derive(Debug, Clone, PartialEq)]
pub struct Heard {
    /// The one channel.
    pub samples: Vec<i16>,
    /// When its first sample was heard (ns, the input's stamps; 0 when they were not given).
    pub stamp_ns: i64,
    /// Whether it came out of the beam (`false`: the chunk's channels were mixed).
    pub beamformed: bool,
    /// Where the localizer placed the block's dominant sound (rad, the array's frame), if it
    /// rose over the stream's floor.
    pub located_rad: Option<f64>,
    /// Whether that sound came from elsewhere than where the beam listens (more than
    /// [`HER_DIRECTION_DEG`] away), with no sound of hers in the last [`HER_HOLD_S`]: someone
    /// else's. The end-pointer neither opens nor stretches an utterance on it.
    pub elsewhere: bool,
}

/// The beam on the live stream.
#[derive(Clone)]
pub struct LiveBeam {
    geometry: ArrayGeometry,
    beam: DelayAndSum,
    srp: SrpPhat,
    azimuth_rad: f64,
    /// The input of the block being filled (interleaved), and its first sample's stamp.
    pending: Vec<i16>,
    pending_stamp_ns: i64,
    out: Vec<f32>,
    /// Blocks since the last one placed at her (saturating).
    since_her: usize,
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
            srp: SrpPhat::new(geometry, SrpPhat::default_grid())?,
            azimuth_rad,
            pending: Vec::new(),
            pending_stamp_ns: 0,
            out: Vec::new(),
            since_her: usize::MAX,
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

    /// How much later than the microphones the beam's output is (ns), besides the wait for a
    /// whole block: a block's stamp already accounts for it.
    pub fn latency_ns(&self) -> i64 {
        let rate = i64::from(self.geometry.sample_rate_hz().max(1));
        self.beam.latency_samples() as i64 * 1_000_000_000 / rate
    }

    fn block_frames(&self) -> usize {
        ((BLOCK_S * f64::from(self.geometry.sample_rate_hz())) as usize).max(1)
    }

    fn ns(&self, frames: usize) -> i64 {
        frames as i64 * 1_000_000_000 / i64::from(self.geometry.sample_rate_hz().max(1))
    }

    /// A chunk of `channels` interleaved channels (`samples.len()` a whole number of frames),
    /// its first sample heard at `stamp_ns`: the blocks it completes, beamformed and judged,
    /// when its channels are the array's. A chunk of another channel count is mixed into one
    /// channel and given back at once (after what was pending, which is judged on its own).
    pub fn push(&mut self, samples: &[i16], channels: usize, stamp_ns: i64) -> Vec<Heard> {
        let mut heard = Vec::new();
        if channels != self.channels() {
            heard.extend(self.finish());
            heard.push(Heard {
                samples: audio::wav::mix_to_mono(samples, channels),
                stamp_ns,
                beamformed: false,
                located_rad: None,
                elsewhere: false,
            });
            return heard;
        }
        if self.pending.is_empty() {
            self.pending_stamp_ns = stamp_ns;
        }
        self.pending.extend_from_slice(samples);
        let block = self.block_frames() * channels;
        while self.pending.len() >= block {
            let rest = self.pending.split_off(block);
            let full = std::mem::replace(&mut self.pending, rest);
            heard.push(self.judge(&full));
            self.pending_stamp_ns += self.ns(self.block_frames());
        }
        heard
    }

    /// The block being filled, beamformed and judged as it is (the end of a recording).
    pub fn finish(&mut self) -> Option<Heard> {
        if self.pending.is_empty() {
            return None;
        }
        let block = std::mem::take(&mut self.pending);
        Some(self.judge(&block))
    }

    /// One block (interleaved, the array's channels) beamformed, and where its sound is from.
    fn judge(&mut self, block: &[i16]) -> Heard {
        let located = self
            .srp
            .locate(Multichannel::Interleaved(block))
            .ok()
            .flatten()
            .map(|l| l.azimuth_rad);
        let beamformed = self
            .beam
            .process(Multichannel::Interleaved(block), &mut self.out)
            .is_ok();
        let samples = if beamformed {
            self.out
                .iter()
                .map(|&x| x.round().clamp(-32768.0, 32767.0) as i16)
                .collect()
        } else {
            audio::wav::mix_to_mono(block, self.channels())
        };
        let hers = located.map(|az| {
            let off = (az - self.azimuth_rad + std::f64::consts::PI)
                .rem_euclid(2.0 * std::f64::consts::PI)
                - std::f64::consts::PI;
            off.abs() <= HER_DIRECTION_DEG.to_radians()
        });
        let hold = (HER_HOLD_S / BLOCK_S).round() as usize;
        let elsewhere = hers == Some(false) && self.since_her.saturating_add(1) > hold;
        self.since_her = match hers {
            Some(true) => 0,
            _ => self.since_her.saturating_add(1),
        };
        Heard {
            samples,
            stamp_ns: self.pending_stamp_ns - if beamformed { self.latency_ns() } else { 0 },
            beamformed,
            located_rad: located,
            elsewhere,
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
    /// and is taken down when it comes from the side; bursts of noise from the side are judged
    /// someone else's, from straight ahead hers; chunks of another channel count are mixed,
    /// not lost.
    #[test]
    fn the_beam_passes_its_direction_in_chunks_and_mixes_what_does_not_fit() {
        let g = ArrayGeometry::builtin("circular_6").unwrap();
        let n = 16_000;
        let tone: Vec<f64> = (0..n)
            .map(|i| 8000.0 * (2.0 * std::f64::consts::PI * 2000.0 * i as f64 / 16_000.0).sin())
            .collect();
        // 150 ms bursts of noise, 150 ms apart (the localizer ignores a steady sound).
        let mut rng = audio::signal::NoiseRng::new(5);
        let bursts: Vec<f64> = (0..n)
            .map(|i| rng.gaussian() * if (i / 2400) % 2 == 0 { 3000.0 } else { 30.0 })
            .collect();
        let heard = |signal: &[f64], deg: f64| {
            let ch = render_plane_wave(&g, signal, direction(f64::to_radians(deg), 0.0), 16_000.0)
                .unwrap();
            let mut beam = LiveBeam::new(&g, 0.0).unwrap();
            let pcm = interleave(&ch);
            let mut out = Vec::new();
            let (mut at, mut k) = (0, 0);
            while at < pcm.len() {
                let size = [160, 320, 97, 1600][k % 4] * 6;
                let chunk = &pcm[at..(at + size).min(pcm.len())];
                out.extend(beam.push(chunk, 6, 0));
                (at, k) = (at + size, k + 1);
            }
            out.extend(beam.finish());
            assert!(out.iter().all(|h| h.beamformed));
            assert_eq!(out.iter().map(|h| h.samples.len()).sum::<usize>(), n);
            let samples: Vec<i16> = out.iter().flat_map(|h| h.samples.clone()).collect();
            let elsewhere = out.iter().filter(|h| h.elsewhere).count();
            (rms(&samples[4000..]), elsewhere, out.len())
        };
        let (ahead, _, _) = heard(&tone, 0.0);
        assert!(
            (ahead / (8000.0 / 2f64.sqrt()) - 1.0).abs() < 0.1,
            "ahead {ahead:.0}"
        );
        let (side, _, _) = heard(&tone, 90.0);
        assert!(side < 0.5 * ahead, "ahead {ahead:.0}, side {side:.0}");
        let (_, elsewhere, _) = heard(&bursts, 0.0);
        assert_eq!(elsewhere, 0);
        let (_, elsewhere, blocks) = heard(&bursts, 90.0);
        assert!(
            elsewhere >= blocks / 3,
            "{elsewhere} of {blocks} blocks elsewhere"
        );

        let mut beam = LiveBeam::new(&g, 0.0).unwrap();
        let h = beam.push(&[100, 300, -50, 50], 2, 7);
        assert_eq!(h.len(), 1);
        assert!(!h[0].beamformed && !h[0].elsewhere);
        assert_eq!((h[0].samples.as_slice(), h[0].stamp_ns), (&[200, 0][..], 7));
    }

    /// A block from elsewhere soon after one of hers is still hers (a syllable of her command
    /// the others' talk stood over); once her last is [`HER_HOLD_S`] behind, it is theirs.
    #[test]
    fn the_others_take_over_only_once_she_has_been_quiet_a_while() {
        let g = ArrayGeometry::builtin("circular_6").unwrap();
        let mut rng = audio::signal::NoiseRng::new(9);
        // 0.5 s of the room's noise (the localizer learns its floor), 0.5 s of her (straight
        // ahead), then 1 s of someone at 90 degrees.
        let block = |deg: f64, seconds: f64, rng: &mut audio::signal::NoiseRng| {
            let s: Vec<f64> = (0..(seconds * 16_000.0) as usize)
                .map(|i| rng.gaussian() * if (i / 800) % 2 == 0 { 3000.0 } else { 300.0 })
                .collect();
            interleave(
                &render_plane_wave(&g, &s, direction(f64::to_radians(deg), 0.0), 16_000.0).unwrap(),
            )
        };
        let mut pcm: Vec<i16> = (0..8000 * 6)
            .map(|_| (rng.gaussian() * 30.0).round() as i16)
            .collect();
        pcm.extend(block(0.0, 0.5, &mut rng));
        pcm.extend(block(90.0, 1.0, &mut rng));
        let mut beam = LiveBeam::new(&g, 0.0).unwrap();
        let heard: Vec<Heard> = pcm
            .chunks(320 * 6)
            .flat_map(|c| beam.push(c, 6, 0))
            .collect();
        let verdicts: Vec<bool> = heard[5..].iter().map(|h| h.elsewhere).collect();
        let heard = &heard[5..];
        // Her blocks, then the held ones (the others already located), then theirs.
        let hold = (HER_HOLD_S / BLOCK_S).round() as usize;
        assert!(verdicts[..5].iter().all(|e| !e), "{verdicts:?}");
        assert!(verdicts[5..5 + hold].iter().all(|e| !e), "{verdicts:?}");
        assert!(verdicts[5 + hold + 1..].iter().all(|&e| e), "{verdicts:?}");
        assert!(
            heard[5..].iter().all(|h| h
                .located_rad
                .is_some_and(|a| (a.to_degrees() - 90.0).abs() < 15.0)),
            "{:?}",
            heard.iter().map(|h| h.located_rad).collect::<Vec<_>>()
        );
    }

    /// Blocks are stamped with when their sound was heard: the input's stamps, the beam's
    /// latency taken off.
    #[test]
    fn blocks_carry_the_time_their_sound_was_heard() {
        let g = ArrayGeometry::builtin("circular_4").unwrap();
        let mut beam = LiveBeam::new(&g, 0.0).unwrap();
        let chunk = vec![0i16; 320 * 4];
        let mut blocks = Vec::new();
        for k in 0..10 {
            blocks.extend(beam.push(&chunk, 4, 1_000_000_000 + k * 20_000_000));
        }
        let stamps: Vec<i64> = blocks
            .iter()
            .map(|h| h.stamp_ns + beam.latency_ns())
            .collect();
        assert_eq!(stamps, [1_000_000_000, 1_100_000_000]);
    }
}
