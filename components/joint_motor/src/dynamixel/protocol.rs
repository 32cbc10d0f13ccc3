//! Dynamixel Protocol 2.0 packets: framing, CRC-16, byte stuffing, decoding.
//!
//! # Packet layout (all multi-byte fields little-endian)
//! ```text
//! FF FF FD 00 | ID | LEN_L LEN_H | INSTR | PARAM... | CRC_L CRC_H
//! ```
//! - `LEN` counts the bytes after itself: instruction, (stuffed) parameters and the 2 CRC bytes.
//! - Byte stuffing: inside instruction + parameters, every `FF FF FD` is sent as `FF FF FD FD`,
//!   so the header never appears inside a packet. `LEN` and the CRC are computed on the stuffed
//!   bytes.
//! - CRC-16: polynomial 0x8005, initial value 0, not reflected, over every byte from the header
//!   to the last parameter.
//! - A status packet (servo → controller) has instruction `0x55` and, as its first parameter,
//!   the error byte ([`StatusError`]).

use thiserror::Error;

/// The 4-byte header that opens every packet.
pub const HEADER: [u8; 4] = [0xFF, 0xFF, 0xFD, 0x00];
/// The id every servo listens to (replies only to ping and sync read).
pub const BROADCAST_ID: u8 = 0xFE;
/// Largest `LEN` accepted when decoding (bytes); X-series buffers are far smaller.
pub const MAX_LENGTH: usize = 1024;

/// Instruction codes used here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Instruction {
    Ping = 0x01,
    Read = 0x02,
    Write = 0x03,
    SyncRead = 0x82,
    SyncWrite = 0x83,
    Status = 0x55,
}

impl Instruction {
    /// The instruction for a code, if it is one used here.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x01 => Self::Ping,
            0x02 => Self::Read,
            0x03 => Self::Write,
            0x82 => Self::SyncRead,
            0x83 => Self::SyncWrite,
            0x55 => Self::Status,
            _ => return None,
        })
    }
}

const fn crc_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x8005
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// The CRC-16 lookup table for polynomial 0x8005 (the e-manual's `crc_table`).
pub const CRC_TABLE: [u16; 256] = crc_table();

/// CRC-16 (poly 0x8005, init 0) of `bytes`, as in the ROBOTIS e-manual's `update_crc`.
pub fn crc16(bytes: &[u8]) -> u16 {
    bytes.iter().fold(0u16, |crc, &b| {
        let i = ((crc >> 8) as u8 ^ b) as usize;
        (crc << 8) ^ CRC_TABLE[i]
    })
}

/// Inserts `FD` after every `FF FF FD` in `body` (instruction + parameters).
pub fn stuff(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + body.len() / 3);
    for (i, &b) in body.iter().enumerate() {
        out.push(b);
        if i >= 2 && body[i - 2..=i] == [0xFF, 0xFF, 0xFD] {
            out.push(0xFD);
        }
    }
    out
}

/// Undoes [`stuff`]: every `FF FF FD FD` becomes `FF FF FD`.
pub fn unstuff(body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len());
    let mut i = 0;
    while i < body.len() {
        if body[i..].starts_with(&[0xFF, 0xFF, 0xFD, 0xFD]) {
            out.extend_from_slice(&[0xFF, 0xFF, 0xFD]);
            i += 4;
        } else {
            out.push(body[i]);
            i += 1;
        }
    }
    out
}

/// A packet's content after unstuffing: who, what, and the parameters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    pub id: u8,
    /// Raw instruction code (see [`Instruction`]).
    pub instruction: u8,
    pub params: Vec<u8>,
}

impl Packet {
    /// A packet with a known instruction.
    pub fn new(id: u8, instruction: Instruction, params: Vec<u8>) -> Self {
        Self {
            id,
            instruction: instruction as u8,
            params,
        }
    }

