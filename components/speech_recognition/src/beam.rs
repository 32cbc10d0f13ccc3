//! Hearing through a microphone array on the live stream: `audio/in` chunks whose channels are
//! the array's microphones (`audio_io --array`) beamformed, chunk by chunk, into the one channel
//! the end-pointer and the decoder take, with the same delay-and-sum beamformer as `--wav
//! --array` ([`crate::array_wav`]).
//!
//! Where the beam listens is its [`Aim`]: a fixed azimuth of the array's own frame
//! (`--target-azimuth-deg`, 0 by default: straight ahead, where a robot with the array on its head
//! looks); the person the deep representation holds, the azimuth given from outside block by
//! block ([`crate::steer`], `--array-frame`); or, when nobody is known, the loudest talker: the
//! sector the localizer placed most of the last [`LOUDEST_WINDOW_S`]'s sounds in ([`Loudest`]).
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

/// How far the aim must move before the beam is steered again (degrees): well inside the main
/// lobe, so that a person's small moves do not re-steer it block after block.
pub const STEER_STEP_DEG: f64 = 2.0;

/// How much of the past the loudest talker is found in (s).
pub const LOUDEST_WINDOW_S: f64 = 1.0;

/// The sectors the loudest talker is found in (degrees): the localizer's spread on one talker.
pub const LOUDEST_SECTOR_DEG: f64 = 20.0;

/// How many of the window's blocks must be placed in one sector before the beam turns there: a
/// syllable or two, not a door's bang.
pub const LOUDEST_MIN_BLOCKS: usize = 3;

/// What the beam listens to.
#[derive(Debug, Clone, PartialEq)]
pub enum Aim {
    /// A set azimuth (rad, the array's frame).
    Fixed(f64),
    /// A node of the deep representation, at this azimuth now (rad, the array's frame).
    Node { name: String, azimuth_rad: f64 },
    /// Nobody is known: the loudest talker ([`Loudest`]).
    Loudest,
}

impl Aim {
    /// What `speech/listening` says it is steered at: the node's name, `loudest` or `fixed`.
    pub fn label(&self) -> &str {
        match self {
            Aim::Fixed(_) => "fixed",
            Aim::Node { name, .. } => name,
            Aim::Loudest => "loudest",
        }
    }
}

/// The loudest talker, from where the localizer placed the last [`LOUDEST_WINDOW_S`] of blocks:
/// the [`LOUDEST_SECTOR_DEG`] sector that holds most of them (at least [`LOUDEST_MIN_BLOCKS`]),
/// at their circular mean. The localizer places each block's dominant sound, so the talker who
/// holds the floor holds the most blocks.
#[derive(Debug, Clone, Default)]
pub struct Loudest {
    /// The window's blocks: where each one's sound was placed (rad), if anywhere.
    recent: std::collections::VecDeque<Option<f64>>,
    window: usize,
}

impl Loudest {
    /// A window of `window` blocks.
    pub fn new(window: usize) -> Self {
        Self {
            recent: std::collections::VecDeque::with_capacity(window + 1),
            window: window.max(1),
        }
    }

    /// One block's placement.
    pub fn push(&mut self, located_rad: Option<f64>) {
        self.recent.push_back(located_rad);
        while self.recent.len() > self.window {
            self.recent.pop_front();
        }
    }

    /// Where the loudest talker is (rad), if one holds enough of the window.
    pub fn azimuth_rad(&self) -> Option<f64> {
        let placed: Vec<f64> = self.recent.iter().flatten().copied().collect();
        let half = (LOUDEST_SECTOR_DEG / 2.0).to_radians();
        // Each placement as a sector's centre: the one with the most placements within half a
        // sector of it (ties: the most recent).
        let (count, centre) = placed
            .iter()
            .map(|&c| {
                (
                    placed
                        .iter()
                        .filter(|&&a| angle_between(a, c) <= half)
                        .count(),
                    c,
                )
            })
            .fold((0, 0.0), |best, x| if x.0 >= best.0 { x } else { best });
        if count < LOUDEST_MIN_BLOCKS {
            return None;
        }
        let (s, c) = placed
            .iter()
            .filter(|&&a| angle_between(a, centre) <= half)
            .fold((0.0, 0.0), |(s, c), a| (s + a.sin(), c + a.cos()));
        Some(s.atan2(c))
    }
}

/// The angle between two azimuths (rad, 0 to π).
fn angle_between(a: f64, b: f64) -> f64 {
    ((a - b + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI)
        .abs()
}

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
    /// Where it is steered (rad, the array's frame), and at what.
    azimuth_rad: f64,
    aim: Aim,
    loudest: Loudest,
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
            .field("aim", &self.aim)
            .finish()
    }
}

