//! The GameController -> robots game state packet: 118 bytes, header `RGme`, version 18, UDP
//! port [`GAMECONTROLLER_PORT`], 2 Hz.
//!
//! | offset | type | field |
//! |---|---|---|
//! | 0 | 4 chars | `RGme` |
//! | 4 | u8 | version 18 |
//! | 5 | u8 | packet number |
//! | 6 | u8 | players per team |
//! | 7 | u8 | competition phase |
//! | 8 | u8 | competition type |
//! | 9 | u8 | game phase (0..=3) |
//! | 10 | u8 | state (0..=5) |
//! | 11 | u8 | set play (0..=5) |
//! | 12 | u8 | first half (0/1) |
//! | 13 | u8 | kicking team (255 none) |
//! | 14 | i16 | seconds remaining |
//! | 16 | i16 | secondary time |
//! | 18 | 50 bytes | team info 0 |
//! | 68 | 50 bytes | team info 1 |
//!
//! Team info: +0 team number, +1 field player colour, +2 goalkeeper colour, +3 goalkeeper,
//! +4 score, +5 penalty shot counter, +6 u16 single shots, +8 u16 message budget, +10 twenty
//! players x {u8 penalty, u8 seconds till unpenalised}.
//!
//! The decoder is strict on the fields the coach game's logic depends on (state, set play, game
//! phase, first half) and keeps the others as sent (unknown penalty codes become
//! [`Penalty::Other`]), so a newer GameController's extra codes do not blind the robot.

use crate::types::{
    GameControllerState, GamePhase, GameState, Penalty, PlayerInfo, SetPlay, TeamInfo,
};
use crate::validation::{PacketError, PacketKind};
use crate::wire::{bytes4_at, i16_at, put, u8_at, u16_at};

/// Length of a game state packet (bytes).
pub const GAMECONTROLLER_PACKET_LEN: usize = 118;
/// The robots' UDP port for game state packets.
pub const GAMECONTROLLER_PORT: u16 = 3838;
/// Header.
pub const GAMECONTROLLER_HEADER: [u8; 4] = *b"RGme";
/// Supported version.
pub const GAMECONTROLLER_VERSION: u8 = 18;
/// Player slots per team info.
pub const PLAYER_SLOTS: usize = 20;
/// Kicking-team value meaning "none".
pub const NO_KICKING_TEAM: u8 = 255;

const TEAM_INFO_LEN: usize = 50;
const OFF_TEAMS: [usize; 2] = [18, 68];

/// Why a state cannot be encoded (only the simulated GameController encodes).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GameControllerEncodeError {
    /// A team info with more than 20 players.
    #[error("team info with {0} players, at most 20 fit")]
    TooManyPlayers(usize),
    /// The kicking team is `Some(255)`, which means "none" on the wire.
    #[error("kicking team 255 is reserved for none")]
    ReservedKickingTeam,
}

fn invalid(field: &'static str, value: u8) -> PacketError {
    PacketError::InvalidValue {
        kind: PacketKind::GameController,
        field,
        value: u32::from(value),
    }
}

fn decode_team(b: &[u8], off: usize) -> TeamInfo {
    let players = (0..PLAYER_SLOTS)
        .map(|i| PlayerInfo {
            penalty: Penalty::from_wire(u8_at(b, off + 10 + 2 * i)),
            secs_till_unpenalised: u8_at(b, off + 11 + 2 * i),
        })
        .collect();
    TeamInfo {
        team_number: u8_at(b, off),
        field_player_colour: u8_at(b, off + 1),
        goalkeeper_colour: u8_at(b, off + 2),
        goalkeeper: u8_at(b, off + 3),
        score: u8_at(b, off + 4),
        penalty_shot: u8_at(b, off + 5),
        single_shots: u16_at(b, off + 6),
        message_budget: u16_at(b, off + 8),
        players,
    }
}

