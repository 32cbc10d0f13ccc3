//! The Executive: a hierarchical concurrent state machine engine and the games' machines.
//!
//! - [`engine`]: the statechart engine (no bus, no clock): states, regions, history, timers.
//! - [`touch`]: Loki's touch-the-ball game (seed 001 §V) on the engine, with its state tree.
//! - [`settings`]: the settings file.
//! - [`game_log`]: a line of a game's log.
//! - [`propose`]: structural DR changes checked against the game.
//! - [`state_file`]: a game's resume record in the state folder.
//! - [`component`]: the `executive` process on the bus.

pub mod coach;
pub mod component;
pub mod engine;
pub mod game_log;
pub mod propose;
pub mod settings;
pub mod state_file;
pub mod touch;
