//! libfreenect, loaded at run time, and one camera opened through it.
//!
//! The library is `libfreenect.so.0.5` (Debian's `libfreenect0.5`) found the usual way
//! (`LD_LIBRARY_PATH` first), or a path given by the caller. Loading it at run time rather than
//! linking it keeps the rest of robocog buildable without it, gives a clear error naming the
//! package when it is missing, and lets Debian's fakenect library (same name, in
//! `/usr/lib/<triplet>/fakenect/`) stand in for the device in tests.
//!
//! A [`Device`] is not `Send`: libfreenect calls back from inside its event loop, on the thread
//! that pumps it, so one thread opens the device, pumps it ([`Device::poll`]) and drops it.
//! Frames are copied out of libfreenect's buffers in its callbacks and handed out in pairs (the
//! newest colour and depth images once both have arrived since the last pair).

use std::cell::Cell;
use std::ffi::{CStr, c_char, c_int, c_void};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::{HEIGHT, PIXELS, WIDTH};

/// The library name tried when none is given.
pub const DEFAULT_LIBRARY: &str = "libfreenect.so.0.5";

#[repr(C)]
struct Ctx {
    _private: [u8; 0],
}
#[repr(C)]
struct Dev {
    _private: [u8; 0],
}

/// `freenect_frame_mode` (24 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct FrameMode {
    reserved: u32,
    resolution: c_int,
    format: i32,
    bytes: i32,
    width: i16,
    height: i16,
    data_bits_per_pixel: i8,
    padding_bits_per_pixel: i8,
    framerate: i8,
    is_valid: i8,
}

/// `freenect_raw_tilt_state`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct RawTiltState {
    accel: [i16; 3],
    tilt_angle: i8,
    tilt_status: c_int,
}

#[repr(C)]
struct DeviceAttributes {
    next: *mut DeviceAttributes,
    camera_serial: *const c_char,
}

const RESOLUTION_MEDIUM: c_int = 1;
const VIDEO_RGB: i32 = 0;
const DEPTH_11BIT: i32 = 0;
const DEPTH_REGISTERED: i32 = 4;
const DEVICE_CAMERA: c_int = 2;
const DEVICE_MOTOR: c_int = 1;
const LOG_WARNING: c_int = 2;
const COUNTS_PER_G: f64 = 819.0;
const GRAVITY: f64 = 9.80665;

type FrameCb = unsafe extern "C" fn(*mut Dev, *mut c_void, u32);
type LogCb = unsafe extern "C" fn(*mut Ctx, c_int, *const c_char);

struct Fns {
    init: unsafe extern "C" fn(*mut *mut Ctx, *mut c_void) -> c_int,
    shutdown: unsafe extern "C" fn(*mut Ctx) -> c_int,
    set_log_level: unsafe extern "C" fn(*mut Ctx, c_int),
    set_log_callback: unsafe extern "C" fn(*mut Ctx, Option<LogCb>),
    select_subdevices: unsafe extern "C" fn(*mut Ctx, c_int),
    num_devices: unsafe extern "C" fn(*mut Ctx) -> c_int,
    open_device: unsafe extern "C" fn(*mut Ctx, *mut *mut Dev, c_int) -> c_int,
    close_device: unsafe extern "C" fn(*mut Dev) -> c_int,
    set_depth_callback: unsafe extern "C" fn(*mut Dev, Option<FrameCb>),
    set_video_callback: unsafe extern "C" fn(*mut Dev, Option<FrameCb>),
    find_video_mode: unsafe extern "C" fn(c_int, i32) -> FrameMode,
    find_depth_mode: unsafe extern "C" fn(c_int, i32) -> FrameMode,
    set_video_mode: unsafe extern "C" fn(*mut Dev, FrameMode) -> c_int,
    set_depth_mode: unsafe extern "C" fn(*mut Dev, FrameMode) -> c_int,
    start_depth: unsafe extern "C" fn(*mut Dev) -> c_int,
    start_video: unsafe extern "C" fn(*mut Dev) -> c_int,
    stop_depth: unsafe extern "C" fn(*mut Dev) -> c_int,
    stop_video: unsafe extern "C" fn(*mut Dev) -> c_int,
    process_events_timeout: unsafe extern "C" fn(*mut Ctx, *mut nix::libc::timeval) -> c_int,
    update_tilt_state: unsafe extern "C" fn(*mut Dev) -> c_int,
    get_tilt_state: unsafe extern "C" fn(*mut Dev) -> *mut RawTiltState,
    list_device_attributes:
        Option<unsafe extern "C" fn(*mut Ctx, *mut *mut DeviceAttributes) -> c_int>,
    free_device_attributes: Option<unsafe extern "C" fn(*mut DeviceAttributes)>,
}

