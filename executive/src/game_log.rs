//! A line of a game's log, as the games' machines write it and the Executive publishes it.

/// A line of the game log (the Executive publishes it on `executive/log` as a `GameLog`, and
/// prints it on the console).
#[derive(Debug, Clone, PartialEq)]
pub struct LogLine {
    /// `state`, `said`, `heard`, `ball`, `reach`, `sent`, `refused`, `anomaly`, `done`.
    pub kind: &'static str,
    pub text: String,
    /// The distance the line is about (m), -1 when none.
    pub distance_m: f64,
}

impl LogLine {
    /// A line about no distance (`distance_m` -1).
    pub fn new(kind: &'static str, text: String) -> LogLine {
        LogLine {
            kind,
            text,
            distance_m: -1.0,
        }
    }
}
