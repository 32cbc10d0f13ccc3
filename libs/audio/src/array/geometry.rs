//! Where the microphones of an array are: [`ArrayGeometry`], read from a TOML file of
//! `models/arrays/` or from the copies of those files built into the library.

use std::path::Path;

use serde::Deserialize;

use super::{ArrayError, SPEED_OF_SOUND_M_S};

/// The shipped geometries, by name, as built into the library (`models/arrays/<name>.toml`).
const BUILTIN: [(&str, &str); 4] = [
    (
        "kinect_v1",
        include_str!("../../../../models/arrays/kinect_v1.toml"),
    ),
    (
        "circular_4",
        include_str!("../../../../models/arrays/circular_4.toml"),
    ),
    (
        "circular_6",
        include_str!("../../../../models/arrays/circular_6.toml"),
    ),
    (
        "laptop_2",
        include_str!("../../../../models/arrays/laptop_2.toml"),
    ),
];

/// The fewest and the most microphones of an array.
const MIN_MICS: usize = 2;
const MAX_MICS: usize = 8;
/// The closest two microphones may be (m).
const MIN_SPACING_M: f64 = 0.005;
/// The widest an array may be (m): wider, a source a few metres away is no longer a plane wave.
const MAX_APERTURE_M: f64 = 1.0;
/// The sample rates accepted (Hz).
const RATES_HZ: std::ops::RangeInclusive<u32> = 8_000..=192_000;
/// How far from the line through the two outermost microphones the others may be for the array
/// to count as linear (m).
const LINE_TOLERANCE_M: f64 = 0.001;

/// A geometry file as written (`models/arrays/*.toml`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GeometryFile {
    name: String,
    #[serde(default)]
    description: String,
    sample_rate_hz: u32,
    mics: Vec<[f64; 3]>,
}

/// A microphone array: where its microphones are and the rate it samples at.
///
/// Positions are in metres in the array's own frame: x forward, y left, z up (right-handed, ROS
/// REP 103). Azimuth 0 is straight ahead (+x), positive to the left (+y); elevation is positive
/// upwards. Microphone `i` is channel `i` of the audio (0-based). A valid geometry has 2 to 8
/// microphones with finite coordinates, at least 5 mm apart, at most 1 m across, and a sample
/// rate of 8 to 192 kHz.
#[derive(Debug, Clone, PartialEq)]
pub struct ArrayGeometry {
    name: String,
    description: String,
    sample_rate_hz: u32,
    mics: Vec<[f64; 3]>,
}

impl ArrayGeometry {
    /// The names of the geometries built into the library (and shipped in `models/arrays/`).
    pub const BUILTIN_NAMES: [&str; 4] = ["kinect_v1", "circular_4", "circular_6", "laptop_2"];

    /// A geometry from its parts: `mics` are positions in metres (see [`ArrayGeometry`]),
    /// `sample_rate_hz` the rate of the audio in Hz. Checked as a file's would be.
    pub fn new(
        name: &str,
        description: &str,
        sample_rate_hz: u32,
        mics: Vec<[f64; 3]>,
    ) -> Result<Self, ArrayError> {
        let geometry = Self {
            name: name.to_owned(),
            description: description.to_owned(),
            sample_rate_hz,
            mics,
        };
        geometry.validate()?;
        Ok(geometry)
    }

    /// A geometry from the text of a TOML file: keys `name`, `description` (optional),
    /// `sample_rate_hz` and `mics` (a list of `[x, y, z]` in metres). Any other key is an error.
    pub fn from_toml_str(text: &str) -> Result<Self, ArrayError> {
        Self::parse(text, "(text)")
    }

    /// A geometry from a TOML file (see [`ArrayGeometry::from_toml_str`]).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ArrayError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ArrayError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    /// One of the geometries built into the library, by name ([`ArrayGeometry::BUILTIN_NAMES`]),
    /// so that a program finds it without the `models` folder.
    pub fn builtin(name: &str) -> Result<Self, ArrayError> {
        let (_, text) =
            BUILTIN
                .iter()
                .find(|(n, _)| *n == name)
                .ok_or_else(|| ArrayError::UnknownBuiltin {
                    name: name.to_owned(),
                    builtin: Self::BUILTIN_NAMES.join(", "),
                })?;
        Self::parse(text, &format!("{name} (built-in)"))
    }

    /// A geometry named as a flag or a manifest gives it: a bare name (`kinect_v1`: no folder, no
    /// extension) is `<models_dir>/arrays/<name>.toml`, or the built-in copy when that file is
    /// not there; anything else is the path of a file.
    pub fn by_name_or_path(name_or_path: &str, models_dir: &Path) -> Result<Self, ArrayError> {
        let as_path = Path::new(name_or_path);
        let bare = as_path.components().count() == 1 && as_path.extension().is_none();
        if !bare {
            return Self::load(as_path);
        }
        let path = models_dir
            .join("arrays")
            .join(format!("{name_or_path}.toml"));
        if path.is_file() {
            return Self::load(&path);
        }
        Self::builtin(name_or_path).map_err(|_| ArrayError::NotFound {
            name: name_or_path.to_owned(),
            path,
            builtin: Self::BUILTIN_NAMES.join(", "),
        })
    }