/// Errors of the library and the device.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// The library cannot be loaded.
    #[error(
        "cannot load libfreenect ({name}): {reason}\n  install Debian's libfreenect0.5 \
         (apt-get install libfreenect0.5), or give the library's path"
    )]
    Load {
        /// The name or path tried.
        name: String,
        /// The loader's message.
        reason: String,
    },
    /// The library lacks a function of the libfreenect 0.5 API.
    #[error("{name} is not libfreenect 0.5: it has no {symbol}")]
    Symbol {
        /// The library.
        name: String,
        /// The missing function.
        symbol: &'static str,
    },
    /// `freenect_init` failed (libusb could not start).
    #[error("libfreenect could not start (freenect_init returned {0}): is libusb usable here?")]
    Init(c_int),
    /// No camera is connected.
    #[error(
        "no Kinect-class camera found: libfreenect sees no device.\n  {}\n  check that it is \
         plugged in and powered (the Kinect v1 needs its 12 V adapter), and that this user may \
         open it (the udev rules of libfreenect0.5)",
        usb_summary(.usb)
    )]
    NoDevice {
        /// Kinect-class USB devices the system lists, `vendor:product name`.
        usb: Vec<String>,
    },
    /// The requested device index is not connected.
    #[error("camera {index} requested, but libfreenect sees {found} ({})", serial_list(.serials))]
    NoSuchDevice {
        /// The index asked for.
        index: u32,
        /// How many there are.
        found: u32,
        /// Their serial numbers, where the library lists them.
        serials: Vec<String>,
    },
    /// Opening the camera failed.
    #[error(
        "libfreenect could not open camera {index} ({code}): it is probably in use by another \
         program, or this user lacks permission on its USB device"
    )]
    Open {
        /// The index.
        index: u32,
        /// libfreenect's return value.
        code: c_int,
    },
    /// The library refused a stream setting or failed to start or pump a stream.
    #[error("libfreenect failed to {what} ({code})")]
    Stream {
        /// What it was doing.
        what: &'static str,
        /// libfreenect's return value.
        code: c_int,
    },
}

fn usb_summary(usb: &[String]) -> String {
    if usb.is_empty() {
        "no Kinect or Xtion USB device is listed by the system either".into()
    } else {
        format!(
            "the system lists these Kinect-class USB devices: {}",
            usb.join(", ")
        )
    }
}

fn serial_list(serials: &[String]) -> String {
    if serials.is_empty() {
        "serial numbers not available".into()
    } else {
        format!("serials {}", serials.join(", "))
    }
}

/// Kinect-class USB devices in `/sys/bus/usb/devices` (`vendor:product description`): what the
/// system sees when libfreenect sees nothing.
pub fn kinect_class_usb_devices() -> Vec<String> {
    const KNOWN: [(&str, &str, &str); 6] = [
        ("045e", "02ae", "Kinect v1 camera"),
        ("045e", "02b0", "Kinect v1 motor"),
        ("045e", "02ad", "Kinect v1 audio"),
        ("045e", "02bf", "Kinect for Windows camera"),
        ("1d27", "0600", "Asus Xtion (OpenNI2, not libfreenect)"),
        (
            "1d27",
            "0601",
            "Asus Xtion PRO Live (OpenNI2, not libfreenect)",
        ),
    ];
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir("/sys/bus/usb/devices") else {
        return out;
    };
    for e in entries.flatten() {
        let read = |f: &str| {
            std::fs::read_to_string(e.path().join(f))
                .map(|s| s.trim().to_string())
                .unwrap_or_default()
        };
        let (v, p) = (read("idVendor"), read("idProduct"));
        if let Some((_, _, name)) = KNOWN.iter().find(|(kv, kp, _)| *kv == v && *kp == p) {
            out.push(format!(
                "{v}:{p} {name} at usb {}",
                e.file_name().to_string_lossy()
            ));
        }
    }
    out.sort();
    out
}

