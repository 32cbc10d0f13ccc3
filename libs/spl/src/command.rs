//! The operator -> robot command packet: 11 bytes, Python struct format `<BBBff`, UDP port
//! [`COMMAND_PORT`].
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | u8 | body (0 keep, 1..=10 [`BodyCommand`]) |
//! | 1 | u8 | head (0 keep, 1..=5 [`HeadCommand`]) |
//! | 2 | u8 | strategy (0 Default, 1 Passages) |
//! | 3 | f32 | x (mm, global) |
//! | 7 | f32 | y (mm, global) |
//!
//! [`encode_command`] is the bridge side: it refuses a command without body and head, a
//! target-needing body without a target, and non-finite coordinates, so what leaves the bridge
//! is always exactly 11 valid bytes. [`decode_command`] is the robot side (the simulated robot
//! uses it): it accepts exactly 11 bytes and refuses what the encoder would never produce.

use crate::types::{BodyCommand, FieldPoint, HeadCommand, NaoCommand, Strategy};
use crate::validation::{PacketError, PacketKind};
use crate::wire::{f32_at, put, u8_at};

/// Length of a command packet (bytes).
pub const COMMAND_PACKET_LEN: usize = 11;
/// The robot's UDP port for command packets.
pub const COMMAND_PORT: u16 = 65306;
/// Offset of the original operator software's flat numbering: 1-10 bodies, 11-15 heads.
pub const FLAT_HEAD_OFFSET: u8 = 10;

/// Why a typed command cannot be sent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CommandEncodeError {
    /// Neither a body nor a head command: the packet would carry nothing.
    #[error("a command needs a body or a head command")]
    Empty,
    /// The body command needs a target point and has none.
    #[error("{0:?} needs a target point")]
    MissingTarget(BodyCommand),
    /// The target has a NaN or infinite coordinate.
    #[error("target coordinates must be finite")]
    NonFiniteTarget,
    /// A flat command number outside 1..=15.
    #[error("flat command number {0} is not 1..=15")]
    UnknownFlatNumber(u8),
}

impl NaoCommand {
    /// A body-only command.
    pub fn body(body: BodyCommand, strategy: Strategy, target: Option<FieldPoint>) -> Self {
        Self {
            body: Some(body),
            head: None,
            strategy,
            target,
        }
    }

    /// A head-only command.
    pub fn head(head: HeadCommand, strategy: Strategy) -> Self {
        Self {
            body: None,
            head: Some(head),
            strategy,
            target: None,
        }
    }

    /// A command from the original operator software's flat number (1..=10 body, 11..=15 head).
    pub fn from_flat(
        number: u8,
        strategy: Strategy,
        target: Option<FieldPoint>,
    ) -> Result<Self, CommandEncodeError> {
        if let Some(body) = BodyCommand::from_wire(number) {
            Ok(Self::body(body, strategy, target))
        } else if let Some(head) = number
            .checked_sub(FLAT_HEAD_OFFSET)
            .and_then(HeadCommand::from_wire)
        {
            Ok(Self::head(head, strategy))
        } else {
            Err(CommandEncodeError::UnknownFlatNumber(number))
        }
    }
}

/// Encode a typed command into the 11-byte packet. The target is written only for bodies that
/// use it ([`BodyCommand::needs_target`]); otherwise x and y are 0.
pub fn encode_command(cmd: &NaoCommand) -> Result<[u8; COMMAND_PACKET_LEN], CommandEncodeError> {
    if cmd.body.is_none() && cmd.head.is_none() {
        return Err(CommandEncodeError::Empty);
    }
    let target = match cmd.body {
        Some(body) if body.needs_target() => {
            cmd.target.ok_or(CommandEncodeError::MissingTarget(body))?
        }
        _ => FieldPoint::default(),
    };
    if !target.is_finite() {
        return Err(CommandEncodeError::NonFiniteTarget);
    }
    let mut b = [0u8; COMMAND_PACKET_LEN];
    b[0] = cmd.body.map_or(0, BodyCommand::wire_value);
    b[1] = cmd.head.map_or(0, HeadCommand::wire_value);
    b[2] = cmd.strategy.wire_value();
    put(&mut b, 3, &target.x_mm.to_le_bytes());
    put(&mut b, 7, &target.y_mm.to_le_bytes());
    Ok(b)
}

