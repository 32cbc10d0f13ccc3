//! Tests of the simulated sensor: the renderer's geometry and sensor model, and the `sim` driver.

use super::*;

fn camera() -> SimCamera {
    SimCamera::vga(look_at(
        Point3::new(0.0, 0.0, 1.2),
        Point3::new(1.0, 0.0, 0.9),
        Vector3::z(),
    ))
}

fn ball_scene(centre: Point3<f64>) -> Scene {
    Scene {
        ball: Some(Sphere::new(centre, 0.1, [220, 60, 20])),
        ..Scene::default()
    }
}

#[test]
fn look_at_points_optical_axis_at_target() {
    let pose = look_at(
        Point3::new(0.0, 0.0, 1.0),
        Point3::new(2.0, 0.0, 1.0),
        Vector3::z(),
    );
    let z = pose.rotation * Vector3::z();
    let x = pose.rotation * Vector3::x();
    let y = pose.rotation * Vector3::y();
    assert!((z - Vector3::x()).norm() < 1e-12, "z forward {z}");
    assert!((x + Vector3::y()).norm() < 1e-12, "x right (world -y) {x}");
    assert!((y + Vector3::z()).norm() < 1e-12, "y down {y}");
}

#[test]
fn ideal_ball_depth_matches_geometry() {
    let cam = camera();
    let centre = Point3::new(1.0, 0.05, 0.95);
    let mut r = SimRenderer::new(cam, SensorModel::ideal(), 1);
    let f = r.render(&ball_scene(centre), 0.0);
    assert_eq!(f.validate(), Ok(()));
    let [u, v] = cam.project_world(&centre).unwrap();
    let i = (v.round() as usize) * 640 + u.round() as usize;
    let c_c = cam.world_from_camera.inverse_transform_point(&centre);
    // The pixel through the centre sees the front of the sphere, ~radius closer than the centre.
    let expected_mm = (c_c.z - 0.05) * 1000.0;
    assert!(
        (f64::from(f.depth_mm[i]) - expected_mm).abs() < 3.0,
        "depth {} vs {expected_mm}",
        f.depth_mm[i]
    );
    // The colour there is the ball's hue: red dominant.
    let px = &f.rgb[i * 3..i * 3 + 3];
    assert!(px[0] > 2 * px[1] && px[0] > 3 * px[2], "{px:?}");
    // Pixels far from the ball keep the background.
    let far = 10 * 640 + 10;
    assert_ne!(&f.rgb[far * 3..far * 3 + 3], px);
}

#[test]
fn range_limits_give_holes() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::ideal(), 1);
    // Ball 0.2 m in front of the camera: closer than min range.
    let near = cam.world_from_camera * Point3::new(0.0, 0.0, 0.25);
    let f = r.render(&ball_scene(near), 0.0);
    assert_eq!(f.depth_mm[240 * 640 + 320], 0);
    // Sky above the wall (if any) and the wall beyond 4 m are holes too.
    let far_scene = Scene {
        wall_x_m: 6.0,
        table: None,
        ..Scene::default()
    };
    let f = r.render(&far_scene, 0.0);
    assert!(f.depth_mm.iter().filter(|&&d| d == 0).count() > 1000);
    assert!(
        f.depth_mm
            .iter()
            .all(|&d| d == 0 || (400..=4000).contains(&d))
    );
}

#[test]
fn depth_noise_grows_with_distance_squared() {
    // Camera facing the wall head on; measure per-pixel std over frames at 1 m and 2 m.
    let std_at = |dist: f64| {
        let cam = SimCamera::vga(look_at(
            Point3::new(3.0 - dist, 0.0, 1.5),
            Point3::new(3.0, 0.0, 1.5),
            Vector3::z(),
        ));
        let mut r = SimRenderer::new(cam, SensorModel::default(), 7);
        let scene = Scene {
            table: None,
            ..Scene::default()
        };
        let ideal = dist * 1000.0;
        let f = r.render(&scene, 0.0);
        let (mut s2, mut n) = (0.0, 0.0);
        for v in 200..280 {
            for u in 280..360 {
                let d = f64::from(f.depth_mm[v * 640 + u]);
                s2 += (d - ideal) * (d - ideal);
                n += 1.0;
            }
        }
        (s2 / n).sqrt()
    };
    let (s1, s2) = (std_at(1.0), std_at(2.0));
    // Noise (2.5 mm at 1 m) plus disparity quantisation (2.9 mm steps at 1 m, uniform
    // error of sd step / sqrt(12) = 0.8 mm), both growing with z^2.
    assert!((s1 - 2.6).abs() < 0.6, "sigma at 1 m {s1} mm");
    assert!((s2 / s1 - 4.0).abs() < 0.7, "sigma ratio {}", s2 / s1);
}

