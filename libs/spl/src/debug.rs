//! The robot -> operator debug packet: 356 bytes, every 100 ms, to the operator's UDP port
//! [`DEBUG_PORT`]. Python format `<d4sBBBB3ff2fHBB20B20f20f20fHH2B2B2f2f2f2f12B`.
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | 8 bytes | the robot's vtable pointer: ignored, never interpreted |
//! | 8 | 4 chars | header `RGrt` |
//! | 12 | u8 | version (4) |
//! | 13 | u8 | player number |
//! | 14 | u8 | team number |
//! | 15 | u8 | fallen (0/1) |
//! | 16 | f32 x3 | pose x, y (mm), theta (rad) |
//! | 28 | f32 | ball age (s) |
//! | 32 | f32 x2 | ball (mm) |
//! | 40 | u16 | number of data bytes (348) |
//! | 42 | u8 | role |
//! | 43 | u8 | obstacles seen (may exceed 20) |
//! | 44 | u8 x20 | obstacle types |
//! | 64 | f32 x20 | obstacle x (mm) |
//! | 144 | f32 x20 | obstacle y (mm) |
//! | 224 | u32 x20 | obstacle last seen (ms) |
//! | 304 | u16 | message budget |
//! | 306 | u16 | seconds remaining |
//! | 308 | u8 x2 | arm contact (left, right) |
//! | 310 | u8 x2 | arm push direction (left, right) |
//! | 312 | u32 x2 | arm time of last contact (ms) |
//! | 320 | u32 | time since whistle (ms) |
//! | 324 | u8 | whistle state; 3 padding bytes |
//! | 328 | f32 x2 | team ball (mm) |
//! | 336 | f32 x2 | team ball velocity (mm/s) |
//! | 344 | f32 | battery |
//! | 348 | f32 | CPU temperature |
//! | 352 | u8 | referee gesture; 3 padding bytes |
//!
//! Only the first `min(obstacles seen, 20)` obstacle slots are read and validated: the rest of
//! the robot's array is whatever its memory held. Padding is ignored.

use crate::types::{
    FieldPoint, FieldPose, NaoLocalModel, NaoObstacle, ObstacleKind, PlayerRole, WhistleState,
};
use crate::validation::{PacketError, PacketKind};
use crate::wire::{bytes4_at, f32_at, put, u8_at, u16_at, u32_at};

/// Length of a debug packet (bytes).
pub const DEBUG_PACKET_LEN: usize = 356;
/// The operator PC's UDP port for debug packets.
pub const DEBUG_PORT: u16 = 65305;
/// Header at offset 8.
pub const DEBUG_HEADER: [u8; 4] = *b"RGrt";
/// Supported version (offset 12).
pub const DEBUG_VERSION: u8 = 4;
/// The "number of data bytes" field's expected value (offset 40).
pub const DEBUG_DATA_BYTES: u16 = 348;
/// Obstacle slots in the packet.
pub const MAX_OBSTACLES: usize = 20;

const OFF_HEADER: usize = 8;
const OFF_VERSION: usize = 12;
const OFF_PLAYER: usize = 13;
const OFF_TEAM: usize = 14;
const OFF_FALLEN: usize = 15;
const OFF_POSE: usize = 16;
const OFF_BALL_AGE: usize = 28;
const OFF_BALL: usize = 32;
const OFF_DATA_BYTES: usize = 40;
const OFF_ROLE: usize = 42;
const OFF_OBS_COUNT: usize = 43;
const OFF_OBS_TYPES: usize = 44;
const OFF_OBS_X: usize = 64;
const OFF_OBS_Y: usize = 144;
const OFF_OBS_SEEN: usize = 224;
const OFF_BUDGET: usize = 304;
const OFF_SECS: usize = 306;
const OFF_ARM_CONTACT: usize = 308;
const OFF_ARM_PUSH: usize = 310;
const OFF_ARM_TIME: usize = 312;
const OFF_WHISTLE_TIME: usize = 320;
const OFF_WHISTLE: usize = 324;
const OFF_TEAM_BALL: usize = 328;
const OFF_TEAM_BALL_VEL: usize = 336;
const OFF_BATTERY: usize = 344;
const OFF_TEMPERATURE: usize = 348;
const OFF_GESTURE: usize = 352;

