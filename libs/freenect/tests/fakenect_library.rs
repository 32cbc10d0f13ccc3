#![expect(
    clippy::disallowed_methods,
    reason = "an integration test: waits on real child processes and the real fakenect library on the wall clock"
)]
#![allow(clippy::unwrap_used)]
//! The device API through Debian's real fakenect library (`libfreenect-dev`): frames written as
//! a dump, or streamed live through a FIFO, come out of libfreenect's callbacks intact; a live
//! stream that ends is an error from `poll`, and a fresh load of the library reads the next one.
//!
//! fakenect reads `FAKENECT_PATH` from the environment, so each case runs in a child process of
//! this test binary with the variable set (`ROBOCOG_FAKENECT_CASE` names the case).

use freenect::device::{DepthFormat, Device, Library};
use freenect::fakenect::{DumpWriter, LiveDump, Offer, RawTilt};
use freenect::{PIXELS, WIDTH};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn fakenect() -> Option<PathBuf> {
    let mut dirs = vec![PathBuf::from("/usr/lib/fakenect")];
    if let Ok(entries) = std::fs::read_dir("/usr/lib") {
        dirs.extend(entries.flatten().map(|e| e.path().join("fakenect")));
    }
    dirs.into_iter()
        .map(|d| d.join("libfreenect.so.0.5"))
        .find(|p| p.is_file())
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "robocog-fakenect-lib-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn frame(i: usize) -> (Vec<u8>, Vec<u16>) {
    let mut rgb = vec![0u8; PIXELS * 3];
    let mut raw = vec![2047u16; PIXELS];
    for (p, px) in rgb.chunks_exact_mut(3).enumerate() {
        px.copy_from_slice(&[(i % 256) as u8, (p % 256) as u8, 7]);
    }
    for (p, r) in raw.iter_mut().enumerate() {
        *r = ((p / WIDTH + i) % 1000 + 400) as u16;
    }
    (rgb, raw)
}

/// Runs `case` in a child with FAKENECT_PATH = `dir`; returns its stdout.
fn child(case: &str, dir: &Path) -> String {
    let mut c = Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_case",
            "--ignored",
            "--nocapture",
            "--test-threads",
            "1",
        ])
        .env("ROBOCOG_FAKENECT_CASE", case)
        .env("FAKENECT_PATH", dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::inherit())
        .spawn()
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(60);
    let status = loop {
        if let Some(s) = c.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "child {case} hung");
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut out = String::new();
    std::io::Read::read_to_string(&mut c.stdout.take().unwrap(), &mut out).unwrap();
    assert!(status.success(), "child {case} failed: {out}");
    out
}

fn open() -> Device {
    // As the rgbd driver does: fakenect ends the process when the dump has no INDEX.txt.
    let index = PathBuf::from(std::env::var_os("FAKENECT_PATH").unwrap()).join("INDEX.txt");
    let deadline = Instant::now() + Duration::from_secs(20);
    while !index.exists() {
        assert!(Instant::now() < deadline, "no {}", index.display());
        std::thread::sleep(Duration::from_millis(20));
    }
    let lib = Library::load(Some(&fakenect().unwrap())).unwrap();
    assert!(!lib.registers(), "fakenect cannot register depth");
    Device::open(lib, 0, DepthFormat::Raw11).unwrap()
}

fn next(dev: &mut Device) -> freenect::device::RawFrame {
    for _ in 0..1000 {
        if let Some(f) = dev.poll(Duration::from_millis(100)).unwrap() {
            return f;
        }
    }
    panic!("no frame");
}

/// The child side: run by the tests below in a child process with `FAKENECT_PATH` set (ignored
/// on its own).
#[test]
#[ignore = "the child process of the other tests of this file"]
fn child_case() {
    let Ok(case) = std::env::var("ROBOCOG_FAKENECT_CASE") else {
        return;
    };
    match case.as_str() {
        "folder" => {
            let mut dev = open();
            for i in 0..3 {
                let f = next(&mut dev);
                let (rgb, raw) = frame(i);
                assert_eq!(f.rgb, rgb, "colour of frame {i}");
                assert_eq!(f.depth, raw, "depth of frame {i}");
                assert_eq!((f.rgb_ts, f.depth_ts), (10 + i as u32, 20 + i as u32));
            }
            let t = dev.tilt().unwrap();
            assert_eq!(t.angle_deg, -3.0);
            assert!((t.accel_mps2[1] + 9.80665).abs() < 1e-9, "{t:?}");
            // The end of a recorded dump is an error: the driver treats it as a lost device.
            let mut ended = false;
            for _ in 0..10 {
                if dev.poll(Duration::from_millis(100)).is_err() {
                    ended = true;
                    break;
                }
            }
            assert!(ended, "the dump's end was not reported");
            println!("folder ok");
        }
        "live" => {
            // Two streams one after the other: the second is read by a fresh load of the library.
            for round in 0..2 {
                let mut dev = open();
                let f = next(&mut dev);
                assert_eq!(f.rgb[0], 100 + round, "stream {round}");
                let mut err = false;
                for _ in 0..200 {
                    match dev.poll(Duration::from_millis(100)) {
                        Ok(_) => {}
                        Err(_) => {
                            err = true;
                            break;
                        }
                    }
                }
                assert!(err, "stream {round}: its end was not reported");
                drop(dev);
                println!("stream {round} ok");
            }
        }
        other => panic!("unknown case {other}"),
    }
}

#[test]
fn frames_of_a_dump_folder_come_through_fakenect() {
    let Some(_) = fakenect() else {
        panic!("Debian's fakenect library is missing: apt-get install libfreenect-dev");
    };
    let dir = scratch("folder");
    let mut w = DumpWriter::create(&dir).unwrap();
    w.tilt(
        999.0,
        0,
        &RawTilt {
            accel: [0, -819, 0],
            tilt_half_deg: -6,
            status: 0,
        },
    )
    .unwrap();
    for i in 0..3 {
        let (rgb, raw) = frame(i);
        let t = 1000.0 + i as f64 / 30.0;
        w.rgb(t, 10 + i as u32, &rgb).unwrap();
        w.depth(t, 20 + i as u32, &raw).unwrap();
    }
    drop(w);
    assert!(child("folder", &dir).contains("folder ok"));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_live_dump_streams_through_fakenect_and_a_new_stream_is_read_after_a_reload() {
    let dir = scratch("live");
    let writer_dir = dir.clone();
    let writer = std::thread::Builder::new()
        .name("live-dump-writer".into())
        .spawn(move || {
            for round in 0..2u8 {
                let mut live = LiveDump::create(&writer_dir).unwrap();
                let (mut rgb, raw) = frame(0);
                rgb[0] = 100 + round;
                let deadline = Instant::now() + Duration::from_secs(30);
                let mut sent = 0;
                while sent < 20 && Instant::now() < deadline {
                    if live.offer(sent, &rgb, &raw, None).unwrap() == Offer::Sent {
                        sent += 1;
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
                assert_eq!(sent, 20, "round {round}: the reader took {sent} frames");
                // Dropping the dump closes the FIFO: the reader sees the stream end.
            }
        })
        .unwrap();
    let out = child("live", &dir);
    writer.join().unwrap();
    assert!(out.contains("stream 1 ok"), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}