#[test]
fn depth_is_quantised_in_disparity() {
    let cam = SimCamera::vga(look_at(
        Point3::new(1.0, 0.0, 1.5),
        Point3::new(3.0, 0.0, 1.5),
        Vector3::z(),
    ));
    let sensor = SensorModel {
        depth_noise_coeff_per_m: 0.0,
        ..SensorModel::default()
    };
    let scene = Scene {
        table: None,
        ..Scene::default()
    };
    let f = SimRenderer::new(cam, sensor, 1).render(&scene, 0.0);
    let mut values: Vec<u16> = f.depth_mm.iter().copied().filter(|&d| d > 0).collect();
    values.sort_unstable();
    values.dedup();
    // The wall is seen at optical depth exactly 2 m: one quantised value, within half a
    // step (11.5 mm / 2) of 2000 mm.
    assert_eq!(values.len(), 1, "{values:?}");
    assert!((i32::from(values[0]) - 2000).abs() <= 6, "{values:?}");
}

#[test]
fn edges_get_holes_and_render_is_deterministic() {
    let cam = camera();
    let scene = ball_scene(Point3::new(1.0, 0.0, 0.95));
    let mut a = SimRenderer::new(cam, SensorModel::default(), 42);
    let mut b = SimRenderer::new(cam, SensorModel::default(), 42);
    let fa = a.render(&scene, 0.5);
    let fb = b.render(&scene, 0.5);
    assert_eq!(fa, fb);
    let [u, v] = cam.project_world(&Point3::new(1.0, 0.0, 0.95)).unwrap();
    // Walk right from the ball centre across its rim; some rim pixels must be holes.
    let row = v.round() as usize;
    let holes = (u as usize..640)
        .take(60)
        .filter(|&x| fa.depth_mm[row * 640 + x] == 0)
        .count();
    assert!(holes >= 1, "no hole at the ball's edge");
    let mut c = SimRenderer::new(cam, SensorModel::default(), 43);
    assert_ne!(c.render(&scene, 0.5).depth_mm, fa.depth_mm);
}

#[test]
fn hand_and_motion_blur_render() {
    let cam = camera();
    let mut scene = ball_scene(Point3::new(1.0, 0.0, 0.95));
    scene.hand = Some(HandArm {
        elbow_w: Point3::new(1.1, -0.35, 0.85),
        hand_w: Point3::new(1.02, -0.08, 0.93),
        forearm_radius_m: 0.035,
        hand_radius_m: 0.05,
        skin: [225, 175, 145],
    });
    let mut r = SimRenderer::new(cam, SensorModel::ideal(), 1);
    let f = r.render(&scene, 0.0);
    let [u, v] = cam.project_world(&Point3::new(1.1, -0.35, 0.85)).unwrap();
    let i = v.round() as usize * 640 + u.round() as usize;
    let px = &f.rgb[i * 3..i * 3 + 3];
    assert!(
        px[0] > px[1] && px[1] > px[2],
        "skin-ish at the elbow {px:?}"
    );
    // Motion blur widens the ball's smear along the motion.
    let mut blurred = scene.clone();
    blurred.hand = None;
    if let Some(b) = blurred.ball.as_mut() {
        b.velocity_w_mps = Vector3::new(0.0, -3.0, 0.0);
    }
    let mut sensor = SensorModel::ideal();
    sensor.motion_blur_samples = 5;
    sensor.exposure_s = 0.03;
    let mut rb = SimRenderer::new(cam, sensor, 1);
    let mut rs = SimRenderer::new(cam, SensorModel::ideal(), 1);
    let fb = rb.render(&blurred, 0.0);
    if let Some(b) = blurred.ball.as_mut() {
        b.velocity_w_mps = Vector3::zeros();
    }
    let fs = rs.render(&blurred, 0.0);
    let mut empty = blurred.clone();
    empty.ball = None;
    let fe = SimRenderer::new(cam, SensorModel::ideal(), 1).render(&empty, 0.0);
    let touched = |f: &Frame| {
        f.rgb
            .chunks_exact(3)
            .zip(fe.rgb.chunks_exact(3))
            .filter(|(a, b)| a != b)
            .count()
    };
    assert!(
        touched(&fb) > touched(&fs) + 200,
        "{} vs {}",
        touched(&fb),
        touched(&fs)
    );
}

mod driver {
    use super::*;
    use crate::RgbdDriver;

    #[test]
    fn sim_driver_renders_the_current_scene_at_the_time_asked() {
        let cam = SimCamera::vga(look_at(
            Point3::new(0.0, 0.0, 1.3),
            Point3::new(1.0, 0.0, 0.9),
            Vector3::z(),
        ));
        let mut d = SimDriver {
            renderer: SimRenderer::new(cam, SensorModel::ideal(), 3),
            scene: Scene::default(),
        };
        let empty = d.next_frame(1.5).unwrap().unwrap();
        assert_eq!(empty.timestamp_s, 1.5);
        d.scene.ball = Some(Sphere::new(Point3::new(0.9, 0.0, 0.9), 0.1, [20, 30, 220]));
        let with_ball = d.next_frame(1.6).unwrap().unwrap();
        assert_ne!(empty.rgb, with_ball.rgb);
        let changed = empty
            .depth_mm
            .iter()
            .zip(&with_ball.depth_mm)
            .filter(|(a, b)| a != b)
            .count();
        // A 10 cm ball ~0.95 m away covers about pi * 27^2 = 2300 pixels.
        assert!((1800..2900).contains(&changed), "{changed}");
    }
}
