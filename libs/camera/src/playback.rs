//! Recorded sequences in the TUM RGB-D layout: a reader ([`TumSequence`], [`PlaybackDriver`])
//! and a writer ([`TumWriter`]).
//!
//! The layout (<https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats>):
//! - `rgb.txt` and `depth.txt`: one `timestamp filename` line per image (timestamp in s, file
//!   name relative to the folder); lines starting with `#` and blank lines are comments.
//! - Colour images: 8-bit RGB PNG (RGBA is accepted, the alpha dropped).
//! - Depth images: 16-bit grayscale PNG, `5000` units per metre (so `value / 5` is millimetres),
//!   0 = no measurement.
//! - Colour and depth are paired by nearest timestamp within [`OpenOptions::max_pair_dt_s`]
//!   (like TUM's `associate.py`); unpaired colour images are skipped and counted.
//! - This crate adds an optional `intrinsics.txt` (`fx fy cx cy` in pixels on one line); without
//!   it the intrinsics come from [`OpenOptions::intrinsics`].
//!
//! Every error names the file, and for index files the line (1-based).

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::types::{Frame, FrameError, Intrinsics};

/// TUM depth scale: PNG units per metre.
pub const TUM_DEPTH_UNITS_PER_M: f64 = 5000.0;

/// Errors reading or writing a TUM sequence.
#[derive(Debug, thiserror::Error)]
pub enum PlaybackError {
    /// `rgb.txt` or `depth.txt` does not exist.
    #[error("missing index file {path}")]
    MissingIndex {
        /// The file that should exist.
        path: PathBuf,
    },
    /// An I/O error on a file.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A line of an index (or `intrinsics.txt`) that does not parse.
    #[error("{path}:{line}: {reason}: {text:?}")]
    BadLine {
        /// The index file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
        /// The offending line.
        text: String,
    },
    /// An image named by an index does not exist.
    #[error("{index}:{line}: image {path} does not exist")]
    MissingImage {
        /// The missing image.
        path: PathBuf,
        /// The index file naming it.
        index: PathBuf,
        /// 1-based line number in the index.
        line: usize,
    },
    /// A PNG does not decode.
    #[error("cannot decode PNG {path}: {source}")]
    Png {
        /// The image.
        path: PathBuf,
        /// The cause.
        source: png::DecodingError,
    },
    /// A PNG has the wrong colour type or bit depth.
    #[error("{path}: expected {expected}, found {found}")]
    WrongFormat {
        /// The image.
        path: PathBuf,
        /// What this reader needs.
        expected: &'static str,
        /// What the file holds.
        found: String,
    },
    /// Colour and depth of one pair differ in size.
    #[error("size mismatch: {rgb_path} is {}x{}, {depth_path} is {}x{}", rgb.0, rgb.1, depth.0, depth.1)]
    SizeMismatch {
        /// The colour image.
        rgb_path: PathBuf,
        /// The depth image.
        depth_path: PathBuf,
        /// Colour width and height, pixels.
        rgb: (u32, u32),
        /// Depth width and height, pixels.
        depth: (u32, u32),
    },
    /// No colour image could be paired with a depth image.
    #[error("{path}: no colour/depth pairs (indices empty or timestamps too far apart)")]
    Empty {
        /// The sequence folder.
        path: PathBuf,
    },
    /// Writing a PNG failed.
    #[error("cannot encode PNG {path}: {source}")]
    Encode {
        /// The image.
        path: PathBuf,
        /// The cause.
        source: png::EncodingError,
    },
    /// The writer was given an inconsistent frame.
    #[error("cannot write frame: {0}")]
    InvalidFrame(#[from] FrameError),
    /// An index names a frame out of range.
    #[error("frame index {index} out of range (sequence has {len})")]
    OutOfRange {
        /// Asked index.
        index: usize,
        /// Sequence length.
        len: usize,
    },
}

/// How a component paces playback. The library only yields frames and their recorded
/// timestamps; [`PlaybackMode::delay_s`] tells the caller how long to wait between two frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlaybackMode {
    /// At the recorded timestamps, once through.
    #[default]
    Recorded,
    /// As fast as the caller asks, once through.
    AsFastAsAsked,
    /// At the recorded timestamps, looping forever; timestamps keep increasing across loops.
    Looping,
}

