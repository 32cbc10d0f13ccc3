//! A simulated RoboCup SPL field for the Nao coach game: the 2024 shared-autonomy challenge
//! (two robots per team, one operator-controlled, one attack of 90 s). Pure simulation core:
//! no sockets, no clock; a process wraps [`SplField`] later and moves its [`Datagram`]s over
//! UDP.
//!
//! # Frame and units
//!
//! Field 9000 x 6000 mm, origin at the centre spot, x towards the goal our team attacks
//! (+4500 mm), y left, angles in radians. Simulated time in seconds, advanced by
//! [`SplField::step`] in fixed ticks of 10 ms.
//!
//! # Robots
//!
//! - Player 2 of our team, the **controlled** robot (role 18): obeys the 11-byte command
//!   packets given to [`SplField::receive_command`] (decoded by the `spl` library's strict robot-side
//!   decoder), with the behaviour card's semantics, intent rather than quirks: GoToPosition walks
//!   to (x, y); Dribble pushes a ball at the feet towards a free point (stands if the ball is
//!   farther than 600 mm); GoToBallAndDribble walks to the ball and dribbles; Kick shoots at the
//!   goal; Spazza clears the ball away from our goal; Pass kicks to the teammate, or dribbles
//!   when it is down; AskForTheBall faces the ball and makes the teammate pass; Turn faces
//!   (x, y); SearchTheBall turns with the head scanning until the ball is seen; Stop stands.
//!   Kick, Spazza, Pass, GoToPosition, Turn and SearchTheBall are one-shot: done, the robot
//!   stands. Heads: LookAtTheBall tracks the remembered ball (scans when it has none),
//!   LookForward, LookLeft/LookRight (±1 rad), Scan (±1.5 rad, 4 s period).
//! - Player 1, the **autonomous** teammate (role 17): striker when nearer the ball than the
//!   controlled robot (shoots from x > 1000 mm, dribbles before; passes to the controlled
//!   robot when asked, or under the Passages strategy when it is ahead), supporter otherwise.
//! - Two opponents: a keeper on its goal line and a defender who clears the ball.
//!
//! Commands are obeyed in PLAYING only; READY walks to the ready poses; INITIAL, SET and
//! FINISHED stand still ("no motion in SET").
//!
//! # Physics, perception, rules
//!
//! Ball with constant rolling friction, pushed and deflected by robot contacts. Perception
//! through a ±30° camera on a moving head plus the feet area, Gaussian noise growing with
//! distance, last-seen times; obstacles kept 2 s. Walking robots fall now and then (seeded) and
//! get up after `getup_s`. Timeline INITIAL -> READY -> SET -> PLAYING (90 s) -> FINISHED; a
//! goal ends the attempt. A goal is 2 points (not counted if the controlled robot touched the
//! ball last), a completed pass (kicked, then touched by a teammate before an opponent, having
//! travelled at least 1 m) 1 point.
//!
//! # Output
//!
//! Every 100 ms a 356-byte debug packet per robot of ours, every 500 ms a 118-byte
//! GameController packet, both encoded by the `spl` library. Deterministic for a given seed
//! ([`rng::SimRng`], no system randomness).

pub mod field;
pub mod rng;
pub mod sim;
pub mod types;

pub use field::V2;
pub use sim::{ControlledState, SimRobot, SplField, TICK_S};
pub use types::{Datagram, RobotId, Side, SimConfig, SimEvent};

#[cfg(test)]
mod tests;

pub mod process;
