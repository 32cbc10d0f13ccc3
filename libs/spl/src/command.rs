//! The operator -> robot command packet: 11 bytes, Python struct format `<BBBff`, UDP port
//! [`COMMAND_PORT`].
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | u8 | body ([`NaoBody`]: 0 keep, 1..=10) |
//! | 1 | u8 | head ([`NaoHead`]: 0 keep, 1..=5) |
//! | 2 | u8 | strategy (0 Default, 1 Passages) |
//! | 3 | f32 | x (mm, global) |
//! | 7 | f32 | y (mm, global) |
//!
//! [`encode_command`] is the bridge side: it takes the bus's [`NaoCommand`] and refuses a command
//! without body and head, and non-finite target coordinates, so what leaves the bridge
//! is always exactly 11 valid bytes. [`decode_command`] is the robot side (the simulated robot
//! uses it): it accepts exactly 11 bytes and refuses what the encoder would never produce.

use crate::types::{FieldPoint, NaoBody, NaoCommand, NaoHead, NaoStrategy};
use crate::validation::{PacketError, PacketKind};
use crate::wire::{f32_at, put, u8_at};

/// Length of a command packet (bytes).
pub const COMMAND_PACKET_LEN: usize = 11;
/// The robot's UDP port for command packets.
pub const COMMAND_PORT: u16 = 65306;
/// Offset of the original operator software's flat numbering: 1-10 bodies, 11-15 heads.
pub const FLAT_HEAD_OFFSET: u8 = 10;

/// Why a command cannot be sent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CommandEncodeError {
    /// Neither a body nor a head command: the packet would carry nothing.
    #[error("a command needs a body or a head command")]
    Empty,
    /// The target has a NaN or infinite coordinate.
    #[error("target coordinates must be finite")]
    NonFiniteTarget,
    /// A flat command number outside 1..=15.
    #[error("flat command number {0} is not 1..=15")]
    UnknownFlatNumber(u8),
}

/// A command from the original operator software's flat number (1..=10 body, 11..=15 head).
pub fn command_from_flat(
    number: u8,
    strategy: NaoStrategy,
    target: FieldPoint,
) -> Result<NaoCommand, CommandEncodeError> {
    match number {
        1..=10 => NaoBody::from_wire(number).map(|b| NaoCommand::body(b, strategy, target)),
        11..=15 => {
            NaoHead::from_wire(number - FLAT_HEAD_OFFSET).map(|h| NaoCommand::head(h, strategy))
        }
        _ => None,
    }
    .ok_or(CommandEncodeError::UnknownFlatNumber(number))
}

/// Encode a command into the 11-byte packet. The target is written only for bodies that use it
/// ([`NaoBody::needs_target`]); otherwise x and y are 0. The header and `source` are not sent.
pub fn encode_command(cmd: &NaoCommand) -> Result<[u8; COMMAND_PACKET_LEN], CommandEncodeError> {
    if cmd.body == NaoBody::Keep && cmd.head == NaoHead::Keep {
        return Err(CommandEncodeError::Empty);
    }
    let target = if cmd.body.needs_target() {
        cmd.target
    } else {
        FieldPoint::default()
    };
    if !target.is_finite() {
        return Err(CommandEncodeError::NonFiniteTarget);
    }
    let mut b = [0u8; COMMAND_PACKET_LEN];
    b[0] = cmd.body.wire_value();
    b[1] = cmd.head.wire_value();
    b[2] = cmd.strategy.wire_value();
    put(&mut b, 3, &target.x_mm.to_le_bytes());
    put(&mut b, 7, &target.y_mm.to_le_bytes());
    Ok(b)
}

