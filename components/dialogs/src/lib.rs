//! # dialogs: the confirm/reject loop of voice commands (seed 001 §V.D, Fig. 5)
//!
//! [`machine::Dialog`] decides, from the recognizer's confidence, whether a heard command goes
//! straight to the game (`game/command`), is confirmed first ("Did you say ...?" on `speech/say`,
//! answered by voice or on `game/answer`), or is ignored. The component ([`component`]) wires it
//! to the bus.

pub mod component;
pub mod machine;

pub use machine::{Action, Dialog, DialogConfig};
