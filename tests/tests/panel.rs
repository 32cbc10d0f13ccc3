#![allow(clippy::unwrap_used)]
//! The command panel end to end, in a real browser: the simulated SPL field, the Nao bridge, the
//! simulated camera and the panel as separate processes (the test itself stands in for the
//! Executive's spoken confirmation and for the ball tracker); headless Chromium
//! (Debian's `chromium`) driven by `playwright-core` (tests/browser/panel.mjs) clicks the page.
//!
//! Asserted on the robot's side: GoToPosition plus a click on the field reaches the simulated
//! robot as the exact command packet, and the robot walks towards the clicked point. Asserted on
//! the page: robots move, the coach machine's status (`coach/status`) shows its state and a ball
//! last-seen age updating from new statuses, then GoToPosition as the last command sent, and is
//! greyed out when it goes stale; the spoken answer appears, a click off the carpet is refused with its
//! reason, bad WebSocket input is refused and the server keeps serving, the camera and the ball's
//! window show. Screenshots of both views land in the test's scratch folder.
//!
//! Needs node, Chromium and tests/browser/node_modules: `scripts/test` installs them. Missing
//! ones fail this test (they are not skipped).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::command::{Command, CommandSource};
use interfaces::msg::nao::NaoBody;
use interfaces::msg::tracking::{BallTrack, BallTrackState, PixelWindow};
use interfaces::{Bus, topics};
use robocog_tests::*;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::io::AsyncBufReadExt;

fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// node, Chromium and playwright-core must be there: fail (not skip) with what to do.
fn browser_stack() -> PathBuf {
    let hint = "run scripts/test, which installs the browser stack (Debian chromium, node, \
                playwright-core via npm ci in tests/browser)";
    let node = std::process::Command::new("node").arg("--version").output();
    assert!(
        node.as_ref().is_ok_and(|o| o.status.success()),
        "node is missing: {hint}"
    );
    let chromium = std::env::var_os("CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    assert!(
        chromium.is_file(),
        "Chromium is missing ({}): {hint}",
        chromium.display()
    );
    let browser = repo().join("tests/browser");
    assert!(
        browser
            .join("node_modules/playwright-core/package.json")
            .is_file(),
        "playwright-core is missing from tests/browser/node_modules: {hint}"
    );
    browser
}

