//! The simulated ball's motion: straight moves at a constant speed, on the caller's clock.
//!
//! World frame, metres, seconds. The person moves the ball from where it is to a target at a
//! given speed (0 = at once); a new move starts from wherever the ball is at that moment.

/// Where the ball is and how it moves, at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallState {
    pub position_m: [f64; 3],
    pub velocity_mps: [f64; 3],
    pub present: bool,
    pub held: bool,
}

/// The ball and its current move.
#[derive(Debug, Clone)]
pub struct Ball {
    from_m: [f64; 3],
    to_m: [f64; 3],
    start_s: f64,
    duration_s: f64,
    present: bool,
    held: bool,
}

impl Ball {
    /// A ball resting at `position_m`.
    pub fn new(position_m: [f64; 3], present: bool, held: bool) -> Self {
        Self {
            from_m: position_m,
            to_m: position_m,
            start_s: 0.0,
            duration_s: 0.0,
            present,
            held,
        }
    }

    /// Start moving to `to_m` at `speed_mps` (0 = be there now), from where the ball is at `now_s`.
    pub fn move_to(
        &mut self,
        now_s: f64,
        to_m: [f64; 3],
        speed_mps: f64,
        present: bool,
        held: bool,
    ) {
        let from = self.at(now_s).position_m;
        let dist = dist(&from, &to_m);
        self.from_m = from;
        self.to_m = to_m;
        self.start_s = now_s;
        self.duration_s = if speed_mps > 0.0 {
            dist / speed_mps
        } else {
            0.0
        };
        self.present = present;
        self.held = held;
    }

    /// When the current move ends (s).
    pub fn arrival_s(&self) -> f64 {
        self.start_s + self.duration_s
    }

    /// The ball at `now_s`.
    pub fn at(&self, now_s: f64) -> BallState {
        let t = if self.duration_s > 0.0 {
            ((now_s - self.start_s) / self.duration_s).clamp(0.0, 1.0)
        } else {
            1.0
        };
        let moving = t > 0.0 && t < 1.0;
        let mut p = [0.0; 3];
        let mut v = [0.0; 3];
        for k in 0..3 {
            p[k] = self.from_m[k] + t * (self.to_m[k] - self.from_m[k]);
            if moving {
                v[k] = (self.to_m[k] - self.from_m[k]) / self.duration_s;
            }
        }
        BallState {
            position_m: p,
            velocity_mps: v,
            present: self.present,
            held: self.held,
        }
    }
}

/// Euclidean distance (m).
pub fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_at_the_given_speed_and_stops_at_the_target() {
        let mut b = Ball::new([0.5, 0.0, 0.8], true, false);
        b.move_to(10.0, [0.5, 0.3, 0.8], 0.1, true, true);
        assert!((b.arrival_s() - 13.0).abs() < 1e-9);
        let mid = b.at(11.5);
        assert!((mid.position_m[1] - 0.15).abs() < 1e-9);
        assert!((mid.velocity_mps[1] - 0.1).abs() < 1e-9);
        assert!(mid.held);
        let end = b.at(20.0);
        assert_eq!(end.position_m, [0.5, 0.3, 0.8]);
        assert_eq!(end.velocity_mps, [0.0; 3]);
        // Before the move started it was still at the start.
        assert_eq!(b.at(9.0).position_m, [0.5, 0.0, 0.8]);
    }

    #[test]
    fn a_new_move_starts_where_the_ball_is() {
        let mut b = Ball::new([0.0; 3], true, true);
        b.move_to(0.0, [1.0, 0.0, 0.0], 1.0, true, true);
        b.move_to(0.5, [0.5, 1.0, 0.0], 0.0, false, false);
        let s = b.at(0.5);
        assert_eq!(s.position_m, [0.5, 1.0, 0.0]);
        assert!(!s.present && !s.held);
    }
}
