//! Little-endian field access on fixed-size buffers. Callers check the buffer length first, so
//! reads and writes at compile-time offsets cannot go out of bounds; the helpers still return
//! zero / do nothing rather than panic if they ever did.

pub(crate) fn u8_at(b: &[u8], off: usize) -> u8 {
    b.get(off).copied().unwrap_or(0)
}

fn array_at<const N: usize>(b: &[u8], off: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(s) = b.get(off..off + N) {
        out.copy_from_slice(s);
    }
    out
}

pub(crate) fn bytes4_at(b: &[u8], off: usize) -> [u8; 4] {
    array_at::<4>(b, off)
}

pub(crate) fn u16_at(b: &[u8], off: usize) -> u16 {
    u16::from_le_bytes(array_at::<2>(b, off))
}

pub(crate) fn i16_at(b: &[u8], off: usize) -> i16 {
    i16::from_le_bytes(array_at::<2>(b, off))
}

pub(crate) fn u32_at(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(array_at::<4>(b, off))
}

pub(crate) fn f32_at(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes(array_at::<4>(b, off))
}

pub(crate) fn put(b: &mut [u8], off: usize, bytes: &[u8]) {
    if let Some(s) = b.get_mut(off..off + bytes.len()) {
        s.copy_from_slice(bytes);
    }
}