/// The coach graph plus the simulated camera (for the touch view), in `dir`.
fn manifest(dir: &Path) -> PathBuf {
    let launch = repo().join("launch").canonicalize().unwrap();
    let text = format!(
        r#"include = ["{}"]

[graph]
name = "panel_test"

[vars]
panel_http = "127.0.0.1:8642"

[[component]]
name = "command_generator"
binary = "command_generator"
args = ["--http", "${{panel_http}}", "--camera-hz", "5"]
depends_on = ["nao_bridge"]
external_inputs = ["speech/speaking", "speech/utterance", "vision/ball", "vision/ball_events",
    "speech/listening"]

# The coach machine: it answers and checks the panel's requests, then commands the robot.
[[component]]
name = "deep_representation"
binary = "deep_representation"
args = ["--scene", "coach"]

[[component]]
name = "executive"
binary = "executive"
args = ["--game", "coach"]
depends_on = ["nao_bridge", "deep_representation"]

[[component]]
name = "rgbd"
binary = "rgbd"
args = ["--driver", "sim", "--scenario", "moving", "--fps", "30"]
"#,
        launch.join("nao_field.toml").display(),
    );
    let p = dir.join("panel_test.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[derive(Debug)]
struct Step {
    name: String,
    data: serde_json::Value,
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_click_on_the_page_moves_the_simulated_robot_and_bad_input_is_refused() {
    let browser_dir = browser_stack();
    let ns = unique_namespace("panel");
    let dir = scratch(&ns);
    let manifest = manifest(&dir);
    let panel_port = free_tcp_port();
    let sets = [
        format!("debug_port={}", free_udp_port()),
        format!("gc_port={}", free_udp_port()),
        format!("command_port={}", free_udp_port()),
        format!("panel_http=127.0.0.1:{panel_port}"),
    ];
    let mut extra = Vec::new();
    for s in &sets {
        extra.push("--set");
        extra.push(s.as_str());
    }
    let launch = Launch::start(&manifest, &ns, &extra);
    launch
        .lines
        .wait_for("the panel", Duration::from_secs(30), |l| {
            l.contains("command panel on http://")
        });
    let bus = Bus::open(&launch.connect_args(), "test-panel")
        .await
        .unwrap();
    let truth = bus.subscriber(&topics::SIM_FIELD_TRUTH).await.unwrap();
    let nao_commands = bus.subscriber(&topics::NAO_COMMAND).await.unwrap();
    let answers = bus.subscriber(&topics::GAME_ANSWER).await.unwrap();
    let diag = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    let talk = bus.subscriber(&topics::SPEECH_TALK).await.unwrap();

    // What the panel asks (coach requests, game commands) and what the Executive says.
    let requests = bus.subscriber(&topics::COACH_REQUEST).await.unwrap();
    let spoken = bus.subscriber(&topics::SPEECH_SAY).await.unwrap();
    let game_commands = bus.subscriber(&topics::GAME_COMMAND).await.unwrap();
    let game_seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let seen = game_seen.clone();
    tokio::spawn(async move {
        while let Ok(c) = game_commands.recv().await {
            seen.lock().unwrap().push((c.command, c.source));
        }
    });

    // A stand-in for the ball tracker (the touch view shows its window and 3D position): the
    // sim's true ball, projected with the camera's intrinsics.
    let tracks = bus.publisher(&topics::VISION_BALL).await.unwrap();
    let frames = bus.subscriber(&topics::VISION_RGBD).await.unwrap();
    let ball_truth = bus.subscriber(&topics::SIM_BALL_TRUTH).await.unwrap();
    tokio::spawn(async move {
        let Ok(frame) = frames.recv().await else {
            return;
        };
        let k = frame.intrinsics;
        drop(frames);
        while let Ok(b) = ball_truth.recv().await {
            let [x, y, z] = b.centre_m;
            if !b.in_view || z <= 0.0 {
                continue;
            }
            let (u, v) = (k.fx * x / z + k.cx, k.fy * y / z + k.cy);
            let r = k.fx * b.diameter_m / 2.0 / z;
            let mut t = BallTrack {
                frame_seq: b.frame_seq,
                state: BallTrackState::Tracking,
                found: true,
                window: PixelWindow {
                    x: (u - r).max(0.0) as u32,
                    y: (v - r).max(0.0) as u32,
                    width: (2.0 * r) as u32,
                    height: (2.0 * r) as u32,
                },
                centre_px: [u, v],
                has_centre_m: true,
                centre_m: b.centre_m,
                diameter_m: b.diameter_m,
                confidence: 1.0,
                ..Default::default()
            };
            if tracks.publish(&mut t).await.is_err() {
                return;
            }
        }
    });

    // A recognizer hearing through an array, as it says where it listens (at the player the
    // deep representation holds): a talker at 60 degrees to the left, someone else's (the touch
    // view shows it).
    let listening = bus.publisher(&topics::SPEECH_LISTENING).await.unwrap();
    tokio::spawn(async move {
        loop {
            let mut m = interfaces::msg::speech::ListeningDirection {
                header: interfaces::Header {
                    frame_id: "circular_4".into(),
                    ..Default::default()
                },
                beam_azimuth_rad: 0.0,
                listening_to: "player".into(),
                located: true,
                talker_azimuth_rad: 60f64.to_radians(),
                elsewhere: true,
            };
            if listening.publish(&mut m).await.is_err() {
                return;
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    });

    // The browser script.
    let (tx, ty) = (-3000.0f32, 1500.0f32);
    let mut node = tokio::process::Command::new("node")
        .arg(browser_dir.join("panel.mjs"))
        .args(["--url", &format!("http://127.0.0.1:{panel_port}/")])
        .args(["--out", &dir.display().to_string()])
        .args(["--target-x", &tx.to_string(), "--target-y", &ty.to_string()])
        .current_dir(&browser_dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .unwrap();
    let mut out = tokio::io::BufReader::new(node.stdout.take().unwrap()).lines();
    let mut err = tokio::io::BufReader::new(node.stderr.take().unwrap()).lines();
    let stderr = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let stderr_w = stderr.clone();
    tokio::spawn(async move {
        while let Ok(Some(l)) = err.next_line().await {
            stderr_w.lock().unwrap().push(l);
        }
    });
    // The browser script prints a few dozen steps; the test reads them as they come.
    let (steps_tx, mut steps) = tokio::sync::mpsc::channel::<Step>(256);
    let stdout_all = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    let stdout_w = stdout_all.clone();
    tokio::spawn(async move {
        while let Ok(Some(l)) = out.next_line().await {
            stdout_w.lock().unwrap().push(l.clone());
            if let Some(rest) = l.strip_prefix("PANEL ")
                && let Some((name, json)) = rest.split_once(' ')
            {
                let data = serde_json::from_str(json).unwrap_or(serde_json::Value::Null);
                let _ = steps_tx
                    .send(Step {
                        name: name.to_string(),
                        data,
                    })
                    .await;
            }
        }
    });
    let browser_output = || {
        format!(
            "browser stdout:\n{}\nbrowser stderr:\n{}\ngraph:\n{}",
            stdout_all.lock().unwrap().join("\n"),
            stderr.lock().unwrap().join("\n"),
            launch.lines.all().join("\n")
        )
    };

    // Wait for the click, then check the robot's side.
    let mut names = Vec::new();
    let clicked = loop {
        let step = tokio::time::timeout(Duration::from_secs(120), steps.recv()).await;
        match step {
            Ok(Some(s)) if s.name == "clicked" => break s,
            Ok(Some(s)) => {
                eprintln!("browser: {} {}", s.name, s.data);
                names.push(s.name);
            }
            _ => panic!("the browser never clicked the field\n{}", browser_output()),
        }
    };
    let target = &clicked.data["target"];
    let (x, y) = (
        target["x_mm"].as_f64().unwrap() as f32,
        target["y_mm"].as_f64().unwrap() as f32,
    );
    assert!((x - tx).hypot(y - ty) < 60.0, "clicked ({x}, {y})");
    // The exact command packet at the simulated robot, and the robot walking there.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(25);
    let mut start_distance = None;
    loop {
        let f = tokio::time::timeout_at(deadline, truth.recv())
            .await
            .unwrap_or_else(|_| {
                panic!(
                    "the simulated robot did not walk to ({x}, {y})\n{}",
                    browser_output()
                )
            })
            .unwrap();
        // The packet first; after it the page also sends a head command (LookLeft), which
        // changes the last packet but not the walk.
        if start_distance.is_none() && f.last_command.len() == 5 && f.last_command[0] == 1.0 {
            assert_eq!(f.last_command, vec![1.0, 0.0, 0.0, x, y]);
        }
        if f.last_command.len() == 5 && (f.last_command[0] == 1.0 || start_distance.is_some()) {
            assert_eq!(f.controlled_body, "GoToPosition");
            let d = (f.controlled.x_mm - x).hypot(f.controlled.y_mm - y);
            let d0 = *start_distance.get_or_insert(d);
            if d < 200.0 || d < d0 - 500.0 {
                eprintln!("robot: {d0:.0} mm from the target, then {d:.0} mm");
                break;
            }
        }
    }

    // The rest of the browser's steps.
    let status = tokio::time::timeout(Duration::from_secs(180), async {
        while let Some(s) = steps.recv().await {
            eprintln!("browser: {} {}", s.name, s.data);
            names.push(s.name);
        }
        node.wait().await
    })
    .await
    .unwrap_or_else(|_| panic!("the browser script ran over 180 s\n{}", browser_output()))
    .unwrap();
    assert!(
        status.success(),
        "the browser script failed\n{}",
        browser_output()
    );
    for step in [
        "coach_status",
        "coach_last",
        "said",
        "refused_target",
        "raw_websocket",
        "coach_stale",
        "talk",
        "touch",
        "done",
    ] {
        assert!(names.iter().any(|n| n == step), "no {step} step: {names:?}");
    }

    // Only the accepted commands left the panel, as coach requests: GoToPosition, then LookLeft
    // (raw socket); none went to the robot directly.
    let mut asked = Vec::new();
    while let Some(r) = requests.try_recv() {
        asked.push((
            r.command.body,
            r.command.head,
            r.command.target,
            r.command.source,
        ));
    }
    assert_eq!(asked.len(), 2, "{asked:?}");
    assert_eq!(asked[0].0, NaoBody::GoToPosition);
    assert_eq!((asked[0].2.x_mm, asked[0].2.y_mm), (x, y));
    assert_eq!(asked[1].1, interfaces::msg::nao::NaoHead::LookLeft);
    assert!(asked.iter().all(|c| c.3 == "panel"));
    // The coach machine answered them aloud and sent them on, as the Executive.
    let mut sent = Vec::new();
    while let Some(c) = nao_commands.try_recv() {
        sent.push((c.body, c.head, c.target, c.source));
    }
    assert!(
        sent.iter()
            .any(|c| c.0 == NaoBody::GoToPosition && (c.2.x_mm, c.2.y_mm) == (x, y)),
        "{sent:?}"
    );
    assert!(
        sent.iter()
            .any(|c| c.1 == interfaces::msg::nao::NaoHead::LookLeft),
        "{sent:?}"
    );
    assert!(sent.iter().all(|c| c.3 == "executive"), "{sent:?}");
    let mut said = Vec::new();
    while let Some(m) = spoken.try_recv() {
        said.push(m.text.to_lowercase());
    }
    assert!(said.iter().any(|t| t.contains("position")), "{said:?}");
    let games: Vec<_> = game_seen.lock().unwrap().clone();
    assert!(
        games.contains(&(Command::TouchBall, CommandSource::Panel)),
        "{games:?}"
    );
    let answer = answers.try_recv().expect("the yes answer on game/answer");
    assert!(answer.yes);

    // The talk key, as it went: held with V (1.3 s), held with the button (1.3 s), held by a
    // socket that went away. Each hold is sent at once and again every 0.5 s, and ends with the
    // key up: the last one from the server, for the socket that did not say so.
    let mut keys = Vec::new();
    while let Some(k) = talk.try_recv() {
        assert_eq!(k.source, "panel");
        keys.push(k.held);
    }
    let mut runs: Vec<(bool, usize)> = Vec::new();
    for held in keys {
        match runs.last_mut() {
            Some((h, n)) if *h == held => *n += 1,
            _ => runs.push((held, 1)),
        }
    }
    let shape: Vec<bool> = runs.iter().map(|r| r.0).collect();
    assert_eq!(shape, [true, false, true, false, true, false], "{runs:?}");
    assert!(
        runs[0].1 >= 2 && runs[2].1 >= 2,
        "no repeats while held: {runs:?}"
    );

    // Refusals counted on diagnostics.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
    loop {
        let d = tokio::time::timeout_at(deadline, diag.recv())
            .await
            .expect("the panel's refusal counters")
            .unwrap();
        if d.component == "command_generator"
            && d.get("rejected/malformed") >= 1
            && d.get("rejected/unknown_command") >= 1
            && d.get("rejected/too_large") >= 1
            && d.get("rejected/target_outside_field") >= 1
            && d.get("rejected/connection_error") >= 1
        {
            break;
        }
    }

    for shot in ["panel-coach.png", "panel-touch.png"] {
        let p = dir.join(shot);
        let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert!(
            bytes.starts_with(b"\x89PNG") && bytes.len() > 20_000,
            "{}",
            p.display()
        );
        eprintln!("screenshot: {}", p.display());
    }
}

#[test]
fn the_panel_refuses_a_non_loopback_address_without_the_flag_and_a_token() {
    let port = free_tcp_port().to_string();
    let addr = format!("0.0.0.0:{port}");
    let cases: [(&[&str], &str); 3] = [
        (&["--http", &addr], "--allow-remote"),
        (&["--http", &addr, "--allow-remote"], "without a token"),
        (
            &["--http", &addr, "--allow-remote", "--token", "short"],
            "too short",
        ),
    ];
    for (args, why) in cases {
        let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        let out = run(&bin("command_generator"), &args, Duration::from_secs(10));
        let err = String::from_utf8_lossy(&out.stderr);
        // A configuration error (EX_CONFIG): the launcher would not restart it.
        assert_eq!(out.status.code(), Some(78), "{args:?}: {err}");
        assert!(err.contains(why), "{args:?}: {err}");
    }
}
