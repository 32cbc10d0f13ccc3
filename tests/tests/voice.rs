#![allow(clippy::unwrap_used, clippy::expect_used)] // a test fails by panicking
//! The voice chain as processes on the bus: synthesized speech published on `audio/in` reaches
//! a launched `speech_recognition`, whose utterance goes through `dialogs` to `game/command`;
//! bad audio is dropped and counted; `speech_generator` speaks a request on `audio/out`.
//!
//! Needs the workspace's binaries built (`cargo build --release --workspace --bins`).
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::command::{Answer, Command};
use interfaces::msg::speech::{AudioChunk, Priority, SayRequest, SpeakingState};
use interfaces::{Bus, topics};
use robocog_tests::*;
use std::time::Duration;

mod common {
    use audio::signal::{NoiseKind, NoiseRng, mix_at_snr};
    use audio::synth::{Voice, synthesize_16k};

    pub fn voice(name: &str, speed_wpm: u32, pitch: u8) -> Voice {
        Voice {
            voice: name.into(),
            speed_wpm,
            pitch,
        }
    }

    /// `text` spoken by `v`, between 0.6 s of white noise before and 0.8 s after, at `snr_db`.
    pub fn spoken(text: &str, v: &Voice, snr_db: f64, seed: u64) -> Vec<i16> {
        let speech = synthesize_16k(text, v).expect("espeak-ng speaks");
        mix_at_snr(
            &speech,
            snr_db,
            NoiseKind::White,
            0.6,
            0.8,
            &mut NoiseRng::new(seed),
        )
    }
}

