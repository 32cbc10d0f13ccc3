#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: times the tracker's CPU work on the wall clock"
)]
//! Benchmark core of the ball tracker: renders a seeded 640x480 sequence with the `rgbd` sim (a
//! 10 cm red ball moving at about 1 m/s, 1 m from the camera, 30 Hz), runs the tracker on every
//! frame (`--speed-scale K` makes the ball K times faster) and prints per-frame tracker time (p50 / p99, µs) and the mean centre error (pixels, and
//! mm in 3D) in a table, then one JSON object as the very last line.
//!
//! ```text
//! cargo run -p ball_tracker --release --example bench_tracker -- [--frames 300] [--seed 1] [--speed-scale 1] [--write-tum DIR]
//! ```
//!
//! `--write-tum DIR` also writes the sequence in the TUM RGB-D layout, with `ball.txt`
//! (`timestamp x y z`, ball centre in the camera optical frame, m), for the OpenCV peer
//! `bench/opencv_camshift.py`. Only `BallTracker::process` is timed (not rendering or writing).

use std::io::Write;
use std::time::Instant;

use ball_tracker::hsv::rgb_to_hsv;
use ball_tracker::{BallTracker, Target, TrackEvent, TrackState, TrackerConfig};
use camera::playback::TumWriter;
use camera::sim::{Scene, SensorModel, SimCamera, SimRenderer, Sphere, look_at};
use nalgebra::{Point3, Vector3};

