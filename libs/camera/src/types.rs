//! Bus-facing data types of the RGB-D camera (plain serde structs, meant to move to `interfaces`).
//!
//! Conventions:
//! - Image coordinates in pixels, `u` the column (right), `v` the row (down); following OpenCV and
//!   ROS, pixel `(u, v)` has its centre at `(u, v)`, so the principal point of a 640x480 camera
//!   is near `(319.5, 239.5)`.
//! - The camera frame is the *optical* frame: z forward (along the optical axis), x right, y down.
//! - Colour is RGB8, row-major, 3 bytes a pixel. Depth is `u16` millimetres along the optical
//!   axis (the z coordinate, not the ray length), row-major; `0` means "no measurement".
//! - Time is in seconds (`f64`), on whatever clock the producer uses (sim time, recording time).

use serde::{Deserialize, Serialize};

/// Pinhole intrinsics in pixels (no distortion): the bus' own type.
pub use interfaces::msg::vision::Intrinsics;

/// One registered RGB-D frame: colour and depth share the pixel grid and the intrinsics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// RGB8 row-major, `width * height * 3` bytes.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis, millimetres, row-major, `width * height` values; 0 = no data.
    pub depth_mm: Vec<u16>,
    /// Pinhole intrinsics of both images.
    pub intrinsics: Intrinsics,
    /// Capture time, seconds.
    pub timestamp_s: f64,
}

/// Why a [`Frame`] is not usable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    /// Width or height is zero.
    #[error("frame has zero size ({width}x{height})")]
    ZeroSize {
        /// Declared width, pixels.
        width: u32,
        /// Declared height, pixels.
        height: u32,
    },
    /// A buffer's length disagrees with `width * height`.
    #[error("{buffer} buffer has {actual} elements, expected {expected} for {width}x{height}")]
    BufferSize {
        /// `"rgb"` or `"depth"`.
        buffer: &'static str,
        /// Elements found.
        actual: usize,
        /// Elements expected.
        expected: usize,
        /// Declared width, pixels.
        width: u32,
        /// Declared height, pixels.
        height: u32,
    },
    /// Non-finite or non-positive focal lengths.
    #[error("invalid intrinsics {0:?}")]
    Intrinsics(Intrinsics),
}

impl Frame {
    /// A black frame without depth (all zeros) of the given size.
    pub fn blank(width: u32, height: u32, intrinsics: Intrinsics, timestamp_s: f64) -> Frame {
        let n = width as usize * height as usize;
        Frame {
            width,
            height,
            rgb: vec![0; n * 3],
            depth_mm: vec![0; n],
            intrinsics,
            timestamp_s,
        }
    }

    /// Number of pixels, `width * height`.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Checks sizes and intrinsics; a frame that passes can be indexed without bounds surprises.
    pub fn validate(&self) -> Result<(), FrameError> {
        if self.width == 0 || self.height == 0 {
            return Err(FrameError::ZeroSize {
                width: self.width,
                height: self.height,
            });
        }
        let n = self.pixel_count();
        if self.rgb.len() != n * 3 {
            return Err(FrameError::BufferSize {
                buffer: "rgb",
                actual: self.rgb.len(),
                expected: n * 3,
                width: self.width,
                height: self.height,
            });
        }
        if self.depth_mm.len() != n {
            return Err(FrameError::BufferSize {
                buffer: "depth",
                actual: self.depth_mm.len(),
                expected: n,
                width: self.width,
                height: self.height,
            });
        }
        if !self.intrinsics.is_valid() {
            return Err(FrameError::Intrinsics(self.intrinsics));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_back_project_round_trip() {
        let k = Intrinsics::KINECT_640X480;
        let p = [0.12, -0.05, 1.3];
        let [u, v] = k.project(p).unwrap();
        let q = k.back_project(u, v, 1.3);
        for i in 0..3 {
            assert!((p[i] - q[i]).abs() < 1e-12);
        }
        assert!(k.project([0.0, 0.0, -1.0]).is_none());
    }

    #[test]
    fn validate_rejects_bad_buffers() {
        let k = Intrinsics::KINECT_640X480;
        assert!(Frame::blank(4, 3, k, 0.0).validate().is_ok());
        assert!(matches!(
            Frame::blank(0, 3, k, 0.0).validate(),
            Err(FrameError::ZeroSize { .. })
        ));
        let mut f = Frame::blank(4, 3, k, 0.0);
        f.depth_mm.pop();
        assert!(matches!(
            f.validate(),
            Err(FrameError::BufferSize {
                buffer: "depth",
                ..
            })
        ));
        let mut f = Frame::blank(4, 3, k, 0.0);
        f.rgb.push(0);
        assert!(matches!(
            f.validate(),
            Err(FrameError::BufferSize { buffer: "rgb", .. })
        ));
        let mut f = Frame::blank(4, 3, k, 0.0);
        f.intrinsics.fx = 0.0;
        assert!(matches!(f.validate(), Err(FrameError::Intrinsics(_))));
    }
}
