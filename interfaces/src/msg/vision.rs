//! Camera messages.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// Pinhole intrinsics of a camera, in pixels (optical frame: z forward, x right, y down).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// One registered RGB-D frame: colour (RGB8, row-major) and depth (u16 millimetres, 0 = no
/// reading, little-endian bytes), of the same size, in the camera's optical frame
/// (`header.frame_id`). About 1.5 MB at 640x480: it travels through shared memory on one host.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RgbdFrame {
    pub header: Header,
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    #[serde(with = "serde_bytes")]
    pub rgb: Vec<u8>,
    #[serde(with = "serde_bytes")]
    pub depth_mm: Vec<u8>,
}

impl RgbdFrame {
    /// A black frame with no depth, of the given size.
    pub fn blank(width: u32, height: u32, intrinsics: Intrinsics) -> Self {
        let n = width as usize * height as usize;
        Self {
            header: Header::default(),
            width,
            height,
            intrinsics,
            rgb: vec![0; n * 3],
            depth_mm: vec![0; n * 2],
        }
    }

    /// Whether the buffers match the declared size (a subscriber checks before use).
    pub fn is_consistent(&self) -> bool {
        let n = self.width as usize * self.height as usize;
        n > 0 && self.rgb.len() == n * 3 && self.depth_mm.len() == n * 2
    }

    /// Depth at pixel (u, v) in millimetres, `None` outside the image or for a malformed frame.
    pub fn depth_at(&self, u: u32, v: u32) -> Option<u16> {
        if u >= self.width || v >= self.height {
            return None;
        }
        let i = 2 * (v as usize * self.width as usize + u as usize);
        Some(u16::from_le_bytes([
            *self.depth_mm.get(i)?,
            *self.depth_mm.get(i + 1)?,
        ]))
    }
}

/// The head camera's health, from the `rgbd` component's hardware drivers (`freenect`): on every
/// change (streaming, lost, stalled, back) and once a second. The simulated and playback drivers
/// do not publish it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraStatus {
    pub header: Header,
    /// The driver (`freenect`).
    pub driver: String,
    /// Frames are coming.
    pub streaming: bool,
    /// What streams (device, library, depth format), or why nothing does.
    pub detail: String,
    /// Frames published since the component started.
    pub frames: u64,
    /// Times the device was lost since the component started.
    pub losses: u64,
}
