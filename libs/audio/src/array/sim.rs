//! What an array hears, for tests and simulators: the channels a far source gives, and a room of
//! talkers, in free field or in a reverberant shoebox room.

use rustfft::{FftPlanner, num_complex::Complex};

use super::geometry::unit;
use super::room::{RIR_DELAY_SAMPLES, RoomSource, ShoeboxRoom};
use super::{ArrayError, ArrayGeometry, SPEED_OF_SOUND_M_S};

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

/// A room of talkers as an array hears it, for tests and simulators: the player says `phrases`
/// one after the other, `gap_s` apart, after `lead_s` where only the others talk; the others
/// chat all along, each `under_db` under the player's average speech level (as spoken, before
/// the room); every microphone has a little noise of its own. Without `reverb`, every talker is
/// a plane wave (far, in free field); with it, a point source in a reverberant room.
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
    /// The reverberant room the talkers and the array are in; `None` for plane waves in free
    /// field.
    pub reverb: Option<Reverb>,
}

/// Where a [`TalkersRoom`]'s talkers stand in a reverberant shoebox room: the array at
/// `array_m` (its frame's axes along the room's, turned `yaw_rad` about z), every talker
/// `distance_m` from it at the talker's azimuth (array frame) and at the array's height.
///
/// Each talker is heard through the room's impulse responses ([`ShoeboxRoom::render`]), all
/// scaled by one gain: the one that brings the player's speech (direct sound and reflections) to
/// the array's centre at the level it has as spoken, as a plane wave does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reverb {
    /// The room, in its own frame (m, z up, from the corner at the origin).
    pub room: ShoeboxRoom,
    /// Where the array's centre (the origin of its frame) is, in the room's frame (m).
    pub array_m: [f64; 3],
    /// How far the array's frame is turned about the vertical from the room's (rad): 0, its
    /// forward is the room's +x; positive, towards +y.
    pub yaw_rad: f64,
    /// How far every talker stands from the array's centre (m), finite and positive.
    pub distance_m: f64,
}

impl Reverb {
    /// Where a talker at `azimuth_rad` (the array's frame) stands, in the room's frame (m).
    pub fn talker_m(&self, azimuth_rad: f64) -> [f64; 3] {
        let (sin, cos) = (azimuth_rad + self.yaw_rad).sin_cos();
        [
            self.array_m[0] + self.distance_m * cos,
            self.array_m[1] + self.distance_m * sin,
            self.array_m[2],
        ]
    }

    /// How much later the direct sound of a talker reaches the array's centre than a plane wave
    /// carrying the same signal would (samples at `rate_hz`, rounded): the time it travels
    /// `distance_m`, plus the impulse responses' own delay ([`RIR_DELAY_SAMPLES`]).
    pub fn direct_delay_samples(&self, rate_hz: f64) -> usize {
        (self.distance_m / SPEED_OF_SOUND_M_S * rate_hz).round() as usize + RIR_DELAY_SAMPLES
    }

