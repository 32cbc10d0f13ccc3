//! The dump format Debian's `fakenect` replays (libfreenect's `fakenect/fakenect.c` and the
//! `fakenect-record` tool that writes it), so a simulated camera can send its frames through the
//! real library's code.
//!
//! A dump is a folder with one file per sample and an `INDEX.txt` listing them in order, one file
//! name a line. A name is `TYPE-TIME-TIMESTAMP.EXT`: `TYPE` is `r` (colour), `d` (depth) or `a`
//! (accelerometer and tilt), `TIME` the host time of the sample in seconds (fakenect sleeps the
//! recorded gaps), `TIMESTAMP` the device's 32-bit frame timestamp.
//! - `r-*.ppm`: `P6 640 480 255\n` and 640x480 RGB8.
//! - `d-*.pgm`: `P5 640 480 65535\n` and 640x480 11-bit raw disparities as host-endian `u16`
//!   (what the sensor sends in `FREENECT_DEPTH_11BIT`; 2047 = no measurement).
//! - `a-*.dump`: a `freenect_raw_tilt_state`: accelerometer x, y, z (`i16`, 819 counts per g),
//!   tilt angle (`i8`, half degrees), padding, tilt status (`i32`).
//!
//! fakenect opens a sample's file as soon as it reads its line, and ends the process if the file
//! is missing, so a writer writes the file first and the line after.
//!
//! [`DumpWriter`] writes a finished folder. [`LiveDump`] streams: its `INDEX.txt` is a FIFO, so a
//! driver reading through fakenect gets frames as the simulated device renders them. A frame
//! offered while the reader has not yet taken the previous lines is dropped (counted), as a real
//! camera drops frames the host does not collect: the files of the last few frames are kept and
//! older ones removed, so the folder stays small. fakenect sleeps between two samples what their
//! recorded times say, less the time it has spent since the previous one; for a live source that
//! sleep only piles up delay (the reader waits for the writer anyway, then waits again), so a
//! live dump records its samples a microsecond apart and the FIFO alone paces the stream.

use std::collections::VecDeque;
use std::fs::File;
use std::io::Write;
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};

use crate::{HEIGHT, PIXELS, WIDTH};

