#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: times the renderer's CPU work on the wall clock"
)]
//! Times the sim renderer: 640x480 frames of the default scene with a moving ball, ideal and
//! default sensor. `cargo run -p rgbd --release --example bench_render`.

use std::time::Instant;

use camera::sim::{HandArm, Scene, SensorModel, SimCamera, SimRenderer, Sphere, look_at};
use nalgebra::{Point3, Vector3};

fn main() {
    let cam = SimCamera::vga(look_at(
        Point3::new(0.0, 0.0, 1.3),
        Point3::new(1.0, 0.0, 0.9),
        Vector3::z(),
    ));
    for (name, sensor) in [
        ("ideal", SensorModel::ideal()),
        ("default", SensorModel::default()),
        (
            "default+blur5",
            SensorModel {
                motion_blur_samples: 5,
                ..SensorModel::default()
            },
        ),
    ] {
        let mut r = SimRenderer::new(cam, sensor, 1);
        let mut scene = Scene::default();
        let mut ms = Vec::new();
        for i in 0..200 {
            let t = i as f64 / 30.0;
            let c = Point3::new(0.95, 0.3 * (2.0 * t).sin(), 0.95);
            let mut b = Sphere::new(c, 0.1, [220, 40, 30]);
            b.velocity_w_mps = Vector3::new(0.0, 0.6 * (2.0 * t).cos(), 0.0);
            scene.ball = Some(b);
            scene.hand = Some(HandArm {
                elbow_w: c + Vector3::new(0.2, 0.3, -0.15),
                hand_w: c + Vector3::new(0.03, 0.07, -0.05),
                forearm_radius_m: 0.035,
                hand_radius_m: 0.045,
                skin: [225, 175, 145],
            });
            let t0 = Instant::now();
            let f = r.render(&scene, t);
            ms.push(t0.elapsed().as_secs_f64() * 1e3);
            std::hint::black_box(f);
        }
        let first = ms[0];
        ms.sort_by(f64::total_cmp);
        println!(
            "{name:<14} first (background) {first:6.2} ms, p50 {:5.2} ms, p99 {:5.2} ms",
            ms[ms.len() / 2],
            ms[ms.len() * 99 / 100]
        );
    }
}