/// libfreenect, loaded.
pub struct Library {
    name: String,
    registers: bool,
    f: Fns,
    // Last: the functions above point into it.
    _lib: libloading::Library,
}

impl std::fmt::Debug for Library {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Library")
            .field("name", &self.name)
            .field("registers", &self.registers)
            .finish()
    }
}

impl Library {
    /// Loads libfreenect: `path`, or [`DEFAULT_LIBRARY`] through the dynamic loader's search.
    pub fn load(path: Option<&Path>) -> Result<Arc<Library>, DeviceError> {
        let name = path
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| DEFAULT_LIBRARY.to_string());
        let file: PathBuf = path
            .map(Path::to_path_buf)
            .unwrap_or(DEFAULT_LIBRARY.into());
        // SAFETY: loading runs the library's initialisers; libfreenect's have no preconditions.
        let lib = unsafe { libloading::Library::new(&file) }.map_err(|e| DeviceError::Load {
            name: name.clone(),
            reason: e.to_string(),
        })?;
        macro_rules! sym {
            ($n:literal) => {{
                // SAFETY: the type is the function's C signature in libfreenect.h (0.5).
                match unsafe { lib.get(concat!($n, "\0").as_bytes()) } {
                    Ok(s) => *s,
                    Err(_) => {
                        return Err(DeviceError::Symbol {
                            name: name.clone(),
                            symbol: $n,
                        });
                    }
                }
            }};
        }
        macro_rules! opt_sym {
            ($n:literal) => {{
                // SAFETY: as above.
                unsafe { lib.get(concat!($n, "\0").as_bytes()) }
                    .ok()
                    .map(|s| *s)
            }};
        }
        let f = Fns {
            init: sym!("freenect_init"),
            shutdown: sym!("freenect_shutdown"),
            set_log_level: sym!("freenect_set_log_level"),
            set_log_callback: sym!("freenect_set_log_callback"),
            select_subdevices: sym!("freenect_select_subdevices"),
            num_devices: sym!("freenect_num_devices"),
            open_device: sym!("freenect_open_device"),
            close_device: sym!("freenect_close_device"),
            set_depth_callback: sym!("freenect_set_depth_callback"),
            set_video_callback: sym!("freenect_set_video_callback"),
            find_video_mode: sym!("freenect_find_video_mode"),
            find_depth_mode: sym!("freenect_find_depth_mode"),
            set_video_mode: sym!("freenect_set_video_mode"),
            set_depth_mode: sym!("freenect_set_depth_mode"),
            start_depth: sym!("freenect_start_depth"),
            start_video: sym!("freenect_start_video"),
            stop_depth: sym!("freenect_stop_depth"),
            stop_video: sym!("freenect_stop_video"),
            process_events_timeout: sym!("freenect_process_events_timeout"),
            update_tilt_state: sym!("freenect_update_tilt_state"),
            get_tilt_state: sym!("freenect_get_tilt_state"),
            list_device_attributes: opt_sym!("freenect_list_device_attributes"),
            free_device_attributes: opt_sym!("freenect_free_device_attributes"),
        };
        // The device's own depth-to-colour registration: libfreenect has it, fakenect does not
        // (asking fakenect for FREENECT_DEPTH_REGISTERED aborts the process).
        // SAFETY: only the symbol's presence is checked; it is never called.
        let registers =
            unsafe { lib.get::<unsafe extern "C" fn()>(b"freenect_copy_registration\0") }.is_ok();
        Ok(Arc::new(Library {
            name,
            registers,
            f,
            _lib: lib,
        }))
    }

    /// The name or path it was loaded from.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Whether the library registers depth to the colour camera itself
    /// (`FREENECT_DEPTH_REGISTERED`, from the calibration stored in the device). fakenect
    /// cannot.
    pub fn registers(&self) -> bool {
        self.registers
    }
}