impl PlaybackMode {
    /// Seconds to wait between a frame stamped `prev_s` and the next stamped `next_s`.
    pub fn delay_s(self, prev_s: f64, next_s: f64) -> f64 {
        match self {
            PlaybackMode::AsFastAsAsked => 0.0,
            PlaybackMode::Recorded | PlaybackMode::Looping => (next_s - prev_s).max(0.0),
        }
    }

    /// Whether the sequence restarts at its end.
    pub fn loops(self) -> bool {
        self == PlaybackMode::Looping
    }
}

/// Options for [`TumSequence::open`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OpenOptions {
    /// Intrinsics used when the folder has no `intrinsics.txt`.
    pub intrinsics: Intrinsics,
    /// Largest colour/depth timestamp difference paired, s.
    pub max_pair_dt_s: f64,
    /// Depth PNG units per metre (TUM: 5000).
    pub depth_units_per_m: f64,
}

impl Default for OpenOptions {
    fn default() -> OpenOptions {
        OpenOptions {
            intrinsics: Intrinsics::KINECT_640X480,
            max_pair_dt_s: 0.02,
            depth_units_per_m: TUM_DEPTH_UNITS_PER_M,
        }
    }
}

/// One index line: timestamp, image path, 1-based line number.
#[derive(Debug, Clone)]
struct IndexEntry {
    timestamp_s: f64,
    path: PathBuf,
}

/// One colour/depth pair.
#[derive(Debug, Clone)]
struct Pair {
    timestamp_s: f64,
    rgb: PathBuf,
    depth: PathBuf,
}

/// An opened TUM sequence: indices parsed, images checked to exist, colour paired with depth.
/// Images are decoded on demand by [`TumSequence::load`].
#[derive(Debug, Clone)]
pub struct TumSequence {
    root: PathBuf,
    pairs: Vec<Pair>,
    intrinsics: Intrinsics,
    depth_units_per_m: f64,
    unpaired: usize,
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PlaybackError + '_ {
    move |source| PlaybackError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn read_text(path: &Path) -> Result<String, PlaybackError> {
    std::fs::read_to_string(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            PlaybackError::MissingIndex {
                path: path.to_path_buf(),
            }
        } else {
            PlaybackError::Io {
                path: path.to_path_buf(),
                source: e,
            }
        }
    })
}

/// Parses a TUM index file, checking that each named image exists.
fn parse_index(root: &Path, name: &str) -> Result<Vec<IndexEntry>, PlaybackError> {
    let path = root.join(name);
    let text = read_text(&path)?;
    let mut out: Vec<IndexEntry> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let trimmed = raw.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let bad = |reason: &str| PlaybackError::BadLine {
            path: path.clone(),
            line,
            reason: reason.to_string(),
            text: raw.to_string(),
        };
        let mut tokens = trimmed.split_whitespace();
        let (Some(ts), Some(file), None) = (tokens.next(), tokens.next(), tokens.next()) else {
            return Err(bad("expected `timestamp filename`"));
        };
        let timestamp_s: f64 = ts
            .parse()
            .ok()
            .filter(|t: &f64| t.is_finite())
            .ok_or_else(|| bad("timestamp is not a finite number"))?;
        if out.last().is_some_and(|p| timestamp_s <= p.timestamp_s) {
            return Err(bad("timestamps must increase"));
        }
        let image = root.join(file);
        if !image.is_file() {
            return Err(PlaybackError::MissingImage {
                path: image,
                index: path.clone(),
                line,
            });
        }
        out.push(IndexEntry {
            timestamp_s,
            path: image,
        });
    }
    Ok(out)
}

