#![allow(clippy::unwrap_used)]
//! Replay determinism of both games. Loki's touch-the-ball game (below) and the Nao coach game
//! (at the end of this file, [`a_replayed_coach_game_takes_the_recorded_steps`]).
//!
//! The touch game: a real game is recorded with
//! `robocog record`, then replayed with `robocog replay` into the Executive and the ball tracker
//! alone (`launch/touch_replay.toml`: no joints, no IK, no camera, no speech, no simulated
//! person), and the replayed Executive must take exactly the recorded steps.
//!
//! # What is recorded
//!
//! `launch/touch_the_ball.toml` with the simulated person playing [`SCENARIO`] (about 40 s: play,
//! scan, touch, the courtesy delay, quit), the simulated camera at [`CAMERA_FPS`] so the frames
//! (1.5 MB each at 640x480) make a file of about 300 MB rather than 2 GB, every topic of the
//! namespace, none dropped (asserted).
//!
//! # What is replayed, and into what
//!
//! Everything but what the replay graph publishes itself ([`REPLAY_GRAPH_OUTPUTS`]): the
//! frames, the measured joints (the DR follows them, so the tracker's `dr/transform` at a frame's
//! stamp is the recorded pose), the person's commands, the reach statuses and the speech events.
//! The tracker tracks the recorded frames again, with the target the replayed Executive sends
//! it; the Executive plays the game again from the replayed commands and its own tracker's tracks
//! and events. The graph runs on the replay's clock (`--clock bus`: the recording's time, which
//! `robocog replay` publishes on `clock`). Three replays, each into a fresh graph: at the
//! recorded rate (the README's command); at 4x and as fast as possible, both with
//! `--sync` [`SYNC`] (the replay waits for the graph's own track, event, target or step wherever
//! the recording has one, so it never runs ahead of the tracker or the Executive).
//!
//! # What must be identical, and why it can be
//!
//! - **The Executive's steps**, in all three: every `executive/transitions` message, in order,
//!   compared on (step number, event, states exited, states entered, active states). The tracker
//!   runs on its frames' stamps, so its events come from the same frames. The Executive's timers
//!   (the scan's 0.3 s hold on a point the neck reached and its 3 s move time-out, courtesy delay
//!   5 s, homing 2 s, the tracker watchdog 1.5 s) run on the replay's clock, which is at each
//!   replayed message's recorded time when the message arrives, and every input first fires the
//!   timers due: so a timer and an input keep their recorded order at any rate, unless they came
//!   within the Executive's own reaction time (milliseconds) of each other. The scenario keeps
//!   that away: no command races the courtesy delay (no "you touched it"), "quit the game" comes
//!   3 s after homing started (the homing timer is 2 s), and the closest race is a scan step and
//!   the detection it causes (the head moves on to the next scan point and the ball comes into
//!   view; with the ball where the scan looks first it is seen during the first turn, before any
//!   scan timer). The test prints that margin, and a divergence's message repeats it. The reach
//!   statuses carry the goal ids the live Executive numbered; the replayed one numbers its goals
//!   the same way (a counter, one per gaze or reach goal), so with the same steps the same
//!   statuses mean the same thing to it (the neck's `reached` moves the scan on, as it did live).
//! - **The tracker's output**, at the recorded rate: every track of a replayed frame is compared
//!   with the recorded track of the same frame (same stamp): same state and found flag, the
//!   camera-frame centre within [`CAMERA_TOLERANCE_M`], the world centre within
//!   [`WORLD_TOLERANCE_M`] (the DR interpolates the head's pose at the frame's stamp from the
//!   joint states it has applied by the time the tracker asks), and the same ball events.
//!
//! A difference fails with the first divergence and the sequences around it.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::executive::StateTransition;
use interfaces::msg::tracking::{BallEvent, BallTrack};
use interfaces::{Bus, Message, topics};
use robocog_tests::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The simulated camera's rate while the game is recorded (the game plays the same at 5 Hz:
/// the tracker's watchdog wants a track every 1.5 s).
const CAMERA_FPS: &str = "5";

/// What `launch/touch_replay.toml` publishes itself, left out of the replay.
const REPLAY_GRAPH_OUTPUTS: &str = "executive/transitions,executive/log,speech/say,\
vision/ball_target,body/reach,vision/ball,vision/ball_events,dr/changes,diagnostics";

