//! Field geometry and a small 2D vector type.
//!
//! Global frame: millimetres, origin at the centre spot, x towards the goal our team attacks
//! (the opponents' goal at x = +4500 mm), y to the left, angles in radians counter-clockwise.

use std::f64::consts::PI;

use spl::FieldPoint;

/// Half the field length (mm): the field is 9000 mm long.
pub const FIELD_HALF_LENGTH_MM: f64 = 4500.0;
/// Half the field width (mm): the field is 6000 mm wide.
pub const FIELD_HALF_WIDTH_MM: f64 = 3000.0;
/// Half the goal mouth (mm), inner side of the posts.
pub const GOAL_HALF_WIDTH_MM: f64 = 750.0;
/// Ball centre to robot centre at contact (mm): feet plus ball radius.
pub const BALL_CONTACT_MM: f64 = 160.0;
/// Ball centre to robot centre from which a kick reaches the ball (mm).
pub const KICK_REACH_MM: f64 = 210.0;
/// The four goalposts (centres).
pub const GOALPOSTS: [V2; 4] = [
    V2::new(FIELD_HALF_LENGTH_MM, 800.0),
    V2::new(FIELD_HALF_LENGTH_MM, -800.0),
    V2::new(-FIELD_HALF_LENGTH_MM, 800.0),
    V2::new(-FIELD_HALF_LENGTH_MM, -800.0),
];

/// Centre of the goal we attack.
pub fn opponent_goal() -> V2 {
    V2::new(FIELD_HALF_LENGTH_MM, 0.0)
}

/// Centre of the goal we defend.
pub fn own_goal() -> V2 {
    V2::new(-FIELD_HALF_LENGTH_MM, 0.0)
}

/// `a - b` wrapped to (-pi, pi].
pub fn angle_diff(a: f64, b: f64) -> f64 {
    let mut d = (a - b) % (2.0 * PI);
    if d > PI {
        d -= 2.0 * PI;
    } else if d <= -PI {
        d += 2.0 * PI;
    }
    d
}

/// A 2D vector (mm or mm/s).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct V2 {
    /// x
    pub x: f64,
    /// y
    pub y: f64,
}

impl V2 {
    /// Zero.
    pub const ZERO: V2 = V2 { x: 0.0, y: 0.0 };

    /// A vector.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// Length.
    pub fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }

    /// Unit vector (zero stays zero).
    pub fn normalized(self) -> V2 {
        let n = self.norm();
        if n > 1e-9 { self * (1.0 / n) } else { V2::ZERO }
    }

    /// Direction (rad).
    pub fn angle(self) -> f64 {
        self.y.atan2(self.x)
    }

    /// Dot product.
    pub fn dot(self, o: V2) -> f64 {
        self.x * o.x + self.y * o.y
    }

    /// z of the cross product.
    pub fn cross(self, o: V2) -> f64 {
        self.x * o.y - self.y * o.x
    }

    /// As a wire point (f32 mm).
    pub fn to_point(self) -> FieldPoint {
        FieldPoint::new(self.x as f32, self.y as f32)
    }
}

impl std::ops::Add for V2 {
    type Output = V2;
    fn add(self, o: V2) -> V2 {
        V2::new(self.x + o.x, self.y + o.y)
    }
}

impl std::ops::Sub for V2 {
    type Output = V2;
    fn sub(self, o: V2) -> V2 {
        V2::new(self.x - o.x, self.y - o.y)
    }
}

impl std::ops::Mul<f64> for V2 {
    type Output = V2;
    fn mul(self, k: f64) -> V2 {
        V2::new(self.x * k, self.y * k)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_diff_wraps() {
        assert!((angle_diff(3.0, -3.0) - (6.0 - 2.0 * PI)).abs() < 1e-12);
        assert!((angle_diff(-3.0, 3.0) + (6.0 - 2.0 * PI)).abs() < 1e-12);
        assert_eq!(angle_diff(1.0, 0.5), 0.5);
    }
}