/// Decode a game state packet.
pub fn decode_gamecontroller(b: &[u8]) -> Result<GameControllerState, PacketError> {
    const K: PacketKind = PacketKind::GameController;
    if b.len() != GAMECONTROLLER_PACKET_LEN {
        return Err(PacketError::WrongSize {
            kind: K,
            expected: GAMECONTROLLER_PACKET_LEN,
            got: b.len(),
        });
    }
    let header = bytes4_at(b, 0);
    if header != GAMECONTROLLER_HEADER {
        return Err(PacketError::WrongHeader {
            kind: K,
            expected: GAMECONTROLLER_HEADER,
            found: header,
        });
    }
    let version = u8_at(b, 4);
    if version != GAMECONTROLLER_VERSION {
        return Err(PacketError::UnknownVersion {
            kind: K,
            expected: GAMECONTROLLER_VERSION,
            found: version,
        });
    }
    let phase_raw = u8_at(b, 9);
    let state_raw = u8_at(b, 10);
    let set_play_raw = u8_at(b, 11);
    let first_half = match u8_at(b, 12) {
        0 => false,
        1 => true,
        v => return Err(invalid("first_half", v)),
    };
    let kicking = u8_at(b, 13);
    Ok(GameControllerState {
        packet_number: u8_at(b, 5),
        players_per_team: u8_at(b, 6),
        competition_phase: u8_at(b, 7),
        competition_type: u8_at(b, 8),
        game_phase: GamePhase::from_wire(phase_raw)
            .ok_or_else(|| invalid("game_phase", phase_raw))?,
        state: GameState::from_wire(state_raw).ok_or_else(|| invalid("state", state_raw))?,
        set_play: SetPlay::from_wire(set_play_raw)
            .ok_or_else(|| invalid("set_play", set_play_raw))?,
        first_half,
        kicking_team: (kicking != NO_KICKING_TEAM).then_some(kicking),
        secs_remaining: i16_at(b, 14),
        secondary_time: i16_at(b, 16),
        teams: [decode_team(b, OFF_TEAMS[0]), decode_team(b, OFF_TEAMS[1])],
    })
}