    /// What each microphone of `geometry` hears (at 16 kHz) of `talkers` (each a signal and the
    /// azimuth it comes from, rad, array frame), cut or padded to `n` samples: the room's
    /// reverberant tail past `n` is left out.
    fn hear(
        &self,
        geometry: &ArrayGeometry,
        talkers: &[(Vec<f64>, f64)],
        n: usize,
    ) -> Result<Vec<Vec<f64>>, RoomError> {
        if !(self.distance_m.is_finite() && self.distance_m > 0.0) {
            return Err(RoomError::BadDistance(self.distance_m));
        }
        let Some(&(_, player_rad)) = talkers.first() else {
            return Ok(vec![vec![0.0; n]; geometry.channels()]);
        };
        // The room renders at the geometry's rate; the talkers are at 16 kHz whatever it is.
        let at_16k = ArrayGeometry::new(
            geometry.name(),
            geometry.description(),
            16_000,
            geometry.mics().to_vec(),
        )?;
        let sources = talkers
            .iter()
            .enumerate()
            .map(|(k, (signal, azimuth_rad))| {
                let position_m = self.talker_m(*azimuth_rad);
                // Checked here too, so that the error says which talker is out.
                let inside = position_m
                    .iter()
                    .zip(self.room.dims_m)
                    .all(|(&p, l)| p > 0.0 && p < l);
                if !inside {
                    return Err(RoomError::Outside {
                        what: if k == 0 {
                            "player".to_owned()
                        } else {
                            format!("other talker {k}")
                        },
                        position_m,
                        dims_m: self.room.dims_m,
                    });
                }
                Ok(RoomSource { position_m, signal })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let mut channels = self
            .room
            .render(&at_16k, self.array_m, self.yaw_rad, &sources)?;
        // One gain for every talker, so that `under_db` still holds as they speak: the one that
        // brings the player's speech to the array's centre at the level it has as spoken (the
        // impulse response's energy is its power gain, exactly for white noise and about so for
        // speech). The direct sound alone at that level, as a plane wave has it, would leave the
        // reflections adding several dB on top (some 5 dB at 1.5 m in a 6 x 5 x 3 m room of
        // RT60 0.5 s), enough to clip a loud voice.
        let player = self
            .room
            .rir(self.talker_m(player_rad), self.array_m, 16_000.0)?;
        let scale = 1.0 / player.iter().map(|h| h * h).sum::<f64>().sqrt().max(1e-12);
        for channel in &mut channels {
            channel.resize(n, 0.0);
            channel.iter_mut().for_each(|x| *x *= scale);
        }
        Ok(channels)
    }
}

/// What [`TalkersRoom::render`] gives: the array's recording and where each phrase starts.
#[derive(Debug, Clone)]
pub struct RenderedRoom {
    /// The array's channels, interleaved, at 16 kHz.
    pub pcm: crate::wav::Pcm,
    /// The first sample (per channel) of each of the player's phrases: when its direct sound
    /// reaches the array's centre.
    pub starts: Vec<usize>,
}

/// Why a room could not be rendered: a [`TalkersRoom`], or a [`super::room::ShoeboxRoom`] that
/// cannot be made or positions that do not fit in it.
#[derive(Debug, thiserror::Error)]
pub enum RoomError {
    #[error(transparent)]
    Synth(#[from] crate::synth::SynthError),
    #[error(transparent)]
    Array(#[from] ArrayError),
    #[error("the talkers' distance from the array, {0} m, is not a positive finite number")]
    BadDistance(f64),
    #[error("the room's dimensions {0:?} m are not all finite and positive")]
    BadDimensions([f64; 3]),
    #[error("the walls' absorption {0} is not between 0 and 1")]
    BadAbsorption(f64),
    #[error("the reverberation time {0} s is not a positive finite number")]
    BadRt60(f64),
    #[error(
        "a room of {dims_m:?} m cannot die away in {rt60_s} s: its walls would have to absorb \
         {absorption:.2} of the energy, more than all of it (ask for a longer RT60 or a smaller \
         room)"
    )]
    Rt60TooShort {
        dims_m: [f64; 3],
        rt60_s: f64,
        absorption: f64,
    },
    #[error(
        "images up to {max_order} reflections are too many (at most {limit}, or an impulse \
         response takes too long): ask for a shorter RT60, a larger room or a lower order"
    )]
    OrderTooHigh { max_order: usize, limit: usize },
    #[error("the {what} at {position_m:?} m is not inside the room (0 to {dims_m:?} m)")]
    Outside {
        what: String,
        position_m: [f64; 3],
        dims_m: [f64; 3],
    },
    #[error(
        "the source at {source_m:?} m and the microphone at {mic_m:?} m are closer than \
         {min_m} m"
    )]
    SameSpot {
        source_m: [f64; 3],
        mic_m: [f64; 3],
        min_m: f64,
    },
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
        let level = said.iter().map(|s| active_power(s)).sum::<f64>() / said.len().max(1) as f64;
        let gain = 10f64.powf(-self.under_db / 20.0);
        // Every talker, the player first: what they say over the whole recording, and where.
        let mut talkers = vec![(track, self.player_azimuth_rad)];
        for (k, (voice, azimuth, sentences)) in self.others.iter().enumerate() {
            let talk = talker(voice, sentences, k)?;
            let scale = gain * (level / active_power(&talk).max(1e-9)).sqrt();
            let other: Vec<f64> = (0..n)
                .map(|i| f64::from(talk[i % talk.len()]) * scale)
                .collect();
            talkers.push((other, *azimuth));
        }
        let channels = match &self.reverb {
            None => {
                let mut sum = vec![vec![0.0; n]; geometry.channels()];
                for (signal, azimuth) in &talkers {
                    let heard =
                        render_plane_wave(geometry, signal, super::direction(*azimuth, 0.0), RATE)?;
                    for (c, h) in sum.iter_mut().zip(heard) {
                        for (x, y) in c.iter_mut().zip(h) {
                            *x += y;
                        }
                    }
                }
                sum
            }
            Some(reverb) => {
                // A scorer looks for each phrase where it is heard: from its direct sound on.
                let delay = reverb.direct_delay_samples(RATE);
                for start in &mut starts {
                    *start += delay;
                }
                reverb.hear(geometry, &talkers, n)?
            }
        };
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::array::{Multichannel, SrpPhat};
    use crate::synth::Voice;

    const RATE: usize = 16_000;
    /// 10 ms at 16 kHz.
    const FRAME: usize = RATE / 100;
    /// The silence after the player's phrase (s).
    const GAP_S: f64 = 0.6;

    /// Channel `c` of an interleaved recording of `channels` channels.
    fn channel(samples: &[i16], channels: usize, c: usize) -> Vec<f64> {
        samples
            .iter()
            .skip(c)
            .step_by(channels)
            .map(|&x| f64::from(x))
            .collect()
    }

    /// Mean square.
    fn power(x: &[f64]) -> f64 {
        x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64
    }

    fn db(ratio: f64) -> f64 {
        10.0 * ratio.log10()
    }

    /// The angle between two azimuths (rad), in degrees.
    fn error_deg(a_rad: f64, b_rad: f64) -> f64 {
        let d = a_rad - b_rad;
        d.sin().atan2(d.cos()).to_degrees().abs()
    }

    fn lone_player(azimuth_deg: f64, reverb: Option<Reverb>) -> TalkersRoom<'static> {
        TalkersRoom {
            player: Voice {
                voice: "en-us+f3".into(),
                speed_wpm: 160,
                pitch: 50,
            },
            phrases: &["the garden looks lovely after the rain in spring"],
            player_azimuth_rad: azimuth_deg.to_radians(),
            others: vec![],
            under_db: 0.0,
            lead_s: 0.5,
            gap_s: GAP_S,
            mic_noise: 30.0,
            seed: 7,
            reverb,
        }
    }

    #[test]
    fn a_reverberant_room_keeps_the_player_where_she_stands_and_rings_after_her() {
        let geometry = ArrayGeometry::builtin("circular_4").unwrap();
        let channels = geometry.channels();
        // The array turned 20 degrees off the room's axes, the player 50 degrees off its own.
        let reverb = Reverb {
            room: ShoeboxRoom::for_rt60([6.0, 5.0, 3.0], 0.3).unwrap(),
            array_m: [2.5, 2.5, 1.2],
            yaw_rad: 20f64.to_radians(),
            distance_m: 1.5,
        };
        let azimuth_deg = 50.0;
        let dry = lone_player(azimuth_deg, None).render(&geometry).unwrap();
        let wet = lone_player(azimuth_deg, Some(reverb))
            .render(&geometry)
            .unwrap();
        assert_eq!(wet.pcm.samples.len(), dry.pcm.samples.len(), "same length");
        let (dry0, wet0) = (
            channel(&dry.pcm.samples, channels, 0),
            channel(&wet.pcm.samples, channels, 0),
        );
        let noise = power(&wet0[..dry.starts[0] - FRAME]);

        // The phrase is heard from `starts` on, as in free field: its first 10 ms frame 10 dB over
        // the noise comes as long after `starts` in the room as without it (measured: both 80
        // samples after).
        let onset = |x: &[f64], start: usize| {
            (start - 2 * FRAME..x.len() - FRAME)
                .step_by(FRAME / 10)
                .find(|&i| power(&x[i..i + FRAME]) > 10.0 * noise)
                .map(|i| i as f64 - start as f64)
        };
        let (dry_onset, wet_onset) = (onset(&dry0, dry.starts[0]), onset(&wet0, wet.starts[0]));
        println!("onset after start: dry {dry_onset:?}, room {wet_onset:?} samples");
        let (Some(dry_onset), Some(wet_onset)) = (dry_onset, wet_onset) else {
            panic!("no onset: dry {dry_onset:?}, room {wet_onset:?}");
        };
        assert!((wet_onset - dry_onset).abs() <= 32.0, "2 ms");

        // SRP-PHAT places her at her azimuth over her phrase, despite the reflections. Measured:
        // 13 of the 14 200 ms blocks of her phrase within 2 degrees (the last 38 degrees off),
        // the whole phrase within 1 degree.
        let block = RATE / 5;
        let mut srp = SrpPhat::new(&geometry, SrpPhat::default_grid()).unwrap();
        // Her phrase as synthesized (with the synthesizer's own silences), in the room.
        let said =
            dry.pcm.samples.len() / channels - dry.starts[0] - (GAP_S * RATE as f64) as usize;
        let end = wet.starts[0] + said;
        let mut errors = Vec::new();
        for (b, frames) in wet.pcm.samples.chunks(block * channels).enumerate() {
            let located = srp.locate(Multichannel::Interleaved(frames)).unwrap();
            if b * block >= wet.starts[0]
                && (b + 1) * block <= end
                && let Some(l) = located
            {
                errors.push(error_deg(l.azimuth_rad, azimuth_deg.to_radians()));
            }
        }
        println!("errors of the blocks of her phrase (degrees): {errors:.1?}");
        assert!(errors.len() >= 5, "{errors:?}");
        let within = errors.iter().filter(|&&e| e <= 15.0).count();
        assert!(within * 10 >= errors.len() * 8, "{errors:?}");
        let mut whole = SrpPhat::new(&geometry, SrpPhat::default_grid()).unwrap();
        let phrase = &wet.pcm.samples[wet.starts[0] * channels..end * channels];
        let l = whole
            .locate(Multichannel::Interleaved(phrase))
            .unwrap()
            .unwrap_or_else(|| panic!("her phrase not located"));
        println!("her whole phrase: {l:?}");
        assert!(
            error_deg(l.azimuth_rad, azimuth_deg.to_radians()) <= 15.0,
            "{l:?}"
        );

        // After her phrase the room rings: her phrase ends with its last 10 ms frame (in free
        // field) within 20 dB of its loudest; the 100 ms after it are well over the noise and
        // well over free field's, where her voice only fades, and the next 100 ms die away.
        // Measured: 24.2 dB over the noise, then 9.2 dB; free field 9.3 dB.
        let frames: Vec<f64> = dry0.chunks(FRAME).map(power).collect();
        let loudest = frames.iter().fold(0.0f64, |m, &p| m.max(p));
        let last = frames
            .iter()
            .rposition(|&p| p > 0.01 * loudest)
            .map(|f| (f + 1) * FRAME)
            .unwrap_or_else(|| panic!("silent"));
        let delay = wet.starts[0] - dry.starts[0];
        let window = RATE / 10;
        let tail = |x: &[f64], from: usize| db(power(&x[from..from + window]) / noise);
        let (room_tail, room_later, dry_tail) = (
            tail(&wet0, last + delay),
            tail(&wet0, last + delay + window),
            tail(&dry0, last),
        );
        println!(
            "after her phrase, over the noise: room {room_tail:.1} dB then {room_later:.1} dB, \
             free field {dry_tail:.1} dB"
        );
        assert!(room_tail > 15.0, "{room_tail}");
        assert!(room_tail > dry_tail + 10.0, "{room_tail} {dry_tail}");
        assert!(room_later < room_tail - 10.0, "{room_later} {room_tail}");

        // A talker the room cannot hold is an error that names her.
        let far = Reverb {
            distance_m: 4.0,
            ..reverb
        };
        let out = lone_player(azimuth_deg, Some(far)).render(&geometry);
        assert!(
            matches!(&out, Err(RoomError::Outside { what, .. }) if what == "player"),
            "{out:?}"
        );
    }
}
