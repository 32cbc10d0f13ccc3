//! The `freenect` driver: a Kinect v1 (or another camera libfreenect drives) through libfreenect,
//! and the simulated Kinect that feeds the same driver through Debian's fakenect.
//!
//! The device is pumped on a thread of its own ([`KinectSource::open`]), which owns the
//! libfreenect context, converts every colour and depth pair into a registered [`Frame`] and
//! hands it over through a small queue (a frame the component has not taken when the next one is
//! ready is dropped and counted, as a camera drops frames a slow host does not collect). When the
//! device fails (unplugged, or a fakenect dump's end), the thread says so, drops the library and
//! opens it again every second until the device is back; the component reports both on
//! `diagnostics` and `vision/camera_status`.
//!
//! Depth is registered to the colour camera by libfreenect where it can
//! (`FREENECT_DEPTH_REGISTERED`, with the calibration the device carries); fakenect cannot, so
//! there the driver asks for the 11-bit disparities and registers them itself
//! ([`freenect::kinect::register`]) with the nominal Kinect calibration or the depth camera's
//! camera_info file. The intrinsics published with every frame are the colour camera's: from
//! its camera_info file (`--rgb-camera-info`), else the nominal 525 px.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use freenect::Pinhole;
use freenect::calibration::CameraInfo;
use freenect::device::{DepthFormat, Device, DeviceError, Library, RawFrame, Tilt};
use freenect::fakenect::{LiveDump, Offer, RawTilt};
use freenect::kinect::{DepthCalibration, RawToMm, register, unregister};

use camera::{Frame, Intrinsics};

/// Which depth format to ask the device for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DepthMode {
    /// Registered by libfreenect where the library can, else raw (fakenect).
    Auto,
    /// libfreenect's registration (needs the real library and a device that carries it).
    Registered,
    /// 11-bit disparities, registered by robocog with the calibration.
    Raw,
}

/// Where libfreenect comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LibraryChoice {
    /// `libfreenect.so.0.5` through the loader's search.
    System,
    /// Debian's fakenect stand-in, replaying the dump `FAKENECT_PATH` names.
    Fakenect,
    /// A library file.
    Path(PathBuf),
}

impl LibraryChoice {
    /// `system`, `fakenect` or a path.
    pub fn parse(s: &str) -> Result<LibraryChoice, String> {
        Ok(match s {
            "system" => LibraryChoice::System,
            "fakenect" => LibraryChoice::Fakenect,
            "" => return Err("empty library name (use system, fakenect or a path)".into()),
            p => LibraryChoice::Path(PathBuf::from(p)),
        })
    }

    /// The file to load, `None` for the loader's search.
    pub fn resolve(&self) -> anyhow::Result<Option<PathBuf>> {
        match self {
            LibraryChoice::System => Ok(None),
            LibraryChoice::Path(p) => Ok(Some(p.clone())),
            LibraryChoice::Fakenect => fakenect_library().map(Some).context(
                "fakenect's libfreenect is not installed (Debian's libfreenect-dev ships it in \
                 /usr/lib/<triplet>/fakenect/): apt-get install libfreenect-dev",
            ),
        }
    }
}

/// Debian's fakenect library (`/usr/lib/<triplet>/fakenect/libfreenect.so.0.5`), if installed.
pub fn fakenect_library() -> Option<PathBuf> {
    let mut dirs = vec![PathBuf::from("/usr/lib/fakenect")];
    if let Ok(entries) = std::fs::read_dir("/usr/lib") {
        dirs.extend(entries.flatten().map(|e| e.path().join("fakenect")));
    }
    dirs.push(PathBuf::from("/usr/local/lib/fakenect"));
    dirs.into_iter()
        .map(|d| d.join("libfreenect.so.0.5"))
        .find(|p| p.is_file())
}