/// The depth format asked of the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthFormat {
    /// Millimetres on the colour camera's grid, registered by libfreenect.
    Registered,
    /// 11-bit disparities of the depth camera (robocog converts and registers).
    Raw11,
}

/// One colour and depth pair, copied out of libfreenect's buffers.
#[derive(Debug, Clone)]
pub struct RawFrame {
    /// 640x480 RGB8.
    pub rgb: Vec<u8>,
    /// 640x480 depth in the format the device was opened with.
    pub depth: Vec<u16>,
    /// The format of `depth`.
    pub format: DepthFormat,
    /// The device's timestamp of the colour image.
    pub rgb_ts: u32,
    /// The device's timestamp of the depth image.
    pub depth_ts: u32,
}

/// The accelerometer and tilt motor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tilt {
    /// Tilt motor angle, degrees.
    pub angle_deg: f64,
    /// Accelerometer, m/s², in the device's axes.
    pub accel_mps2: [f64; 3],
    /// Motor status (0 stopped, 1 at a limit, 4 moving).
    pub status: i32,
}

#[derive(Default)]
struct Sink {
    rgb: Vec<u8>,
    rgb_ts: u32,
    rgb_new: bool,
    depth: Vec<u16>,
    depth_ts: u32,
    depth_new: bool,
}

thread_local! {
    /// The sink of the device being pumped on this thread, while [`Device::poll`] runs.
    static SINK: Cell<*mut Sink> = const { Cell::new(std::ptr::null_mut()) };
}

unsafe extern "C" fn on_depth(_dev: *mut Dev, data: *mut c_void, ts: u32) {
    let sink = SINK.with(Cell::get);
    if sink.is_null() || data.is_null() {
        return;
    }
    // SAFETY: `sink` points at the pumping Device's sink for the duration of its poll (set and
    // cleared around freenect_process_events on this thread); libfreenect's depth buffer holds
    // one medium-resolution frame of 16-bit values in both formats we ask for. It is read as
    // bytes: fakenect hands out a pointer just past a PGM header, not aligned for `u16`.
    unsafe {
        let sink = &mut *sink;
        let src = std::slice::from_raw_parts(data as *const u8, PIXELS * 2);
        sink.depth.clear();
        sink.depth.extend(
            src.chunks_exact(2)
                .map(|b| u16::from_ne_bytes([b[0], b[1]])),
        );
        sink.depth_ts = ts;
        sink.depth_new = true;
    }
}

unsafe extern "C" fn on_video(_dev: *mut Dev, data: *mut c_void, ts: u32) {
    let sink = SINK.with(Cell::get);
    if sink.is_null() || data.is_null() {
        return;
    }
    // SAFETY: as in `on_depth`; the video buffer holds one 640x480 RGB8 frame.
    unsafe {
        let sink = &mut *sink;
        let src = std::slice::from_raw_parts(data as *const u8, PIXELS * 3);
        sink.rgb.clear();
        sink.rgb.extend_from_slice(src);
        sink.rgb_ts = ts;
        sink.rgb_new = true;
    }
}

unsafe extern "C" fn on_log(_ctx: *mut Ctx, level: c_int, msg: *const c_char) {
    if msg.is_null() {
        return;
    }
    // SAFETY: libfreenect passes a NUL-terminated message.
    let text = unsafe { CStr::from_ptr(msg) }.to_string_lossy();
    let text = text.trim_end();
    if level <= LOG_WARNING {
        tracing::warn!("libfreenect: {text}");
    } else {
        tracing::debug!("libfreenect: {text}");
    }
}

/// One camera, streaming colour and depth.
pub struct Device {
    lib: Arc<Library>,
    ctx: *mut Ctx,
    dev: *mut Dev,
    format: DepthFormat,
    sink: Box<Sink>,
    serials: Vec<String>,
}

impl std::fmt::Debug for Device {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Device")
            .field("library", &self.lib.name)
            .field("format", &self.format)
            .field("serials", &self.serials)
            .finish()
    }
}

