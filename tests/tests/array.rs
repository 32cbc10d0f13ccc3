#![allow(clippy::unwrap_used, clippy::expect_used)] // a test fails by panicking
//! A microphone array through a real sound server: `audio_io --array` captures every channel of
//! a multichannel source onto `audio/in`, and `speech_recognition --array` beamforms them into the
//! commands it hears. The array is a null sink of `aux` channels, as USB arrays show up, into
//! which the test plays what each microphone hears of a room of talkers.
//!
//! Needs the workspace's binaries built (`cargo build --release --workspace --bins`).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use audio::array::sim::{RenderedRoom, TalkersRoom};
use audio::array::{ArrayGeometry, Multichannel, SrpPhat};
use audio::synth::Voice;
use interfaces::msg::command::{Command, Game};
use interfaces::msg::speech::{ListeningDirection, Utterance};
use interfaces::{Bus, topics};
use robocog_tests::*;
use std::time::Duration;

fn voice(name: &str, speed_wpm: u32, pitch: u8) -> Voice {
    Voice {
        voice: name.into(),
        speed_wpm,
        pitch,
    }
}

/// The recognizer and the microphone on the sound server `server`, both given `--array
/// array`, the microphone on `source` with `more` flags of its own. The talkers are espeak-ng
/// voices and every command they say must be heard: the recognizer decodes with the model
/// adapted on those voices (the default, stock, model hears them less surely; its figures on
/// them are `scripts/bench speech`'s).
fn manifest(server: &SoundServer, source: &str, array: &str, more: &str) -> String {
    format!(
        r#"
[[component]]
name = "speech_recognition"
binary = "{}"
args = ["--game", "touch", "--array", "{array}", "--acoustic-model", "adapted"]

[[component]]
name = "audio_io"
binary = "{}"
args = ["--server", "{}", "--source", "{source}", "--sink", "room", "--array", "{array}"{more}]
depends_on = ["speech_recognition"]
external_inputs = ["audio/out", "speech/speaking"]
"#,
        bin("speech_recognition").display(),
        bin("audio_io").display(),
        server.address,
    )
}