/// What the driver needs to know, from the component's flags.
#[derive(Debug, Clone)]
pub struct KinectConfig {
    /// The library.
    pub library: LibraryChoice,
    /// Camera index (0: the first).
    pub index: u32,
    /// Depth format.
    pub depth_mode: DepthMode,
    /// The colour camera's camera_info file.
    pub rgb_camera_info: Option<PathBuf>,
    /// The depth camera's camera_info file (raw mode).
    pub depth_camera_info: Option<PathBuf>,
    /// The depth camera's origin in the colour camera's optical frame (m, raw mode).
    pub depth_origin_m: [f64; 3],
}

/// What the pump thread tells the component.
#[derive(Debug)]
pub enum Event {
    /// One registered frame, with when it was taken from libfreenect.
    Frame(Box<Frame>, Instant, FrameStats),
    /// The device is streaming (first open, or back after a loss).
    Opened {
        /// A readable description (library, format, serials).
        description: String,
    },
    /// The device stopped delivering (error from libfreenect); reopening.
    Lost {
        /// Why.
        reason: String,
    },
    /// Opening failed again while reopening (said once per loss).
    StillAway {
        /// Why.
        reason: String,
    },
    /// The tilt motor and accelerometer, about once a second.
    Tilt(Tilt),
}

/// What one frame held: counted by the component.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Pixels with a depth measurement after registration.
    pub depth_pixels: usize,
    /// Colour pixels saturated on every channel.
    pub saturated_pixels: usize,
}

impl FrameStats {
    /// Of `frame`.
    pub fn of(frame: &Frame) -> FrameStats {
        FrameStats {
            depth_pixels: frame.depth_mm.iter().filter(|&&d| d != 0).count(),
            saturated_pixels: frame
                .rgb
                .chunks_exact(3)
                .filter(|p| p[0] == 255 && p[1] == 255 && p[2] == 255)
                .count(),
        }
    }
}

/// Converts the device's frames into registered frames.
#[derive(Debug)]
pub struct Converter {
    rgb: Pinhole,
    calib: DepthCalibration,
    table: RawToMm,
}

impl Converter {
    /// With the colour camera's intrinsics and the depth camera's calibration.
    pub fn new(rgb: Pinhole, calib: DepthCalibration) -> Converter {
        Converter {
            rgb,
            calib,
            table: RawToMm::default(),
        }
    }

    /// The frame's intrinsics.
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            fx: self.rgb.fx,
            fy: self.rgb.fy,
            cx: self.rgb.cx,
            cy: self.rgb.cy,
        }
    }

    /// A registered frame from the device's pair (`timestamp_s` is set by the caller).
    pub fn convert(&self, raw: RawFrame) -> Frame {
        let depth_mm = match raw.format {
            DepthFormat::Registered => raw.depth,
            DepthFormat::Raw11 => {
                let mut out = vec![0u16; freenect::PIXELS];
                register(&raw.depth, &self.table, &self.calib, &self.rgb, &mut out);
                out
            }
        };
        Frame {
            width: freenect::WIDTH as u32,
            height: freenect::HEIGHT as u32,
            rgb: raw.rgb,
            depth_mm,
            intrinsics: self.intrinsics(),
            timestamp_s: 0.0,
        }
    }
}

fn pinhole(i: Intrinsics) -> Pinhole {
    Pinhole {
        fx: i.fx,
        fy: i.fy,
        cx: i.cx,
        cy: i.cy,
    }
}