/// Decode a command packet as the robot does, strictly: exactly 11 bytes, known body, head and
/// strategy values, finite coordinates, not empty. `target` is the packet's (x, y) for
/// target-needing bodies and (0, 0) otherwise; the header and `source` are left empty.
pub fn decode_command(bytes: &[u8]) -> Result<NaoCommand, PacketError> {
    const K: PacketKind = PacketKind::Command;
    if bytes.len() != COMMAND_PACKET_LEN {
        return Err(PacketError::WrongSize {
            kind: K,
            expected: COMMAND_PACKET_LEN,
            got: bytes.len(),
        });
    }
    let body_raw = u8_at(bytes, 0);
    let head_raw = u8_at(bytes, 1);
    let strategy_raw = u8_at(bytes, 2);
    let invalid = |field, value: u8| PacketError::InvalidValue {
        kind: K,
        field,
        value: u32::from(value),
    };
    let body = NaoBody::from_wire(body_raw).ok_or_else(|| invalid("body", body_raw))?;
    let head = NaoHead::from_wire(head_raw).ok_or_else(|| invalid("head", head_raw))?;
    let strategy =
        NaoStrategy::from_wire(strategy_raw).ok_or_else(|| invalid("strategy", strategy_raw))?;
    let x = f32_at(bytes, 3);
    let y = f32_at(bytes, 7);
    if !x.is_finite() {
        return Err(PacketError::NonFinite {
            kind: K,
            field: "x",
        });
    }
    if !y.is_finite() {
        return Err(PacketError::NonFinite {
            kind: K,
            field: "y",
        });
    }
    if body == NaoBody::Keep && head == NaoHead::Keep {
        return Err(PacketError::EmptyCommand);
    }
    let target = if body.needs_target() {
        FieldPoint::new(x, y)
    } else {
        FieldPoint::default()
    };
    Ok(NaoCommand {
        body,
        head,
        strategy,
        target,
        ..Default::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::validation::DropReason;

    #[test]
    fn hand_built_packet_decodes_field_by_field() {
        // GoToPosition (1), LookLeft (3), Passages (1), x = 1500.5, y = -2250.25
        let mut b = [0u8; 11];
        b[0] = 1;
        b[1] = 3;
        b[2] = 1;
        b[3..7].copy_from_slice(&1500.5f32.to_le_bytes());
        b[7..11].copy_from_slice(&(-2250.25f32).to_le_bytes());
        let c = decode_command(&b).unwrap();
        assert_eq!(c.body, NaoBody::GoToPosition);
        assert_eq!(c.head, NaoHead::LookLeft);
        assert_eq!(c.strategy, NaoStrategy::Passages);
        assert_eq!(c.target, FieldPoint::new(1500.5, -2250.25));
    }

    #[test]
    fn encoder_writes_the_documented_bytes() {
        let c = NaoCommand {
            body: NaoBody::Turn,
            head: NaoHead::Scan,
            strategy: NaoStrategy::Default,
            target: FieldPoint::new(-1.0, 2.0),
            ..Default::default()
        };
        let b = encode_command(&c).unwrap();
        assert_eq!(b.len(), 11);
        assert_eq!(&b[..3], &[8, 5, 0]);
        // -1.0f32 = 0xBF800000, 2.0f32 = 0x40000000, little-endian.
        assert_eq!(&b[3..], &[0, 0, 0x80, 0xBF, 0, 0, 0, 0x40]);
        assert_eq!(decode_command(&b).unwrap(), c);
    }

    #[test]
    fn every_body_and_head_round_trips() {
        for body in NaoBody::ALL {
            let target = if body.needs_target() {
                FieldPoint::new(100.0, -50.0)
            } else {
                FieldPoint::default()
            };
            let c = NaoCommand::body(body, NaoStrategy::Passages, target);
            let b = encode_command(&c).unwrap();
            assert_eq!(b[0], body.wire_value());
            assert_eq!(decode_command(&b).unwrap(), c);
        }
        for head in NaoHead::ALL {
            let c = NaoCommand::head(head, NaoStrategy::Default);
            let b = encode_command(&c).unwrap();
            assert_eq!((b[0], b[1]), (0, head.wire_value()));
            assert_eq!(decode_command(&b).unwrap(), c);
        }
    }

    #[test]
    fn encoder_refuses_nothing_and_nan() {
        let empty = NaoCommand::default();
        assert_eq!(encode_command(&empty), Err(CommandEncodeError::Empty));
        let nan = NaoCommand::body(
            NaoBody::Turn,
            NaoStrategy::Default,
            FieldPoint::new(f32::NAN, 0.0),
        );
        assert_eq!(
            encode_command(&nan),
            Err(CommandEncodeError::NonFiniteTarget)
        );
        // A kick ignores the target: x, y are sent as zeros.
        let kick = NaoCommand::body(
            NaoBody::Kick,
            NaoStrategy::Default,
            FieldPoint::new(9.0, 9.0),
        );
        assert_eq!(&encode_command(&kick).unwrap()[3..], &[0; 8]);
    }

    #[test]
    fn flat_numbering_maps_bodies_and_heads() {
        let origin = FieldPoint::default();
        let c = command_from_flat(4, NaoStrategy::Default, origin).unwrap();
        assert_eq!(c.body, NaoBody::Kick);
        let c = command_from_flat(15, NaoStrategy::Default, origin).unwrap();
        assert_eq!(c.head, NaoHead::Scan);
        assert_eq!(c.body, NaoBody::Keep);
        assert!(command_from_flat(0, NaoStrategy::Default, origin).is_err());
        assert!(command_from_flat(16, NaoStrategy::Default, origin).is_err());
        assert_eq!(NaoStrategy::from_gui_number(2), Some(NaoStrategy::Passages));
        assert_eq!(NaoStrategy::from_gui_number(3), None);
    }

    #[test]
    fn decoder_errors_have_their_reason() {
        let ok = encode_command(&NaoCommand::head(NaoHead::Scan, NaoStrategy::Default)).unwrap();
        assert_eq!(
            decode_command(&ok[..10]).unwrap_err().reason(),
            DropReason::WrongSize
        );
        let mut long = ok.to_vec();
        long.push(0);
        assert_eq!(
            decode_command(&long).unwrap_err().reason(),
            DropReason::WrongSize
        );
        let mut b = ok;
        b[0] = 11;
        assert_eq!(
            decode_command(&b).unwrap_err().reason(),
            DropReason::InvalidValue
        );
        let mut b = ok;
        b[1] = 6;
        assert_eq!(
            decode_command(&b).unwrap_err().reason(),
            DropReason::InvalidValue
        );
        let mut b = ok;
        b[2] = 2;
        assert_eq!(
            decode_command(&b).unwrap_err().reason(),
            DropReason::InvalidValue
        );
        let mut b = ok;
        b[7..11].copy_from_slice(&f32::INFINITY.to_le_bytes());
        assert_eq!(
            decode_command(&b).unwrap_err().reason(),
            DropReason::NonFinite
        );
        let mut b = ok;
        b[1] = 0;
        assert_eq!(decode_command(&b).unwrap_err(), PacketError::EmptyCommand);
    }
}