/// Encode a game state packet (missing player slots are zero).
pub fn encode_gamecontroller(
    s: &GameControllerState,
) -> Result<[u8; GAMECONTROLLER_PACKET_LEN], GameControllerEncodeError> {
    if s.kicking_team == Some(NO_KICKING_TEAM) {
        return Err(GameControllerEncodeError::ReservedKickingTeam);
    }
    let mut b = [0u8; GAMECONTROLLER_PACKET_LEN];
    put(&mut b, 0, &GAMECONTROLLER_HEADER);
    b[4] = GAMECONTROLLER_VERSION;
    b[5] = s.packet_number;
    b[6] = s.players_per_team;
    b[7] = s.competition_phase;
    b[8] = s.competition_type;
    b[9] = s.game_phase.wire_value();
    b[10] = s.state.wire_value();
    b[11] = s.set_play.wire_value();
    b[12] = u8::from(s.first_half);
    b[13] = s.kicking_team.unwrap_or(NO_KICKING_TEAM);
    put(&mut b, 14, &s.secs_remaining.to_le_bytes());
    put(&mut b, 16, &s.secondary_time.to_le_bytes());
    for (t, off) in s.teams.iter().zip(OFF_TEAMS) {
        if t.players.len() > PLAYER_SLOTS {
            return Err(GameControllerEncodeError::TooManyPlayers(t.players.len()));
        }
        let tb = [
            t.team_number,
            t.field_player_colour,
            t.goalkeeper_colour,
            t.goalkeeper,
            t.score,
            t.penalty_shot,
        ];
        put(&mut b, off, &tb);
        put(&mut b, off + 6, &t.single_shots.to_le_bytes());
        put(&mut b, off + 8, &t.message_budget.to_le_bytes());
        for (i, p) in t.players.iter().enumerate() {
            b[off + 10 + 2 * i] = p.penalty.wire_value();
            b[off + 11 + 2 * i] = p.secs_till_unpenalised;
        }
    }
    debug_assert_eq!(OFF_TEAMS[1] + TEAM_INFO_LEN, GAMECONTROLLER_PACKET_LEN);
    Ok(b)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::validation::DropReason;

    pub(crate) fn hand_built() -> Vec<u8> {
        crate::samples::gamecontroller_packet()
    }

    #[test]
    fn hand_built_packet_decodes_every_field() {
        let s = decode_gamecontroller(&hand_built()).unwrap();
        assert_eq!(
            (
                s.packet_number,
                s.players_per_team,
                s.competition_phase,
                s.competition_type
            ),
            (201, 2, 1, 1)
        );
        assert_eq!(s.game_phase, GamePhase::Overtime);
        assert_eq!(s.state, GameState::Playing);
        assert_eq!(s.set_play, SetPlay::KickIn);
        assert!(s.first_half);
        assert_eq!(s.kicking_team, Some(42));
        assert_eq!((s.secs_remaining, s.secondary_time), (-12, 25));
        let us = s.team(42).unwrap();
        assert_eq!(
            (
                us.field_player_colour,
                us.goalkeeper_colour,
                us.goalkeeper,
                us.score,
                us.penalty_shot
            ),
            (5, 6, 1, 4, 2)
        );
        assert_eq!((us.single_shots, us.message_budget), (0x0304, 1150));
        // Our player 2: code (1 + 7) % 16 = 8, local game stuck, 102 s.
        assert_eq!(
            *us.player(2).unwrap(),
            PlayerInfo {
                penalty: Penalty::LocalGameStuck,
                secs_till_unpenalised: 102
            }
        );
        for team in 0..2usize {
            let t = &s.teams[team];
            for i in 0..20usize {
                let p = t.player(i as u8 + 1).unwrap();
                assert_eq!(p.penalty.wire_value(), ((i + 7 * team) % 16) as u8);
                assert_eq!(usize::from(p.secs_till_unpenalised), 100 * team + i + 1);
            }
        }
        assert_eq!(us.player(6).unwrap().penalty, Penalty::Other(12));
        assert_eq!(us.player(7).unwrap().penalty, Penalty::Other(13));
        assert!(us.player(21).is_none() && us.player(0).is_none());
        let them = s.opponent_of(42).unwrap();
        assert_eq!(
            (them.team_number, them.score, them.message_budget),
            (7, 3, 900)
        );
        assert_eq!(them.single_shots, 0x0102);
        assert_eq!(them.player(1).unwrap().penalty, Penalty::None);
        assert_eq!(them.player(16).unwrap().penalty, Penalty::Manual);
        assert_eq!(them.player(13).unwrap().penalty, Penalty::Other(12));
        assert_eq!(them.player(15).unwrap().penalty, Penalty::Substitute);
        assert!(s.team(99).is_none());
    }

    #[test]
    fn round_trip_is_byte_exact() {
        let hand = hand_built();
        let s = decode_gamecontroller(&hand).unwrap();
        let enc = encode_gamecontroller(&s).unwrap();
        assert_eq!(enc.to_vec(), hand);
        let mut none = hand.clone();
        none[13] = 255;
        assert_eq!(decode_gamecontroller(&none).unwrap().kicking_team, None);
    }

    #[test]
    fn each_malformation_has_its_reason() {
        let good = hand_built();
        let reason = |b: &[u8]| decode_gamecontroller(b).unwrap_err().reason();
        assert_eq!(reason(&good[..117]), DropReason::WrongSize);
        assert_eq!(reason(&[]), DropReason::WrongSize);
        let mut b = good.clone();
        b[3] = b'x';
        assert_eq!(reason(&b), DropReason::WrongHeader);
        let mut b = good.clone();
        b[4] = 17;
        assert_eq!(reason(&b), DropReason::UnknownVersion);
        for (off, v) in [(9, 4), (10, 6), (11, 6), (12, 2)] {
            let mut b = good.clone();
            b[off] = v;
            assert_eq!(reason(&b), DropReason::InvalidValue, "offset {off}");
        }
    }
}
