//! Camera frames for the page: the colour image of an [`RgbdFrame`], shrunk to at most
//! [`MAX_WIDTH`] pixels wide by keeping every n-th pixel, encoded as JPEG (pure Rust). The page
//! scales pixel coordinates of the ball's window by the frame's declared size, so shrinking
//! does not move the overlay.

use interfaces::msg::vision::RgbdFrame;

/// Widest image sent to a page, pixels.
pub const MAX_WIDTH: u32 = 640;
/// JPEG quality (1-100).
pub const QUALITY: u8 = 70;

/// Why a frame could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("inconsistent frame: {width}x{height} with {rgb} colour bytes")]
    Inconsistent { width: u32, height: u32, rgb: usize },
    #[error("frame too large for JPEG: {0}x{1}")]
    TooLarge(u32, u32),
    #[error("JPEG encoding failed: {0}")]
    Encode(#[from] jpeg_encoder::EncodingError),
}

/// The frame's colour image as JPEG bytes.
pub fn to_jpeg(frame: &RgbdFrame) -> Result<Vec<u8>, CameraError> {
    let (w, h) = (frame.width, frame.height);
    let n = w as usize * h as usize;
    if n == 0 || frame.rgb.len() != n * 3 {
        return Err(CameraError::Inconsistent {
            width: w,
            height: h,
            rgb: frame.rgb.len(),
        });
    }
    let step = w.div_ceil(MAX_WIDTH).max(1);
    let (ow, oh) = (w.div_ceil(step), h.div_ceil(step));
    let (Ok(ow16), Ok(oh16)) = (u16::try_from(ow), u16::try_from(oh)) else {
        return Err(CameraError::TooLarge(w, h));
    };
    let shrunk;
    let pixels: &[u8] = if step == 1 {
        &frame.rgb
    } else {
        let mut v = Vec::with_capacity(ow as usize * oh as usize * 3);
        for y in (0..h).step_by(step as usize) {
            let row = y as usize * w as usize * 3;
            for x in (0..w).step_by(step as usize) {
                let i = row + x as usize * 3;
                v.extend_from_slice(&frame.rgb[i..i + 3]);
            }
        }
        shrunk = v;
        &shrunk
    };
    let mut out = Vec::with_capacity(32 * 1024);
    let encoder = jpeg_encoder::Encoder::new(&mut out, QUALITY);
    encoder.encode(pixels, ow16, oh16, jpeg_encoder::ColorType::Rgb)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use interfaces::msg::vision::Intrinsics;

    #[test]
    fn frames_become_jpeg_and_bad_frames_are_refused() {
        let mut f = RgbdFrame::blank(1280, 720, Intrinsics::default());
        f.rgb
            .iter_mut()
            .enumerate()
            .for_each(|(i, p)| *p = (i % 251) as u8);
        let j = to_jpeg(&f).unwrap();
        assert_eq!(&j[..2], &[0xFF, 0xD8], "JPEG start of image");
        // 1280 wide is halved: the SOF0 marker says 640x360.
        let sof = j.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
        let hgt = u16::from_be_bytes([j[sof + 5], j[sof + 6]]);
        let wid = u16::from_be_bytes([j[sof + 7], j[sof + 8]]);
        assert_eq!((wid, hgt), (640, 360));
        f.rgb.truncate(10);
        assert!(matches!(to_jpeg(&f), Err(CameraError::Inconsistent { .. })));
    }
}
