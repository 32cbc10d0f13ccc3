//! The detector's settings.

/// The detector's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Frame length (ns).
    pub frame_ns: i64,
    /// Reference frames quieter than this are no voice (dBFS).
    pub voice_min_dbfs: f64,
    /// The echo path's delays looked at (ms).
    pub min_delay_ms: i64,
    pub max_delay_ms: i64,
    /// The robot's speech the echo path is measured over (s), and how often (s of it).
    pub path_window_s: f64,
    pub path_every_s: f64,
    /// The correlation of the levels under which a measure is not taken.
    pub min_correlation: f64,
    /// How fast the room's echo of a frame may die away (dB/s), fastest first.
    pub decays_db_per_s: [f64; 4],
    /// How far over the predicted echo the microphone may stand, in 99 % of the robot's frames,
    /// for a decay to fit (dB).
    pub fit_db: f64,
    /// Frames either side of the delay a frame's echo may fall on (at full level; the room's
    /// decay counts from there).
    pub jitter_frames: i64,
    /// The least and the most the microphone must stand over the echo it may hold for a frame
    /// to be the player's (dB).
    pub margin_db: (f64, f64),
    /// ... and over the microphone's floor (dB).
    pub over_floor_db: f64,
    /// Frames like the player's among the last `onset_window` that make the player speak.
    pub onset_frames: usize,
    pub onset_window: usize,
    /// How long after the player's last frame the canceller's output passes whole (s).
    pub hold_s: f64,
    /// ... and how long before the first (s): her first sounds, heard before they were known
    /// to be hers. The caller holds the canceller's output back this long.
    pub lookback_s: f64,
    /// How long after the reference's last voiced frame its echo may still be in the room (s),
    /// beyond the echo path's delay.
    pub tail_s: f64,
    /// How fast the floors rise (dB/s; they fall at once).
    pub floor_rise_db_per_s: f64,
    /// Whether the player's frames over the robot are the microphone as it is rather than the
    /// canceller's output (see [`DoubleTalk::process`]).
    pub pass_microphone: bool,
    /// How much the canceller takes out of the robot is judged over this much of its speech
    /// (s)...
    pub residual_window_s: f64,
    /// ... and its output tells the player only when that is at least this (dB, the median
    /// over that window: an adapted canceller)...
    pub min_erle_db: f64,
    /// ... when it stands at most this far under the microphone (dB): once its suppressor lets
    /// her through, the canceller passes the player nearly whole (4-8 dB under a microphone
    /// that also holds the robot's echo), while its leaks stand 10-15 dB under the microphone.
    pub player_share_db: f64,
    /// Frames of the canceller's output like the player's among the last `onset_window` that
    /// make the player speak (its leaks come in bursts of a frame or two).
    pub canceller_onset_frames: usize,
    /// The player heard on the microphone alone (over the robot's echo) is taken only once the
    /// canceller's output confirms her: one of its frames, from `confirm_before_frames` before
    /// her onset to `confirm_s` after, stands this far over what the canceller leaves of the
    /// robot lately (dB over the median of its residue; while that is not known, she is taken
    /// at once), and [`Config::over_floor_db`] over the room as the canceller passes it.
    /// `None`: she is taken at once.
    pub confirm_db: Option<f64>,
    pub confirm_before_frames: i64,
    pub confirm_s: f64,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            frame_ns: 10_000_000,
            voice_min_dbfs: -70.0,
            min_delay_ms: -50,
            max_delay_ms: 500,
            path_window_s: 3.0,
            path_every_s: 1.0,
            min_correlation: 0.6,
            decays_db_per_s: [400.0, 200.0, 120.0, 60.0],
            fit_db: 3.0,
            jitter_frames: 4,
            margin_db: (4.0, 10.0),
            over_floor_db: 10.0,
            onset_frames: 2,
            onset_window: 4,
            hold_s: 0.3,
            lookback_s: 0.08,
            tail_s: 0.3,
            floor_rise_db_per_s: 3.0,
            pass_microphone: true,
            residual_window_s: 3.0,
            min_erle_db: 20.0,
            player_share_db: 8.0,
            canceller_onset_frames: 3,
            confirm_db: Some(10.0),
            confirm_before_frames: 8,
            confirm_s: 0.1,
        }
    }
}