/// The replay graph's outputs that the others act on, which a faster replay waits for: the
/// tracker's tracks and events (the Executive's inputs), the Executive's target (the tracker's)
/// and its steps (which every timer's and input's effect is).
const SYNC: &str = "vision/ball,vision/ball_events,vision/ball_target,executive/transitions";

/// The tracker's centre in the camera frame: the same frames give the same pixels.
const CAMERA_TOLERANCE_M: f64 = 0.001;
/// The tracker's centre in `world`: through the DR's head pose at the frame's stamp.
const WORLD_TOLERANCE_M: f64 = 0.01;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn decode<T: Message>(data: &[u8]) -> T {
    interfaces::codec::decode(data, T::TYPE_NAME).unwrap()
}

/// A step as compared: (step, event, exited, entered, active).
type StepKey = (u64, String, Vec<String>, Vec<String>, Vec<String>);

fn key(t: &StateTransition) -> StepKey {
    (
        t.step,
        t.event.clone(),
        t.exited.clone(),
        t.entered.clone(),
        t.active.clone(),
    )
}

fn show(k: &StepKey) -> String {
    format!(
        "step {}: {}: exited {:?} entered {:?} now {:?}",
        k.0, k.1, k.2, k.3, k.4
    )
}

/// The index of the first difference of two sequences (or the shorter one's length).
fn first_divergence<T: PartialEq>(a: &[T], b: &[T]) -> Option<usize> {
    let n = a.iter().zip(b).take_while(|(x, y)| x == y).count();
    (n < a.len().max(b.len())).then_some(n)
}

/// The two sequences from a little before `at`, side by side, for a failure message.
fn around<T>(recorded: &[T], replayed: &[T], at: usize, show: impl Fn(&T) -> String) -> String {
    let mut s = String::new();
    for i in at.saturating_sub(3)..(at + 4).min(recorded.len().max(replayed.len())) {
        let mark = if i == at { ">>" } else { "  " };
        let r = recorded.get(i).map_or("(none)".into(), &show);
        let p = replayed.get(i).map_or("(none)".into(), &show);
        s.push_str(&format!(
            "{mark} #{i}\n     recorded: {r}\n     replayed: {p}\n"
        ));
    }
    s
}