/// Reads the calibration files, logging what they say.
pub fn converter(config: &KinectConfig) -> anyhow::Result<Converter> {
    let rgb = match &config.rgb_camera_info {
        Some(path) => {
            let info = CameraInfo::from_file(path)?;
            if info.has_distortion() {
                tracing::warn!(
                    "{}: distortion {} {:?} is not applied (frames are published unrectified \
                     with pinhole intrinsics)",
                    path.display(),
                    info.distortion.0,
                    info.distortion.1
                );
            }
            tracing::info!(
                "colour camera {:?} from {}: fx {:.1} fy {:.1} cx {:.1} cy {:.1} (calibrated at {}x{})",
                info.camera_name,
                path.display(),
                info.intrinsics.fx,
                info.intrinsics.fy,
                info.intrinsics.cx,
                info.intrinsics.cy,
                info.calibrated_size.0,
                info.calibrated_size.1
            );
            info.intrinsics
        }
        None => pinhole(Intrinsics::KINECT_640X480),
    };
    let mut calib = DepthCalibration {
        depth_origin_in_rgb_m: config.depth_origin_m,
        ..DepthCalibration::default()
    };
    if let Some(path) = &config.depth_camera_info {
        calib.depth = CameraInfo::from_file(path)?.intrinsics;
    }
    Ok(Converter::new(rgb, calib))
}

/// The running driver: its thread's events.
#[derive(Debug)]
pub struct KinectSource {
    /// Events from the pump thread.
    pub events: tokio::sync::mpsc::Receiver<Event>,
    /// Frames the component did not take in time.
    pub dropped: Arc<std::sync::atomic::AtomicU64>,
    stop: Arc<AtomicBool>,
    /// The colour camera's intrinsics.
    pub intrinsics: Intrinsics,
}

impl Drop for KinectSource {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// fakenect ends the process when its dump has no `INDEX.txt`, so the driver checks first: an
/// error when `FAKENECT_PATH` is not set, `Ok(false)` while the index is not there yet (a
/// simulated Kinect that has not started).
fn fakenect_ready() -> anyhow::Result<bool> {
    let dir = std::env::var_os("FAKENECT_PATH").context(
        "FAKENECT_PATH is not set: fakenect replays the dump folder it names (a folder written \
         by fakenect-record, or a simulated Kinect's live dump)",
    )?;
    Ok(Path::new(&dir).join("INDEX.txt").exists())
}

fn open_device(
    choice: &LibraryChoice,
    index: u32,
    mode: DepthMode,
) -> anyhow::Result<(Device, String)> {
    if *choice == LibraryChoice::Fakenect && !fakenect_ready()? {
        anyhow::bail!(NotYet);
    }
    let path = choice.resolve()?;
    let lib = Library::load(path.as_deref())?;
    let format = match mode {
        DepthMode::Registered if !lib.registers() => anyhow::bail!(
            "{} cannot register depth (fakenect, or an old libfreenect): use --depth-mode raw",
            lib.name()
        ),
        DepthMode::Registered => DepthFormat::Registered,
        DepthMode::Raw => DepthFormat::Raw11,
        DepthMode::Auto if lib.registers() => DepthFormat::Registered,
        DepthMode::Auto => DepthFormat::Raw11,
    };
    let name = lib.name().to_string();
    let device = Device::open(lib, index, format)?;
    let description = format!(
        "camera {index} through {name}, depth {}{}",
        match format {
            DepthFormat::Registered => "registered by libfreenect",
            DepthFormat::Raw11 => "as 11-bit disparities, registered here",
        },
        if device.serials().is_empty() {
            String::new()
        } else {
            format!(", serials {}", device.serials().join(", "))
        }
    );
    Ok((device, description))
}

/// The fakenect dump's index is not there yet.
#[derive(Debug, thiserror::Error)]
#[error("the fakenect dump has no INDEX.txt yet (is the simulated Kinect running?)")]
struct NotYet;

/// Whether an open error is one that waiting can fix (a device not there yet) rather than a
/// configuration mistake (no library, a library that is not libfreenect).
fn is_config_error(e: &anyhow::Error) -> bool {
    matches!(
        e.downcast_ref::<DeviceError>(),
        Some(DeviceError::Load { .. } | DeviceError::Symbol { .. })
    ) || (e.downcast_ref::<DeviceError>().is_none() && e.downcast_ref::<NotYet>().is_none())
}

impl KinectSource {
    /// Opens the camera once (a missing library, no camera, a bad calibration file: an error
    /// now, before the component joins the bus), then keeps it streaming on its own thread.
    #[expect(
        clippy::disallowed_methods,
        reason = "waits, blocking, for the camera device to appear before the component joins the \
                  bus: device time"
    )]
    pub fn open(config: &KinectConfig) -> anyhow::Result<KinectSource> {
        let conv = converter(config)?;
        let intrinsics = conv.intrinsics();
        let mut waited = false;
        let (device, description) = loop {
            match open_device(&config.library, config.index, config.depth_mode) {
                Err(e) if e.downcast_ref::<NotYet>().is_some() => {
                    if interfaces::node::preflight() {
                        // The simulated Kinect of the running graph writes it.
                        return Err(interfaces::node::NotYetCheckable(e.to_string()).into());
                    }
                    if !waited {
                        waited = true;
                        tracing::info!("{e}: waiting for it");
                    }
                    std::thread::sleep(Duration::from_millis(100));
                }
                r => break r.context("cannot open the RGB-D camera")?,
            }
        };
        drop(device);
        tracing::info!("{description}");
        let (tx, rx) = tokio::sync::mpsc::channel(4);
        let stop = Arc::new(AtomicBool::new(false));
        let dropped = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let (stop2, dropped2, config2) = (stop.clone(), dropped.clone(), config.clone());
        std::thread::Builder::new()
            .name("freenect".into())
            .spawn(move || pump(config2, conv, tx, stop2, dropped2))
            .context("cannot start the camera thread")?;
        Ok(KinectSource {
            events: rx,
            dropped,
            stop,
            intrinsics,
        })
    }
}