/// Why a local model cannot be encoded (only the simulated robot encodes).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DebugEncodeError {
    /// More than 20 obstacles in the list.
    #[error("{0} obstacles, at most 20 fit")]
    TooManyObstacles(usize),
    /// The list length is not `min(obstacles_seen, 20)`.
    #[error("{listed} obstacles listed but obstacles_seen is {seen}")]
    ObstacleCountMismatch {
        /// Obstacles in the list.
        listed: usize,
        /// The count field.
        seen: u8,
    },
    /// A float field is NaN or infinite.
    #[error("field {0} is not finite")]
    NonFinite(&'static str),
}

fn finite(v: f32, field: &'static str) -> Result<f32, PacketError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PacketError::NonFinite {
            kind: PacketKind::Debug,
            field,
        })
    }
}

fn invalid(field: &'static str, value: u32) -> PacketError {
    PacketError::InvalidValue {
        kind: PacketKind::Debug,
        field,
        value,
    }
}

fn point_at(
    b: &[u8],
    off: usize,
    fx: &'static str,
    fy: &'static str,
) -> Result<FieldPoint, PacketError> {
    Ok(FieldPoint::new(
        finite(f32_at(b, off), fx)?,
        finite(f32_at(b, off + 4), fy)?,
    ))
}

/// Decode a debug packet into a robot's local world model. Refuses a wrong length, a header
/// other than `RGrt`, a version other than 4, a data-bytes field other than 348, `fallen` > 1,
/// unknown obstacle types or whistle states (in the used slots), and any non-finite float in a
/// used field.
pub fn decode_debug(b: &[u8]) -> Result<NaoLocalModel, PacketError> {
    const K: PacketKind = PacketKind::Debug;
    if b.len() != DEBUG_PACKET_LEN {
        return Err(PacketError::WrongSize {
            kind: K,
            expected: DEBUG_PACKET_LEN,
            got: b.len(),
        });
    }
    let header = bytes4_at(b, OFF_HEADER);
    if header != DEBUG_HEADER {
        return Err(PacketError::WrongHeader {
            kind: K,
            expected: DEBUG_HEADER,
            found: header,
        });
    }
    let version = u8_at(b, OFF_VERSION);
    if version != DEBUG_VERSION {
        return Err(PacketError::UnknownVersion {
            kind: K,
            expected: DEBUG_VERSION,
            found: version,
        });
    }
    let data_bytes = u16_at(b, OFF_DATA_BYTES);
    if data_bytes != DEBUG_DATA_BYTES {
        return Err(invalid("num_data_bytes", u32::from(data_bytes)));
    }
    let fallen = match u8_at(b, OFF_FALLEN) {
        0 => false,
        1 => true,
        v => return Err(invalid("fallen", u32::from(v))),
    };
    let pose = FieldPose {
        x_mm: finite(f32_at(b, OFF_POSE), "pose_x")?,
        y_mm: finite(f32_at(b, OFF_POSE + 4), "pose_y")?,
        theta_rad: finite(f32_at(b, OFF_POSE + 8), "pose_theta")?,
    };
    let ball_age_s = finite(f32_at(b, OFF_BALL_AGE), "ball_age")?;
    let ball = point_at(b, OFF_BALL, "ball_x", "ball_y")?;
    let obstacles_seen = u8_at(b, OFF_OBS_COUNT);
    let used = usize::from(obstacles_seen).min(MAX_OBSTACLES);
    let mut obstacles = Vec::with_capacity(used);
    for i in 0..used {
        let t = u8_at(b, OFF_OBS_TYPES + i);
        let kind =
            ObstacleKind::from_wire(t).ok_or_else(|| invalid("obstacle_type", u32::from(t)))?;
        obstacles.push(NaoObstacle {
            kind,
            center: FieldPoint::new(
                finite(f32_at(b, OFF_OBS_X + 4 * i), "obstacle_x")?,
                finite(f32_at(b, OFF_OBS_Y + 4 * i), "obstacle_y")?,
            ),
            last_seen_ms: u32_at(b, OFF_OBS_SEEN + 4 * i),
        });
    }
    let contact = |side: usize| -> Result<bool, PacketError> {
        match u8_at(b, OFF_ARM_CONTACT + side) {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(invalid("arm_contact", u32::from(v))),
        }
    };
    let whistle_raw = u8_at(b, OFF_WHISTLE);
    let whistle = WhistleState::from_wire(whistle_raw)
        .ok_or_else(|| invalid("whistle", u32::from(whistle_raw)))?;
    Ok(NaoLocalModel {
        header: Default::default(),
        player_number: u8_at(b, OFF_PLAYER),
        team_number: u8_at(b, OFF_TEAM),
        fallen,
        pose,
        ball_age_s,
        ball,
        role: PlayerRole::from_wire(u8_at(b, OFF_ROLE)),
        obstacles_seen,
        obstacles,
        message_budget: u16_at(b, OFF_BUDGET),
        secs_remaining: u16_at(b, OFF_SECS),
        arm_contact: [contact(0)?, contact(1)?],
        arm_push_direction: [u8_at(b, OFF_ARM_PUSH), u8_at(b, OFF_ARM_PUSH + 1)],
        arm_last_contact_ms: [u32_at(b, OFF_ARM_TIME), u32_at(b, OFF_ARM_TIME + 4)],
        time_since_whistle_ms: u32_at(b, OFF_WHISTLE_TIME),
        whistle,
        team_ball: point_at(b, OFF_TEAM_BALL, "team_ball_x", "team_ball_y")?,
        team_ball_velocity: point_at(b, OFF_TEAM_BALL_VEL, "team_ball_vx", "team_ball_vy")?,
        battery: finite(f32_at(b, OFF_BATTERY), "battery")?,
        cpu_temperature_c: finite(f32_at(b, OFF_TEMPERATURE), "cpu_temperature")?,
        referee_gesture: u8_at(b, OFF_GESTURE),
    })
}