    /// The wire bytes: header, id, length, stuffed body, CRC.
    pub fn encode(&self) -> Vec<u8> {
        let mut body = Vec::with_capacity(1 + self.params.len());
        body.push(self.instruction);
        body.extend_from_slice(&self.params);
        let body = stuff(&body);
        let len = (body.len() + 2) as u16;
        let mut out = Vec::with_capacity(7 + body.len() + 2);
        out.extend_from_slice(&HEADER);
        out.push(self.id);
        out.extend_from_slice(&len.to_le_bytes());
        out.extend_from_slice(&body);
        let crc = crc16(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// For a status packet: its error byte and the data after it.
    pub fn status(&self) -> Result<(StatusError, &[u8]), DecodeError> {
        if self.instruction != Instruction::Status as u8 {
            return Err(DecodeError::NotStatus(self.instruction));
        }
        let (&err, data) = self.params.split_first().ok_or(DecodeError::BadLength(0))?;
        Ok((StatusError(err), data))
    }
}

/// The error byte of a status packet: bit 7 = hardware alert, bits 0–6 = error number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StatusError(pub u8);

impl StatusError {
    /// The servo has a hardware error (see its Hardware Error Status register); data still valid.
    pub fn alert(self) -> bool {
        self.0 & 0x80 != 0
    }

    /// The instruction's error number (0 = none).
    pub fn code(self) -> u8 {
        self.0 & 0x7F
    }

    /// The e-manual's name of [`StatusError::code`].
    pub fn describe(self) -> &'static str {
        match self.code() {
            0 => "no error",
            1 => "result fail",
            2 => "instruction error",
            3 => "CRC error",
            4 => "data range error",
            5 => "data length error",
            6 => "data limit error",
            7 => "access error",
            _ => "unknown error",
        }
    }
}

/// Why bytes did not decode into a packet.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum DecodeError {
    #[error("bytes before a packet header")]
    NoHeader,
    #[error("impossible length field {0}")]
    BadLength(usize),
    #[error("CRC mismatch: computed {computed:#06x}, received {received:#06x}")]
    Crc { computed: u16, received: u16 },
    #[error("expected a status packet, got instruction {0:#04x}")]
    NotStatus(u8),
}

/// What [`decode`] found at the front of a byte buffer.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Decoded {
    /// A whole, valid packet taking the first `consumed` bytes.
    Packet { packet: Packet, consumed: usize },
    /// The first `consumed` bytes are to be dropped for `error`.
    Invalid { error: DecodeError, consumed: usize },
    /// Not enough bytes yet.
    NeedMore,
}

/// Decodes the first packet of `buf` (which may hold partial or several packets, or junk).
pub fn decode(buf: &[u8]) -> Decoded {
    let Some(start) = buf.windows(4).position(|w| w == HEADER) else {
        // Keep a tail that may be the start of a header.
        let keep = (1..=3.min(buf.len()))
            .rev()
            .find(|&k| HEADER.starts_with(&buf[buf.len() - k..]))
            .unwrap_or(0);
        let junk = buf.len() - keep;
        return if junk > 0 {
            Decoded::Invalid {
                error: DecodeError::NoHeader,
                consumed: junk,
            }
        } else {
            Decoded::NeedMore
        };
    };
    if start > 0 {
        return Decoded::Invalid {
            error: DecodeError::NoHeader,
            consumed: start,
        };
    }
    if buf.len() < 7 {
        return Decoded::NeedMore;
    }
    let len = u16::from_le_bytes([buf[5], buf[6]]) as usize;
    if !(3..=MAX_LENGTH).contains(&len) {
        // Skip this header and resynchronise on the next one.
        return Decoded::Invalid {
            error: DecodeError::BadLength(len),
            consumed: 1,
        };
    }
    let total = 7 + len;
    if buf.len() < total {
        return Decoded::NeedMore;
    }
    let computed = crc16(&buf[..total - 2]);
    let received = u16::from_le_bytes([buf[total - 2], buf[total - 1]]);
    if computed != received {
        return Decoded::Invalid {
            error: DecodeError::Crc { computed, received },
            consumed: total,
        };
    }
    let body = unstuff(&buf[7..total - 2]);
    let Some((&instruction, params)) = body.split_first() else {
        return Decoded::Invalid {
            error: DecodeError::BadLength(len),
            consumed: total,
        };
    };
    Decoded::Packet {
        packet: Packet {
            id: buf[4],
            instruction,
            params: params.to_vec(),
        },
        consumed: total,
    }
}

/// Parameters of READ: address and data length.
pub fn read_params(address: u16, length: u16) -> Vec<u8> {
    let mut p = address.to_le_bytes().to_vec();
    p.extend_from_slice(&length.to_le_bytes());
    p
}

/// Parameters of WRITE: address then data.
pub fn write_params(address: u16, data: &[u8]) -> Vec<u8> {
    let mut p = address.to_le_bytes().to_vec();
    p.extend_from_slice(data);
    p
}

/// Parameters of SYNC READ: address, data length, then the ids.
pub fn sync_read_params(address: u16, length: u16, ids: &[u8]) -> Vec<u8> {
    let mut p = read_params(address, length);
    p.extend_from_slice(ids);
    p
}