/// The pump thread: open, stream, and reopen after a loss, until `stop` or the component's end.
#[expect(
    clippy::disallowed_methods,
    reason = "the camera's device thread: it polls and reopens the real device and reads its tilt \
              on the wall, and stamps each frame's arrival for its age"
)]
fn pump(
    config: KinectConfig,
    conv: Converter,
    tx: tokio::sync::mpsc::Sender<Event>,
    stop: Arc<AtomicBool>,
    dropped: Arc<std::sync::atomic::AtomicU64>,
) {
    let mut lost_reported = false;
    while !stop.load(Ordering::Relaxed) && !tx.is_closed() {
        let (mut device, description) =
            match open_device(&config.library, config.index, config.depth_mode) {
                Ok(d) => d,
                Err(e) => {
                    if !lost_reported {
                        lost_reported = true;
                        let _ = tx.blocking_send(Event::StillAway {
                            reason: format!("{e:#}"),
                        });
                    }
                    if is_config_error(&e) {
                        tracing::error!("{e:#}");
                    }
                    std::thread::sleep(Duration::from_secs(1));
                    continue;
                }
            };
        lost_reported = false;
        if tx.blocking_send(Event::Opened { description }).is_err() {
            return;
        }
        let mut last_tilt = Instant::now();
        let reason = loop {
            if stop.load(Ordering::Relaxed) || tx.is_closed() {
                return;
            }
            match device.poll(Duration::from_millis(100)) {
                Ok(Some(raw)) => {
                    let at = Instant::now();
                    let frame = conv.convert(raw);
                    let stats = FrameStats::of(&frame);
                    match tx.try_send(Event::Frame(Box::new(frame), at, stats)) {
                        Ok(()) => {}
                        Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {
                            dropped.fetch_add(1, Ordering::Relaxed);
                        }
                        Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => return,
                    }
                }
                Ok(None) => {}
                Err(e) => break e.to_string(),
            }
            if last_tilt.elapsed() >= Duration::from_secs(1) {
                last_tilt = Instant::now();
                if let Some(t) = device.tilt() {
                    let _ = tx.try_send(Event::Tilt(t));
                }
            }
        };
        drop(device);
        if tx.blocking_send(Event::Lost { reason }).is_err() {
            return;
        }
        std::thread::sleep(Duration::from_secs(1));
    }
}