/// Decode a command packet as the robot does, strictly: exactly 11 bytes, known body, head and
/// strategy values, finite coordinates, not empty. `target` is `Some` only for target-needing
/// bodies.
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
    let body = match body_raw {
        0 => None,
        v => Some(BodyCommand::from_wire(v).ok_or_else(|| invalid("body", v))?),
    };
    let head = match head_raw {
        0 => None,
        v => Some(HeadCommand::from_wire(v).ok_or_else(|| invalid("head", v))?),
    };
    let strategy =
        Strategy::from_wire(strategy_raw).ok_or_else(|| invalid("strategy", strategy_raw))?;
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
    if body.is_none() && head.is_none() {
        return Err(PacketError::EmptyCommand);
    }
    Ok(NaoCommand {
        body,
        head,
        strategy,
        target: body
            .filter(|b| b.needs_target())
            .map(|_| FieldPoint::new(x, y)),
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
        assert_eq!(c.body, Some(BodyCommand::GoToPosition));
        assert_eq!(c.head, Some(HeadCommand::LookLeft));
        assert_eq!(c.strategy, Strategy::Passages);
        assert_eq!(c.target, Some(FieldPoint::new(1500.5, -2250.25)));
    }

    #[test]
    fn encoder_writes_the_documented_bytes() {
        let c = NaoCommand {
            body: Some(BodyCommand::Turn),
            head: Some(HeadCommand::Scan),
            strategy: Strategy::Default,
            target: Some(FieldPoint::new(-1.0, 2.0)),
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
        for body in BodyCommand::ALL {
            let target = body.needs_target().then(|| FieldPoint::new(100.0, -50.0));
            let c = NaoCommand::body(body, Strategy::Passages, target);
            let b = encode_command(&c).unwrap();
            assert_eq!(b[0], body.wire_value());
            assert_eq!(decode_command(&b).unwrap(), c);
        }
        for head in HeadCommand::ALL {
            let c = NaoCommand::head(head, Strategy::Default);
            let b = encode_command(&c).unwrap();
            assert_eq!((b[0], b[1]), (0, head.wire_value()));
            assert_eq!(decode_command(&b).unwrap(), c);
        }
    }

    #[test]
    fn encoder_refuses_nothing_missing_target_and_nan() {
        let empty = NaoCommand {
            body: None,
            head: None,
            strategy: Strategy::Default,
            target: None,
        };
        assert_eq!(encode_command(&empty), Err(CommandEncodeError::Empty));
        let no_target = NaoCommand::body(BodyCommand::GoToPosition, Strategy::Default, None);
        assert_eq!(
            encode_command(&no_target),
            Err(CommandEncodeError::MissingTarget(BodyCommand::GoToPosition))
        );
        let nan = NaoCommand::body(
            BodyCommand::Turn,
            Strategy::Default,
            Some(FieldPoint::new(f32::NAN, 0.0)),
        );
        assert_eq!(
            encode_command(&nan),
            Err(CommandEncodeError::NonFiniteTarget)
        );
        // A kick ignores the target: x, y are sent as zeros.
        let kick = NaoCommand::body(
            BodyCommand::Kick,
            Strategy::Default,
            Some(FieldPoint::new(9.0, 9.0)),
        );
        assert_eq!(&encode_command(&kick).unwrap()[3..], &[0; 8]);
    }

    #[test]
    fn flat_numbering_maps_bodies_and_heads() {
        let c = NaoCommand::from_flat(4, Strategy::Default, None).unwrap();
        assert_eq!(c.body, Some(BodyCommand::Kick));
        let c = NaoCommand::from_flat(15, Strategy::Default, None).unwrap();
        assert_eq!(c.head, Some(HeadCommand::Scan));
        assert_eq!(c.body, None);
        assert!(NaoCommand::from_flat(0, Strategy::Default, None).is_err());
        assert!(NaoCommand::from_flat(16, Strategy::Default, None).is_err());
        assert_eq!(Strategy::from_gui_number(2), Some(Strategy::Passages));
        assert_eq!(Strategy::from_gui_number(3), None);
    }

    #[test]
    fn decoder_errors_have_their_reason() {
        let ok = encode_command(&NaoCommand::head(HeadCommand::Scan, Strategy::Default)).unwrap();
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
