//! X-series units: position ticks (4096 per revolution, tick 2048 = 0 rad) and Profile Velocity
//! (0.229 rev/min per unit).

use std::f64::consts::TAU;

/// Ticks per revolution.
pub const TICKS_PER_REV: f64 = 4096.0;
/// The tick at 0 rad.
pub const CENTER_TICK: i32 = 2048;
/// One Profile Velocity unit in rev/min.
pub const PROFILE_VELOCITY_RPM: f64 = 0.229;
/// One Profile Acceleration unit in rev/min².
pub const PROFILE_ACCELERATION_RPM2: f64 = 214.577;

/// Servo angle (rad) to the nearest tick (saturating at the i32 range for absurd inputs).
pub fn rad_to_ticks(rad: f64) -> i32 {
    let t = (rad * TICKS_PER_REV / TAU).round() + f64::from(CENTER_TICK);
    t.clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

/// Tick to servo angle (rad).
pub fn ticks_to_rad(ticks: i32) -> f64 {
    f64::from(ticks - CENTER_TICK) * TAU / TICKS_PER_REV
}

/// The Profile Velocity value for a speed (rad/s): the largest not faster than it, at least 1
/// (0 would mean "no limit"); so below 0.024 rad/s the servo moves at 0.024 rad/s.
pub fn profile_velocity(speed_rad_s: f64) -> u32 {
    let rpm = speed_rad_s.abs() * 60.0 / TAU;
    let units = (rpm / PROFILE_VELOCITY_RPM).floor();
    units.clamp(1.0, 32767.0) as u32
}

/// The Profile Acceleration value for an acceleration (rad/s²): the largest not above it, at
/// least 1 (0 would mean "no limit"); so below 0.37 rad/s² the servo accelerates at 0.37 rad/s².
pub fn profile_acceleration(acc_rad_s2: f64) -> u32 {
    let rpm2 = acc_rad_s2.abs() * 3600.0 / TAU;
    let units = (rpm2 / PROFILE_ACCELERATION_RPM2).floor();
    units.clamp(1.0, 32767.0) as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn ticks_conversion() {
        assert_eq!(rad_to_ticks(0.0), 2048);
        assert_eq!(rad_to_ticks(PI / 2.0), 3072);
        assert_eq!(rad_to_ticks(-PI), 0);
        assert_eq!(ticks_to_rad(1024), -PI / 2.0);
        for t in 0..4096 {
            assert_eq!(rad_to_ticks(ticks_to_rad(t)), t);
        }
        // Resolution: half a tick at most.
        let r = 0.123_456;
        assert!((ticks_to_rad(rad_to_ticks(r)) - r).abs() <= TAU / 4096.0 / 2.0);
    }

    #[test]
    fn profile_velocity_never_faster_than_asked() {
        for speed in [0.05, 0.5, 1.0, 3.0, 6.0] {
            let u = profile_velocity(speed);
            let back = f64::from(u) * PROFILE_VELOCITY_RPM * TAU / 60.0;
            assert!(back <= speed && back > speed - 0.024, "{speed} -> {u}");
        }
        assert_eq!(profile_velocity(0.001), 1);
        for acc in [1.0, 20.0, 100.0] {
            let u = profile_acceleration(acc);
            let back = f64::from(u) * PROFILE_ACCELERATION_RPM2 * TAU / 3600.0;
            assert!(back <= acc && back > acc - 0.375, "{acc} -> {u}");
        }
    }
}