/// Errors of the dump writers.
#[derive(Debug, thiserror::Error)]
pub enum DumpError {
    /// A file of the dump cannot be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A buffer does not hold one 640x480 image.
    #[error("{what} buffer has {len} values, expected {expected}")]
    Size {
        /// `"rgb"` or `"depth"`.
        what: &'static str,
        /// Values found.
        len: usize,
        /// Values expected.
        expected: usize,
    },
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> DumpError + '_ {
    move |source| DumpError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The accelerometer and tilt motor state a dump carries (`freenect_raw_tilt_state`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RawTilt {
    /// Accelerometer counts (819 per g) along the device's x, y, z.
    pub accel: [i16; 3],
    /// Tilt angle, half degrees.
    pub tilt_half_deg: i8,
    /// Tilt motor status (0 stopped, 1 at limit, 4 moving).
    pub status: i32,
}

impl RawTilt {
    /// The 12 bytes of the C struct (x86-64 and ARM little-endian layout).
    pub fn to_bytes(&self) -> [u8; 12] {
        let mut b = [0u8; 12];
        b[0..2].copy_from_slice(&self.accel[0].to_le_bytes());
        b[2..4].copy_from_slice(&self.accel[1].to_le_bytes());
        b[4..6].copy_from_slice(&self.accel[2].to_le_bytes());
        b[6] = self.tilt_half_deg.to_le_bytes()[0];
        b[8..12].copy_from_slice(&self.status.to_le_bytes());
        b
    }
}

/// The file name of a sample: `TYPE-TIME-TIMESTAMP.EXT` as fakenect-record writes it.
pub fn file_name(kind: char, time_s: f64, device_ts: u32) -> String {
    let ext = match kind {
        'r' => "ppm",
        'd' => "pgm",
        _ => "dump",
    };
    format!("{kind}-{time_s:.6}-{device_ts}.{ext}")
}

fn rgb_bytes(rgb: &[u8]) -> Result<Vec<u8>, DumpError> {
    if rgb.len() != PIXELS * 3 {
        return Err(DumpError::Size {
            what: "rgb",
            len: rgb.len(),
            expected: PIXELS * 3,
        });
    }
    let mut out = format!("P6 {WIDTH} {HEIGHT} 255\n").into_bytes();
    out.extend_from_slice(rgb);
    Ok(out)
}

fn depth_bytes(raw: &[u16]) -> Result<Vec<u8>, DumpError> {
    if raw.len() != PIXELS {
        return Err(DumpError::Size {
            what: "depth",
            len: raw.len(),
            expected: PIXELS,
        });
    }
    let mut out = format!("P5 {WIDTH} {HEIGHT} 65535\n").into_bytes();
    out.reserve(PIXELS * 2);
    for r in raw {
        out.extend_from_slice(&r.to_ne_bytes());
    }
    Ok(out)
}

fn write_file(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), DumpError> {
    let path = dir.join(name);
    std::fs::write(&path, bytes).map_err(io_err(&path))
}

/// Writes a finished dump folder (a recording to replay).
#[derive(Debug)]
pub struct DumpWriter {
    dir: PathBuf,
    index: File,
}

impl DumpWriter {
    /// Creates `dir` (and its parents) and an empty `INDEX.txt` in it.
    pub fn create(dir: &Path) -> Result<DumpWriter, DumpError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        let path = dir.join("INDEX.txt");
        let index = File::create(&path).map_err(io_err(&path))?;
        Ok(DumpWriter {
            dir: dir.to_path_buf(),
            index,
        })
    }

    fn line(&mut self, name: &str) -> Result<(), DumpError> {
        let path = self.dir.join("INDEX.txt");
        writeln!(self.index, "{name}").map_err(io_err(&path))
    }

    /// Appends a colour image (640x480 RGB8).
    pub fn rgb(&mut self, time_s: f64, device_ts: u32, rgb: &[u8]) -> Result<(), DumpError> {
        let name = file_name('r', time_s, device_ts);
        write_file(&self.dir, &name, &rgb_bytes(rgb)?)?;
        self.line(&name)
    }

    /// Appends a depth image (640x480 11-bit raw disparities).
    pub fn depth(&mut self, time_s: f64, device_ts: u32, raw: &[u16]) -> Result<(), DumpError> {
        let name = file_name('d', time_s, device_ts);
        write_file(&self.dir, &name, &depth_bytes(raw)?)?;
        self.line(&name)
    }

    /// Appends an accelerometer and tilt sample.
    pub fn tilt(&mut self, time_s: f64, device_ts: u32, t: &RawTilt) -> Result<(), DumpError> {
        let name = file_name('a', time_s, device_ts);
        write_file(&self.dir, &name, &t.to_bytes())?;
        self.line(&name)
    }
}

nix::ioctl_read_bad!(fionread, nix::libc::FIONREAD, nix::libc::c_int);

/// Bytes written into a pipe and not yet read (`FIONREAD`).
fn unread_bytes(fd: &File) -> std::io::Result<usize> {
    let mut n: nix::libc::c_int = 0;
    // SAFETY: FIONREAD on a pipe writes one int through the pointer, which is valid for the call.
    unsafe { fionread(fd.as_raw_fd(), &mut n) }.map_err(std::io::Error::from)?;
    Ok(usize::try_from(n).unwrap_or(0))
}

/// True when nobody has the FIFO open for reading any more (`POLLERR` on the write end).
fn reader_gone(fd: &File) -> bool {
    use nix::poll::{PollFd, PollFlags, PollTimeout, poll};
    use std::os::fd::AsFd;
    let mut fds = [PollFd::new(fd.as_fd(), PollFlags::POLLOUT)];
    match poll(&mut fds, PollTimeout::ZERO) {
        Ok(_) => fds[0]
            .revents()
            .is_some_and(|r| r.contains(PollFlags::POLLERR)),
        Err(_) => true,
    }
}

/// What [`LiveDump::offer`] did with a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offer {
    /// Written; the reader will get it.
    Sent,
    /// No reader has the FIFO open (the driver is not running, or restarting).
    NoReader,
    /// The reader has not taken the previous frame yet: this one is dropped.
    ReaderBehind,
}

/// Number of frames whose files are kept in a live dump (older ones are removed).
pub const LIVE_KEEP_FRAMES: usize = 30;

/// Sample files of a previous stream older than this are removed when a live dump is created.
pub const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(10);

/// A live dump folder whose `INDEX.txt` is a FIFO: frames go to a fakenect reader as they are
/// offered.
#[derive(Debug)]
pub struct LiveDump {
    dir: PathBuf,
    fifo: PathBuf,
    writer: Option<File>,
    kept: VecDeque<Vec<PathBuf>>,
    /// The time written into the next sample's name (s): a microsecond a frame.
    clock_s: f64,
}