/// Parameters of SYNC WRITE: address, data length, then `id, data` per servo (all the same length).
pub fn sync_write_params(address: u16, length: u16, items: &[(u8, Vec<u8>)]) -> Vec<u8> {
    let mut p = read_params(address, length);
    for (id, data) in items {
        p.push(*id);
        p.extend_from_slice(data);
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The e-manual's example: PING to id 1.
    const PING_1: [u8; 10] = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01, 0x19, 0x4E];

    #[test]
    fn ping_matches_the_emanual_example() {
        assert_eq!(crc16(&PING_1[..8]), 0x4E19);
        assert_eq!(Packet::new(1, Instruction::Ping, vec![]).encode(), PING_1);
        // The e-manual's table starts 0x0000, 0x8005, 0x800F, 0x000A.
        assert_eq!(&CRC_TABLE[..4], &[0x0000, 0x8005, 0x800F, 0x000A]);
        assert_eq!(CRC_TABLE[255], 0x0202);
    }

    #[test]
    fn emanual_read_and_status_examples() {
        // READ id 1, Present Position (132), 4 bytes.
        let read = Packet::new(1, Instruction::Read, read_params(132, 4)).encode();
        assert_eq!(
            read,
            [
                0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x07, 0x00, 0x02, 0x84, 0x00, 0x04, 0x00, 0x1D, 0x15
            ]
        );
        // Its status: position 166 (0xA6).
        let status = [
            0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x08, 0x00, 0x55, 0x00, 0xA6, 0x00, 0x00, 0x00, 0x8C,
            0xC0,
        ];
        let Decoded::Packet { packet, consumed } = decode(&status) else {
            panic!("status did not decode")
        };
        assert_eq!(consumed, status.len());
        let (err, data) = packet.status().unwrap();
        assert_eq!(err, StatusError(0));
        assert_eq!(data, [0xA6, 0, 0, 0]);
    }

    #[test]
    fn stuffing_round_trips_and_hides_the_header() {
        assert_eq!(stuff(&[0xFF, 0xFF, 0xFD]), [0xFF, 0xFF, 0xFD, 0xFD]);
        assert_eq!(unstuff(&[0xFF, 0xFF, 0xFD, 0xFD]), [0xFF, 0xFF, 0xFD]);
        // Exhaustive over all 4^6 sequences of the bytes that matter.
        let alphabet = [0xFF, 0xFD, 0x00, 0x55];
        for n in 0..4usize.pow(6) {
            let body: Vec<u8> = (0..6).map(|k| alphabet[(n >> (2 * k)) & 3]).collect();
            let s = stuff(&body);
            assert_eq!(unstuff(&s), body, "{body:02X?}");
            let p = Packet::new(3, Instruction::Write, body.clone());
            let wire = p.encode();
            assert_eq!(
                wire.windows(4).filter(|w| *w == HEADER).count(),
                1,
                "{wire:02X?}"
            );
            assert_eq!(
                decode(&wire),
                Decoded::Packet {
                    packet: p,
                    consumed: wire.len()
                }
            );
        }
    }

    #[test]
    fn malformed_packets_rejected() {
        let mut bad = PING_1;
        bad[9] ^= 0x01;
        assert!(matches!(
            decode(&bad),
            Decoded::Invalid {
                error: DecodeError::Crc { .. },
                consumed: 10
            }
        ));
        // Junk before a packet is dropped, then the packet decodes.
        let mut buf = vec![0x00, 0x12, 0xFF];
        buf.extend_from_slice(&PING_1);
        assert_eq!(
            decode(&buf),
            Decoded::Invalid {
                error: DecodeError::NoHeader,
                consumed: 3
            }
        );
        assert!(matches!(decode(&buf[3..]), Decoded::Packet { .. }));
        // Impossible lengths.
        let mut short = PING_1;
        short[5] = 0x02;
        assert!(matches!(
            decode(&short),
            Decoded::Invalid {
                error: DecodeError::BadLength(2),
                consumed: 1
            }
        ));
        let huge = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0xFF, 0xFF, 0x01];
        assert!(matches!(
            decode(&huge),
            Decoded::Invalid {
                error: DecodeError::BadLength(_),
                ..
            }
        ));
        // Truncated: wait for more; a partial header is kept.
        assert_eq!(decode(&PING_1[..9]), Decoded::NeedMore);
        assert_eq!(decode(&[0xFF, 0xFF]), Decoded::NeedMore);
        assert_eq!(
            decode(&[0x01, 0xFF, 0xFF]),
            Decoded::Invalid {
                error: DecodeError::NoHeader,
                consumed: 1
            }
        );
        // A ping is no status packet.
        let Decoded::Packet { packet, .. } = decode(&PING_1) else {
            panic!()
        };
        assert_eq!(packet.status(), Err(DecodeError::NotStatus(0x01)));
    }

    #[test]
    fn status_error_byte() {
        let e = StatusError(0x84);
        assert!(e.alert());
        assert_eq!(e.code(), 4);
        assert_eq!(e.describe(), "data range error");
    }
}