/// Encode a local model as the robot would send it (the 8 leading bytes and the padding are
/// zero; unused obstacle slots are zero).
pub fn encode_debug(m: &NaoLocalModel) -> Result<[u8; DEBUG_PACKET_LEN], DebugEncodeError> {
    if m.obstacles.len() > MAX_OBSTACLES {
        return Err(DebugEncodeError::TooManyObstacles(m.obstacles.len()));
    }
    if m.obstacles.len() != usize::from(m.obstacles_seen).min(MAX_OBSTACLES) {
        return Err(DebugEncodeError::ObstacleCountMismatch {
            listed: m.obstacles.len(),
            seen: m.obstacles_seen,
        });
    }
    let floats: [(f32, &'static str); 11] = [
        (m.pose.x_mm, "pose_x"),
        (m.pose.y_mm, "pose_y"),
        (m.pose.theta_rad, "pose_theta"),
        (m.ball_age_s, "ball_age"),
        (m.ball.x_mm, "ball_x"),
        (m.ball.y_mm, "ball_y"),
        (m.team_ball.x_mm, "team_ball_x"),
        (m.team_ball.y_mm, "team_ball_y"),
        (m.team_ball_velocity.x_mm, "team_ball_vx"),
        (m.team_ball_velocity.y_mm, "team_ball_vy"),
        (m.battery, "battery"),
    ];
    for (v, name) in floats {
        if !v.is_finite() {
            return Err(DebugEncodeError::NonFinite(name));
        }
    }
    if !m.cpu_temperature_c.is_finite() {
        return Err(DebugEncodeError::NonFinite("cpu_temperature"));
    }
    if m.obstacles.iter().any(|o| !o.center.is_finite()) {
        return Err(DebugEncodeError::NonFinite("obstacle"));
    }
    let mut b = [0u8; DEBUG_PACKET_LEN];
    put(&mut b, OFF_HEADER, &DEBUG_HEADER);
    b[OFF_VERSION] = DEBUG_VERSION;
    b[OFF_PLAYER] = m.player_number;
    b[OFF_TEAM] = m.team_number;
    b[OFF_FALLEN] = u8::from(m.fallen);
    put(&mut b, OFF_POSE, &m.pose.x_mm.to_le_bytes());
    put(&mut b, OFF_POSE + 4, &m.pose.y_mm.to_le_bytes());
    put(&mut b, OFF_POSE + 8, &m.pose.theta_rad.to_le_bytes());
    put(&mut b, OFF_BALL_AGE, &m.ball_age_s.to_le_bytes());
    put(&mut b, OFF_BALL, &m.ball.x_mm.to_le_bytes());
    put(&mut b, OFF_BALL + 4, &m.ball.y_mm.to_le_bytes());
    put(&mut b, OFF_DATA_BYTES, &DEBUG_DATA_BYTES.to_le_bytes());
    b[OFF_ROLE] = m.role.wire_value();
    b[OFF_OBS_COUNT] = m.obstacles_seen;
    for (i, o) in m.obstacles.iter().enumerate() {
        b[OFF_OBS_TYPES + i] = o.kind.wire_value();
        put(&mut b, OFF_OBS_X + 4 * i, &o.center.x_mm.to_le_bytes());
        put(&mut b, OFF_OBS_Y + 4 * i, &o.center.y_mm.to_le_bytes());
        put(&mut b, OFF_OBS_SEEN + 4 * i, &o.last_seen_ms.to_le_bytes());
    }
    put(&mut b, OFF_BUDGET, &m.message_budget.to_le_bytes());
    put(&mut b, OFF_SECS, &m.secs_remaining.to_le_bytes());
    for side in 0..2 {
        b[OFF_ARM_CONTACT + side] = u8::from(m.arm_contact[side]);
        b[OFF_ARM_PUSH + side] = m.arm_push_direction[side];
        put(
            &mut b,
            OFF_ARM_TIME + 4 * side,
            &m.arm_last_contact_ms[side].to_le_bytes(),
        );
    }
    put(
        &mut b,
        OFF_WHISTLE_TIME,
        &m.time_since_whistle_ms.to_le_bytes(),
    );
    b[OFF_WHISTLE] = m.whistle.wire_value();
    put(&mut b, OFF_TEAM_BALL, &m.team_ball.x_mm.to_le_bytes());
    put(&mut b, OFF_TEAM_BALL + 4, &m.team_ball.y_mm.to_le_bytes());
    put(
        &mut b,
        OFF_TEAM_BALL_VEL,
        &m.team_ball_velocity.x_mm.to_le_bytes(),
    );
    put(
        &mut b,
        OFF_TEAM_BALL_VEL + 4,
        &m.team_ball_velocity.y_mm.to_le_bytes(),
    );
    put(&mut b, OFF_BATTERY, &m.battery.to_le_bytes());
    put(&mut b, OFF_TEMPERATURE, &m.cpu_temperature_c.to_le_bytes());
    b[OFF_GESTURE] = m.referee_gesture;
    Ok(b)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::validation::DropReason;

    pub(crate) fn hand_built() -> Vec<u8> {
        crate::samples::debug_packet()
    }

    #[test]
    fn hand_built_packet_decodes_every_field() {
        let m = decode_debug(&hand_built()).unwrap();
        assert_eq!((m.player_number, m.team_number, m.fallen), (2, 17, true));
        assert_eq!(
            m.pose,
            FieldPose {
                x_mm: -1234.5,
                y_mm: 987.25,
                theta_rad: 1.5
            }
        );
        assert_eq!(m.ball_age_s, 2.75);
        assert_eq!(m.ball, FieldPoint::new(3000.0, -1500.0));
        assert_eq!(m.role, PlayerRole::Controlled);
        assert_eq!(m.obstacles_seen, 3);
        assert_eq!(
            m.obstacles,
            vec![
                NaoObstacle {
                    kind: ObstacleKind::Opponent,
                    center: FieldPoint::new(100.0, 200.0),
                    last_seen_ms: 1000
                },
                NaoObstacle {
                    kind: ObstacleKind::Teammate,
                    center: FieldPoint::new(-300.0, 400.0),
                    last_seen_ms: 70_000
                },
                NaoObstacle {
                    kind: ObstacleKind::FallenOpponent,
                    center: FieldPoint::new(500.0, -600.0),
                    // Decoded as u32: as f32 this would be a tiny denormal-looking number.
                    last_seen_ms: 4_000_000_000
                },
            ]
        );
        assert_eq!((m.message_budget, m.secs_remaining), (1100, 75));
        assert_eq!(m.arm_contact, [true, false]);
        assert_eq!(m.arm_push_direction, [2, 3]);
        assert_eq!(m.arm_last_contact_ms, [123_456, 654_321]);
        assert_eq!(m.time_since_whistle_ms, 2500);
        assert_eq!(m.whistle, WhistleState::Detected);
        // The team ball is at 328, its velocity at 336 (the Python server was one place off).
        assert_eq!(m.team_ball, FieldPoint::new(-2000.0, 250.0));
        assert_eq!(m.team_ball_velocity, FieldPoint::new(120.0, -60.0));
        assert_eq!(m.battery, 0.8);
        assert_eq!(m.cpu_temperature_c, 55.5);
        assert_eq!(m.referee_gesture, 7);
    }

    #[test]
    fn encoder_reproduces_the_hand_built_bytes_except_ignored_ones() {
        let hand = hand_built();
        let m = decode_debug(&hand).unwrap();
        let enc = encode_debug(&m).unwrap();
        assert_eq!(decode_debug(&enc).unwrap(), m);
        let ignored = |i: usize| {
            i < 8 || (325..328).contains(&i) || (353..356).contains(&i)
                // unused obstacle slots
                || (47..64).contains(&i)
                || (76..144).contains(&i)
                || (156..224).contains(&i)
                || (236..304).contains(&i)
        };
        for i in 0..356 {
            if !ignored(i) {
                assert_eq!(enc[i], hand[i], "byte {i}");
            }
        }
    }

    #[test]
    fn more_than_twenty_obstacles_seen_decodes_twenty() {
        let mut b = hand_built();
        b[43] = 25;
        for i in 0..20 {
            b[44 + i] = 2;
            b[64 + 4 * i..68 + 4 * i].copy_from_slice(&(i as f32).to_le_bytes());
            b[144 + 4 * i..148 + 4 * i].copy_from_slice(&0f32.to_le_bytes());
        }
        let m = decode_debug(&b).unwrap();
        assert_eq!(m.obstacles_seen, 25);
        assert_eq!(m.obstacles.len(), 20);
        assert_eq!(m.obstacles[19].center.x_mm, 19.0);
        assert_eq!(encode_debug(&m).unwrap()[43], 25);
    }

    #[test]
    fn each_malformation_has_its_reason() {
        let good = hand_built();
        let reason = |b: &[u8]| decode_debug(b).unwrap_err().reason();
        assert_eq!(reason(&good[..355]), DropReason::WrongSize);
        assert_eq!(
            reason(&[good.clone(), vec![0]].concat()),
            DropReason::WrongSize
        );
        let mut b = good.clone();
        b[8] = b'X';
        assert_eq!(reason(&b), DropReason::WrongHeader);
        let mut b = good.clone();
        b[12] = 5;
        assert_eq!(reason(&b), DropReason::UnknownVersion);
        for off in [
            16, 20, 24, 28, 32, 36, 64, 144, 328, 332, 336, 340, 344, 348,
        ] {
            let mut b = good.clone();
            b[off..off + 4].copy_from_slice(&f32::NAN.to_le_bytes());
            assert_eq!(reason(&b), DropReason::NonFinite, "offset {off}");
        }
        for (off, v) in [(15, 2), (44, 8), (324, 3), (308, 2), (40, 0)] {
            let mut b = good.clone();
            b[off] = v;
            assert_eq!(reason(&b), DropReason::InvalidValue, "offset {off}");
        }
    }

    #[test]
    fn encoder_refuses_inconsistent_models() {
        let mut m = decode_debug(&hand_built()).unwrap();
        m.obstacles_seen = 2;
        assert!(matches!(
            encode_debug(&m),
            Err(DebugEncodeError::ObstacleCountMismatch { .. })
        ));
        let mut m = decode_debug(&hand_built()).unwrap();
        m.battery = f32::INFINITY;
        assert_eq!(
            encode_debug(&m),
            Err(DebugEncodeError::NonFinite("battery"))
        );
    }
}
