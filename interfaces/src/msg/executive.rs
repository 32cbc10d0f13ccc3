//! The Executive's messages: what its state machines do, for the game log, the command panel, the
//! viewer and the tests.
//!
//! State names are paths from the machine's root, joined by `/` (`game/playing/reach/moving`).
//! A **configuration** is the set of active leaf states plus their ancestors (with parallel
//! regions, several leaves are active at once).

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// One step of a machine (topic `executive/transitions`): the event that fired, the states left
/// (innermost first) and entered (outermost first), and the configuration after the step.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StateTransition {
    pub header: Header,
    /// The machine (`touch_the_ball`, `coach`).
    pub machine: String,
    /// The triggering event (`command:touch_ball`, `ball:lost`, `timer:courtesy`, `start`).
    pub event: String,
    /// States left, innermost first.
    pub exited: Vec<String>,
    /// States entered, outermost first.
    pub entered: Vec<String>,
    /// Active leaf states after the step, sorted.
    pub active: Vec<String>,
    /// Steps taken by this machine since it started (1 for the first).
    pub step: u64,
}

/// `executive/configuration` request: the current configuration of a machine ("" = the one
/// running).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ConfigurationRequest {
    pub header: Header,
    pub machine: String,
}

/// `executive/configuration` reply.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Configuration {
    pub header: Header,
    pub machine: String,
    /// Active leaf states, sorted.
    pub active: Vec<String>,
    /// Every active state (leaves and their ancestors), sorted.
    pub all_active: Vec<String>,
    /// Steps taken so far.
    pub step: u64,
    /// The machine drawn as a Mermaid `stateDiagram-v2`.
    pub mermaid: String,
}

/// A line of the game log (topic `executive/log`): what the robot did and why, for people.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GameLog {
    pub header: Header,
    pub machine: String,
    /// `state`, `said`, `heard`, `ball`, `reach`, `anomaly`, `done`.
    pub kind: String,
    pub text: String,
    /// A distance the line is about (m), `-1` when none (hand to ball, ball to camera).
    pub distance_m: f64,
}
