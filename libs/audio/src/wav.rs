//! Minimal RIFF/WAVE reading and writing for 16-bit PCM: what espeak-ng writes with `--stdout`,
//! what the recognizer's `--wav` reads, and what `--wav-dir` stores.
//!
//! Samples are interleaved signed 16-bit; `sample_rate_hz` is per channel. espeak-ng streams to a
//! pipe with unknown length, so its header's sizes are placeholders (0 or 0x7fffffff): the data
//! chunk then runs to the end of the bytes.

/// Decoded PCM audio.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Pcm {
    pub sample_rate_hz: u32,
    pub channels: u16,
    /// Interleaved samples.
    pub samples: Vec<i16>,
}

impl Pcm {
    /// Duration in seconds.
    pub fn duration_s(&self) -> f64 {
        if self.sample_rate_hz == 0 || self.channels == 0 {
            return 0.0;
        }
        self.samples.len() as f64 / self.channels as f64 / self.sample_rate_hz as f64
    }
    /// The mono mix (channel average).
    pub fn to_mono(&self) -> Vec<i16> {
        mix_to_mono(&self.samples, usize::from(self.channels))
    }
}

/// `samples` of `channels` interleaved channels mixed into one: each frame's mean (a last,
/// partial frame is the mean of what it has).
pub fn mix_to_mono(samples: &[i16], channels: usize) -> Vec<i16> {
    samples
        .chunks(channels.max(1))
        .map(|f| (f.iter().map(|&s| i32::from(s)).sum::<i32>() / f.len() as i32) as i16)
        .collect()
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WavError {
    #[error("not a RIFF/WAVE file")]
    NotWav,
    #[error("unsupported WAV encoding (format {format}, {bits} bits): only 16-bit PCM")]
    Unsupported { format: u16, bits: u16 },
    #[error("WAV file has no fmt or data chunk")]
    MissingChunk,
    #[error("WAV header declares {0} channels")]
    BadChannels(u16),
}

fn u16_at(b: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_le_bytes([*b.get(i)?, *b.get(i + 1)?]))
}
fn u32_at(b: &[u8], i: usize) -> Option<u32> {
    Some(u32::from_le_bytes([
        *b.get(i)?,
        *b.get(i + 1)?,
        *b.get(i + 2)?,
        *b.get(i + 3)?,
    ]))
}

/// Parse a 16-bit PCM WAV file from bytes.
pub fn parse(bytes: &[u8]) -> Result<Pcm, WavError> {
    if bytes.len() < 12 || &bytes[0..4] != b"RIFF" || &bytes[8..12] != b"WAVE" {
        return Err(WavError::NotWav);
    }
    let mut i = 12;
    let mut fmt: Option<(u16, u16, u32, u16)> = None;
    while i + 8 <= bytes.len() {
        let id = &bytes[i..i + 4];
        let size = u32_at(bytes, i + 4).ok_or(WavError::NotWav)? as usize;
        let body = i + 8;
        if id == b"fmt " {
            let format = u16_at(bytes, body).ok_or(WavError::MissingChunk)?;
            let channels = u16_at(bytes, body + 2).ok_or(WavError::MissingChunk)?;
            let rate = u32_at(bytes, body + 4).ok_or(WavError::MissingChunk)?;
            let bits = u16_at(bytes, body + 14).ok_or(WavError::MissingChunk)?;
            fmt = Some((format, channels, rate, bits));
        } else if id == b"data" {
            let (format, channels, rate, bits) = fmt.ok_or(WavError::MissingChunk)?;
            // 0xFFFE is WAVE_FORMAT_EXTENSIBLE, accepted when 16 bits.
            if !(format == 1 || format == 0xFFFE) || bits != 16 {
                return Err(WavError::Unsupported { format, bits });
            }
            if channels == 0 {
                return Err(WavError::BadChannels(channels));
            }
            let end = if size == 0 || body + size > bytes.len() {
                bytes.len()
            } else {
                body + size
            };
            let samples = bytes[body..end]
                .chunks_exact(2)
                .map(|b| i16::from_le_bytes([b[0], b[1]]))
                .collect();
            return Ok(Pcm {
                sample_rate_hz: rate,
                channels,
                samples,
            });
        }
        // Chunks are padded to an even size; an unknown streaming size ends the walk.
        if size >= u32::MAX as usize / 2 {
            break;
        }
        i = body + size + (size & 1);
    }
    Err(WavError::MissingChunk)
}

/// Encode 16-bit PCM as a WAV file.
pub fn encode(pcm: &Pcm) -> Vec<u8> {
    let data_len = (pcm.samples.len() * 2) as u32;
    let block = pcm.channels as u32 * 2;
    let mut b = Vec::with_capacity(44 + data_len as usize);
    b.extend_from_slice(b"RIFF");
    b.extend_from_slice(&(36 + data_len).to_le_bytes());
    b.extend_from_slice(b"WAVEfmt ");
    b.extend_from_slice(&16u32.to_le_bytes());
    b.extend_from_slice(&1u16.to_le_bytes());
    b.extend_from_slice(&pcm.channels.to_le_bytes());
    b.extend_from_slice(&pcm.sample_rate_hz.to_le_bytes());
    b.extend_from_slice(&(pcm.sample_rate_hz * block).to_le_bytes());
    b.extend_from_slice(&(block as u16).to_le_bytes());
    b.extend_from_slice(&16u16.to_le_bytes());
    b.extend_from_slice(b"data");
    b.extend_from_slice(&data_len.to_le_bytes());
    for s in &pcm.samples {
        b.extend_from_slice(&s.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_streaming_sizes() {
        let pcm = Pcm {
            sample_rate_hz: 22050,
            channels: 2,
            samples: vec![1, -2, 300, -32768, 32767, 0],
        };
        let mut bytes = encode(&pcm);
        assert_eq!(parse(&bytes).unwrap(), pcm);
        assert!((pcm.duration_s() - 3.0 / 22050.0).abs() < 1e-12);
        assert_eq!(pcm.to_mono(), vec![0, -16234, 16383]);
        // A streamed header (sizes unknown) still reads to the end.
        bytes[40..44].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
        assert_eq!(parse(&bytes).unwrap(), pcm);
    }

    #[test]
    fn bad_files_are_errors() {
        assert_eq!(parse(b"hello"), Err(WavError::NotWav));
        let mut bytes = encode(&Pcm {
            sample_rate_hz: 8000,
            channels: 1,
            samples: vec![0; 4],
        });
        bytes[34] = 8; // 8-bit
        assert!(matches!(
            parse(&bytes),
            Err(WavError::Unsupported { bits: 8, .. })
        ));
        assert_eq!(parse(&bytes[..36]), Err(WavError::MissingChunk));
    }
}