fn parse_intrinsics(root: &Path) -> Result<Option<Intrinsics>, PlaybackError> {
    let path = root.join("intrinsics.txt");
    if !path.exists() {
        return Ok(None);
    }
    let text = read_text(&path)?;
    for (i, raw) in text.lines().enumerate() {
        let trimmed = raw.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let bad = |reason: &str| PlaybackError::BadLine {
            path: path.clone(),
            line: i + 1,
            reason: reason.to_string(),
            text: raw.to_string(),
        };
        let v: Vec<f64> = trimmed
            .split_whitespace()
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|_| bad("expected four numbers `fx fy cx cy`"))?;
        let [fx, fy, cx, cy] = v[..] else {
            return Err(bad("expected four numbers `fx fy cx cy`"));
        };
        let k = Intrinsics { fx, fy, cx, cy };
        if !k.is_valid() {
            return Err(bad("focal lengths must be positive and finite"));
        }
        return Ok(Some(k));
    }
    Err(PlaybackError::BadLine {
        path,
        line: 0,
        reason: "no `fx fy cx cy` line".into(),
        text: String::new(),
    })
}

/// A decoded PNG: width, height, colour type, bit depth, bytes.
fn decode_png(
    path: &Path,
) -> Result<(u32, u32, png::ColorType, png::BitDepth, Vec<u8>), PlaybackError> {
    let file = File::open(path).map_err(io_err(path))?;
    let png_err = |source| PlaybackError::Png {
        path: path.to_path_buf(),
        source,
    };
    let mut reader = png::Decoder::new(BufReader::new(file))
        .read_info()
        .map_err(png_err)?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| PlaybackError::WrongFormat {
            path: path.to_path_buf(),
            expected: "an image of addressable size",
            found: "an image too large to decode".into(),
        })?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(png_err)?;
    buf.truncate(info.buffer_size());
    Ok((
        info.width,
        info.height,
        info.color_type,
        info.bit_depth,
        buf,
    ))
}

impl TumSequence {
    /// Opens the sequence in folder `root`: parses `rgb.txt`, `depth.txt` (and
    /// `intrinsics.txt` if present), checks that every image exists and pairs colour with depth.
    pub fn open(
        root: impl AsRef<Path>,
        options: OpenOptions,
    ) -> Result<TumSequence, PlaybackError> {
        let root = root.as_ref().to_path_buf();
        let rgb = parse_index(&root, "rgb.txt")?;
        let depth = parse_index(&root, "depth.txt")?;
        let intrinsics = parse_intrinsics(&root)?.unwrap_or(options.intrinsics);
        let mut pairs = Vec::with_capacity(rgb.len());
        let mut unpaired = 0;
        for c in &rgb {
            // Depth timestamps increase: binary search the nearest.
            let k = depth.partition_point(|d| d.timestamp_s < c.timestamp_s);
            let best = [k.checked_sub(1), Some(k)]
                .into_iter()
                .flatten()
                .filter_map(|j| depth.get(j))
                .min_by(|a, b| {
                    (a.timestamp_s - c.timestamp_s)
                        .abs()
                        .total_cmp(&(b.timestamp_s - c.timestamp_s).abs())
                });
            match best {
                Some(d) if (d.timestamp_s - c.timestamp_s).abs() <= options.max_pair_dt_s => {
                    pairs.push(Pair {
                        timestamp_s: c.timestamp_s,
                        rgb: c.path.clone(),
                        depth: d.path.clone(),
                    });
                }
                _ => unpaired += 1,
            }
        }
        if pairs.is_empty() {
            return Err(PlaybackError::Empty { path: root });
        }
        Ok(TumSequence {
            root,
            pairs,
            intrinsics,
            depth_units_per_m: options.depth_units_per_m,
            unpaired,
        })
    }

    /// Number of colour/depth pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    /// Never true: [`TumSequence::open`] refuses empty sequences.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Colour images skipped for lack of a depth image close enough in time.
    pub fn unpaired_count(&self) -> usize {
        self.unpaired
    }

    /// The sequence folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Recorded timestamp of pair `index`, s.
    pub fn timestamp_s(&self, index: usize) -> Option<f64> {
        self.pairs.get(index).map(|p| p.timestamp_s)
    }

