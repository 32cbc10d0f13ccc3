//! # spl: the RoboCup SPL's wire protocols and the coach's team world model
//!
//! Not a process: the Nao bridge and the simulated SPL field share it. The SPQR coach protocol
//! (`shared/protocols/nao-spqr.md`), the GameController game state
//! (`shared/protocols/gamecontroller.md`), input validation and the fused team world model. Pure
//! library: no sockets, no clock; time is passed in as seconds (`f64`) of the caller's clock.
//!
//! # Frames and units
//!
//! Global field frame: millimetres, origin at the centre spot, x towards the opponent goal, y
//! to the left, angles in radians counter-clockwise from +x. All wire values little-endian.
//! Robot-clock timestamps (obstacle last seen, arm contact) are `u32` milliseconds.
//!
//! # Packets
//!
//! | packet | direction | bytes | port | codec |
//! |---|---|---|---|---|
//! | command `<BBBff` | bridge -> robot | 11 | 65306 | [`command`] |
//! | debug `RGrt` v4 | robot -> bridge | 356 | 65305 | [`debug`] |
//! | game state `RGme` v18 | GameController -> all | 118 | 3838 | [`gamecontroller`] |
//!
//! # Command numbering (one numbering, the robot's)
//!
//! | byte | value | meaning |
//! |---|---|---|
//! | 0 body | 0 | [`NaoBody::Keep`]: keep the current body command |
//! | | 1..=10 | [`NaoBody`]: 1 GoToPosition, 2 Dribble, 3 GoToBallAndDribble, 4 Kick, 5 Spazza, 6 Pass, 7 AskForTheBall, 8 Turn, 9 SearchTheBall, 10 Stop |
//! | 1 head | 0 | [`NaoHead::Keep`]: keep the current head command |
//! | | 1..=5 | [`NaoHead`]: 1 LookAtTheBall, 2 LookForward, 3 LookLeft, 4 LookRight, 5 Scan |
//! | 2 strategy | 0, 1 | [`NaoStrategy`]: 0 Default, 1 Passages |
//!
//! The command is the bus message `interfaces::msg::nao::NaoCommand` (re-exported here with the
//! other Nao messages, see [`types`]), whose enums follow this numbering
//! ([`NaoBody::wire_value`] etc.). The original operator GUI's strategy numbers (1 Default,
//! 2 Passages, 3 Defence) are mapped by [`NaoStrategy::from_gui_number`] (Defence does not exist
//! on the robot and is refused); its flat command numbers (1-10 bodies, 11-15 heads) by
//! [`command::command_from_flat`]. GoToPosition and Turn carry their target in x, y; the other
//! bodies send 0, 0. A packet is always exactly 11 bytes and never carries neither body nor
//! head ([`CommandEncodeError::Empty`]).
//!
//! # Bad input
//!
//! Every decoder returns a [`PacketError`] per reason (wrong size, wrong header, unknown
//! version, non-finite float, invalid value, empty command, unknown source); a
//! [`DropMonitor`] counts them ([`DropCounters`]) and logs at most one line per reason per
//! second. No input panics (fuzzed with proptest in this crate's tests). [`Inbound`] is the
//! whole receive path of the Nao bridge, in that crate.
//!
//! # World model
//!
//! [`WorldModelFusion`] fuses the local models of the controlled robot and its teammate into a
//! [`NaoWorldModel`] (the `nao/world_model` message): a constant-velocity Kalman filter for the ball (with ball-age handling)
//! and distance-associated obstacle tracks with ages; see [`world_model`].
//!
//! The data types of the link are in [`types`]: the bus messages of `interfaces::msg::nao`,
//! which the codecs and the fusion read and write directly, and the GameController packet.

pub mod command;
pub mod debug;
pub mod gamecontroller;
pub mod samples;
pub mod types;
pub mod validation;
mod wire;
pub mod world_model;

pub use command::{
    COMMAND_PACKET_LEN, COMMAND_PORT, CommandEncodeError, decode_command, encode_command,
};
pub use debug::{DEBUG_PACKET_LEN, DEBUG_PORT, DebugEncodeError, decode_debug, encode_debug};
pub use gamecontroller::{
    GAMECONTROLLER_PACKET_LEN, GAMECONTROLLER_PORT, GameControllerEncodeError,
    decode_gamecontroller, encode_gamecontroller,
};
pub use types::*;
pub use validation::{
    DropCounters, DropMonitor, DropReason, PacketError, PacketKind, RateLimiter, SourceFilter,
};
pub use world_model::{BallFilter, FusionConfig, WorldModelFusion};

#[cfg(test)]
mod fuzz;
