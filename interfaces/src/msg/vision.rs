//! Camera messages.

use crate::header::Header;
use crate::msg::Borrowable;
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

    /// The frame as a view borrowing its buffers (to publish with
    /// [`crate::bus::Publisher::publish_view`], or to share code with a received view).
    pub fn view(&self) -> RgbdFrameView<'_> {
        RgbdFrameView {
            header: self.header.clone(),
            width: self.width,
            height: self.height,
            intrinsics: self.intrinsics,
            rgb: &self.rgb,
            depth_mm: &self.depth_mm,
        }
    }

    /// Whether the buffers match the declared size (a subscriber checks before use).
    pub fn is_consistent(&self) -> bool {
        consistent(self.width, self.height, &self.rgb, &self.depth_mm)
    }

    /// Depth at pixel (u, v) in millimetres, `None` outside the image or for a malformed frame.
    pub fn depth_at(&self, u: u32, v: u32) -> Option<u16> {
        depth_at(self.width, self.height, &self.depth_mm, u, v)
    }
}

/// An [`RgbdFrame`] read in place: the header, size and intrinsics decoded, the colour and depth
/// buffers borrowed from the received payload (for a frame that came through shared memory, they
/// point into the publisher's shared-memory buffer: no copy). Same wire format as [`RgbdFrame`]:
/// the same bytes decode as either, and a view encodes to exactly the bytes of the frame.
///
/// Like a decoded [`RgbdFrame`], a view is only well-formed CDR: check [`RgbdFrameView::is_consistent`]
/// (or convert with checks) before indexing the buffers.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RgbdFrameView<'a> {
    pub header: Header,
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    /// RGB8, row-major.
    #[serde(borrow, with = "serde_bytes")]
    pub rgb: &'a [u8],
    /// u16 millimetres, little-endian byte pairs (not aligned to 2 in the payload: read them
    /// with `u16::from_le_bytes`, or [`RgbdFrameView::depth_at`]).
    #[serde(borrow, with = "serde_bytes")]
    pub depth_mm: &'a [u8],
}

impl RgbdFrameView<'_> {
    /// An owned copy of the frame (one copy of each buffer).
    pub fn to_frame(&self) -> RgbdFrame {
        RgbdFrame {
            header: self.header.clone(),
            width: self.width,
            height: self.height,
            intrinsics: self.intrinsics,
            rgb: self.rgb.to_vec(),
            depth_mm: self.depth_mm.to_vec(),
        }
    }

    /// Whether the buffers match the declared size (check before use).
    pub fn is_consistent(&self) -> bool {
        consistent(self.width, self.height, self.rgb, self.depth_mm)
    }

    /// Depth at pixel (u, v) in millimetres, `None` outside the image or for a malformed frame.
    pub fn depth_at(&self, u: u32, v: u32) -> Option<u16> {
        depth_at(self.width, self.height, self.depth_mm, u, v)
    }
}

impl Borrowable for RgbdFrame {
    type View<'a> = RgbdFrameView<'a>;
    fn view_header_mut<'v>(view: &'v mut RgbdFrameView<'_>) -> &'v mut Header {
        &mut view.header
    }
}

fn consistent(width: u32, height: u32, rgb: &[u8], depth_mm: &[u8]) -> bool {
    // In u64: width * height cannot overflow it, and the products saturate.
    let n = u64::from(width) * u64::from(height);
    n > 0 && rgb.len() as u64 == n.saturating_mul(3) && depth_mm.len() as u64 == n.saturating_mul(2)
}