    fn parse(text: &str, origin: &str) -> Result<Self, ArrayError> {
        let file: GeometryFile = toml::from_str(text).map_err(|source| ArrayError::Parse {
            origin: origin.to_owned(),
            source: Box::new(source),
        })?;
        Self::new(
            &file.name,
            &file.description,
            file.sample_rate_hz,
            file.mics,
        )
    }

    fn validate(&self) -> Result<(), ArrayError> {
        let name = || self.name.clone();
        let count = self.mics.len();
        if !(MIN_MICS..=MAX_MICS).contains(&count) {
            return Err(ArrayError::MicCount {
                name: name(),
                count,
            });
        }
        if let Some((index, &position)) = self
            .mics
            .iter()
            .enumerate()
            .find(|(_, p)| p.iter().any(|c| !c.is_finite()))
        {
            return Err(ArrayError::NonFinitePosition {
                name: name(),
                index,
                position,
            });
        }
        for (first, second) in self.pairs() {
            let d = distance(self.mics[first], self.mics[second]);
            if d < MIN_SPACING_M {
                return Err(ArrayError::Coincident {
                    name: name(),
                    first,
                    second,
                    distance_mm: d * 1000.0,
                });
            }
        }
        let aperture_m = self.aperture_m();
        if aperture_m > MAX_APERTURE_M {
            return Err(ArrayError::Aperture {
                name: name(),
                aperture_m,
            });
        }
        if !RATES_HZ.contains(&self.sample_rate_hz) {
            return Err(ArrayError::SampleRate {
                name: name(),
                rate_hz: self.sample_rate_hz,
            });
        }
        Ok(())
    }

    /// Its name (the `name` key of its file).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// What array it is (the `description` key of its file).
    pub fn description(&self) -> &str {
        &self.description
    }

    /// The sample rate of its audio (Hz).
    pub fn sample_rate_hz(&self) -> u32 {
        self.sample_rate_hz
    }

    /// The number of microphones, which is the number of channels of its audio.
    pub fn channels(&self) -> usize {
        self.mics.len()
    }

    /// The position of microphone `i` (metres, array frame).
    ///
    /// # Panics
    /// If `i >= self.channels()`, as indexing a slice does.
    pub fn mic(&self, i: usize) -> [f64; 3] {
        self.mics[i]
    }

    /// The positions of all microphones, in channel order (metres, array frame).
    pub fn mics(&self) -> &[[f64; 3]] {
        &self.mics
    }

    /// The largest distance between two microphones (metres).
    pub fn aperture_m(&self) -> f64 {
        self.pairs()
            .map(|(i, j)| distance(self.mics[i], self.mics[j]))
            .fold(0.0, f64::max)
    }

    /// The pairs of microphones `(i, j)` with `i < j`.
    pub(crate) fn pairs(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        let n = self.mics.len();
        (0..n).flat_map(move |i| (i + 1..n).map(move |j| (i, j)))
    }

    /// The unit vector along the line the microphones are on (from the first of the two
    /// outermost ones to the second), if they are all within 1 mm of one line. A linear array
    /// hears a source and its mirror image across that line alike.
    pub fn linear_axis(&self) -> Option<[f64; 3]> {
        let (i, j) = self.pairs().max_by(|&(a, b), &(c, d)| {
            distance(self.mics[a], self.mics[b]).total_cmp(&distance(self.mics[c], self.mics[d]))
        })?;
        let axis = unit(sub(self.mics[j], self.mics[i]))?;
        let on_line = self.mics.iter().all(|&p| {
            let v = sub(p, self.mics[i]);
            let along = dot(v, axis);
            let off = sub(v, axis.map(|a| a * along));
            dot(off, off).sqrt() <= LINE_TOLERANCE_M
        });
        on_line.then_some(axis)
    }

    /// When a plane wave from `direction` (a unit vector towards the source, array frame, see
    /// [`super::direction`]) reaches each microphone, relative to when it passes the origin of
    /// the array frame (seconds, in channel order). A microphone at `p` hears it `p·d / c` earlier,
    /// so its offset is `-p·d / c` (negative: earlier), with `c` = [`SPEED_OF_SOUND_M_S`].
    pub fn delays_s(&self, direction: [f64; 3]) -> Vec<f64> {
        self.mics
            .iter()
            .map(|&p| -dot(p, direction) / SPEED_OF_SOUND_M_S)
            .collect()
    }

    /// Checks that a source of `channels` channels fits this geometry (one per microphone).
    pub fn check_channels(&self, channels: usize) -> Result<(), ArrayError> {
        if channels == self.mics.len() {
            Ok(())
        } else {
            Err(ArrayError::ChannelMismatch {
                name: self.name.clone(),
                channels,
                mics: self.mics.len(),
            })
        }
    }
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d).sqrt()
}

/// `v` scaled to length 1, if it is finite and not (almost) zero.
pub(crate) fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let norm = dot(v, v).sqrt();
    (norm.is_finite() && norm > 1e-12).then(|| v.map(|c| c / norm))
}
