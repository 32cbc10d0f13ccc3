//! Files in, commands out for a microphone array: the channels of a multichannel recording
//! beamformed into the one channel the recognizer decodes, steered at a given azimuth or at the
//! talker the localizer (SRP-PHAT) finds loudest over the recording, with the component's own
//! beam ([`crate::beam::LiveBeam`]: delay-and-sum in 100 ms blocks, each judged hers or someone
//! else's for the end-pointer), fed in `audio_io`'s 20 ms chunks. (The
//! library's adaptive beamformer, MVDR, is not used here yet: learning the noise from the blocks
//! the localizer places elsewhere than the talker gave no command at all on the test's room.)
//!
//! `speech_recognition --wav FILE --array <name|geometry file> [--target-azimuth-deg DEG]`:
//! the azimuth is in the array's own frame (`models/arrays/README.md`: 0 straight ahead,
//! positive to the left).

use crate::beam::{Heard, LiveBeam};
use audio::array::{ArrayError, ArrayGeometry, Multichannel, SrpPhat};
use audio::wav::Pcm;

/// The localizer's blocks (s): a syllable or two of one talker.
const BLOCK_S: f64 = 0.2;
/// The width of the azimuth bins in which the localizer's blocks vote for a talker (degrees).
const VOTE_BIN_DEG: f64 = 5.0;
/// The fewest blocks (0.6 s of sound) a talker needs around its bin to be chosen.
const MIN_TALKER_BLOCKS: usize = 3;
/// Why a recording cannot be beamformed.
#[derive(Debug, thiserror::Error)]
pub enum ArrayWavError {
    /// The geometry, the channel count, or the samples do not fit.
    #[error(transparent)]
    Array(#[from] ArrayError),
    /// A given azimuth that is not a number.
    #[error("the target azimuth must be a finite number of degrees, not {0}")]
    BadAzimuth(f64),
    /// No block of the recording had a sound above the stream's own floor.
    #[error(
        "the localizer found no talker in the recording (silent, or one steady sound throughout): give the talker's azimuth"
    )]
    NoTalker,
}

/// The one channel a beam gave, and where it listened.
#[derive(Debug, Clone, PartialEq)]
pub struct Beamformed {
    /// The enhanced channel at the array's sample rate in the live beam's blocks, each judged
    /// hers or someone else's, as the component hears `audio/in` (the beam's latency late).
    pub heard: Vec<Heard>,
    /// Its rate (the geometry's).
    pub sample_rate_hz: u32,
    /// Where the beam was steered (rad, the array's frame).
    pub azimuth_rad: f64,
    /// Whether the localizer chose it (no azimuth was given).
    pub located: bool,
    /// The localizer's blocks with a sound in them, of all its blocks.
    pub blocks_located: usize,
    pub blocks: usize,
}

/// Beamforms `pcm`, whose channels are the microphones of `geometry` in its order, towards
/// `target_azimuth_rad`, or towards the talker the localizer finds loudest (the azimuth bin
/// whose blocks are loudest on average). A recording at another rate than the geometry's is
/// resampled first.
pub fn beamform(
    pcm: &Pcm,
    geometry: &ArrayGeometry,
    target_azimuth_rad: Option<f64>,
) -> Result<Beamformed, ArrayWavError> {
    geometry.check_channels(usize::from(pcm.channels))?;
    if let Some(az) = target_azimuth_rad
        && !az.is_finite()
    {
        return Err(ArrayWavError::BadAzimuth(az));
    }
    let channels = usize::from(pcm.channels);
    let rate = geometry.sample_rate_hz();
    let interleaved = at_rate(pcm, rate);
    let frames = interleaved.len() / channels;
    let block = ((BLOCK_S * f64::from(rate)) as usize).max(1) * channels;
    let located = localize(geometry, &interleaved, block)?;
    let blocks = located.len();
    let blocks_located = located.iter().flatten().count();
    let azimuth_rad = match target_azimuth_rad {
        Some(az) => az,
        None => loudest_talker(&located)?,
    };
    // In audio_io's 20 ms chunks, through the component's own beam.
    let mut beam = LiveBeam::new(geometry, azimuth_rad)?;
    let chunk = (f64::from(rate) * 0.02) as usize * channels;
    let mut heard: Vec<Heard> = interleaved
        .chunks(chunk.max(channels))
        .flat_map(|c| beam.push(c, channels, 0))
        .collect();
    heard.extend(beam.finish());
    debug_assert_eq!(heard.iter().map(|h| h.samples.len()).sum::<usize>(), frames);
    Ok(Beamformed {
        heard,
        sample_rate_hz: rate,
        azimuth_rad,
        located: target_azimuth_rad.is_none(),
        blocks_located,
        blocks,
    })
}

