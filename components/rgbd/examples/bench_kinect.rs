#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: times the real fakenect library and the conversion on the wall clock"
)]
//! The freenect driver's cost per frame through Debian's fakenect: a dump of rendered frames
//! (colour, and the depth camera's 11-bit disparities) is replayed through the real fakenect
//! library as fast as it delivers, and each pair is timed in the two halves of the driver's
//! work: libfreenect delivering and the copy out of its buffers (the library's share), and the
//! conversion into a registered frame (robocog's share: disparity to mm and registration).
//! Run by `scripts/bench kinect`, which sets `FAKENECT_PATH` to the dump this program writes
//! first (`bench_kinect write DIR`, then `bench_kinect replay`).

use std::time::{Duration, Instant};

use camera::RgbdDriver;
use camera::scenario::{CameraPose, Scenario, ScenarioSim};
use camera::sim::SensorModel;
use freenect::device::{DepthFormat, Device, Library};
use freenect::fakenect::DumpWriter;
use freenect::kinect::{DepthCalibration, unregister};
use rgbd::kinect::{Converter, fakenect_library};

const FRAMES: usize = 300;

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn write(dir: &std::path::Path) -> anyhow::Result<()> {
    let pose = CameraPose::parse("0,0,1.5,0,30,0").map_err(anyhow::Error::msg)?;
    let mut sim = ScenarioSim::new(Scenario::Moving, pose, SensorModel::default(), 1);
    let mut w = DumpWriter::create(dir)?;
    let calib = DepthCalibration::default();
    let mut raw = vec![0u16; freenect::PIXELS];
    for i in 0..FRAMES {
        let t = i as f64 / 30.0;
        let f = sim
            .next_frame(t)?
            .ok_or_else(|| anyhow::anyhow!("sim ended"))?;
        let k = f.intrinsics;
        let rgb = freenect::Pinhole {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        };
        unregister(&f.depth_mm, &calib, &rgb, &mut raw);
        // Samples a microsecond apart: fakenect replays without pacing.
        let time_s = 1000.0 + i as f64 * 1e-6;
        w.rgb(time_s, i as u32, &f.rgb)?;
        w.depth(time_s, i as u32, &raw)?;
    }
    Ok(())
}

fn replay() -> anyhow::Result<()> {
    let path = fakenect_library().ok_or_else(|| anyhow::anyhow!("no fakenect library"))?;
    let lib = Library::load(Some(&path))?;
    let mut dev = Device::open(lib, 0, DepthFormat::Raw11)?;
    let conv = Converter::new(freenect::Pinhole::KINECT_RGB, DepthCalibration::default());
    let (mut deliver_us, mut convert_us) = (Vec::new(), Vec::new());
    let mut t0 = Instant::now();
    while deliver_us.len() < FRAMES - 1 {
        match dev.poll(Duration::from_millis(100)) {
            Ok(Some(raw)) => {
                deliver_us.push(t0.elapsed().as_secs_f64() * 1e6);
                let t1 = Instant::now();
                let frame = conv.convert(raw);
                convert_us.push(t1.elapsed().as_secs_f64() * 1e6);
                std::hint::black_box(frame);
                t0 = Instant::now();
            }
            Ok(None) => {}
            Err(e) => anyhow::bail!("after {} frames: {e}", deliver_us.len()),
        }
    }
    let n = deliver_us.len();
    let (d50, d99) = (pct(&mut deliver_us, 0.5), pct(&mut deliver_us, 0.99));
    let (c50, c99) = (pct(&mut convert_us, 0.5), pct(&mut convert_us, 0.99));
    println!("freenect driver through fakenect, {n} 640x480 frames (colour + 11-bit depth)");
    println!("| part | p50 us | p99 us |");
    println!("|---|---:|---:|");
    println!("| libfreenect (fakenect) delivery + copy out | {d50:.0} | {d99:.0} |");
    println!("| robocog: disparity to mm + registration | {c50:.0} | {c99:.0} |");
    println!("| whole driver per frame | {:.0} | |", d50 + c50);
    println!(
        "{}",
        serde_json::json!({
            "frames": n,
            "library_delivery_p50_us": d50,
            "library_delivery_p99_us": d99,
            "convert_register_p50_us": c50,
            "convert_register_p99_us": c99,
            "driver_per_frame_p50_us": d50 + c50,
            "ratio_convert_over_library_delivery_p50": c50 / d50,
            "budget_share_at_30hz_p50": (d50 + c50) / 33_333.0,
        })
    );
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    match args.get(1).map(String::as_str) {
        Some("write") => {
            write(std::path::Path::new(args.get(2).ok_or_else(|| {
                anyhow::anyhow!("usage: bench_kinect write DIR")
            })?))
        }
        Some("replay") => replay(),
        _ => anyhow::bail!("usage: bench_kinect write DIR | replay (with FAKENECT_PATH=DIR)"),
    }
}
