//! Kinect v1 (and other Kinect-class devices libfreenect drives) for the `rgbd` component, and
//! what it takes to test that path without the hardware.
//!
//! - [`device`]: libfreenect, loaded at run time (`libfreenect.so.0.5`, Debian's `libfreenect0.5`)
//!   rather than linked, so that the same binary runs against a real Kinect or against Debian's
//!   `fakenect`, the libfreenect stand-in that replays a recorded dump folder (point
//!   `LD_LIBRARY_PATH` at its folder and `FAKENECT_PATH` at the dump). A [`device::Device`]
//!   opens one camera, streams colour (RGB8) and depth, and reports the tilt motor and
//!   accelerometer. Errors name what is missing and list what is connected.
//! - [`kinect`]: the depth camera's geometry: the 11-bit disparity the sensor sends, converted to
//!   millimetres, and depth registered onto the colour camera's pixel grid (and back, for the
//!   simulated device). libfreenect registers depth itself (`FREENECT_DEPTH_REGISTERED`) with
//!   the calibration the device carries; the fakenect library cannot, so robocog does it with a
//!   [`kinect::DepthCalibration`].
//! - [`calibration`]: intrinsics from a ROS `camera_info` YAML file, the format `camera_calibration`
//!   and the ROS Kinect drivers write.
//! - [`fakenect`]: the dump format fakenect replays (`INDEX.txt`, `r-*.ppm`, `d-*.pgm`, `a-*.dump`),
//!   written as a folder or streamed live through a FIFO, so a simulated camera can feed frames
//!   through the real library's code.

// This crate exists to call libfreenect's C functions, which Rust only allows in `unsafe` blocks;
// the workspace denies unsafe code everywhere else, so the safe wrapper lives here.
#![allow(unsafe_code)]

pub mod calibration;
pub mod device;
pub mod fakenect;
pub mod kinect;

/// Width of the Kinect v1's medium-resolution colour and depth images, pixels.
pub const WIDTH: usize = 640;
/// Height of the Kinect v1's medium-resolution colour and depth images, pixels.
pub const HEIGHT: usize = 480;
/// Pixels in one image.
pub const PIXELS: usize = WIDTH * HEIGHT;

/// Pinhole intrinsics in pixels: `u = fx * x / z + cx`, `v = fy * y / z + cy` in an optical frame
/// (z forward, x right, y down).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Pinhole {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
}

impl Pinhole {
    /// The colour camera's nominal intrinsics at 640x480 (the "ROS default" for Kinect-class
    /// cameras): fx = fy = 525, principal point (319.5, 239.5).
    pub const KINECT_RGB: Pinhole = Pinhole {
        fx: 525.0,
        fy: 525.0,
        cx: 319.5,
        cy: 239.5,
    };

    /// The depth (infrared) camera's nominal intrinsics at 640x480: fx = fy = 580.
    pub const KINECT_DEPTH: Pinhole = Pinhole {
        fx: 580.0,
        fy: 580.0,
        cx: 319.5,
        cy: 239.5,
    };

    /// True when both focal lengths are finite and positive and the principal point is finite.
    pub fn is_valid(&self) -> bool {
        self.fx.is_finite()
            && self.fy.is_finite()
            && self.fx > 0.0
            && self.fy > 0.0
            && self.cx.is_finite()
            && self.cy.is_finite()
    }
}
