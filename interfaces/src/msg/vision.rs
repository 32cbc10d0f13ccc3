//! Camera messages.

use crate::header::Header;
use crate::msg::Borrowable;
use crate::msg::ros::{CameraInfo, Image};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// Pinhole intrinsics of a camera in pixels, without distortion (optical frame: z forward,
/// x right, y down): a point `(x, y, z)` projects to `u = fx * x / z + cx`, `v = fy * y / z + cy`.
/// The one pinhole model of the workspace: the camera library, the tracker and the frames share it;
/// a whole camera (name, frame, image size, depth range) is [`crate::msg::dr::CameraIntrinsics`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point column, pixels.
    pub cx: f64,
    /// Principal point row, pixels.
    pub cy: f64,
}

impl Intrinsics {
    /// The Kinect / Xtion / TUM "ROS default" intrinsics for 640x480: fx = fy = 525, principal
    /// point (319.5, 239.5).
    pub const KINECT_640X480: Intrinsics = Intrinsics {
        fx: 525.0,
        fy: 525.0,
        cx: 319.5,
        cy: 239.5,
    };

    /// Projects a point of the optical frame (m) to pixel coordinates; `None` if `z <= 0`.
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        if p[2] <= 0.0 {
            return None;
        }
        Some([
            self.fx * p[0] / p[2] + self.cx,
            self.fy * p[1] / p[2] + self.cy,
        ])
    }

    /// Back-projects pixel `(u, v)` at optical-axis depth `z_m` to a point of the optical frame (m).
    pub fn back_project(&self, u: f64, v: f64, z_m: f64) -> [f64; 3] {
        [
            (u - self.cx) * z_m / self.fx,
            (v - self.cy) * z_m / self.fy,
            z_m,
        ]
    }

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

/// One registered RGB-D frame: colour (RGB8, row-major) and depth (u16 millimetres, 0 = no
/// reading, little-endian bytes), of the same size, in the camera's optical frame
/// (`header.frame_id`). About 1.5 MB at 640x480: it travels through shared memory on one host.
///
/// On the wire (`robocog_msgs/RgbdFrame`): the header, the camera's `sensor_msgs/CameraInfo`
/// (one for both images: they are registered), and two `sensor_msgs/Image`s, `rgb8` and `16UC1`
/// (millimetres, little-endian), so ROS 2 tools read the images as images.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
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
#[serde(remote = "Self")]
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

/// The encoding of [`RgbdFrame::rgb`] in its `sensor_msgs/Image`.
pub const RGB_ENCODING: &str = "rgb8";
/// The encoding of [`RgbdFrame::depth_mm`] in its `sensor_msgs/Image` (millimetres).
pub const DEPTH_ENCODING: &str = "16UC1";

/// [`RgbdFrame`] on the wire.
#[derive(Serialize, Deserialize)]
#[serde(rename = "RgbdFrame")]
struct RgbdFrameWire<'a> {
    header: Header,
    camera_info: CameraInfo,
    #[serde(borrow)]
    rgb: Image<'a>,
    #[serde(borrow)]
    depth: Image<'a>,
}

