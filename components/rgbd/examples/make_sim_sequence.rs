#![expect(
    clippy::disallowed_methods,
    reason = "an offline tool: reports how long rendering and writing took on the wall clock"
)]
//! Renders a short sim sequence (a red 10 cm ball rolling across the table, 30 Hz, 640x480) and
//! writes it in the TUM RGB-D layout, plus `ball.txt`: `timestamp x y z` of the ball centre in
//! the camera optical frame (m). This made `tests/data/sim_ball_seq/`:
//!
//! ```text
//! cargo run -p rgbd --release --example make_sim_sequence -- components/rgbd/tests/data/sim_ball_seq 10
//! ```

use std::io::Write;

use camera::playback::TumWriter;
use camera::sim::{Scene, SensorModel, SimCamera, SimRenderer, Sphere, look_at};
use nalgebra::{Point3, Vector3};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = args
        .next()
        .unwrap_or_else(|| "components/rgbd/tests/data/sim_ball_seq".into());
    let frames: usize = args.next().map_or(Ok(10), |s| s.parse())?;
    let cam = SimCamera::vga(look_at(
        Point3::new(0.0, 0.0, 1.3),
        Point3::new(1.0, 0.0, 0.9),
        Vector3::z(),
    ));
    let sensor = SensorModel {
        // No colour noise keeps the PNGs small (depth noise stays: the tracker must cope).
        colour_noise_std: 0.0,
        ..SensorModel::default()
    };
    let mut renderer = SimRenderer::new(cam, sensor, 2024);
    let mut writer = TumWriter::create(&dir)?;
    writer.set_compression(png::Compression::High);
    let mut truth = std::fs::File::create(std::path::Path::new(&dir).join("ball.txt"))?;
    writeln!(
        truth,
        "# ball centre in the camera optical frame\n# timestamp x_m y_m z_m"
    )?;
    let t0 = 1_700_000_000.0;
    let mut scene = Scene::default();
    let start = std::time::Instant::now();
    for i in 0..frames {
        let t = i as f64 / 30.0;
        // 0.5 m/s towards the robot's right, on the table top (radius 5 cm above 0.75 m).
        let centre = Point3::new(0.95, 0.15 - 0.5 * t, 0.80);
        let mut ball = Sphere::new(centre, 0.1, [220, 40, 30]);
        ball.velocity_w_mps = Vector3::new(0.0, -0.5, 0.0);
        scene.ball = Some(ball);
        let frame = renderer.render(&scene, t0 + t);
        writer.write(&frame)?;
        let c = cam.world_from_camera.inverse_transform_point(&centre);
        writeln!(
            truth,
            "{:.6} {:.6} {:.6} {:.6}",
            frame.timestamp_s, c.x, c.y, c.z
        )?;
    }
    writer.finish()?;
    eprintln!("wrote {frames} frames to {dir} in {:?}", start.elapsed());
    Ok(())
}