impl LiveDump {
    /// Creates `dir` and the FIFO `dir/INDEX.txt` (replacing a file of that name that is not a
    /// FIFO) and removes sample files more than [`STALE_AFTER`] old (a reader of a previous
    /// stream may still need the newest ones).
    pub fn create(dir: &Path) -> Result<LiveDump, DumpError> {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
        for entry in std::fs::read_dir(dir).map_err(io_err(dir))?.flatten() {
            let name = entry.file_name();
            let name = name.to_string_lossy();
            let sample = [".ppm", ".pgm", ".dump"].iter().any(|e| name.ends_with(e));
            let stale = entry
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_none_or(|age| age > STALE_AFTER);
            if sample && stale {
                let _ = std::fs::remove_file(entry.path());
            }
        }
        // A FIFO left by a writer that died is reused: a reader may already be waiting on it
        // (a new FIFO in its place would leave that reader blocked forever).
        let fifo = dir.join("INDEX.txt");
        let is_fifo = std::fs::symlink_metadata(&fifo)
            .map(|m| std::os::unix::fs::FileTypeExt::is_fifo(&m.file_type()))
            .unwrap_or(false);
        if !is_fifo {
            let _ = std::fs::remove_file(&fifo);
            nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::from_bits_truncate(0o644)).map_err(
                |e| DumpError::Io {
                    path: fifo.clone(),
                    source: e.into(),
                },
            )?;
        }
        Ok(LiveDump {
            dir: dir.to_path_buf(),
            fifo,
            writer: None,
            kept: VecDeque::new(),
            clock_s: 1.0,
        })
    }

    /// The folder to give fakenect (`FAKENECT_PATH`).
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// True while a reader has the FIFO open.
    pub fn connected(&self) -> bool {
        self.writer.is_some()
    }

    /// Opens the FIFO for writing if a reader has it open (never blocks).
    fn connect(&mut self) -> Result<bool, DumpError> {
        if self.writer.is_some() {
            return Ok(true);
        }
        use std::os::unix::fs::OpenOptionsExt;
        match std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(nix::libc::O_NONBLOCK)
            .open(&self.fifo)
        {
            Ok(f) => {
                self.writer = Some(f);
                Ok(true)
            }
            // ENXIO: no reader yet.
            Err(e) if e.raw_os_error() == Some(nix::libc::ENXIO) => Ok(false),
            Err(e) => Err(io_err(&self.fifo)(e)),
        }
    }

    /// Offers one frame (colour, depth as raw disparities, and optionally the tilt state) with the
    /// device timestamp `device_ts`.
    pub fn offer(
        &mut self,
        device_ts: u32,
        rgb: &[u8],
        raw_depth: &[u16],
        tilt: Option<&RawTilt>,
    ) -> Result<Offer, DumpError> {
        let rgb = rgb_bytes(rgb)?;
        let depth = depth_bytes(raw_depth)?;
        if self.writer.as_ref().is_some_and(reader_gone) {
            // The reader went away: what it left unread goes with this end.
            self.writer = None;
        }
        if !self.connect()? {
            return Ok(Offer::NoReader);
        }
        let behind = match &self.writer {
            Some(w) => unread_bytes(w).map_err(io_err(&self.fifo))? > 0,
            None => false,
        };
        if behind {
            return Ok(Offer::ReaderBehind);
        }
        self.clock_s += 1e-6;
        let time_s = self.clock_s;
        let mut lines = String::new();
        let mut samples = vec![
            (file_name('r', time_s, device_ts), rgb),
            (file_name('d', time_s, device_ts), depth),
        ];
        if let Some(t) = tilt {
            samples.push((file_name('a', time_s, device_ts), t.to_bytes().to_vec()));
        }
        let mut files = Vec::with_capacity(samples.len());
        for (name, bytes) in &samples {
            write_file(&self.dir, name, bytes)?;
            files.push(self.dir.join(name));
            lines.push_str(name);
            lines.push('\n');
        }
        self.kept.push_back(files);
        // One write of a few dozen bytes into an empty pipe is atomic and never short.
        let result = match self.writer.as_mut() {
            Some(w) => w.write_all(lines.as_bytes()),
            None => Ok(()),
        };
        while self.kept.len() > LIVE_KEEP_FRAMES {
            for old in self.kept.pop_front().unwrap_or_default() {
                let _ = std::fs::remove_file(old);
            }
        }
        match result {
            Ok(()) => Ok(Offer::Sent),
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {
                // The reader went away: wait for the next one.
                self.writer = None;
                Ok(Offer::NoReader)
            }
            Err(e) => Err(io_err(&self.fifo)(e)),
        }
    }
}

