//! Between the library's [`Frame`] and the bus message [`RgbdFrame`].
//!
//! - Colour: RGB8 row-major in both.
//! - Depth: `u16` millimetres along the optical axis (0 = no reading); on the bus as
//!   little-endian byte pairs (`RgbdFrame::depth_mm`), in the library as `Vec<u16>`.
//! - Time: `Frame::timestamp_s` (s) <-> `header.stamp_ns` (ns since the epoch on the publisher's
//!   clock). An `f64` of seconds since 1970 resolves about 0.24 µs, ample for 30 Hz frames.
//! - Frame: the message's `header.frame_id` names the camera's optical frame (z forward, x right,
//!   y down), e.g. `head_rgbd_optical_frame` of `models/loki.urdf`.
//!
//! A subscriber must not trust a decoded message: [`from_msg`] (an owned message) and
//! [`from_view`] (a frame read in place from the bus, `Subscriber::recv_borrowed`) check every
//! size (with overflow guards) and the intrinsics before anything indexes the buffers.

use crate::types::{Frame, FrameError};
use interfaces::Header;
use interfaces::msg::vision::{RgbdFrame, RgbdFrameView};

/// Largest frame accepted from the bus, pixels (a 16 Mpx camera; anything larger is garbage).
pub const MAX_PIXELS: u64 = 1 << 24;

/// Why a bus message is not a usable frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConvertError {
    /// Width times height beyond [`MAX_PIXELS`].
    #[error("frame of {width}x{height} pixels is larger than {MAX_PIXELS} pixels")]
    TooLarge {
        /// Declared width, pixels.
        width: u32,
        /// Declared height, pixels.
        height: u32,
    },
    /// The depth buffer is not whole `u16`s.
    #[error("depth buffer has an odd number of bytes ({0})")]
    OddDepthBytes(usize),
    /// Sizes or intrinsics inconsistent.
    #[error(transparent)]
    Frame(#[from] FrameError),
}

/// The bus message for `frame`, stamped with its timestamp, in frame `frame_id`. Takes the frame
/// by value so the colour buffer moves instead of being copied.
pub fn into_msg(frame: Frame, frame_id: &str) -> RgbdFrame {
    let mut depth = Vec::with_capacity(frame.depth_mm.len() * 2);
    for d in &frame.depth_mm {
        depth.extend_from_slice(&d.to_le_bytes());
    }
    RgbdFrame {
        header: Header {
            stamp_ns: seconds_to_ns(frame.timestamp_s),
            seq: 0,
            frame_id: frame_id.to_string(),
        },
        width: frame.width,
        height: frame.height,
        intrinsics: frame.intrinsics,
        rgb: frame.rgb,
        depth_mm: depth,
    }
}

/// The library frame of a bus message, checked: sizes agree, intrinsics valid. Its
/// `timestamp_s` is the header's stamp in seconds.
pub fn from_msg(msg: &RgbdFrame) -> Result<Frame, ConvertError> {
    from_view(&msg.view())
}

/// The library frame of a frame read in place (its buffers borrowed from the received payload),
/// checked as [`from_msg`] does. The buffers are copied once, here, into the frame's own (the
/// depth converted to `u16`), and nothing is copied when a check fails.
pub fn from_view(msg: &RgbdFrameView<'_>) -> Result<Frame, ConvertError> {
    if u64::from(msg.width) * u64::from(msg.height) > MAX_PIXELS {
        return Err(ConvertError::TooLarge {
            width: msg.width,
            height: msg.height,
        });
    }
    if !msg.depth_mm.len().is_multiple_of(2) {
        return Err(ConvertError::OddDepthBytes(msg.depth_mm.len()));
    }
    // Sizes first, so a garbage header costs no copy.
    let n = msg.width as usize * msg.height as usize;
    if n > 0 && msg.depth_mm.len() != n * 2 {
        return Err(FrameError::BufferSize {
            buffer: "depth",
            actual: msg.depth_mm.len() / 2,
            expected: n,
            width: msg.width,
            height: msg.height,
        }
        .into());
    }
    if n > 0 && msg.rgb.len() != n * 3 {
        return Err(FrameError::BufferSize {
            buffer: "rgb",
            actual: msg.rgb.len(),
            expected: n * 3,
            width: msg.width,
            height: msg.height,
        }
        .into());
    }
    let frame = Frame {
        width: msg.width,
        height: msg.height,
        rgb: msg.rgb.to_vec(),
        depth_mm: msg
            .depth_mm
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect(),
        intrinsics: msg.intrinsics,
        timestamp_s: msg.header.stamp_s(),
    };
    frame.validate()?;
    Ok(frame)
}

/// Seconds to nanoseconds, saturating (non-finite gives 0).
pub fn seconds_to_ns(t_s: f64) -> i64 {
    if t_s.is_finite() {
        (t_s * 1e9).round() as i64
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Intrinsics;

    fn frame() -> Frame {
        let mut f = Frame::blank(4, 3, Intrinsics::KINECT_640X480, 1_700_000_000.25);
        for (i, d) in f.depth_mm.iter_mut().enumerate() {
            *d = 1000 + 257 * i as u16;
        }
        for (i, c) in f.rgb.iter_mut().enumerate() {
            *c = i as u8;
        }
        f
    }

    #[test]
    fn round_trip_keeps_pixels_depth_and_time() {
        let f = frame();
        let msg = into_msg(f.clone(), "head_rgbd_optical_frame");
        assert!(msg.is_consistent());
        assert_eq!(msg.header.frame_id, "head_rgbd_optical_frame");
        assert!((msg.header.stamp_ns - 1_700_000_000_250_000_000).abs() < 1_000);
        // Depth is little-endian on the bus, and the interfaces' accessor agrees.
        assert_eq!(msg.depth_at(1, 0), Some(1257));
        assert_eq!(&msg.depth_mm[2..4], &1257u16.to_le_bytes());
        let back = from_msg(&msg).unwrap();
        assert_eq!(from_view(&msg.view()).unwrap(), back);
        assert_eq!(back.rgb, f.rgb);
        assert_eq!(back.depth_mm, f.depth_mm);
        assert_eq!(back.intrinsics, f.intrinsics);
        assert!((back.timestamp_s - f.timestamp_s).abs() < 1e-6);
    }

    #[test]
    fn inconsistent_messages_are_errors_not_panics() {
        let good = into_msg(frame(), "cam");
        let mut m = good.clone();
        m.depth_mm.pop();
        assert_eq!(from_msg(&m), Err(ConvertError::OddDepthBytes(23)));
        let mut m = good.clone();
        m.depth_mm.truncate(20);
        assert!(matches!(
            from_msg(&m),
            Err(ConvertError::Frame(FrameError::BufferSize {
                buffer: "depth",
                ..
            }))
        ));
        let mut m = good.clone();
        m.rgb.push(0);
        assert!(matches!(
            from_msg(&m),
            Err(ConvertError::Frame(FrameError::BufferSize {
                buffer: "rgb",
                ..
            }))
        ));
        let mut m = good.clone();
        m.width = u32::MAX;
        m.height = u32::MAX;
        assert!(matches!(from_msg(&m), Err(ConvertError::TooLarge { .. })));
        let mut m = good.clone();
        m.width = 0;
        assert!(matches!(
            from_msg(&m),
            Err(ConvertError::Frame(FrameError::ZeroSize { .. }))
        ));
        let mut m = good;
        m.intrinsics.fx = f64::NAN;
        assert!(matches!(
            from_msg(&m),
            Err(ConvertError::Frame(FrameError::Intrinsics(_)))
        ));
    }
}
