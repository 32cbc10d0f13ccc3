//! The simulated person and world of Loki's touch-the-ball game (seed 001 §V): a stand-in for
//! the human player and the ball, apart from the components, at the hardware boundary only.
//!
//! The person plays a scenario (`scenarios/*.toml`, see [`scenario`]): she speaks commands
//! through espeak-ng into `audio/in`, or with `--voice pulse` into a sound server's sink that
//! the robot's microphone (`audio_io`) hears (so they go through the real recognizer and
//! dialog), holds, moves, puts down and takes away the ball (published on `sim/ball`, which the
//! `rgbd` sim renders), and waits for what the robot should do (say something, reach, look at
//! the ball), measuring it on the bus and in the DR. The process exits 0 when the scenario
//! completes and 1 with the failed step otherwise, so a manifest can end the game with it
//! (`completes_graph`).
//!
//! Frames and units: world frame of the DR (z up, Loki's base at the origin facing +x), metres,
//! seconds.

pub mod ball;
pub mod component;
pub mod person;
pub mod scenario;