impl Device {
    /// Opens camera `index` (0 = the first), sets colour to RGB8 and depth to `format` at
    /// 640x480, and starts both streams. With no camera, the error lists the Kinect-class USB
    /// devices the system sees.
    pub fn open(lib: Arc<Library>, index: u32, format: DepthFormat) -> Result<Device, DeviceError> {
        let f = &lib.f;
        let mut ctx: *mut Ctx = std::ptr::null_mut();
        // SAFETY: `ctx` is a valid out pointer; a null USB context asks libfreenect for its own.
        let rc = unsafe { (f.init)(&mut ctx, std::ptr::null_mut()) };
        if rc < 0 || ctx.is_null() {
            return Err(DeviceError::Init(rc));
        }
        let mut device = Device {
            lib: lib.clone(),
            ctx,
            dev: std::ptr::null_mut(),
            format,
            sink: Box::default(),
            serials: Vec::new(),
        };
        // SAFETY: `ctx` is the live context; the log callback is a plain function.
        unsafe {
            (f.set_log_level)(ctx, LOG_WARNING);
            (f.set_log_callback)(ctx, Some(on_log));
            (f.select_subdevices)(ctx, DEVICE_CAMERA | DEVICE_MOTOR);
        }
        device.serials = device.list_serials();
        // SAFETY: live context.
        let n = unsafe { (f.num_devices)(ctx) };
        if n <= 0 {
            return Err(DeviceError::NoDevice {
                usb: kinect_class_usb_devices(),
            });
        }
        if index >= n as u32 {
            return Err(DeviceError::NoSuchDevice {
                index,
                found: n as u32,
                serials: device.serials.clone(),
            });
        }
        let mut dev: *mut Dev = std::ptr::null_mut();
        // SAFETY: live context, valid out pointer, index checked.
        let rc = unsafe { (f.open_device)(ctx, &mut dev, index as c_int) };
        if rc < 0 || dev.is_null() {
            return Err(DeviceError::Open { index, code: rc });
        }
        device.dev = dev;
        let depth_fmt = match format {
            DepthFormat::Registered => DEPTH_REGISTERED,
            DepthFormat::Raw11 => DEPTH_11BIT,
        };
        // SAFETY: live device; the modes come from the library's own tables; the callbacks are
        // plain functions that only touch the thread-local sink.
        unsafe {
            let video = (f.find_video_mode)(RESOLUTION_MEDIUM, VIDEO_RGB);
            let depth = (f.find_depth_mode)(RESOLUTION_MEDIUM, depth_fmt);
            for (what, mode, bytes) in [
                ("offer 640x480 RGB8 video", video, PIXELS * 3),
                ("offer 640x480 depth", depth, PIXELS * 2),
            ] {
                if mode.is_valid == 0
                    || mode.width as usize != WIDTH
                    || mode.height as usize != HEIGHT
                    || mode.bytes as usize != bytes
                {
                    return Err(DeviceError::Stream { what, code: -1 });
                }
            }
            let rc = (f.set_video_mode)(dev, video);
            if rc < 0 {
                return Err(DeviceError::Stream {
                    what: "set the video mode",
                    code: rc,
                });
            }
            let rc = (f.set_depth_mode)(dev, depth);
            if rc < 0 {
                return Err(DeviceError::Stream {
                    what: "set the depth mode",
                    code: rc,
                });
            }
            (f.set_depth_callback)(dev, Some(on_depth));
            (f.set_video_callback)(dev, Some(on_video));
            let rc = (f.start_depth)(dev);
            if rc < 0 {
                return Err(DeviceError::Stream {
                    what: "start the depth stream",
                    code: rc,
                });
            }
            let rc = (f.start_video)(dev);
            if rc < 0 {
                return Err(DeviceError::Stream {
                    what: "start the video stream",
                    code: rc,
                });
            }
        }
        Ok(device)
    }

    fn list_serials(&self) -> Vec<String> {
        let (Some(list), Some(free)) = (
            self.lib.f.list_device_attributes,
            self.lib.f.free_device_attributes,
        ) else {
            return Vec::new();
        };
        let mut head: *mut DeviceAttributes = std::ptr::null_mut();
        let mut out = Vec::new();
        // SAFETY: live context; the list is walked while it exists and freed once.
        unsafe {
            if list(self.ctx, &mut head) < 0 {
                return out;
            }
            let mut cur = head;
            while !cur.is_null() {
                if !(*cur).camera_serial.is_null() {
                    out.push(
                        CStr::from_ptr((*cur).camera_serial)
                            .to_string_lossy()
                            .into_owned(),
                    );
                }
                cur = (*cur).next;
            }
            if !head.is_null() {
                free(head);
            }
        }
        out
    }