impl Drop for LiveDump {
    /// Removes the FIFO and the sample files but the two newest frames', which the reader may
    /// still be about to open (it reads the FIFO through a stdio buffer, so an empty pipe can
    /// still mean one frame's lines not yet acted on; fakenect ends its process when a listed
    /// file is missing); the next live dump in the folder removes those once they are stale.
    fn drop(&mut self) {
        let _ = self.kept.pop_back();
        let _ = self.kept.pop_back();
        for f in self.kept.drain(..).flatten() {
            let _ = std::fs::remove_file(f);
        }
        let _ = std::fs::remove_file(&self.fifo);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{BufRead, BufReader, Read};

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("robocog-fakenect-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn names_follow_fakenect_record() {
        assert_eq!(file_name('r', 12.5, 7), "r-12.500000-7.ppm");
        assert_eq!(file_name('d', 1.0, 0), "d-1.000000-0.pgm");
        assert_eq!(file_name('a', 1.0, 9), "a-1.000000-9.dump");
    }

    #[test]
    fn tilt_state_has_the_c_layout() {
        let b = RawTilt {
            accel: [1, -819, 2],
            tilt_half_deg: -6,
            status: 4,
        }
        .to_bytes();
        assert_eq!(b, [1, 0, 0xcd, 0xfc, 2, 0, 0xfa, 0, 4, 0, 0, 0]);
    }

    #[test]
    fn a_dump_folder_lists_its_samples_in_order() {
        let dir = scratch("folder");
        let mut w = DumpWriter::create(&dir).unwrap();
        let rgb = vec![7u8; PIXELS * 3];
        let raw = vec![800u16; PIXELS];
        w.rgb(1.0, 10, &rgb).unwrap();
        w.depth(1.0, 11, &raw).unwrap();
        w.tilt(1.0, 11, &RawTilt::default()).unwrap();
        assert!(matches!(
            w.rgb(1.0, 12, &rgb[1..]),
            Err(DumpError::Size { what: "rgb", .. })
        ));
        let index = std::fs::read_to_string(dir.join("INDEX.txt")).unwrap();
        let lines: Vec<&str> = index.lines().collect();
        assert_eq!(
            lines,
            [
                "r-1.000000-10.ppm",
                "d-1.000000-11.pgm",
                "a-1.000000-11.dump"
            ]
        );
        let d = std::fs::read(dir.join(lines[1])).unwrap();
        let header = b"P5 640 480 65535\n";
        assert_eq!(&d[..header.len()], header);
        assert_eq!(d.len(), header.len() + PIXELS * 2);
        assert_eq!(
            u16::from_ne_bytes([d[header.len()], d[header.len() + 1]]),
            800
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_live_dump_drops_frames_the_reader_has_not_taken() {
        let dir = scratch("live");
        let mut live = LiveDump::create(&dir).unwrap();
        let rgb = vec![1u8; PIXELS * 3];
        let raw = vec![900u16; PIXELS];
        assert_eq!(live.offer(0, &rgb, &raw, None).unwrap(), Offer::NoReader);
        let reader = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags_nonblock()
            .open(dir.join("INDEX.txt"))
            .unwrap();
        assert_eq!(live.offer(1, &rgb, &raw, None).unwrap(), Offer::Sent);
        assert_eq!(
            live.offer(2, &rgb, &raw, None).unwrap(),
            Offer::ReaderBehind
        );
        let mut r = BufReader::new(reader);
        let mut line = String::new();
        r.read_line(&mut line).unwrap();
        assert_eq!(line.trim(), "r-1.000001-1.ppm");
        assert!(dir.join(line.trim()).exists());
        line.clear();
        r.read_line(&mut line).unwrap();
        assert_eq!(line.trim(), "d-1.000001-1.pgm");
        assert_eq!(live.offer(3, &rgb, &raw, None).unwrap(), Offer::Sent);
        // Old files are removed once more than LIVE_KEEP_FRAMES frames were sent.
        let mut rest = Vec::new();
        for i in 0..LIVE_KEEP_FRAMES + 2 {
            r.read_to_end(&mut rest).ok();
            live.offer(10 + i as u32, &rgb, &raw, None).unwrap();
        }
        let files = std::fs::read_dir(&dir).unwrap().count();
        assert!(files <= LIVE_KEEP_FRAMES * 2 + 1, "{files} files kept");
        // The reader closes: the next offer finds no reader and does not fail.
        drop(r);
        assert_eq!(live.offer(99, &rgb, &raw, None).unwrap(), Offer::NoReader);
        drop(live);
        assert!(!dir.join("INDEX.txt").exists());
        let left = std::fs::read_dir(&dir).unwrap().count();
        assert_eq!(
            left, 4,
            "the two newest frames' files stay for a late reader"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    trait NonBlock {
        fn custom_flags_nonblock(&mut self) -> &mut Self;
    }
    impl NonBlock for std::fs::OpenOptions {
        fn custom_flags_nonblock(&mut self) -> &mut Self {
            use std::os::unix::fs::OpenOptionsExt;
            self.custom_flags(nix::libc::O_NONBLOCK)
        }
    }
}