/// The graph `text` up, and a bus of the test's own on it.
async fn graph(tag: &str, text: &str) -> (Launch, Bus) {
    let ns = unique_namespace(tag);
    let m = scratch(&ns).join("array.toml");
    std::fs::write(&m, text).unwrap();
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("audio_io up", Duration::from_secs(60), |l| {
            l.contains("audio_io is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-array")
        .await
        .unwrap();
    (launch, bus)
}

/// The player straight ahead saying `phrases`, 1.5 s apart, nobody else in the room.
fn player_alone(phrases: &[&str], geometry: &ArrayGeometry, seed: u64) -> RenderedRoom {
    TalkersRoom {
        player: voice("en-gb", 150, 45),
        phrases,
        player_azimuth_rad: 0.0,
        others: vec![],
        under_db: 0.0,
        lead_s: 1.0,
        gap_s: 1.5,
        mic_noise: 30.0,
        seed,
        reverb: None,
    }
    .render(geometry)
    .unwrap()
}

/// The touch game's commands as exactly themselves, each once, in the order heard.
fn commands(heard: &[Utterance]) -> Vec<Command> {
    heard
        .iter()
        .filter(|u| u.command != Command::None)
        .map(|u| u.command)
        .collect()
}

/// A 4-microphone circular array (a null sink of 4 `aux` channels) behind the server's echo
/// canceller: `audio_io` puts its 4 channels on `audio/in`, each as it is and in its order (the
/// localizer, on what was captured, finds a talker where she spoke from); the recognizer's beam,
/// straight ahead where the player stands, hears her commands.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_array_is_captured_channel_by_channel_and_beamformed_into_her_commands() {
    let server = SoundServer::start_array("array", 4);
    let text = manifest(
        &server,
        "array.monitor",
        "circular_4",
        r#", "--echo-cancel", "webrtc", "--residual-echo", "keep""#,
    );
    let (launch, bus) = graph("array", &text).await;
    let audio = Log::follow(&bus, &topics::AUDIO_IN).await;
    let heard = Log::follow(&bus, &topics::SPEECH_UTTERANCE).await;
    let listening = Log::follow(&bus, &topics::SPEECH_LISTENING).await;
    let geometry = ArrayGeometry::builtin("circular_4").unwrap();

    // The canceller's microphone keeps the array's channels.
    let sources =
        String::from_utf8_lossy(&server.pactl(&["list", "short", "sources"]).stdout).to_string();
    assert!(
        sources
            .lines()
            .any(|l| l.contains("robocog_aec_mic") && l.contains("4ch")),
        "{sources}"
    );

    // Someone speaks from 60 degrees to the left: where the captured channels place her.
    let aside = TalkersRoom {
        player: voice("en-us+f3", 160, 50),
        phrases: &["the garden looks lovely after the rain in spring"],
        player_azimuth_rad: 60f64.to_radians(),
        others: vec![],
        under_db: 0.0,
        lead_s: 0.5,
        gap_s: 0.5,
        mic_noise: 30.0,
        seed: 6,
        reverb: None,
    }
    .render(&geometry)
    .unwrap();
    let before = audio.len();
    play(&server, &aside.pcm.samples);
    let chunks = audio.all()[before..].to_vec();
    assert!(!chunks.is_empty());
    let channels: std::collections::BTreeSet<u16> = chunks.iter().map(|c| c.channels).collect();
    assert_eq!(channels, [4].into(), "audio/in's channels");
    let captured: Vec<i16> = chunks.iter().flat_map(|c| c.samples().unwrap()).collect();
    let mut srp = SrpPhat::new(&geometry, SrpPhat::default_grid()).unwrap();
    let at = srp
        .locate(Multichannel::Interleaved(&captured))
        .unwrap()
        .expect("a talker in what was captured")
        .azimuth_rad
        .to_degrees();
    assert!((at - 60.0).abs() < 10.0, "located at {at:.0} degrees");
    // The recognizer says where it listens, and that she was someone else to it.
    let aside: Vec<ListeningDirection> = listening.all();
    assert!(
        aside
            .iter()
            .all(|l| l.header.frame_id == "circular_4" && l.beam_azimuth_rad == 0.0),
        "{aside:?}"
    );
    assert!(
        aside.iter().any(|l| l.located
            && l.elsewhere
            && (l.talker_azimuth_rad.to_degrees() - 60.0).abs() < 15.0),
        "no block of hers placed elsewhere, at 60 degrees: {aside:?}"
    );
    let before_player = listening.len();

    // The player, straight ahead, says the game's commands.
    let said: Vec<Command> = Command::of_game(Game::Touch).take(5).collect();
    let phrases: Vec<&str> = said.iter().map(|c| c.phrase()).collect();
    let room = player_alone(&phrases, &geometry, 7);
    play(&server, &room.pcm.samples);
    // Until the last command's utterance, or a time-out.
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while commands(&heard.all()).last() != said.last() && std::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let log = launch.lines.all().join("\n");
    assert_eq!(commands(&heard.all()), said, "{log}");
    assert!(
        log.contains("listening at 0 degrees"),
        "the recognizer says where it listens:\n{log}"
    );
    // The player straight ahead is placed there, and heard as herself.
    let player: Vec<ListeningDirection> = listening.all()[before_player..].to_vec();
    assert!(
        player
            .iter()
            .any(|l| l.located && !l.elsewhere && l.talker_azimuth_rad.to_degrees().abs() < 15.0),
        "{player:?}"
    );
}

/// `v` turned by the unit quaternion `q` (x, y, z, w).
fn rotate(q: [f64; 4], v: [f64; 3]) -> [f64; 3] {
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let u = [q[0], q[1], q[2]];
    let t = cross(u, v).map(|x| 2.0 * x);
    let c = cross(u, t);
    [0, 1, 2].map(|i| v[i] + q[3] * t[i] + c[i])
}

/// Listening where the robot looks: with `--array-frame head_rgbd_link`, the recognizer asks
/// the deep representation where the player is in the array's frame and steers the beam there.
/// The player is moved, in the deep representation, to 45 degrees to the left of the array (the
/// first node asked for, `visitor`, is unknown: the next, `player`, is taken): the beam turns
/// to her (`speech/listening` says so), someone straight ahead, where a fixed beam would listen,
/// is someone else to it, and the commands she says from where the deep representation places
/// her are heard, exactly.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_beam_listens_to_the_player_where_the_deep_representation_places_her() {
    use interfaces::msg::dr::{PoseUpdate, Transform, TransformRequest, UpdateRequest};
    let server = SoundServer::start_array("array-dr", 4);
    let text = manifest(&server, "array.monitor", "circular_4", "").replace(
        r#""--acoustic-model", "adapted"]"#,
        &format!(
            r#""--acoustic-model", "adapted",
        "--array-frame", "head_rgbd_link", "--listen-to", "visitor,player"]
depends_on = ["deep_representation"]

[[component]]
name = "deep_representation"
binary = "{}"
args = ["--scene", "touch"]"#,
            bin("deep_representation").display()
        ),
    );
    let (launch, bus) = graph("array-dr", &text).await;
    let heard = Log::follow(&bus, &topics::SPEECH_UTTERANCE).await;
    let listening = Log::follow(&bus, &topics::SPEECH_LISTENING).await;
    let geometry = ArrayGeometry::builtin("circular_4").unwrap();
    let call = Duration::from_secs(10);

    // The player, 1.2 m away at 45 degrees to the left of the array, in the world.
    let ask = |target: &str, source: &str| TransformRequest {
        header: Default::default(),
        target: target.into(),
        source: source.into(),
        stamp_ns: 0,
    };
    let head = bus
        .call(&topics::DR_TRANSFORM, &ask("world", "head_rgbd_link"), call)
        .await
        .unwrap()
        .transform;
    let (c, s) = (45f64.to_radians().cos(), 45f64.to_radians().sin());
    let offset = rotate(head.rotation_xyzw, [1.2 * c, 1.2 * s, 0.0]);
    let at: [f64; 3] = [0, 1, 2].map(|i| head.translation_m[i] + offset[i]);
    let update = UpdateRequest {
        poses: vec![PoseUpdate {
            node: "player".into(),
            pose: Transform {
                translation_m: at,
                rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
            },
        }],
        ..Default::default()
    };
    bus.call(&topics::DR_UPDATE, &update, call).await.unwrap();
    let seen = bus
        .call(
            &topics::DR_TRANSFORM,
            &ask("head_rgbd_link", "player"),
            call,
        )
        .await
        .unwrap()
        .transform
        .translation_m;
    assert!(
        (seen[1].atan2(seen[0]).to_degrees() - 45.0).abs() < 0.1,
        "{seen:?}"
    );

    // The beam turns to her.
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    let turned = |l: &ListeningDirection| {
        l.listening_to == "player" && (l.beam_azimuth_rad.to_degrees() - 45.0).abs() < 3.0
    };
    while !listening.all().iter().any(turned) && std::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let log = launch.lines.all().join("\n");
    assert!(
        listening.all().iter().any(turned),
        "the beam did not turn to the player: {:?}\n{log}",
        listening.all().last()
    );
    // The log says which node it listens to (once, not at every move).
    assert!(
        log.contains("listening to player (the deep representation), at ")
            && !log.contains("listening to visitor ("),
        "{log}"
    );

    // Someone straight ahead speaks: someone else, to a beam on the player.
    let before = listening.len();
    let ahead = TalkersRoom {
        player: voice("en-us+f3", 160, 50),
        phrases: &["the garden looks lovely after the rain in spring"],
        player_azimuth_rad: 0.0,
        others: vec![],
        under_db: 0.0,
        lead_s: 0.5,
        gap_s: 0.5,
        mic_noise: 30.0,
        seed: 16,
        reverb: None,
    }
    .render(&geometry)
    .unwrap();
    play(&server, &ahead.pcm.samples);
    let aside: Vec<ListeningDirection> = listening.all()[before..].to_vec();
    assert!(
        aside.iter().any(|l| l.located
            && l.elsewhere
            && l.listening_to == "player"
            && l.talker_azimuth_rad.to_degrees().abs() < 15.0),
        "no block of the talker ahead placed elsewhere: {aside:?}"
    );

    // The player, where the deep representation places her, says the game's commands.
    let before_player = listening.len();
    let said: Vec<Command> = Command::of_game(Game::Touch).take(3).collect();
    let phrases: Vec<&str> = said.iter().map(|c| c.phrase()).collect();
    let room = TalkersRoom {
        player: voice("en-gb", 150, 45),
        phrases: &phrases,
        player_azimuth_rad: 45f64.to_radians(),
        others: vec![],
        under_db: 0.0,
        lead_s: 1.0,
        gap_s: 1.5,
        mic_noise: 30.0,
        seed: 17,
        reverb: None,
    }
    .render(&geometry)
    .unwrap();
    play(&server, &room.pcm.samples);
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while commands(&heard.all()).last() != said.last() && std::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let log = launch.lines.all().join("\n");
    assert_eq!(commands(&heard.all()), said, "{log}");
    let player: Vec<ListeningDirection> = listening.all()[before_player..].to_vec();
    assert!(
        player.iter().any(|l| l.located
            && !l.elsewhere
            && (l.talker_azimuth_rad.to_degrees() - 45.0).abs() < 15.0),
        "{player:?}"
    );
}