fn depth_at(width: u32, height: u32, depth_mm: &[u8], u: u32, v: u32) -> Option<u16> {
    if u >= width || v >= height {
        return None;
    }
    let i = (u64::from(v) * u64::from(width) + u64::from(u)).checked_mul(2)?;
    let i = usize::try_from(i).ok()?;
    Some(u16::from_le_bytes([
        *depth_mm.get(i)?,
        *depth_mm.get(i.checked_add(1)?)?,
    ]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{self, CodecError};
    use crate::msg::Message;

    fn frame(width: u32, height: u32, frame_id: &str) -> RgbdFrame {
        let mut f = RgbdFrame::blank(
            width,
            height,
            Intrinsics {
                fx: 525.0,
                fy: 526.0,
                cx: 319.5,
                cy: 239.5,
            },
        );
        f.header = Header {
            stamp_ns: 1_700_000_000_123_456_789,
            // Not in the payload: the sequence number travels in the sample's attachment.
            seq: 0,
            frame_id: frame_id.into(),
        };
        for (i, b) in f.rgb.iter_mut().enumerate() {
            *b = (i * 7) as u8;
        }
        for (i, b) in f.depth_mm.iter_mut().enumerate() {
            *b = (i * 13 + 1) as u8;
        }
        f
    }

    fn view_of(bytes: &[u8]) -> Result<RgbdFrameView<'_>, CodecError> {
        codec::decode_borrowed(bytes, RgbdFrame::TYPE_NAME)
    }

    #[test]
    fn a_view_reads_the_same_bytes_as_the_owned_frame_in_place() {
        // Frame names of every length mod 8 move the buffers' alignment around.
        for id in ["", "c", "cam", "head_rgbd_optical_frame", "12345678"] {
            let f = frame(5, 3, id);
            let bytes = codec::encode(&f, RgbdFrame::TYPE_NAME).unwrap();
            let v = view_of(&bytes).unwrap();
            assert_eq!(v.to_frame(), f);
            assert_eq!(v, f.view());
            assert!(v.is_consistent());
            assert_eq!(v.depth_at(4, 2), f.depth_at(4, 2));
            assert_eq!(v.depth_at(5, 0), None);
            // The buffers are the payload's own bytes, not copies.
            let range = bytes.as_ptr_range();
            assert!(range.contains(&v.rgb.as_ptr()) && range.contains(&v.depth_mm.as_ptr()));
            // A view encodes to exactly the frame's bytes (the wire format is one).
            assert_eq!(codec::encode(&f.view(), "view").unwrap(), bytes);
            assert_eq!(codec::encoded_len(&f.view()), bytes.len());
        }
    }

    #[test]
    fn truncated_payloads_are_errors_for_the_view_and_the_owned_frame() {
        let bytes = codec::encode(&frame(4, 2, "cam"), RgbdFrame::TYPE_NAME).unwrap();
        for cut in 0..bytes.len() {
            assert!(view_of(&bytes[..cut]).is_err(), "cut at {cut}");
            assert!(
                codec::decode::<RgbdFrame>(&bytes[..cut], RgbdFrame::TYPE_NAME).is_err(),
                "cut at {cut}"
            );
        }
        assert!(view_of(&bytes).is_ok());
    }

    /// Offsets of the length fields in the payload of `frame(4, 2, "cam")`: encapsulation (4),
    /// stamp (sec, nanosec: 8), frame_id length (4) + "cam\0" (4), width, height (8), 4
    /// intrinsics (32), then rgb's length, 24 bytes, depth's length, 16 bytes.
    const FRAME_ID_LEN_AT: usize = 4 + 8;
    const RGB_LEN_AT: usize = FRAME_ID_LEN_AT + 8 + 8 + 32;
    const DEPTH_LEN_AT: usize = RGB_LEN_AT + 4 + 24;

    #[test]
    fn length_fields_past_the_payload_are_errors_not_allocations() {
        let good = codec::encode(&frame(4, 2, "cam"), RgbdFrame::TYPE_NAME).unwrap();
        assert_eq!(
            &good[FRAME_ID_LEN_AT..FRAME_ID_LEN_AT + 4],
            &4u32.to_le_bytes()
        );
        assert_eq!(&good[RGB_LEN_AT..RGB_LEN_AT + 4], &24u32.to_le_bytes());
        assert_eq!(&good[DEPTH_LEN_AT..DEPTH_LEN_AT + 4], &16u32.to_le_bytes());
        assert_eq!(good.len(), DEPTH_LEN_AT + 4 + 16);
        for at in [FRAME_ID_LEN_AT, RGB_LEN_AT, DEPTH_LEN_AT] {
            for len in [u32::MAX, 1 << 31, good.len() as u32] {
                let mut bad = good.clone();
                bad[at..at + 4].copy_from_slice(&len.to_le_bytes());
                assert!(view_of(&bad).is_err(), "length {len} at {at}");
                assert!(
                    codec::decode::<RgbdFrame>(&bad, RgbdFrame::TYPE_NAME).is_err(),
                    "length {len} at {at}"
                );
            }
        }
    }

    #[test]
    fn wrong_buffer_lengths_decode_but_are_not_consistent() {
        // Well-formed CDR whose buffers disagree with the size: the consumer's check catches it.
        let mut f = frame(4, 2, "cam");
        f.rgb.pop();
        let bytes = codec::encode(&f, RgbdFrame::TYPE_NAME).unwrap();
        let v = view_of(&bytes).unwrap();
        assert!(!v.is_consistent());
        let mut f = frame(4, 2, "cam");
        f.width = u32::MAX;
        f.height = u32::MAX;
        let bytes = codec::encode(&f, RgbdFrame::TYPE_NAME).unwrap();
        let v = view_of(&bytes).unwrap();
        assert!(!v.is_consistent());
        assert_eq!(v.depth_at(u32::MAX - 1, u32::MAX - 1), None);
        assert!(!RgbdFrameView::default().is_consistent());
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