    /// Intrinsics used for every frame.
    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// Decodes pair `index` into a [`Frame`] stamped with the colour timestamp.
    pub fn load(&self, index: usize) -> Result<Frame, PlaybackError> {
        let pair = self.pairs.get(index).ok_or(PlaybackError::OutOfRange {
            index,
            len: self.pairs.len(),
        })?;
        let (rw, rh, rct, rbd, rbytes) = decode_png(&pair.rgb)?;
        let rgb = match (rct, rbd) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => rbytes,
            (png::ColorType::Rgba, png::BitDepth::Eight) => rbytes
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect(),
            (ct, bd) => {
                return Err(PlaybackError::WrongFormat {
                    path: pair.rgb.clone(),
                    expected: "8-bit RGB or RGBA",
                    found: format!("{bd:?} {ct:?}"),
                });
            }
        };
        let (dw, dh, dct, dbd, dbytes) = decode_png(&pair.depth)?;
        if (dct, dbd) != (png::ColorType::Grayscale, png::BitDepth::Sixteen) {
            return Err(PlaybackError::WrongFormat {
                path: pair.depth.clone(),
                expected: "16-bit grayscale",
                found: format!("{dbd:?} {dct:?}"),
            });
        }
        if (rw, rh) != (dw, dh) {
            return Err(PlaybackError::SizeMismatch {
                rgb_path: pair.rgb.clone(),
                depth_path: pair.depth.clone(),
                rgb: (rw, rh),
                depth: (dw, dh),
            });
        }
        let mm_per_unit = 1000.0 / self.depth_units_per_m;
        let depth_mm = dbytes
            .chunks_exact(2)
            .map(|b| {
                let units = u16::from_be_bytes([b[0], b[1]]);
                (f64::from(units) * mm_per_unit).round().min(65535.0) as u16
            })
            .collect();
        let frame = Frame {
            width: rw,
            height: rh,
            rgb,
            depth_mm,
            intrinsics: self.intrinsics,
            timestamp_s: pair.timestamp_s,
        };
        frame.validate()?;
        Ok(frame)
    }
}

/// The `playback` driver: yields a [`TumSequence`]'s frames in order, once or looping.
#[derive(Debug)]
pub struct PlaybackDriver {
    sequence: TumSequence,
    mode: PlaybackMode,
    next: usize,
    loops_done: u32,
}

impl PlaybackDriver {
    /// Plays `sequence` in `mode`.
    pub fn new(sequence: TumSequence, mode: PlaybackMode) -> PlaybackDriver {
        PlaybackDriver {
            sequence,
            mode,
            next: 0,
            loops_done: 0,
        }
    }

    /// The pacing mode (the caller waits [`PlaybackMode::delay_s`] between frames).
    pub fn mode(&self) -> PlaybackMode {
        self.mode
    }

    /// The underlying sequence.
    pub fn sequence(&self) -> &TumSequence {
        &self.sequence
    }

    /// Duration of one pass, s: last minus first timestamp plus one median frame period, so that
    /// looped timestamps keep the frame spacing.
    fn loop_period_s(&self) -> f64 {
        let n = self.sequence.len();
        let ts = |i| self.sequence.timestamp_s(i).unwrap_or(0.0);
        if n < 2 {
            return 1.0 / 30.0;
        }
        let mut gaps: Vec<f64> = (1..n).map(|i| ts(i) - ts(i - 1)).collect();
        gaps.sort_by(f64::total_cmp);
        ts(n - 1) - ts(0) + gaps[gaps.len() / 2]
    }

    /// The next frame; `None` at the end unless looping. Looped frames are stamped
    /// `recorded + loops * period` so timestamps keep increasing.
    pub fn next_recorded(&mut self) -> Result<Option<Frame>, PlaybackError> {
        if self.next >= self.sequence.len() {
            if !self.mode.loops() {
                return Ok(None);
            }
            self.next = 0;
            self.loops_done += 1;
        }
        let mut frame = self.sequence.load(self.next)?;
        frame.timestamp_s += f64::from(self.loops_done) * self.loop_period_s();
        self.next += 1;
        Ok(Some(frame))
    }
}

impl crate::RgbdDriver for PlaybackDriver {
    fn next_frame(&mut self, _now_s: f64) -> Result<Option<Frame>, crate::DriverError> {
        Ok(self.next_recorded()?)
    }
}

/// Writes frames as a TUM RGB-D folder (`rgb.txt`, `depth.txt`, `rgb/*.png`, `depth/*.png`,
/// plus `intrinsics.txt`). Depth is written at 5000 units per metre, saturating at 13.1 m.
#[derive(Debug)]
pub struct TumWriter {
    root: PathBuf,
    rgb_index: BufWriter<File>,
    depth_index: BufWriter<File>,
    wrote_intrinsics: bool,
    compression: png::Compression,
}