impl Beamformed {
    /// The enhanced channel, whole.
    pub fn samples(&self) -> Vec<i16> {
        self.heard
            .iter()
            .flat_map(|h| h.samples.iter().copied())
            .collect()
    }

    /// The blocks the localizer judged someone else's, of all.
    pub fn elsewhere(&self) -> (usize, usize) {
        (
            self.heard.iter().filter(|h| h.elsewhere).count(),
            self.heard.len(),
        )
    }
}

/// Decode `heard` as the component does: each block pushed with whether its sound came from
/// elsewhere, then the end of the stream.
pub fn decode(
    recognizer: &mut crate::Recognizer,
    heard: &[Heard],
) -> Result<Vec<crate::Recognized>, crate::RecognizerError> {
    let mut out = Vec::new();
    for h in heard {
        out.extend(recognizer.push_from(&h.samples, h.elsewhere)?);
    }
    out.extend(recognizer.flush()?);
    Ok(out)
}

/// Where the localizer places each block's dominant sound (azimuth, rad) and the block's energy;
/// `None` for a block with no sound over the stream's floor.
fn localize(
    geometry: &ArrayGeometry,
    interleaved: &[i16],
    block: usize,
) -> Result<Vec<Option<(f64, f64)>>, ArrayWavError> {
    let mut srp = SrpPhat::new(geometry, SrpPhat::default_grid())?;
    interleaved
        .chunks(block)
        .map(|chunk| {
            let energy = chunk.iter().map(|&s| f64::from(s).powi(2)).sum::<f64>();
            Ok(srp
                .locate(Multichannel::Interleaved(chunk))?
                .map(|l| (l.azimuth_rad, energy)))
        })
        .collect()
}

/// The recording's interleaved samples at `rate`.
fn at_rate(pcm: &Pcm, rate: u32) -> Vec<i16> {
    let channels = usize::from(pcm.channels.max(1));
    if pcm.sample_rate_hz == rate {
        return pcm.samples.clone();
    }
    let resampled: Vec<Vec<i16>> = (0..channels)
        .map(|c| {
            let one: Vec<i16> = pcm
                .samples
                .iter()
                .skip(c)
                .step_by(channels)
                .copied()
                .collect();
            audio::signal::resample(&one, pcm.sample_rate_hz, rate)
        })
        .collect();
    let frames = resampled.iter().map(Vec::len).min().unwrap_or(0);
    (0..frames)
        .flat_map(|i| resampled.iter().map(move |ch| ch[i]))
        .collect()
}

/// The azimuth of the talker whose blocks are loudest on average.
fn loudest_talker(located: &[Option<(f64, f64)>]) -> Result<f64, ArrayWavError> {
    let bins = (360.0 / VOTE_BIN_DEG).round() as usize;
    let mut energy_by_bin = vec![0.0_f64; bins];
    let mut azimuths_by_bin: Vec<Vec<(f64, f64)>> = vec![Vec::new(); bins];
    for &(az, energy) in located.iter().flatten() {
        let deg = az.to_degrees().rem_euclid(360.0);
        let bin = ((deg / VOTE_BIN_DEG) as usize).min(bins - 1);
        energy_by_bin[bin] += energy;
        azimuths_by_bin[bin].push((az, energy));
    }
    let located = located.iter().flatten().count();
    if located == 0 {
        return Err(ArrayWavError::NoTalker);
    }
    // The loudest talker is the one whose blocks are loudest on average, not the one who talks
    // most: people chatting all along fill many more blocks than the player's commands. A bin
    // counts with its neighbours, and with enough blocks not to be a door's bang.
    let around = |k: usize| [(k + bins - 1) % bins, k, (k + 1) % bins];
    let score = |k: usize| {
        let n: usize = around(k).iter().map(|&b| azimuths_by_bin[b].len()).sum();
        let e: f64 = around(k).iter().map(|&b| energy_by_bin[b]).sum();
        (n >= MIN_TALKER_BLOCKS.min(located)).then(|| e / n as f64)
    };
    let best = (0..bins)
        .filter_map(|k| score(k).map(|s| (k, s)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k)
        .ok_or(ArrayWavError::NoTalker)?;
    let (mut x, mut y) = (0.0, 0.0);
    for k in around(best) {
        for &(az, e) in &azimuths_by_bin[k] {
            x += e * az.cos();
            y += e * az.sin();
        }
    }
    Ok(y.atan2(x))
}