impl LiveBeam {
    /// A beam of the array `geometry` listening at `azimuth_rad` (the array's frame), aimed
    /// there ([`Aim::Fixed`]) until [`LiveBeam::aim`] says otherwise.
    pub fn new(geometry: &ArrayGeometry, azimuth_rad: f64) -> Result<Self, ArrayError> {
        let mut beam = DelayAndSum::new(geometry);
        beam.steer(direction(azimuth_rad, 0.0))?;
        Ok(Self {
            geometry: geometry.clone(),
            beam,
            srp: SrpPhat::new(geometry, SrpPhat::default_grid())?,
            azimuth_rad,
            aim: Aim::Fixed(azimuth_rad),
            loudest: Loudest::new((LOUDEST_WINDOW_S / BLOCK_S).round() as usize),
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

    /// What it listens to.
    pub fn current_aim(&self) -> &Aim {
        &self.aim
    }

    /// Aims it from the next block on: at a fixed azimuth or a node's (steered at once when
    /// that is [`STEER_STEP_DEG`] or more from where it listens), or at the loudest talker
    /// (steered block by block as the localizer finds them; until it does, it listens where it
    /// did). An azimuth that is not a number is ignored.
    pub fn aim(&mut self, aim: Aim) {
        match &aim {
            Aim::Fixed(a) | Aim::Node { azimuth_rad: a, .. } if a.is_finite() => self.steer(*a),
            Aim::Fixed(_) | Aim::Node { .. } => return,
            Aim::Loudest => {}
        }
        self.aim = aim;
    }

    /// Steers the beam at `azimuth_rad` if that is [`STEER_STEP_DEG`] or more from where it
    /// listens.
    fn steer(&mut self, azimuth_rad: f64) {
        if angle_between(azimuth_rad, self.azimuth_rad) < STEER_STEP_DEG.to_radians() {
            return;
        }
        let a = (azimuth_rad + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
            - std::f64::consts::PI;
        if self.beam.steer(direction(a, 0.0)).is_ok() {
            self.azimuth_rad = a;
        }
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
        self.loudest.push(located);
        if self.aim == Aim::Loudest
            && let Some(a) = self.loudest.azimuth_rad()
        {
            self.steer(a);
        }
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
        let hers =
            located.map(|az| angle_between(az, self.azimuth_rad) <= HER_DIRECTION_DEG.to_radians());
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

    /// The talker who holds the floor is the loudest: the sector with most placements of the
    /// window, at their mean; a few scattered placements are nobody.
    #[test]
    fn the_loudest_talker_is_where_most_of_the_last_second_was_placed() {
        let mut l = Loudest::new(10);
        assert_eq!(l.azimuth_rad(), None);
        for deg in [60.0, 62.0] {
            l.push(Some(f64::to_radians(deg)));
        }
        l.push(None);
        assert_eq!(l.azimuth_rad(), None, "two blocks are not a talker");
        for deg in [-28.0, -32.0, -30.0, -26.0, -34.0] {
            l.push(Some(f64::to_radians(deg)));
        }
        let at = l.azimuth_rad().unwrap().to_degrees();
        assert!((at + 30.0).abs() < 1.0, "{at}");
        // Across the back of the array (±180 degrees) the mean does not fall to 0.
        let mut l = Loudest::new(10);
        for deg in [178.0, -178.0, 179.0, -179.0] {
            l.push(Some(f64::to_radians(deg)));
        }
        let at = l.azimuth_rad().unwrap().to_degrees();
        assert!(at.abs() > 175.0, "{at}");
        // The window forgets: ten blocks later, the placements are gone.
        for _ in 0..10 {
            l.push(None);
        }
        assert_eq!(l.azimuth_rad(), None);
    }

    /// Aimed at the loudest talker, the beam turns to bursts of speech-like noise from 70 degrees
    /// and takes them as hers; aimed at a node, it turns at once; an azimuth that is not a number
    /// changes nothing.
    #[test]
    fn a_beam_aimed_at_the_loudest_talker_turns_to_her_and_one_aimed_at_a_node_turns_at_once() {
        let g = ArrayGeometry::builtin("circular_4").unwrap();
        let mut rng = audio::signal::NoiseRng::new(11);
        let s: Vec<f64> = (0..32_000)
            .map(|i| rng.gaussian() * if (i / 800) % 2 == 0 { 3000.0 } else { 300.0 })
            .collect();
        let mut pcm: Vec<i16> = (0..8000 * 4)
            .map(|_| (rng.gaussian() * 30.0).round() as i16)
            .collect();
        pcm.extend(interleave(
            &render_plane_wave(&g, &s, direction(f64::to_radians(70.0), 0.0), 16_000.0).unwrap(),
        ));
        let mut beam = LiveBeam::new(&g, 0.0).unwrap();
        beam.aim(Aim::Loudest);
        assert_eq!(beam.current_aim().label(), "loudest");
        let heard: Vec<Heard> = pcm
            .chunks(320 * 4)
            .flat_map(|c| beam.push(c, 4, 0))
            .collect();
        let at = beam.azimuth_rad().to_degrees();
        assert!((at - 70.0).abs() < 10.0, "turned to {at:.0} degrees");
        // Her last second: all hers, once the beam turned to her.
        assert!(
            heard[heard.len() - 10..].iter().all(|h| !h.elsewhere),
            "{:?}",
            heard.iter().map(|h| h.elsewhere).collect::<Vec<_>>()
        );

        beam.aim(Aim::Node {
            name: "player".into(),
            azimuth_rad: f64::to_radians(-40.0),
        });
        assert_eq!(beam.current_aim().label(), "player");
        assert!((beam.azimuth_rad().to_degrees() + 40.0).abs() < 1e-9);
        beam.aim(Aim::Node {
            name: "player".into(),
            azimuth_rad: f64::NAN,
        });
        assert!((beam.azimuth_rad().to_degrees() + 40.0).abs() < 1e-9);
        // A step under STEER_STEP_DEG does not re-steer it.
        beam.aim(Aim::Fixed(f64::to_radians(-39.0)));
        assert_eq!(beam.current_aim().label(), "fixed");
        assert!((beam.azimuth_rad().to_degrees() + 40.0).abs() < 1e-9);
    }
}