/// Play `samples` (4 channels) into the array's sink, returning once they were played.
fn play(server: &SoundServer, samples: &[i16]) {
    let seconds = samples.len() as f64 / 4.0 / 16_000.0;
    server.play(
        "array",
        4,
        &SoundServer::aux_map(4),
        samples,
        Duration::from_secs_f64(seconds + 30.0),
    );
}

/// The array's geometry says 6 microphones, the source has 4 channels (the wrong source, or the
/// wrong geometry): `audio_io` says so, counts it on `diagnostics` and goes on in mono, the
/// channels mixed, and the player's command is still heard.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_array_source_with_other_channels_than_the_geometry_goes_on_in_mono() {
    let server = SoundServer::start_array("array-mismatch", 4);
    let text = manifest(&server, "array.monitor", "circular_6", "");
    let (launch, bus) = graph("array-mismatch", &text).await;
    let diagnostics = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    let audio = Log::follow(&bus, &topics::AUDIO_IN).await;
    let heard = Log::follow(&bus, &topics::SPEECH_UTTERANCE).await;
    launch
        .lines
        .wait_for("the mismatch said", Duration::from_secs(5), |l| {
            l.contains("has 4 channels, the array circular_6 has 6 microphones")
        });
    diagnostics_until(&diagnostics, |d| {
        d.component == "audio_io" && d.get("array_channel_mismatch") >= 1
    })
    .await;

    let phrases = [Command::of_game(Game::Touch).next().unwrap().phrase()];
    let room = player_alone(&phrases, &ArrayGeometry::builtin("circular_4").unwrap(), 8);
    play(&server, &room.pcm.samples);
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while commands(&heard.all()).is_empty() && std::time::Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    assert_eq!(
        commands(&heard.all()),
        [Command::of_game(Game::Touch).next().unwrap()],
        "{}",
        launch.lines.all().join("\n")
    );
    assert!(audio.all().iter().all(|c| c.channels == 1));
}

/// Flags that cannot work with an array are refused before the component joins the bus (exit
/// 78, the reason named): an array nobody knows, a rate the geometry is not for, the one-channel
/// residual-echo suppressor behind the canceller.
#[test]
fn array_flags_that_cannot_work_are_refused_at_start() {
    let server = SoundServer::start_array("array-flags", 4);
    for (extra, said) in [
        (&["--array", "circular_9"][..], "circular_9"),
        (
            &["--array", "circular_4", "--rate-hz", "48000"][..],
            "--rate-hz 48000",
        ),
        (
            &["--array", "circular_4", "--echo-cancel", "webrtc"][..],
            "--residual-echo keep",
        ),
    ] {
        let mut args: Vec<String> = [
            "--server",
            &server.address,
            "--source",
            "array.monitor",
            "--sink",
            "room",
            "--preflight",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        args.extend(extra.iter().map(|s| s.to_string()));
        let out = run(&bin("audio_io"), &args, Duration::from_secs(30));
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(78), "{extra:?}: {err}");
        assert!(err.contains(said), "{extra:?}: {err}");
    }
}