fn manifest() -> String {
    format!(
        r#"
[[component]]
name = "speech_recognition"
binary = "{}"
args = ["--game", "touch"]
external_inputs = ["audio/in"]
# As in the games' manifests: it starts once the dialog reads its utterances, and stops first.
depends_on = ["dialogs"]

[[component]]
name = "dialogs"
binary = "{}"
# The test reads game/command itself (there is no Executive here).
args = ["--high", "0.7", "--low", "0.3", "--command-readers", "test-voice"]
external_inputs = ["game/answer"]

[[component]]
name = "speech_generator"
binary = "{}"
"#,
        bin("speech_recognition").display(),
        bin("dialogs").display(),
        bin("speech_generator").display()
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn spoken_command_on_audio_in_becomes_a_game_command() {
    let ns = unique_namespace("voice");
    let dir = scratch(&ns);
    let m = dir.join("voice.toml");
    std::fs::write(&m, manifest()).unwrap();
    let launch = Launch::start(&m, &ns, &[]);
    for who in ["speech_recognition", "dialogs", "speech_generator"] {
        launch.lines.wait_for(who, Duration::from_secs(30), |l| {
            l.contains(&format!("{who} is up"))
        });
    }
    launch
        .lines
        .wait_for("listening", Duration::from_secs(30), |l| {
            l.contains("listening")
        });
    let bus = Bus::open(&launch.connect_args(), "test-voice")
        .await
        .unwrap();
    let audio = bus.publisher(&topics::AUDIO_IN).await.unwrap();
    let utterances = bus.subscriber(&topics::SPEECH_UTTERANCE).await.unwrap();
    let commands = bus.subscriber(&topics::GAME_COMMAND).await.unwrap();
    let said = bus.subscriber(&topics::SPEECH_SAY).await.unwrap();
    let answers = bus.publisher(&topics::GAME_ANSWER).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;

    // Wrong rate, half a stereo frame and empty chunks: dropped, counted, logged.
    let mut bad = AudioChunk::mono(8000, &[100; 800]);
    audio.publish(&mut bad).await.unwrap();
    let mut half = AudioChunk::interleaved(16000, 2, &[100; 1601]);
    audio.publish(&mut half).await.unwrap();
    audio
        .publish(&mut AudioChunk::mono(16000, &[]))
        .await
        .unwrap();
    launch
        .lines
        .wait_for("wrong rate dropped", Duration::from_secs(10), |l| {
            l.contains("dropped audio chunk (wrong_rate")
        });
    launch
        .lines
        .wait_for("half a frame dropped", Duration::from_secs(10), |l| {
            l.contains("dropped audio chunk (partial_frame")
        });

    // A warm-up utterance first: the decoder's cepstral mean starts from the model's prior and
    // adapts over the first utterance (known issue: the very first command after start-up is
    // misheard more often). It is out of the grammar, so the dialog ignores it without a word
    // (a question about it would make the dialog ignore what follows while the robot speaks).
    // Then "touch the ball"; both at 20 dB SNR, in 100 ms chunks, a little faster than real time.
    let v = common::voice("en-us", 160, 50);
    const WARM_UP: &str = "what a lovely day";
    let mut speech = common::spoken(WARM_UP, &v, 20.0, 10);
    speech.extend(common::spoken("touch the ball", &v, 20.0, 11));
    for chunk in speech.chunks(1600) {
        audio
            .publish(&mut AudioChunk::mono(16000, chunk))
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(40)).await;
    }
    let mut heard = vec![];
    while let Some(u) = utterances
        .recv_timeout(Duration::from_secs(20))
        .await
        .unwrap()
    {
        assert!(
            u.in_grammar == (u.command != Command::None) && (0.0..=1.0).contains(&u.confidence)
        );
        heard.push(u);
        if heard.len() == 2 {
            break;
        }
    }
    assert_eq!(heard.len(), 2, "{heard:?}");
    let u = &heard[1];
    assert_eq!(u.command, Command::TouchBall, "{heard:?}");
    // Stream times: the second utterance's speech starts 0.6 s into its 2nd part.
    let first_len_s = common::spoken(WARM_UP, &v, 20.0, 10).len() as f64 / 16000.0;
    assert!(
        u.stream_start_s > first_len_s && u.stream_start_s < first_len_s + 0.7,
        "{u:?}"
    );
    assert!(u.latency_s < 5.0, "{u:?}");
    // The dialog passes it on: at once when the confidence is above its high threshold (0.7),
    // or, between the thresholds (a 20 dB command lands there now and then), after asking
    // "Did you say touch the ball?", answered yes from the panel's topic.
    let asked = u.confidence < 0.7;
    if asked {
        let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
        loop {
            let q = tokio::time::timeout_at(deadline, said.recv())
                .await
                .expect("the dialog's question \"Did you say touch the ball?\"")
                .unwrap();
            if q.text.to_lowercase().contains("did you say touch the ball") {
                break;
            }
        }
        answers
            .publish(&mut Answer {
                yes: true,
                ..Default::default()
            })
            .await
            .unwrap();
    }
    let mut got = vec![];
    while let Some(c) = commands
        .recv_timeout(Duration::from_secs(10))
        .await
        .unwrap()
    {
        got.push((c.command, c.confirmed));
        if c.command == Command::TouchBall {
            break;
        }
    }
    assert!(
        got.contains(&(Command::TouchBall, asked)),
        "{got:?} after {heard:?} (asked: {asked})"
    );

    // A stereo chunk (no --array here) is heard, its channels mixed into one; said once.
    let mut stereo = AudioChunk::interleaved(16000, 2, &[0; 1600]);
    audio.publish(&mut stereo).await.unwrap();
    launch
        .lines
        .wait_for("stereo mixed", Duration::from_secs(10), |l| {
            l.contains("audio/in has 2 channels: mixed into one")
        });
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_generator_speaks_and_an_urgent_request_interrupts() {
    let ns = unique_namespace("voice-gen");
    let dir = scratch(&ns);
    let m = dir.join("gen.toml");
    std::fs::write(
        &m,
        format!(
            "[[component]]\nname = \"speech_generator\"\nbinary = \"{}\"\nargs = [\"--wav-dir\", \"{}\"]\nexternal_inputs = [\"speech/say\"]\n",
            bin("speech_generator").display(),
            dir.join("wavs").display()
        ),
    )
    .unwrap();
    let launch = Launch::start(&m, &ns, &[]);
    launch.lines.wait_for("up", Duration::from_secs(30), |l| {
        l.contains("speech_generator is up")
    });
    let bus = Bus::open(&launch.connect_args(), "test-gen").await.unwrap();
    let say = bus.publisher(&topics::SPEECH_SAY).await.unwrap();
    let events = bus.subscriber(&topics::SPEECH_SPEAKING).await.unwrap();
    let out = bus.subscriber(&topics::AUDIO_OUT).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    let long = "I am going to track the ball with my head and then touch it with my right hand";
    say.publish(&mut SayRequest {
        id: 1,
        text: long.into(),
        priority: Priority::Normal,
        ..Default::default()
    })
    .await
    .unwrap();
    let mut seen = vec![];
    let deadline = tokio::time::Instant::now() + Duration::from_secs(20);
    while tokio::time::Instant::now() < deadline {
        let Some(e) = events.recv_timeout(Duration::from_secs(1)).await.unwrap() else {
            continue;
        };
        seen.push((e.id, e.state));
        if e.id == 1 && e.state == SpeakingState::Started {
            // Audio flows; then an urgent request cuts in.
            let a = out
                .recv_timeout(Duration::from_secs(5))
                .await
                .unwrap()
                .expect("audio out");
            assert_eq!((a.sample_rate_hz, a.channels), (16000, 1));
            say.publish(&mut SayRequest {
                id: 2,
                text: "stop".into(),
                priority: Priority::Urgent,
                ..Default::default()
            })
            .await
            .unwrap();
        }
        if e.id == 2 && e.state == SpeakingState::Finished {
            break;
        }
    }
    assert!(seen.contains(&(1, SpeakingState::Interrupted)), "{seen:?}");
    assert!(seen.contains(&(2, SpeakingState::Started)), "{seen:?}");
    assert!(seen.contains(&(2, SpeakingState::Finished)), "{seen:?}");
    assert!(dir.join("wavs").join("2.wav").is_file());
}

/// The speech components with the robot's microphone and speaker (`audio_io`) on a sound server
/// of the test's own: the room is its null sink, the microphone a virtual source on the room's
/// monitor. The dialog watches the components `microphones` (`--microphones`; empty: none).
fn sound_manifest_with(server: &SoundServer, microphones: &str) -> String {
    format!(
        r#"
[[component]]
name = "speech_recognition"
binary = "{}"
args = ["--game", "touch", "--utterance-readers", "dialogs"]

[[component]]
name = "dialogs"
binary = "{}"
# The test reads game/command itself (there is no Executive here).
args = ["--command-readers", "test-sound", "--microphones", "{}"]
depends_on = ["speech_generator"]
external_inputs = ["game/answer"]

[[component]]
name = "speech_generator"
binary = "{}"

[[component]]
name = "audio_io"
binary = "{}"
args = ["--server", "{}", "--source", "mic", "--sink", "room"]
depends_on = ["speech_recognition"]
"#,
        bin("speech_recognition").display(),
        bin("dialogs").display(),
        microphones,
        bin("speech_generator").display(),
        bin("audio_io").display(),
        server.address,
    )
}

/// A sound server, the speech graph with `audio_io` on it (the dialog watching `microphones`),
/// up, and a bus of the test's own on it; and the test's scratch folder.
async fn sound_graph(
    tag: &str,
    microphones: &str,
) -> (SoundServer, Launch, Bus, std::path::PathBuf) {
    let server = SoundServer::start(tag);
    let ns = unique_namespace(tag);
    let dir = scratch(&ns);
    let m = dir.join("sound.toml");
    std::fs::write(&m, sound_manifest_with(&server, microphones)).unwrap();
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("audio_io up", Duration::from_secs(60), |l| {
            l.contains("audio_io is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-sound")
        .await
        .unwrap();
    (server, launch, bus, dir)
}

/// The first and the last 20 ms frame of a 16 kHz s16le recording that hold sound (RMS above
/// `threshold`), in seconds from its start.
fn sound_span(pcm: &[u8], threshold: f64) -> Option<(f64, f64)> {
    let samples: Vec<i16> = pcm
        .chunks_exact(2)
        .map(|b| i16::from_le_bytes([b[0], b[1]]))
        .collect();
    let loud: Vec<usize> = samples
        .chunks(320)
        .enumerate()
        .filter(|(_, f)| {
            let e = f.iter().map(|&s| f64::from(s).powi(2)).sum::<f64>() / f.len() as f64;
            e.sqrt() > threshold
        })
        .map(|(i, _)| i)
        .collect();
    Some((
        *loud.first()? as f64 * 0.02,
        (*loud.last()? + 1) as f64 * 0.02,
    ))
}

/// The robot's voice goes through the sound server into the room, for as long as it was
/// synthesized; its own microphone hears it, and what it hears of itself is not taken for a
/// command, even though the sentence is made of commands.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_robots_voice_is_played_into_the_room_and_not_taken_for_a_command() {
    let (server, launch, bus, dir) = sound_graph("sound", "").await;
    let commands = bus.subscriber(&topics::GAME_COMMAND).await.unwrap();
    let utterances = bus.subscriber(&topics::SPEECH_UTTERANCE).await.unwrap();
    let speaking = bus.subscriber(&topics::SPEECH_SPEAKING).await.unwrap();
    let diagnostics = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    let say = bus.publisher(&topics::SPEECH_SAY).await.unwrap();
    let out = bus.publisher(&topics::AUDIO_OUT).await.unwrap();
    // The room as a second microphone would hear it.
    let room = dir.join("room.raw");
    let mut recorder = server.record("room.monitor", &room);
    // The recognizer hears the silent room for a moment first (it settles its noise floor).
    tokio::time::sleep(Duration::from_secs(2)).await;
    // Two malformed chunks for the speaker (an odd byte count; no channels): counted, not
    // played.
    let mut odd = AudioChunk::mono(16000, &[100; 160]);
    odd.pcm_s16le.pop();
    out.publish(&mut odd).await.unwrap();
    let mut none = AudioChunk::mono(16000, &[100; 160]);
    none.channels = 0;
    out.publish(&mut none).await.unwrap();

    let text = "Let's play. Touch the ball. Touch the ball now.";
    say.publish(&mut SayRequest {
        id: 1,
        text: text.into(),
        priority: Priority::Normal,
        ..SayRequest::default()
    })
    .await
    .unwrap();
    let mut finished = None;
    let mut finished_at = None;
    let mut heard = Vec::new();
    let mut wrongly = Vec::new();
    let mut audio_io = None;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(40);
    let mut quiet_until = None;
    loop {
        tokio::select! {
            s = speaking.recv() => {
                let s = s.unwrap();
                if s.id == 1 && s.state == SpeakingState::Finished {
                    finished = Some(s.duration_s);
                    finished_at = Some(tokio::time::Instant::now());
                    // What the microphone heard last comes through the recognizer within a few
                    // seconds (end-pointing, decoding).
                    quiet_until = Some(tokio::time::Instant::now() + Duration::from_secs(5));
                }
                assert_ne!(s.state, SpeakingState::Failed, "{s:?}");
            }
            u = utterances.recv() => {
                let u = u.unwrap();
                // When it came, against the end of the sentence (negative: before).
                let after_s = finished_at.map(|t: tokio::time::Instant| t.elapsed().as_secs_f64());
                eprintln!("heard {:?} ({:.2}), {after_s:?} s after the sentence ended", u.text, u.confidence);
                heard.push(u.text);
            }
            c = commands.recv() => wrongly.push(c.unwrap()),
            d = diagnostics.recv() => {
                let d = d.unwrap();
                if d.component == "audio_io" {
                    audio_io = Some(d);
                }
            }
            _ = tokio::time::sleep_until(quiet_until.unwrap_or(deadline)) => break,
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "the sentence did not finish within 40 s\n{}",
            launch.lines.all().join("\n")
        );
    }
    let _ = recorder.kill();
    let _ = recorder.wait();
    let duration_s = finished.expect("the sentence finished");

    // It played, and all of it: the sound in the room lasts as long as the sound of the same
    // sentence synthesized here with the generator's default voice (its audio holds silence at
    // the end, so the sentence's duration is longer than what is heard).
    let pcm = std::fs::read(&room).unwrap();
    let (start, end) = sound_span(&pcm, 300.0).expect("the room heard the robot");
    let played = end - start;
    let own: Vec<u8> = audio::synth::synthesize_16k(text, &common::voice("en-us", 160, 50))
        .unwrap()
        .iter()
        .flat_map(|s| s.to_le_bytes())
        .collect();
    let (s0, s1) = sound_span(&own, 300.0).unwrap();
    let audible = s1 - s0;
    assert!(
        played >= audible - 0.1,
        "played {played:.2} s of a sentence with {audible:.2} s of sound ({duration_s:.2} s long)"
    );
    // The microphone heard it, and the dialog took none of it for a command.
    assert!(
        !heard.is_empty(),
        "the recognizer heard nothing of the robot's voice\n{}",
        launch.lines.all().join("\n")
    );
    assert!(
        wrongly.is_empty(),
        "the robot took its own voice for {wrongly:?} (heard {heard:?})"
    );
    // Counted on diagnostics: it captured and played every chunk; a sentence that took longer
    // than its sound (a chunk came late on a loaded machine, and the speaker ran dry meanwhile)
    // was counted as an under-run, never stretched in silence.
    let d = audio_io.expect("audio_io's diagnostics");
    assert!(d.get("capture_chunks") > 100, "{d:?}");
    assert!(
        d.get("playback_chunks") >= (duration_s * 10.0) as u64 - 1,
        "{d:?}"
    );
    if played > audible + 0.1 {
        assert!(
            d.get("playback_underruns") > 0,
            "stretched by {:.2} s: {d:?}",
            played - audible
        );
    }
    assert_eq!(d.get("capture_overruns"), 0, "{d:?}");
    assert_eq!(d.get("playback_malformed"), 2, "{d:?}");
}

/// A microphone the sound server does not have: audio_io says which devices there are, exits
/// with the configuration code, and the launcher does not restart it.
#[test]
fn a_microphone_that_is_not_there_is_named_with_the_ones_there_are() {
    let server = SoundServer::start("nodevice");
    let out = run(
        &bin("audio_io"),
        &[
            "--server".into(),
            server.address.clone(),
            "--source".into(),
            "usb-headset".into(),
            "--preflight".into(),
        ],
        Duration::from_secs(30),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(78), "{err}");
    assert!(
        err.contains("no source (microphone) named \"usb-headset\""),
        "{err}"
    );
    assert!(
        err.contains("  mic [default]") && err.contains("  room.monitor"),
        "{err}"
    );

    let ns = unique_namespace("nodevice");
    let m = scratch(&ns).join("mic.toml");
    std::fs::write(
        &m,
        format!(
            "[[component]]\nname = \"audio_io\"\nbinary = \"{}\"\nrestart = \"on-failure\"\n\
             args = [\"--server\", \"{}\", \"--source\", \"usb-headset\"]\n\
             external_inputs = [\"audio/out\", \"speech/speaking\"]\n",
            bin("audio_io").display(),
            server.address
        ),
    )
    .unwrap();
    let mut launch = Launch::start(&m, &ns, &[]);
    let status = launch.wait_exit(Duration::from_secs(30));
    let all = launch.lines.all().join("\n");
    assert_eq!(status.code(), Some(78), "{all}");
    assert!(all.contains("usb-headset"), "{all}");
    assert!(!all.contains("restart 1/"), "never restarted: {all}");
}

/// The microphone unplugged in the middle of a game (its source leaves the sound server): the
/// robot says it cannot hear, `audio_io` logs and counts it, and when the microphone is back it
/// is opened again and the robot says so.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_microphone_lost_mid_game_is_said_and_opened_again_when_it_is_back() {
    let (mut server, launch, bus, _) = sound_graph("lostmic", "audio_io").await;
    lost_and_back(
        &mut server,
        &launch,
        &bus,
        |server| {
            let modules =
                String::from_utf8_lossy(&server.pactl(&["list", "short", "modules"]).stdout)
                    .to_string();
            let index = modules
                .lines()
                .find(|l| l.contains("module-virtual-source"))
                .and_then(|l| l.split_whitespace().next())
                .unwrap_or_else(|| panic!("no microphone module in\n{modules}"))
                .to_string();
            assert!(server.pactl(&["unload-module", &index]).status.success());
        },
        |server| {
            let load = [
                "load-module",
                "module-virtual-source",
                "source_name=mic",
                "master=room.monitor",
            ];
            assert!(server.pactl(&load).status.success());
        },
    )
    .await;
}

/// The whole sound server dies in the middle of a game (it crashed, or the session that ran it
/// ended) and comes back: `audio_io` does not exit (a restart would find no server and stop the
/// graph), it logs and counts the microphone lost, the robot says it cannot hear, and when the
/// server is back the microphone is opened again, the robot says so and it captures again.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sound_server_that_dies_and_comes_back_is_said_and_reopened() {
    let (mut server, launch, bus, _) = sound_graph("deadserver", "audio_io").await;
    lost_and_back(
        &mut server,
        &launch,
        &bus,
        SoundServer::kill,
        SoundServer::restart,
    )
    .await;
    // One process all along: audio_io was never restarted.
    assert_eq!(
        launch.lines.count(|l| l.contains("started audio_io")),
        1,
        "audio_io was restarted:\n{}",
        launch.lines.all().join("\n")
    );
}

/// Once the graph is up, `lose` the microphone: the robot says it cannot hear, `audio_io` logs
/// and counts it; then `restore` it: the robot says it hears again, `audio_io` logs it and
/// captures again.
async fn lost_and_back(
    server: &mut SoundServer,
    launch: &Launch,
    bus: &Bus,
    lose: impl FnOnce(&mut SoundServer),
    restore: impl FnOnce(&mut SoundServer),
) {
    let said = bus.subscriber(&topics::SPEECH_SAY).await.unwrap();
    let diagnostics = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    // The dialog has seen the recognizer and the microphone (it says nothing until it has).
    tokio::time::sleep(Duration::from_secs(2)).await;

    lose(server);
    let line = next_line(&said, Duration::from_secs(15)).await;
    assert_eq!(line, "I can't hear you for a moment. Please wait.");
    launch
        .lines
        .wait_for("lost logged", Duration::from_secs(5), |l| {
            l.contains("lost the microphone \"mic\"")
        });
    let lost = diagnostics_until(&diagnostics, |d| {
        d.component == "audio_io" && d.get("microphone_lost") == 1
    })
    .await;

    restore(server);
    let line = next_line(&said, Duration::from_secs(15)).await;
    assert_eq!(line, "I can hear you again.");
    launch
        .lines
        .wait_for("back logged", Duration::from_secs(5), |l| {
            l.contains("the microphone \"mic\" is back")
        });
    // And it captures again (50 chunks are a second).
    let at_loss = lost.get("capture_chunks");
    diagnostics_until(&diagnostics, |d| {
        d.component == "audio_io" && d.get("capture_chunks") >= at_loss + 50
    })
    .await;
}

/// The launcher stops the recognizer before the dialog (it depends on the dialog, as in the
/// games' manifests); the dialog sees it go, and says nothing: the graph is stopping, nothing
/// failed. (Without the launcher's word that the graph stops, the robot told the person it
/// could not hear her as every game ended.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_graph_that_stops_does_not_tell_the_person_it_cannot_hear() {
    let ns = unique_namespace("voicestop");
    let dir = scratch(&ns);
    let m = dir.join("voice.toml");
    std::fs::write(&m, manifest()).unwrap();
    let mut launch = Launch::start(&m, &ns, &[]);
    for who in ["dialogs", "speech_generator", "speech_recognition"] {
        launch.lines.wait_for(who, Duration::from_secs(30), |l| {
            l.contains(&format!("{who} is up"))
        });
    }
    let bus = Bus::open(&launch.connect_args(), "test-voice")
        .await
        .unwrap();
    let said = bus.subscriber(&topics::SPEECH_SAY).await.unwrap();
    // The dialog has seen the recognizer (it never speaks of one it never saw).
    tokio::time::sleep(Duration::from_secs(1)).await;

    launch.sigterm();
    let status = launch.wait_exit(Duration::from_secs(40));
    assert!(
        status.success(),
        "{status}:\n{}",
        launch.lines.all().join("\n")
    );
    let mut lines = Vec::new();
    while let Ok(Ok(r)) = tokio::time::timeout(Duration::from_millis(300), said.recv()).await {
        lines.push(r.text);
    }
    assert!(
        lines.is_empty(),
        "the robot said {lines:?} as the graph stopped:\n{}",
        launch.lines.all().join("\n")
    );
    // Nothing went wrong: a stop logs no error, in the launcher or in a component.
    let all = launch.lines.all();
    assert!(
        !all.iter().any(|l| l.contains(" ERROR ")),
        "an error logged as the graph stopped:\n{}",
        all.join("\n")
    );
}

/// The next thing the robot is asked to say, within `timeout`.
async fn next_line(said: &interfaces::Subscriber<SayRequest>, timeout: Duration) -> String {
    tokio::time::timeout(timeout, said.recv())
        .await
        .unwrap_or_else(|_| panic!("the robot said nothing within {timeout:?}"))
        .unwrap()
        .text
}