/// The simulated Kinect's side of a live fakenect dump: registered frames from the renderer are
/// turned into what the sensor sends (the depth camera's 11-bit disparities, seen from its own
/// position) and offered to the fakenect reader.
#[derive(Debug)]
pub struct KinectSim {
    dump: LiveDump,
    calib: DepthCalibration,
    raw: Vec<u16>,
    /// Frames the reader took.
    pub sent: u64,
    /// Frames dropped because the reader was behind.
    pub dropped: u64,
    waiting_reported: bool,
}

impl KinectSim {
    /// Creates the live dump in `dir`.
    pub fn create(dir: &Path, calib: DepthCalibration) -> anyhow::Result<KinectSim> {
        let dump = LiveDump::create(dir)
            .with_context(|| format!("cannot create the live fakenect dump {}", dir.display()))?;
        tracing::info!(
            "simulated Kinect: frames go to the fakenect dump {} (FAKENECT_PATH for the driver)",
            dir.display()
        );
        Ok(KinectSim {
            dump,
            calib,
            raw: vec![0; freenect::PIXELS],
            sent: 0,
            dropped: 0,
            waiting_reported: false,
        })
    }

    /// Offers a rendered frame (640x480) at host time `time_s`; `accel_mps2` is the gravity the
    /// device's accelerometer feels, in its axes.
    pub fn offer(
        &mut self,
        frame: &Frame,
        time_s: f64,
        accel_mps2: [f64; 3],
    ) -> anyhow::Result<Offer> {
        anyhow::ensure!(
            frame.width as usize == freenect::WIDTH && frame.height as usize == freenect::HEIGHT,
            "the simulated Kinect sends 640x480 frames, not {}x{}",
            frame.width,
            frame.height
        );
        unregister(
            &frame.depth_mm,
            &self.calib,
            &pinhole(frame.intrinsics),
            &mut self.raw,
        );
        let tilt = RawTilt {
            accel: accel_mps2
                .map(|a| (a / 9.80665 * 819.0).round().clamp(-32768.0, 32767.0) as i16),
            tilt_half_deg: 0,
            status: 0,
        };
        // The device's 32-bit timestamp: microseconds of the host time, wrapping.
        let device_ts = ((time_s * 1e6) as u64 & 0xffff_ffff) as u32;
        let offer = self
            .dump
            .offer(device_ts, &frame.rgb, &self.raw, Some(&tilt))?;
        match offer {
            Offer::Sent => {
                self.sent += 1;
                self.waiting_reported = false;
            }
            Offer::ReaderBehind => self.dropped += 1,
            Offer::NoReader => {
                if !self.waiting_reported {
                    self.waiting_reported = true;
                    tracing::info!(
                        "simulated Kinect: no driver reads {} yet; frames are dropped until one does",
                        self.dump.dir().display()
                    );
                }
            }
        }
        Ok(offer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn library_choices() {
        assert_eq!(LibraryChoice::parse("system"), Ok(LibraryChoice::System));
        assert_eq!(
            LibraryChoice::parse("fakenect"),
            Ok(LibraryChoice::Fakenect)
        );
        assert_eq!(
            LibraryChoice::parse("/opt/lib/libfreenect.so"),
            Ok(LibraryChoice::Path("/opt/lib/libfreenect.so".into()))
        );
        assert!(LibraryChoice::parse("").is_err());
    }

    #[test]
    fn frame_stats_count_depth_and_saturation() {
        let mut f = Frame::blank(4, 2, Intrinsics::KINECT_640X480, 0.0);
        f.depth_mm[3] = 900;
        f.rgb[0..3].copy_from_slice(&[255, 255, 255]);
        f.rgb[3..6].copy_from_slice(&[255, 255, 0]);
        assert_eq!(
            FrameStats::of(&f),
            FrameStats {
                depth_pixels: 1,
                saturated_pixels: 1
            }
        );
    }
}
