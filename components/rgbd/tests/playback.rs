//! The TUM playback reader and writer: the shipped sim sequence, a write/read round trip, and
//! one test per kind of malformed folder.

#![allow(clippy::unwrap_used)] // tests may unwrap (helpers outside #[test] included)

use std::path::{Path, PathBuf};

use camera::playback::{
    OpenOptions, PlaybackDriver, PlaybackError, PlaybackMode, TumSequence, TumWriter,
};
use camera::sim::{Scene, SensorModel, SimCamera, SimRenderer, Sphere, look_at};
use camera::{DriverError, RgbdDriver};
use nalgebra::{Point3, Vector3};

fn shipped() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/sim_ball_seq")
}

/// A fresh scratch folder for one test, removed when dropped.
struct Scratch(PathBuf);

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl std::ops::Deref for Scratch {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

fn scratch(name: &str) -> Scratch {
    let p = std::env::temp_dir().join(format!("rgbd-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&p);
    std::fs::create_dir_all(&p).unwrap();
    Scratch(p)
}

/// A copy of the shipped sequence to break.
fn copy_shipped(name: &str) -> Scratch {
    let dst = scratch(name);
    for sub in ["rgb", "depth"] {
        std::fs::create_dir_all(dst.join(sub)).unwrap();
        for e in std::fs::read_dir(shipped().join(sub)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), dst.join(sub).join(e.file_name())).unwrap();
        }
    }
    for f in ["rgb.txt", "depth.txt", "intrinsics.txt"] {
        std::fs::copy(shipped().join(f), dst.join(f)).unwrap();
    }
    dst
}

/// First image named in an index.
fn first_image(dir: &Path, index: &str) -> PathBuf {
    let text = std::fs::read_to_string(dir.join(index)).unwrap();
    let line = text.lines().find(|l| !l.starts_with('#')).unwrap();
    dir.join(line.split_whitespace().nth(1).unwrap())
}

fn write_png(
    path: &Path,
    w: u32,
    h: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) {
    let f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut enc = png::Encoder::new(f, w, h);
    enc.set_color(colour);
    enc.set_depth(depth);
    let mut wr = enc.write_header().unwrap();
    wr.write_image_data(data).unwrap();
    wr.finish().unwrap();
}

#[test]
fn replays_the_shipped_sequence() {
    let seq = TumSequence::open(shipped(), OpenOptions::default()).unwrap();
    assert_eq!(seq.len(), 10);
    assert_eq!(seq.unpaired_count(), 0);
    let truth = std::fs::read_to_string(shipped().join("ball.txt")).unwrap();
    let truth: Vec<Vec<f64>> = truth
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect();
    let mut driver = PlaybackDriver::new(seq, PlaybackMode::AsFastAsAsked);
    let mut n = 0;
    let mut prev = f64::NEG_INFINITY;
    while let Some(f) = driver.next_frame(0.0).unwrap() {
        assert_eq!((f.width, f.height), (640, 480));
        f.validate().unwrap();
        assert!(f.timestamp_s > prev);
        prev = f.timestamp_s;
        let t = &truth[n];
        assert!((t[0] - f.timestamp_s).abs() < 1e-6);
        // The pixel at the ball's projected centre sees its front surface, ~5 cm before the
        // centre (depth noise and quantisation allow a few mm), or a hole.
        let [u, v] = f.intrinsics.project([t[1], t[2], t[3]]).unwrap();
        let i = v.round() as usize * 640 + u.round() as usize;
        let d = f64::from(f.depth_mm[i]);
        assert!(
            (d - (t[3] - 0.05) * 1000.0).abs() < 15.0,
            "frame {n}: {d} mm"
        );
        let px = &f.rgb[i * 3..i * 3 + 3];
        assert!(px[0] > 2 * px[1], "frame {n}: ball colour {px:?}");
        n += 1;
    }
    assert_eq!(n, 10);
    assert!(driver.next_recorded().unwrap().is_none(), "stays exhausted");
}

#[test]
fn looping_keeps_timestamps_increasing() {
    let seq = TumSequence::open(shipped(), OpenOptions::default()).unwrap();
    let mut driver = PlaybackDriver::new(seq, PlaybackMode::Looping);
    let stamps: Vec<f64> = (0..25)
        .map(|_| driver.next_recorded().unwrap().unwrap().timestamp_s)
        .collect();
    for w in stamps.windows(2) {
        let dt = w[1] - w[0];
        assert!((dt - 1.0 / 30.0).abs() < 1e-4, "gap {dt}");
    }
    assert_eq!(PlaybackMode::Looping.delay_s(1.0, 1.5), 0.5);
    assert_eq!(PlaybackMode::AsFastAsAsked.delay_s(1.0, 1.5), 0.0);
}

#[test]
fn writer_and_reader_round_trip_exactly() {
    let dir = scratch("roundtrip");
    let cam = SimCamera::vga(look_at(
        Point3::new(0.0, 0.0, 1.3),
        Point3::new(1.0, 0.0, 0.9),
        Vector3::z(),
    ));
    let mut r = SimRenderer::new(cam, SensorModel::default(), 77);
    let mut scene = Scene::default();
    let mut frames = Vec::new();
    let mut w = TumWriter::create(&dir).unwrap();
    w.set_compression(png::Compression::Fastest);
    for i in 0..3 {
        scene.ball = Some(Sphere::new(
            Point3::new(0.9, 0.1 * i as f64, 0.9),
            0.1,
            [30, 200, 40],
        ));
        let f = r.render(&scene, 12.5 + i as f64 / 30.0);
        w.write(&f).unwrap();
        frames.push(f);
    }
    w.finish().unwrap();
    let seq = TumSequence::open(&dir, OpenOptions::default()).unwrap();
    assert_eq!(seq.len(), 3);
    for (i, f) in frames.iter().enumerate() {
        let g = seq.load(i).unwrap();
        assert_eq!(g.rgb, f.rgb);
        assert_eq!(g.depth_mm, f.depth_mm);
        assert_eq!(g.intrinsics, f.intrinsics);
        assert!((g.timestamp_s - f.timestamp_s).abs() < 1e-6);
    }
    assert!(matches!(
        seq.load(3),
        Err(PlaybackError::OutOfRange { index: 3, len: 3 })
    ));
}

#[test]
fn missing_index_is_named() {
    let dir = copy_shipped("missing-index");
    std::fs::remove_file(dir.join("rgb.txt")).unwrap();
    let err = TumSequence::open(&dir, OpenOptions::default()).unwrap_err();
    match &err {
        PlaybackError::MissingIndex { path } => assert!(path.ends_with("rgb.txt")),
        e => panic!("wrong error {e:?}"),
    }
    assert!(err.to_string().contains("rgb.txt"), "{err}");
}

#[test]
fn bad_line_gives_file_and_line() {
    let dir = copy_shipped("bad-line");
    let mut text = std::fs::read_to_string(dir.join("depth.txt")).unwrap();
    text = text.replacen("1700000000.066667 ", "17000x0000.066667 ", 1);
    std::fs::write(dir.join("depth.txt"), text).unwrap();
    let err = TumSequence::open(&dir, OpenOptions::default()).unwrap_err();
    match &err {
        // Three comment lines, then the third image line.
        PlaybackError::BadLine { path, line, .. } => {
            assert!(path.ends_with("depth.txt"));
            assert_eq!(*line, 6);
        }
        e => panic!("wrong error {e:?}"),
    }
    assert!(err.to_string().contains("depth.txt:6"), "{err}");

    // A line with one token.
    let dir = copy_shipped("bad-line-2");
    std::fs::write(dir.join("rgb.txt"), "# c\n1700000000.000000\n").unwrap();
    let err = TumSequence::open(&dir, OpenOptions::default()).unwrap_err();
    assert!(
        matches!(err, PlaybackError::BadLine { line: 2, .. }),
        "{err}"
    );

    // A bad intrinsics file.
    let dir = copy_shipped("bad-line-3");
    std::fs::write(dir.join("intrinsics.txt"), "525 525 319.5\n").unwrap();
    let err = TumSequence::open(&dir, OpenOptions::default()).unwrap_err();
    match &err {
        PlaybackError::BadLine { path, line: 1, .. } => assert!(path.ends_with("intrinsics.txt")),
        e => panic!("wrong error {e:?}"),
    }
}

#[test]
fn missing_image_gives_index_and_line() {
    let dir = copy_shipped("missing-image");
    let img = first_image(&dir, "rgb.txt");
    std::fs::remove_file(&img).unwrap();
    let err = TumSequence::open(&dir, OpenOptions::default()).unwrap_err();
    match &err {
        PlaybackError::MissingImage { path, index, line } => {
            assert_eq!(path, &img);
            assert!(index.ends_with("rgb.txt"));
            assert_eq!(*line, 4);
        }
        e => panic!("wrong error {e:?}"),
    }
}

#[test]
fn wrong_bit_depth_is_rejected() {
    let dir = copy_shipped("bit-depth");
    let img = first_image(&dir, "depth.txt");
    write_png(
        &img,
        640,
        480,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &vec![7u8; 640 * 480],
    );
    let seq = TumSequence::open(&dir, OpenOptions::default()).unwrap();
    let err = seq.load(0).unwrap_err();
    match &err {
        PlaybackError::WrongFormat { path, expected, .. } => {
            assert_eq!(path, &img);
            assert_eq!(*expected, "16-bit grayscale");
        }
        e => panic!("wrong error {e:?}"),
    }
    // The other frames still load.
    assert!(seq.load(1).is_ok());

    // A 16-bit colour image is wrong too.
    let img = first_image(&dir, "rgb.txt");
    write_png(
        &img,
        4,
        4,
        png::ColorType::Rgb,
        png::BitDepth::Sixteen,
        &[0u8; 4 * 4 * 6],
    );
    assert!(matches!(
        seq.load(0),
        Err(PlaybackError::WrongFormat {
            expected: "8-bit RGB or RGBA",
            ..
        })
    ));
}

#[test]
fn mismatched_sizes_are_rejected() {
    let dir = copy_shipped("sizes");
    let img = first_image(&dir, "depth.txt");
    write_png(
        &img,
        320,
        240,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &vec![0u8; 320 * 240 * 2],
    );
    let seq = TumSequence::open(&dir, OpenOptions::default()).unwrap();
    match seq.load(0).unwrap_err() {
        PlaybackError::SizeMismatch {
            rgb,
            depth,
            depth_path,
            ..
        } => {
            assert_eq!(rgb, (640, 480));
            assert_eq!(depth, (320, 240));
            assert_eq!(depth_path, img);
        }
        e => panic!("wrong error {e:?}"),
    }
}

#[test]
fn corrupt_png_is_a_decode_error() {
    let dir = copy_shipped("corrupt");
    let img = first_image(&dir, "rgb.txt");
    std::fs::write(&img, b"not a png at all").unwrap();
    let seq = TumSequence::open(&dir, OpenOptions::default()).unwrap();
    let mut driver = PlaybackDriver::new(seq, PlaybackMode::Recorded);
    match driver.next_frame(0.0) {
        Err(DriverError::Playback(PlaybackError::Png { path, .. })) => assert_eq!(path, img),
        other => panic!("wrong result {other:?}"),
    }
}

#[test]
fn no_pairs_is_an_error() {
    let dir = copy_shipped("no-pairs");
    // Shift all depth timestamps by 1 s: nothing pairs within 20 ms.
    let text = std::fs::read_to_string(dir.join("depth.txt")).unwrap();
    let shifted: String = text
        .lines()
        .map(|l| {
            if l.starts_with('#') {
                format!("{l}\n")
            } else {
                let mut it = l.split_whitespace();
                let t: f64 = it.next().unwrap().parse().unwrap();
                format!("{:.6} {}\n", t + 1.0, it.next().unwrap())
            }
        })
        .collect();
    std::fs::write(dir.join("depth.txt"), shifted).unwrap();
    assert!(matches!(
        TumSequence::open(&dir, OpenOptions::default()),
        Err(PlaybackError::Empty { .. })
    ));
}