/// How close the recorded game came to a timer/input race: the smallest gap (by the
/// Executive's stamps) between a timer's step and the input step next to it. A replay reproduces
/// the gaps within a few milliseconds; a gap of that order would make the order of the two a
/// matter of luck, which a divergence's message should say.
fn closest_race(steps: &[StateTransition]) -> String {
    let timer = |t: &StateTransition| t.event.starts_with("timer:");
    steps
        .windows(2)
        .filter(|w| timer(&w[0]) != timer(&w[1]))
        .map(|w| {
            let gap_ms = (w[1].header.stamp_ns - w[0].header.stamp_ns) as f64 * 1e-6;
            (gap_ms, format!("{} then {}", w[0].event, w[1].event))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or("no timer step next to an input step".into(), |(g, what)| {
            format!("closest timer/input race in the recording: {what}, {g:.0} ms apart")
        })
}

/// Everything a subscriber receives, drained as it comes (queues are bounded).
fn collect<T: Message>(sub: interfaces::bus::Subscriber<T>) -> Arc<Mutex<Vec<T>>> {
    let got: Arc<Mutex<Vec<T>>> = Arc::default();
    let g = got.clone();
    tokio::spawn(async move {
        while let Ok(m) = sub.recv().await {
            g.lock().unwrap().push(m);
        }
    });
    got
}

fn dist(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The replay graph passes `robocog check` (its external inputs declared).
fn assert_checks(manifest: &Path) {
    let out = run(
        &bin("robocog"),
        &["check".into(), manifest.display().to_string()],
        Duration::from_secs(60),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Every message of a recording, which must have dropped none.
fn read_whole_recording(file: &Path) -> Vec<Rec> {
    let (_, msgs, meta) = read_recording(file);
    for (k, v) in &meta {
        if k.starts_with("dropped/") {
            assert_eq!(v, "0", "the recorder dropped messages of {k}");
        }
    }
    msgs
}

/// Deletes a (large) recording when the test ends, passed or failed.
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// A tool that must not outlive a failed test.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        if self.0.try_wait().ok().flatten().is_none() {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
}

/// The recorded game: the `still` scenario's ball and commands, the person answering "yes"
/// after each command, so a command the recognizer is unsure of ("Did you say ...?") is
/// confirmed rather than dropped (a "yes" with no question pending is ignored), and no "you
/// touched it": the courtesy delay takes the arm home, so no command races that timer. Each
/// `robot_said` after a command matches both the question and the direct answer ("Did you say
/// quit the game?", "Thank you for playing").
const SCENARIO: &str = r#"
name = "touch a still ball, confirming each command"
description = "The person asks to play, to scan the ball and to touch it, saying yes after each command; the arm goes home after the courtesy delay; she ends the game."

[ball]
start = [0.45, 0.30, 1.20]
held = true

[[step]]
say = "let's play"
[[step]]
expect = { robot_said = "play", timeout_s = 10, repeat = 2 }
[[step]]
say = "yes"
[[step]]
expect = { state = "playing", timeout_s = 10 }
[[step]]
say = "scan the ball"
[[step]]
expect = { robot_said = "ball", timeout_s = 10, repeat = 2 }
[[step]]
say = "yes"
[[step]]
expect = { ball_event = "detected", timeout_s = 25 }
[[step]]
expect = { gaze_on_ball_deg = 5.0, timeout_s = 10 }
[[step]]
say = "touch the ball"
[[step]]
expect = { robot_said = "touch", timeout_s = 10, repeat = 2 }
[[step]]
say = "yes"
[[step]]
expect = { reach = "reached", hand_to_ball_m = 0.03, timeout_s = 20 }
[[step]]
expect = { state = "homing", timeout_s = 10 }
[[step]]
pause_s = 3.0
[[step]]
say = "quit the game"
[[step]]
expect = { robot_said = "you", timeout_s = 10, repeat = 2 }
[[step]]
say = "yes"
[[step]]
expect = { state = "finished", timeout_s = 10 }
"#;

/// Plays [`SCENARIO`] while `robocog record` records its namespace into `file`.
fn record_a_game(dir: &Path, file: &Path) {
    let ns = unique_namespace("touchrec");
    let fps = format!("camera_fps={CAMERA_FPS}");
    let scenario_file = dir.join("scenario.toml");
    std::fs::write(&scenario_file, SCENARIO).unwrap();
    let scenario = format!("scenario={}", scenario_file.display());
    let mut live = Launch::start(
        &repo().join("launch/touch_the_ball.toml"),
        &ns,
        &["--set", &scenario, "--set", "panel=false", "--set", &fps],
    );
    let log = dir.join("record.log");
    let mut rec = KillOnDrop(start_recorder(
        &live,
        &ns,
        file,
        &log,
        Duration::from_secs(30),
    ));
    let status = live.wait_exit(Duration::from_secs(300));
    let status_rec = sigterm_and_wait(&mut rec.0, &log);
    let rec_log = std::fs::read_to_string(&log).unwrap();
    assert!(
        status.success(),
        "the recorded game failed ({status}); output:\n{}",
        live.lines.all().join("\n")
    );
    assert!(status_rec.success(), "the recorder failed:\n{rec_log}");
    eprintln!(
        "recorded: {}",
        rec_log
            .lines()
            .find(|l| l.starts_with("recorded "))
            .unwrap_or("")
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_replayed_touch_game_takes_the_recorded_steps() {
    let started = Instant::now();
    let dir = scratch(&unique_namespace("touchreplay"));

    let manifest = repo().join("launch/touch_replay.toml");
    assert_checks(&manifest);

    // 1. A game, recorded.
    let file = dir.join("game.mcap");
    let _cleanup = RemoveOnDrop(file.clone());
    record_a_game(&dir, &file);
    let recorded_at = started.elapsed();
    let msgs = read_whole_recording(&file);
    fn of<'a>(msgs: &'a [Rec], topic: &'a str) -> impl Iterator<Item = &'a Rec> {
        msgs.iter().filter(move |m| m.topic == topic)
    }
    let rec_transitions: Vec<StateTransition> = of(&msgs, "executive/transitions")
        .map(|m| decode::<StateTransition>(&m.data))
        .collect();
    let rec_steps: Vec<StepKey> = rec_transitions.iter().map(key).collect();
    let race = closest_race(&rec_transitions);
    let rec_tracks: BTreeMap<i64, BallTrack> = of(&msgs, "vision/ball")
        .map(|m| decode::<BallTrack>(&m.data))
        .map(|t| (t.header.stamp_ns, t))
        .collect();
    let rec_events: Vec<(u64, String)> = of(&msgs, "vision/ball_events")
        .map(|m| decode::<BallEvent>(&m.data))
        .map(|e| (e.frame_seq, format!("{:?}", e.kind)))
        .collect();
    let frames = of(&msgs, "vision/rgbd").count();
    let span_s = msgs
        .last()
        .map(|l| (l.log_time - msgs[0].log_time) as f64 * 1e-9)
        .unwrap_or(0.0);
    assert_eq!(
        rec_steps.first().map(|s| s.0),
        Some(1),
        "the recording must hold the Executive's first step (the recorder starts before it)"
    );
    assert!(
        rec_steps
            .iter()
            .any(|s| s.4.iter().any(|a| a == "finished")),
        "the recorded game did not finish: {rec_steps:#?}"
    );
    eprintln!("{race}");
    eprintln!(
        "recording: {} messages over {span_s:.1} s, {frames} frames, {} tracks, {} ball events, {} steps, {:.0} MB",
        msgs.len(),
        rec_tracks.len(),
        rec_events.len(),
        rec_steps.len(),
        std::fs::metadata(&file).map(|m| m.len()).unwrap_or(0) as f64 / 1e6
    );
    drop(msgs);

    // 2. The recording into a fresh replay graph, at the recorded rate, as the README says.
    let replayed = replay_into_a_fresh_graph(
        &manifest,
        &file,
        REPLAY_GRAPH_OUTPUTS,
        &[],
        span_s,
        rec_steps.len(),
    )
    .await;
    let replay_s = replayed.wall_s;

    // 3. The Executive took the recorded steps, exactly.
    let got_steps: Vec<StepKey> = replayed.steps.iter().map(key).collect();
    assert_same_steps("at the recorded rate", &rec_steps, &replayed, &race);

    // 4. Faster: at 4x, and as fast as possible, the replay keeping step with the graph (it waits
    // for the tracker's tracks and the Executive's steps where the recording has them). On the
    // replay's clock the timers keep their recorded order.
    for (what, mode) in [
        ("at 4x", &["--rate", "4"][..]),
        ("as fast as possible", &["--as-fast-as-possible"][..]),
    ] {
        let mut args = mode.to_vec();
        args.extend(["--sync", SYNC]);
        let fast = replay_into_a_fresh_graph(
            &manifest,
            &file,
            REPLAY_GRAPH_OUTPUTS,
            &args,
            span_s,
            rec_steps.len(),
        )
        .await;
        assert_same_steps(what, &rec_steps, &fast, &race);
        eprintln!(
            "replay {what}: {:.1} s for {span_s:.1} s recorded; {} steps identical; {}",
            fast.wall_s,
            fast.steps.len(),
            fast.stderr
                .lines()
                .find(|l| l.contains("waited for the graph"))
                .unwrap_or("")
                .trim()
        );
    }

    // 5. At the recorded rate, the tracker found the ball in the same frames, at the same places.
    let got_tracks = replayed.tracks.clone();
    let mut compared = 0usize;
    let (mut worst_cam, mut worst_world) = (0.0f64, 0.0f64);
    for t in &got_tracks {
        let Some(r) = rec_tracks.get(&t.header.stamp_ns) else {
            continue;
        };
        compared += 1;
        let what = format!(
            "the track of frame {} (stamp {})",
            t.frame_seq, t.header.stamp_ns
        );
        assert_eq!(
            (t.frame_seq, t.state, t.found),
            (r.frame_seq, r.state, r.found),
            "{what}: (frame, state, found) replayed vs recorded"
        );
        assert_eq!(t.has_centre_m, r.has_centre_m, "{what}");
        if t.has_centre_m {
            worst_cam = worst_cam.max(dist(&t.centre_m, &r.centre_m));
        }
        assert_eq!(t.has_centre_world, r.has_centre_world, "{what}");
        if t.has_centre_world {
            worst_world = worst_world.max(dist(&t.centre_world_m, &r.centre_world_m));
        }
    }
    let found = |ts: &mut dyn Iterator<Item = &BallTrack>| ts.filter(|t| t.found).count();
    eprintln!(
        "replay: {:.1} s for {span_s:.1} s recorded; {} steps identical; {} tracks ({} with the ball) for {} recorded ({} with the ball), {compared} compared: worst centre difference {:.2} mm (camera), {:.2} mm (world); test {:.0} s (recording {:.0} s)",
        replay_s,
        got_steps.len(),
        got_tracks.len(),
        found(&mut got_tracks.iter()),
        rec_tracks.len(),
        found(&mut rec_tracks.values()),
        worst_cam * 1e3,
        worst_world * 1e3,
        started.elapsed().as_secs_f64(),
        recorded_at.as_secs_f64(),
    );
    assert_eq!(
        compared,
        rec_tracks.len(),
        "every recorded track has its replayed twin ({} replayed)",
        got_tracks.len()
    );
    assert!(
        worst_cam <= CAMERA_TOLERANCE_M,
        "camera-frame centres differ by up to {worst_cam} m"
    );
    assert!(
        worst_world <= WORLD_TOLERANCE_M,
        "world centres differ by up to {worst_world} m"
    );
    let got_events: Vec<(u64, String)> = replayed
        .events
        .iter()
        .map(|e| (e.frame_seq, format!("{:?}", e.kind)))
        .collect();
    if let Some(at) = first_divergence(&rec_events, &got_events) {
        panic!(
            "the replayed tracker's ball events diverged at #{at}:\n{}",
            around(&rec_events, &got_events, at, |e| format!("{e:?}"))
        );
    }
}

/// What one replay into a fresh graph gave.
struct Replayed {
    steps: Vec<StateTransition>,
    tracks: Vec<BallTrack>,
    events: Vec<BallEvent>,
    /// How long `robocog replay` took (wall clock).
    wall_s: f64,
    /// The replay's stderr (its summary).
    stderr: String,
    /// The replay graph's output, for a failure message.
    graph_output: String,
}

/// Replays `file` with `mode` (the pacing flags) into a fresh graph of `manifest`, leaving out
/// `exclude` (what the graph publishes itself), watched from before its Executive starts (its
/// first step is its own), and collects what the graph published. The watcher also reads
/// `nao/command` as `nao_bridge`, as live, so a coach Executive sends its commands rather than
/// holding them. Waits (bounded) for `expected_steps` steps after the replay ended.
async fn replay_into_a_fresh_graph(
    manifest: &Path,
    file: &Path,
    exclude: &str,
    mode: &[&str],
    span_s: f64,
    expected_steps: usize,
) -> Replayed {
    let ns = unique_namespace("replay");
    let graph = Launch::start(manifest, &ns, &[]);
    let bus = Bus::open(&graph.connect_args(), "nao_bridge")
        .await
        .unwrap();
    let _commands = collect(bus.subscriber(&topics::NAO_COMMAND).await.unwrap());
    let steps = collect(
        bus.subscriber(&topics::EXECUTIVE_TRANSITIONS)
            .await
            .unwrap(),
    );
    let tracks = collect(bus.subscriber(&topics::VISION_BALL).await.unwrap());
    let events = collect(bus.subscriber(&topics::VISION_BALL_EVENTS).await.unwrap());
    graph
        .lines
        .wait_for("the executive", Duration::from_secs(60), |l| {
            l.contains("executive is up")
        });
    let mut args: Vec<String> = vec![
        "replay".into(),
        file.display().to_string(),
        "--exclude".into(),
        exclude.into(),
        "--namespace".into(),
        ns.clone(),
        "--connect".into(),
        graph.endpoint.clone(),
        "--progress-s".into(),
        "0".into(),
    ];
    args.extend(mode.iter().map(|a| a.to_string()));
    let replay_started = Instant::now();
    let out = tokio::task::block_in_place(|| {
        run(
            &bin("robocog"),
            &args,
            Duration::from_secs_f64(span_s + 120.0),
        )
    });
    let wall_s = replay_started.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "the replay ({mode:?}) failed:\n{stderr}"
    );
    // The last step follows the last input by the machine's own reaction time only; a replay
    // that took fewer steps is reported with its first divergence.
    let until = Instant::now() + Duration::from_secs(10);
    while steps.lock().unwrap().len() < expected_steps && Instant::now() < until {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_secs(1)).await;
    let replayed = Replayed {
        steps: steps.lock().unwrap().clone(),
        tracks: tracks.lock().unwrap().clone(),
        events: events.lock().unwrap().clone(),
        wall_s,
        stderr,
        graph_output: graph.lines.all().join("\n"),
    };
    drop(graph);
    replayed
}

/// Fails with the first divergence when the replayed Executive did not take the recorded steps.
fn assert_same_steps(what: &str, recorded: &[StepKey], replayed: &Replayed, race: &str) {
    let got: Vec<StepKey> = replayed.steps.iter().map(key).collect();
    if let Some(at) = first_divergence(recorded, &got) {
        panic!(
            "the Executive replayed {what} diverged at step #{at} ({} recorded, {} replayed):\n{}\n{race}\nreplay:\n{}\nreplay graph output:\n{}",
            recorded.len(),
            got.len(),
            around(recorded, &got, at, show),
            replayed.stderr,
            replayed.graph_output
        );
    }
}

// ----- The Nao coach game ------------------------------------------------------------------

/// What `launch/coach_replay.toml` publishes itself, left out of the replay.
const COACH_REPLAY_GRAPH_OUTPUTS: &str = "executive/transitions,executive/log,speech/say,\
nao/command,coach/status,dr/changes,diagnostics";

/// The coach replay graph's output that a faster replay waits for: the Executive's steps.
const COACH_SYNC: &str = "executive/transitions";

/// An attempt of the coach game recorded into `file`: in PLAYING, a kick at our own goal
/// (refused), a dribble (sent), the controlled robot falling and getting up (the dribble
/// resumed), a search for the ball, and a stop. The opponents and the teammate stand still, so
/// nobody scores and the attempt does not end on its own; no random falls.
async fn record_a_coach_game(dir: &Path, file: &Path) {
    use interfaces::msg::nao::{CoachRequest, CoachStatus, FieldPoint, NaoBody, NaoCommand};
    use interfaces::msg::speech::SayRequest;
    let ns = unique_namespace("coachrec");
    let (debug, gc, cmd) = (free_udp_port(), free_udp_port(), free_udp_port());
    let sets = [
        format!("debug_port={debug}"),
        format!("gc_port={gc}"),
        format!("command_port={cmd}"),
        "panel=false".into(),
        "falls_per_min=0".into(),
        "pre_game_s=6".into(),
        "passive_opponents=true".into(),
        "passive_teammate=true".into(),
    ];
    let mut extra = Vec::new();
    for s in &sets {
        extra.extend(["--set", s.as_str()]);
    }
    let live = Launch::start(&repo().join("launch/nao_coach.toml"), &ns, &extra);
    let log = dir.join("record.log");
    let mut rec = KillOnDrop(start_recorder(
        &live,
        &ns,
        file,
        &log,
        Duration::from_secs(30),
    ));
    let bus = Bus::open(&live.connect_args(), "test-coach-record")
        .await
        .unwrap();
    let says = Log::<SayRequest>::follow(&bus, &topics::SPEECH_SAY).await;
    let statuses = Log::<CoachStatus>::follow(&bus, &topics::COACH_STATUS).await;
    let requests = bus.publisher(&topics::COACH_REQUEST).await.unwrap();
    let t = Duration::from_secs(30);
    let said = |text: &'static str| move |s: &SayRequest| s.text == text;
    let request = |body: NaoBody| CoachRequest {
        command: NaoCommand {
            body,
            source: "test".into(),
            ..Default::default()
        },
        ..Default::default()
    };

    statuses
        .wait_from(
            "the Executive in PLAYING",
            0,
            Duration::from_secs(60),
            |s: &CoachStatus| s.state == "coach/playing",
        )
        .await;
    // A kick aimed at our own goal: refused.
    let m = says.len();
    requests
        .publish(&mut CoachRequest {
            aimed: true,
            aim: FieldPoint {
                x_mm: -4500.0,
                y_mm: 0.0,
            },
            ..request(NaoBody::Kick)
        })
        .await
        .unwrap();
    says.wait_from(
        "the own-goal refusal",
        m,
        t,
        said("I will not kick towards our own goal."),
    )
    .await;
    // A dribble; the robot falls and gets up; the dribble is resumed.
    let m = says.len();
    requests
        .publish(&mut request(NaoBody::GoToBallAndDribble))
        .await
        .unwrap();
    says.wait_from("the dribble", m, t, said("Going to the ball to dribble."))
        .await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let field = eventually("the field's pid", Duration::from_secs(10), || {
        component_pid(&live, "spl_field")
    });
    let m = says.len();
    signal(field, "USR1");
    says.wait_from(
        "the fall",
        m,
        t,
        said("I fell. I will get up and carry on."),
    )
    .await;
    says.wait_from(
        "the resume",
        m,
        t,
        said("I am up again. Resuming. Going to the ball to dribble."),
    )
    .await;
    // A search for the ball, then a stop.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let m = says.len();
    requests
        .publish(&mut request(NaoBody::SearchTheBall))
        .await
        .unwrap();
    says.wait_from("the search", m, t, said("Searching for the ball."))
        .await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let m = says.len();
    requests.publish(&mut request(NaoBody::Stop)).await.unwrap();
    says.wait_from("the stop", m, t, said("Stopping.")).await;
    tokio::time::sleep(Duration::from_secs(2)).await;

    let status_rec = sigterm_and_wait(&mut rec.0, &log);
    let rec_log = std::fs::read_to_string(&log).unwrap();
    assert!(status_rec.success(), "the recorder failed:\n{rec_log}");
    eprintln!(
        "recorded: {}; said: {:?}",
        rec_log
            .lines()
            .find(|l| l.starts_with("recorded "))
            .unwrap_or(""),
        says.all().into_iter().map(|s| s.text).collect::<Vec<_>>()
    );
    drop(live);
}

/// A recorded coach attempt replayed into the Executive alone (`launch/coach_replay.toml`) takes
/// the recorded steps exactly: at the recorded rate, at 4x and as fast as possible (those two
/// keeping step with the Executive's steps). Its timers (the robot still down, the link still
/// lost, the teammate's age) run on the replay's clock.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_replayed_coach_game_takes_the_recorded_steps() {
    let started = Instant::now();
    let dir = scratch(&unique_namespace("coachreplay"));
    let manifest = repo().join("launch/coach_replay.toml");
    assert_checks(&manifest);

    let file = dir.join("coach.mcap");
    let _cleanup = RemoveOnDrop(file.clone());
    record_a_coach_game(&dir, &file).await;
    let msgs = read_whole_recording(&file);
    let rec_transitions: Vec<StateTransition> = msgs
        .iter()
        .filter(|m| m.topic == "executive/transitions")
        .map(|m| decode::<StateTransition>(&m.data))
        .collect();
    let rec_steps: Vec<StepKey> = rec_transitions.iter().map(key).collect();
    let race = closest_race(&rec_transitions);
    let span_s = msgs
        .last()
        .map(|l| (l.log_time - msgs[0].log_time) as f64 * 1e-9)
        .unwrap_or(0.0);
    assert_eq!(
        rec_steps.first().map(|s| s.0),
        Some(1),
        "the recording must hold the Executive's first step (the recorder starts before it)"
    );
    for state in ["coach/playing", "coach/robot_down"] {
        assert!(
            rec_steps.iter().any(|s| s.3.iter().any(|a| a == state)),
            "the recorded attempt never entered {state}: {rec_steps:#?}"
        );
    }
    eprintln!("{race}");
    eprintln!(
        "coach recording: {} messages over {span_s:.1} s, {} steps",
        msgs.len(),
        rec_steps.len()
    );
    drop(msgs);

    for (what, mode) in [
        ("at the recorded rate", &[][..]),
        ("at 4x", &["--rate", "4", "--sync", COACH_SYNC][..]),
        (
            "as fast as possible",
            &["--as-fast-as-possible", "--sync", COACH_SYNC][..],
        ),
    ] {
        let replayed = replay_into_a_fresh_graph(
            &manifest,
            &file,
            COACH_REPLAY_GRAPH_OUTPUTS,
            mode,
            span_s,
            rec_steps.len(),
        )
        .await;
        assert_same_steps(what, &rec_steps, &replayed, &race);
        eprintln!(
            "coach replay {what}: {:.1} s for {span_s:.1} s recorded; {} steps identical",
            replayed.wall_s,
            replayed.steps.len()
        );
    }
    eprintln!("test {:.0} s", started.elapsed().as_secs_f64());
}
