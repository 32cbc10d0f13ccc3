//! RGB to HSV (hue degrees `[0, 360)`, saturation and value `[0, 1]`) and hue arithmetic.

/// HSV of an RGB8 pixel: `(hue_deg, saturation, value)`. Grey pixels get hue 0.
#[inline]
pub fn rgb_to_hsv(r: u8, g: u8, b: u8) -> (f32, f32, f32) {
    let (rf, gf, bf) = (f32::from(r), f32::from(g), f32::from(b));
    let max = rf.max(gf).max(bf);
    let min = rf.min(gf).min(bf);
    let delta = max - min;
    let v = max / 255.0;
    if max <= 0.0 || delta <= 0.0 {
        return (0.0, 0.0, v);
    }
    let s = delta / max;
    let h = if max == rf {
        60.0 * ((gf - bf) / delta)
    } else if max == gf {
        60.0 * ((bf - rf) / delta) + 120.0
    } else {
        60.0 * ((rf - gf) / delta) + 240.0
    };
    let h = if h < 0.0 { h + 360.0 } else { h };
    (h, s, v)
}

/// Signed hue difference `a - b` wrapped to `(-180, 180]`, degrees.
#[inline]
pub fn hue_diff_deg(a: f32, b: f32) -> f32 {
    let mut d = (a - b) % 360.0;
    if d > 180.0 {
        d -= 360.0;
    } else if d <= -180.0 {
        d += 360.0;
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primaries_and_greys() {
        assert_eq!(rgb_to_hsv(255, 0, 0), (0.0, 1.0, 1.0));
        assert_eq!(rgb_to_hsv(0, 255, 0), (120.0, 1.0, 1.0));
        assert_eq!(rgb_to_hsv(0, 0, 255), (240.0, 1.0, 1.0));
        assert_eq!(rgb_to_hsv(128, 128, 128).1, 0.0);
        let (h, s, _) = rgb_to_hsv(255, 0, 128);
        assert!((h - 329.9).abs() < 0.2 && s == 1.0);
        // Shading (scaling) keeps hue and saturation.
        let (h1, s1, _) = rgb_to_hsv(220, 40, 30);
        let (h2, s2, _) = rgb_to_hsv(110, 20, 15);
        assert!((h1 - h2).abs() < 0.5 && (s1 - s2).abs() < 0.01);
    }

    #[test]
    fn hue_wraps() {
        assert_eq!(hue_diff_deg(350.0, 10.0), -20.0);
        assert_eq!(hue_diff_deg(10.0, 350.0), 20.0);
        assert_eq!(hue_diff_deg(180.0, 0.0), 180.0);
    }
}