    /// Serial numbers of the connected cameras (empty where the library cannot list them).
    pub fn serials(&self) -> &[String] {
        &self.serials
    }

    /// The depth format the device streams.
    pub fn format(&self) -> DepthFormat {
        self.format
    }

    /// Pumps libfreenect's events once (waiting up to `timeout` on a real device; fakenect
    /// waits for its next sample) and returns a pair when both a colour and a depth image have
    /// arrived since the last pair. An error means the device is gone or broken: drop it.
    pub fn poll(&mut self, timeout: std::time::Duration) -> Result<Option<RawFrame>, DeviceError> {
        let mut tv = nix::libc::timeval {
            tv_sec: timeout.as_secs() as nix::libc::time_t,
            tv_usec: timeout.subsec_micros() as nix::libc::suseconds_t,
        };
        let sink: *mut Sink = &mut *self.sink;
        SINK.with(|s| s.set(sink));
        // SAFETY: live context; the callbacks it runs write to `sink`, which outlives the call.
        let rc = unsafe { (self.lib.f.process_events_timeout)(self.ctx, &mut tv) };
        SINK.with(|s| s.set(std::ptr::null_mut()));
        if rc < 0 {
            return Err(DeviceError::Stream {
                what: "pump its events (device unplugged, or end of a fakenect dump)",
                code: rc,
            });
        }
        let s = &mut *self.sink;
        if s.rgb_new && s.depth_new {
            s.rgb_new = false;
            s.depth_new = false;
            return Ok(Some(RawFrame {
                rgb: s.rgb.clone(),
                depth: s.depth.clone(),
                format: self.format,
                rgb_ts: s.rgb_ts,
                depth_ts: s.depth_ts,
            }));
        }
        Ok(None)
    }

    /// The tilt motor and accelerometer, as the device reports them now.
    pub fn tilt(&mut self) -> Option<Tilt> {
        // SAFETY: live device; the state pointer is the device's own, read at once.
        unsafe {
            if (self.lib.f.update_tilt_state)(self.dev) < 0 {
                return None;
            }
            let s = (self.lib.f.get_tilt_state)(self.dev);
            if s.is_null() {
                return None;
            }
            let s = *s;
            Some(Tilt {
                angle_deg: f64::from(s.tilt_angle) / 2.0,
                accel_mps2: s.accel.map(|c| f64::from(c) / COUNTS_PER_G * GRAVITY),
                status: s.tilt_status,
            })
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        let f = &self.lib.f;
        // SAFETY: the device and context are live and dropped once, streams stopped first.
        unsafe {
            if !self.dev.is_null() {
                (f.stop_depth)(self.dev);
                (f.stop_video)(self.dev);
                (f.close_device)(self.dev);
            }
            (f.shutdown)(self.ctx);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_library_names_the_package() {
        let e = Library::load(Some(Path::new("/nonexistent/libfreenect.so.0.5"))).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("apt-get install libfreenect0.5"), "{msg}");
        assert!(msg.contains("/nonexistent/libfreenect.so.0.5"), "{msg}");
    }

    #[test]
    fn a_library_that_is_not_libfreenect_is_refused() {
        let e = Library::load(Some(Path::new("libm.so.6"))).unwrap_err();
        assert!(
            matches!(
                e,
                DeviceError::Symbol {
                    symbol: "freenect_init",
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn no_device_lists_what_the_system_sees() {
        let e = DeviceError::NoDevice { usb: vec![] };
        assert!(e.to_string().contains("no Kinect or Xtion"), "{e}");
        let e = DeviceError::NoDevice {
            usb: vec!["045e:02b0 Kinect v1 motor at usb 1-2".into()],
        };
        assert!(e.to_string().contains("045e:02b0 Kinect v1 motor"), "{e}");
    }

    #[test]
    fn frame_mode_has_the_c_layout() {
        assert_eq!(std::mem::size_of::<FrameMode>(), 24);
        assert_eq!(std::mem::size_of::<RawTiltState>(), 12);
    }
}