impl TumWriter {
    /// Creates `root` (and `rgb/`, `depth/`) and the two index files, overwriting old indices.
    pub fn create(root: impl AsRef<Path>) -> Result<TumWriter, PlaybackError> {
        let root = root.as_ref().to_path_buf();
        for sub in ["rgb", "depth"] {
            let p = root.join(sub);
            std::fs::create_dir_all(&p).map_err(io_err(&p))?;
        }
        let open = |name: &str, what: &str| -> Result<BufWriter<File>, PlaybackError> {
            let p = root.join(name);
            let mut f = BufWriter::new(File::create(&p).map_err(io_err(&p))?);
            writeln!(
                f,
                "# {what} images\n# written by robocog rgbd\n# timestamp filename"
            )
            .map_err(io_err(&p))?;
            Ok(f)
        };
        Ok(TumWriter {
            rgb_index: open("rgb.txt", "color")?,
            depth_index: open("depth.txt", "depth")?,
            root,
            wrote_intrinsics: false,
            compression: png::Compression::Balanced,
        })
    }

    /// Chooses the PNG compression (default balanced).
    pub fn set_compression(&mut self, compression: png::Compression) {
        self.compression = compression;
    }

    fn write_png(
        &self,
        rel: &str,
        frame: &Frame,
        colour: png::ColorType,
        depth: png::BitDepth,
        data: &[u8],
    ) -> Result<(), PlaybackError> {
        let path = self.root.join(rel);
        let file = File::create(&path).map_err(io_err(&path))?;
        let mut enc = png::Encoder::new(BufWriter::new(file), frame.width, frame.height);
        enc.set_color(colour);
        enc.set_depth(depth);
        enc.set_compression(self.compression);
        let enc_err = |source| PlaybackError::Encode {
            path: path.clone(),
            source,
        };
        let mut w = enc.write_header().map_err(enc_err)?;
        w.write_image_data(data).map_err(enc_err)?;
        w.finish().map_err(enc_err)?;
        Ok(())
    }

    /// Appends one frame (file names from its timestamp, 6 decimals).
    pub fn write(&mut self, frame: &Frame) -> Result<(), PlaybackError> {
        frame.validate()?;
        if !self.wrote_intrinsics {
            let p = self.root.join("intrinsics.txt");
            let k = frame.intrinsics;
            std::fs::write(
                &p,
                format!(
                    "# fx fy cx cy (pixels)\n{} {} {} {}\n",
                    k.fx, k.fy, k.cx, k.cy
                ),
            )
            .map_err(io_err(&p))?;
            self.wrote_intrinsics = true;
        }
        let ts = format!("{:.6}", frame.timestamp_s);
        let rgb_rel = format!("rgb/{ts}.png");
        let depth_rel = format!("depth/{ts}.png");
        self.write_png(
            &rgb_rel,
            frame,
            png::ColorType::Rgb,
            png::BitDepth::Eight,
            &frame.rgb,
        )?;
        let units_per_mm = TUM_DEPTH_UNITS_PER_M / 1000.0;
        let depth_bytes: Vec<u8> = frame
            .depth_mm
            .iter()
            .flat_map(|&mm| {
                let units = (f64::from(mm) * units_per_mm).round().min(65535.0) as u16;
                units.to_be_bytes()
            })
            .collect();
        self.write_png(
            &depth_rel,
            frame,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            &depth_bytes,
        )?;
        let p = self.root.join("rgb.txt");
        writeln!(self.rgb_index, "{ts} {rgb_rel}").map_err(io_err(&p))?;
        let p = self.root.join("depth.txt");
        writeln!(self.depth_index, "{ts} {depth_rel}").map_err(io_err(&p))?;
        Ok(())
    }

    /// Flushes the index files.
    pub fn finish(mut self) -> Result<(), PlaybackError> {
        let p = self.root.join("rgb.txt");
        self.rgb_index.flush().map_err(io_err(&p))?;
        let p = self.root.join("depth.txt");
        self.depth_index.flush().map_err(io_err(&p))?;
        Ok(())
    }
}