impl<'a> RgbdFrameView<'a> {
    fn to_wire(&self) -> RgbdFrameWire<'a> {
        let i = self.intrinsics;
        let image = |encoding, bytes_per_pixel: u32, data| Image {
            header: self.header.clone(),
            height: self.height,
            width: self.width,
            encoding,
            is_bigendian: 0,
            step: self.width.saturating_mul(bytes_per_pixel),
            data,
        };
        RgbdFrameWire {
            header: self.header.clone(),
            camera_info: CameraInfo::pinhole(
                self.header.clone(),
                self.width,
                self.height,
                [i.fx, i.fy, i.cx, i.cy],
            ),
            rgb: image(RGB_ENCODING, 3, self.rgb),
            depth: image(DEPTH_ENCODING, 2, self.depth_mm),
        }
    }

    fn from_wire(w: RgbdFrameWire<'a>) -> Result<Self, String> {
        let (width, height) = (w.rgb.width, w.rgb.height);
        for (image, encoding, bytes_per_pixel) in
            [(&w.rgb, RGB_ENCODING, 3u32), (&w.depth, DEPTH_ENCODING, 2)]
        {
            // An image without pixels has no encoding to check (ROS 2 tools leave it empty).
            let empty = image.data.is_empty() && (image.width == 0 || image.height == 0);
            if image.encoding != encoding && !empty {
                return Err(format!(
                    "an image encoded {:?} where a frame has {encoding:?}",
                    image.encoding
                ));
            }
            if image.is_bigendian != 0 {
                return Err(format!(
                    "a big-endian {encoding} image (frames are little-endian)"
                ));
            }
            if (image.width, image.height) != (width, height) {
                return Err(format!(
                    "a {encoding} image of {}x{} in a {width}x{height} frame (they are registered)",
                    image.width, image.height
                ));
            }
            if image.step != width.saturating_mul(bytes_per_pixel) {
                return Err(format!(
                    "a {encoding} image with rows of {} bytes where {width} pixels take {}",
                    image.step,
                    width.saturating_mul(bytes_per_pixel)
                ));
            }
        }
        let [fx, fy, cx, cy] = w.camera_info.focal_and_centre();
        Ok(RgbdFrameView {
            header: w.header,
            width,
            height,
            intrinsics: Intrinsics { fx, fy, cx, cy },
            rgb: w.rgb.data,
            depth_mm: w.depth.data,
        })
    }
}

impl Serialize for RgbdFrameView<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            RgbdFrameView::serialize(self, s)
        } else {
            self.to_wire().serialize(s)
        }
    }
}

impl<'de: 'a, 'a> Deserialize<'de> for RgbdFrameView<'a> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() {
            RgbdFrameView::deserialize(d)
        } else {
            RgbdFrameView::from_wire(RgbdFrameWire::deserialize(d)?)
                .map_err(serde::de::Error::custom)
        }
    }
}

impl Serialize for RgbdFrame {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            RgbdFrame::serialize(self, s)
        } else {
            self.view().to_wire().serialize(s)
        }
    }
}

impl<'de> Deserialize<'de> for RgbdFrame {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() {
            RgbdFrame::deserialize(d)
        } else {
            <RgbdFrameView<'de> as Deserialize<'de>>::deserialize(d).map(|v| v.to_frame())
        }
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

    /// Offsets of the length fields in the payload of `frame(4, 2, "cam")`, CDR aligning each
    /// value to its size from the end of the 4-byte encapsulation:
    /// - the header: stamp (8), frame_id's length at 12, "cam\0";
    /// - the `CameraInfo` (from 20): header (12), height, width, "plumb_bob" (4 + 10), `d` (5
    ///   f64 from 64), `k`, `r`, `p` (30 f64), binning (8), roi (17): it ends at 373;
    /// - the colour `Image` (header from 376, 16 bytes; height, width; "rgb8" (4 + 5); is_bigendian;
    ///   step at 412): its data's length at 416, then 24 bytes;
    /// - the depth `Image` (from 444, the same with "16UC1"): its data's length at 484, then 16.
    const FRAME_ID_LEN_AT: usize = 12;
    const RGB_LEN_AT: usize = 416;
    const DEPTH_LEN_AT: usize = 484;

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
    fn on_the_wire_a_frame_holds_ros2_images_and_refuses_other_encodings() {
        let good = codec::encode(&frame(4, 2, "cam"), RgbdFrame::TYPE_NAME).unwrap();
        let at = |needle: &[u8]| {
            good.windows(needle.len())
                .position(|w| w == needle)
                .unwrap()
        };
        // The images name their encodings; the camera info its distortion model.
        at(b"rgb8\0");
        at(b"16UC1\0");
        at(b"plumb_bob\0");
        // A BGR image, or depth in metres, is not a frame: a decoding error that says why.
        for (from, to) in [(&b"rgb8"[..], &b"bgr8"[..]), (b"16UC1", b"32FC1")] {
            let mut bad = good.clone();
            let i = at(from);
            bad[i..i + from.len()].copy_from_slice(to);
            let e = codec::decode::<RgbdFrame>(&bad, RgbdFrame::TYPE_NAME).unwrap_err();
            let to = std::str::from_utf8(to).unwrap();
            assert!(e.to_string().contains(to), "{e}");
            assert!(view_of(&bad).is_err());
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