const RED: [u8; 3] = [220, 40, 30];

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// Ball centre and velocity (world, m and m/s) at time `t_s`: a Lissajous figure over the
/// table, about 1 m/s on average.
fn ball_at(t_s: f64, speed_scale: f64) -> (Point3<f64>, Vector3<f64>) {
    let (ay, az, ax) = (0.35, 0.12, 0.15);
    let (wy, wz, wx) = (3.6 * speed_scale, 5.4 * speed_scale, 1.8 * speed_scale);
    (
        Point3::new(
            1.0 + ax * (wx * t_s).sin(),
            ay * (wy * t_s).sin(),
            0.95 + az * (wz * t_s).cos(),
        ),
        Vector3::new(
            ax * wx * (wx * t_s).cos(),
            ay * wy * (wy * t_s).cos(),
            -az * wz * (wz * t_s).sin(),
        ),
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut frames = 300usize;
    let mut seed = 1u64;
    let mut speed_scale = 1.0f64;
    let mut tum_dir: Option<String> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--frames" => frames = args.next().ok_or("--frames N")?.parse()?,
            "--seed" => seed = args.next().ok_or("--seed S")?.parse()?,
            "--speed-scale" => speed_scale = args.next().ok_or("--speed-scale K")?.parse()?,
            "--write-tum" => tum_dir = Some(args.next().ok_or("--write-tum DIR")?),
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    let cam = SimCamera::vga(look_at(
        Point3::new(0.0, 0.0, 1.3),
        Point3::new(1.0, 0.0, 0.9),
        Vector3::z(),
    ));
    let mut renderer = SimRenderer::new(cam, SensorModel::default(), seed);
    let (h, s, _) = rgb_to_hsv(RED[0], RED[1], RED[2]);
    let mut tracker = BallTracker::new(TrackerConfig::default());
    tracker.set_target(Some(Target {
        hue_deg: h,
        saturation: s,
        diameter_m: 0.1,
    }))?;
    let mut writer = match &tum_dir {
        Some(d) => {
            let mut w = TumWriter::create(d)?;
            w.set_compression(png::Compression::Fast);
            let mut truth = std::fs::File::create(std::path::Path::new(d).join("ball.txt"))?;
            writeln!(
                truth,
                "# ball centre in the camera optical frame\n# timestamp x_m y_m z_m"
            )?;
            Some((w, truth))
        }
        None => None,
    };

    let mut scene = Scene::default();
    let mut track_us = Vec::with_capacity(frames);
    let mut render_ms = Vec::with_capacity(frames);
    let (mut err_px, mut err_mm) = (Vec::new(), Vec::new());
    let (mut tracked, mut lost_events) = (0usize, 0usize);
    let mut speed_sum = 0.0;
    let (mut detect_us, mut detect_ok) = (Vec::new(), 0usize);
    for i in 0..frames {
        let t = i as f64 / 30.0;
        let (p, v) = ball_at(t, speed_scale);
        speed_sum += v.norm();
        let mut ball = Sphere::new(p, 0.1, RED);
        ball.velocity_w_mps = v;
        scene.ball = Some(ball);
        let r0 = Instant::now();
        let frame = renderer.render(&scene, t);
        render_ms.push(r0.elapsed().as_secs_f64() * 1e3);
        let truth_c = cam.world_from_camera.inverse_transform_point(&p);
        if let Some((w, truth)) = writer.as_mut() {
            w.write(&frame)?;
            writeln!(
                truth,
                "{:.6} {:.6} {:.6} {:.6}",
                frame.timestamp_s, truth_c.x, truth_c.y, truth_c.z
            )?;
        }
        let t0 = Instant::now();
        let out = tracker.process(&frame, t)?;
        track_us.push(t0.elapsed().as_secs_f64() * 1e6);
        // Every 10th frame, also time a detection from scratch (a fresh target) on a copy of
        // the tracker.
        if i % 10 == 0 {
            let mut fresh = tracker.clone();
            fresh.set_target(tracker.target())?;
            let t1 = Instant::now();
            let o = fresh.process(&frame, t)?;
            detect_us.push(t1.elapsed().as_secs_f64() * 1e6);
            detect_ok += usize::from(o.events.contains(&TrackEvent::BallDetected));
        }
        lost_events += out
            .events
            .iter()
            .filter(|e| **e == TrackEvent::BallLost)
            .count();
        if out.state == TrackState::Tracking
            && let (Some(c), Some(uv)) = (out.centre_m, out.centre_px)
        {
            tracked += 1;
            if let Some([u, v]) = cam.project_world(&p) {
                err_px.push((uv[0] - u).hypot(uv[1] - v));
            }
            err_mm.push(((Vector3::new(c[0], c[1], c[2]) - truth_c.coords).norm()) * 1e3);
        }
    }
    if let Some((w, _)) = writer {
        w.finish()?;
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let mut sorted = track_us.clone();
    sorted.sort_by(f64::total_cmp);
    let mut rsorted = render_ms.clone();
    rsorted.sort_by(f64::total_cmp);
    let (p50, p99) = (percentile(&sorted, 0.5), percentile(&sorted, 0.99));
    detect_us.sort_by(f64::total_cmp);
    let dp50 = percentile(&detect_us, 0.5);
    let (rp50, rp99) = (percentile(&rsorted, 0.5), percentile(&rsorted, 0.99));
    let (epx, emm) = (mean(&err_px), mean(&err_mm));
    let mut emm_sorted = err_mm.clone();
    emm_sorted.sort_by(f64::total_cmp);
    let emm_max = emm_sorted.last().copied().unwrap_or(f64::NAN);

    println!(
        "ball_tracker bench: {frames} frames 640x480, seed {seed}, mean ball speed {:.2} m/s",
        speed_sum / frames as f64
    );
    println!("{:<32} {:>12}", "metric", "value");
    println!(
        "{:<32} {:>12}",
        "frames tracked",
        format!("{tracked}/{frames}")
    );
    println!("{:<32} {:>12}", "ball_lost events", lost_events);
    println!("{:<32} {:>12.0}", "tracker time p50 (us)", p50);
    println!("{:<32} {:>12.0}", "tracker time p99 (us)", p99);
    println!("{:<32} {:>12.0}", "tracker time mean (us)", mean(&track_us));
    println!(
        "{:<32} {:>12}",
        "detections from scratch",
        format!("{detect_ok}/{}", detect_us.len())
    );
    println!("{:<32} {:>12.0}", "detection time p50 (us)", dp50);
    println!("{:<32} {:>12.2}", "centre error mean (px)", epx);
    println!("{:<32} {:>12.2}", "centre error mean (mm, 3D)", emm);
    println!("{:<32} {:>12.2}", "centre error max (mm, 3D)", emm_max);
    println!("{:<32} {:>12.2}", "sim render p50 (ms)", rp50);
    println!("{:<32} {:>12.2}", "sim render p99 (ms)", rp99);
    println!(
        "{{\"impl\":\"ball_tracker\",\"frames\":{frames},\"tracked_frames\":{tracked},\"ball_lost_events\":{lost_events},\"p50_us\":{p50:.1},\"p99_us\":{p99:.1},\"detect_p50_us\":{dp50:.1},\"mean_err_px\":{epx:.3},\"mean_err_mm\":{emm:.3},\"max_err_mm\":{emm_max:.3},\"render_p50_ms\":{rp50:.3},\"render_p99_ms\":{rp99:.3}}}"
    );
    Ok(())
}
