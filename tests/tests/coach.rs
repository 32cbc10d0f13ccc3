#![allow(clippy::unwrap_used, clippy::expect_used)] // a test fails by panicking
//! The Nao coach game end to end (launch/nao_coach.toml): the simulated SPL field, the bridge,
//! the Executive's coach machine and the speech stack as separate processes, on real UDP
//! (loopback) and a fresh namespace, the field time-scaled.
//!
//! One scripted 90 s attempt (simulated time, twice as fast as real time):
//!
//! 1. READY: "stop" by voice (audio on `audio/in`, through the recognizer and the dialog) is
//!    answered and reaches the robot (standing is no motion, so it is allowed before PLAYING).
//! 2. SET: "ask for the ball" by voice is refused, the refusal spoken, and kept.
//! 3. PLAYING: the kept command is done; the teammate passes to the controlled robot (pass 1).
//! 4. A kick aimed at our own goal is refused, and nothing reaches the robot.
//! 5. A dribble from the bus; the controlled robot falls (SIGUSR1 to the field): when it is up,
//!    the dribble resumes (sent again).
//! 6. The teammate falls (SIGUSR2): a pass becomes a dribble, said so.
//! 7. A pass from the bus: the robot passes to the teammate, who scores.
//!
//! Then a lost link and a penalty; push-to-talk (only what is said while the operator holds the
//! talk key is heard); and the faults: in each test one component of the graph is
//! killed (SIGKILL) in the middle of an attempt (see "Faults" below).
//!
//! Needs the workspace's binaries built and `espeak-ng` installed.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::command::Answer;
use interfaces::msg::nao::{
    CoachRequest, CoachStatus, FieldPoint, FieldTruth, GameState, NaoBody, NaoCommand, NaoHead,
    NaoWorldModel,
};
use interfaces::msg::speech::{AudioChunk, SayRequest, SpeakingEvent, SpeakingState};
use interfaces::{Bus, Topic, topics};
use robocog_tests::*;
use std::time::{Duration, Instant};

/// `text` spoken by espeak-ng (en-us, 160 wpm), resampled to 16 kHz, between 0.6 s and 0.8 s of
/// faint white noise (about 30 dB below the speech).
fn spoken(text: &str) -> Vec<i16> {
    let out = std::process::Command::new("espeak-ng")
        .args(["-v", "en-us", "-s", "160", "--stdout", text])
        .output()
        .expect("espeak-ng runs");
    assert!(out.status.success() && out.stdout.len() > 44);
    let rate = u32::from_le_bytes(out.stdout[24..28].try_into().unwrap()) as f64;
    let pcm: Vec<f64> = out.stdout[44..]
        .chunks_exact(2)
        .map(|b| i16::from_le_bytes([b[0], b[1]]) as f64)
        .collect();
    // Linear resampling to 16 kHz.
    let n = (pcm.len() as f64 * 16000.0 / rate) as usize;
    let speech: Vec<f64> = (0..n)
        .map(|i| {
            let x = i as f64 * rate / 16000.0;
            let k = x.floor() as usize;
            let f = x - k as f64;
            let a = pcm.get(k).copied().unwrap_or(0.0);
            let b = pcm.get(k + 1).copied().unwrap_or(a);
            a + (b - a) * f
        })
        .collect();
    let rms = (speech.iter().map(|s| s * s).sum::<f64>() / speech.len().max(1) as f64).sqrt();
    let amp = rms * 10f64.powf(-30.0 / 20.0) * 3f64.sqrt();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut noise = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        ((seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * amp
    };
    let mut out = Vec::new();
    out.extend((0..9600).map(|_| noise()));
    out.extend(speech.iter().map(|s| s + noise()));
    out.extend((0..12800).map(|_| noise()));
    out.into_iter()
        .map(|s| s.round().clamp(-32768.0, 32767.0) as i16)
        .collect()
}

async fn say_into_the_microphone(audio: &interfaces::Publisher<AudioChunk>, text: &str) {
    for chunk in spoken(text).chunks(1600) {
        audio
            .publish(&mut AudioChunk::mono(16000, chunk))
            .await
            .unwrap();
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// Waits until the robot has said everything asked so far: the dialog ignores what it hears
/// while the robot speaks (its own voice), and for half a second after.
async fn wait_until_quiet(says: &Log<SayRequest>, speaking: &Log<SpeakingEvent>) {
    if let Some(last) = says.last() {
        speaking
            .wait_from(
                "the robot to finish speaking",
                0,
                Duration::from_secs(30),
                |e| {
                    e.id == last.id
                        && e.text == last.text
                        && !matches!(e.state, SpeakingState::Queued | SpeakingState::Started)
                },
            )
            .await;
    }
    tokio::time::sleep(Duration::from_millis(700)).await;
}

/// `launch/nao_coach.toml` in namespace `ns` on free UDP ports, without the panel and without
/// random falls, plus `sets` (`var=value`); returns once each of `components` is up.
fn launch_coach(ns: &str, sets: &[String], components: &[&str]) -> Launch {
    let manifest =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/nao_coach.toml");
    let (debug, gc, cmd) = (free_udp_port(), free_udp_port(), free_udp_port());
    let base = [
        format!("debug_port={debug}"),
        format!("gc_port={gc}"),
        format!("command_port={cmd}"),
        "panel=false".into(),
        "falls_per_min=0".into(),
    ];
    let mut extra = Vec::new();
    for s in base.iter().chain(sets) {
        extra.push("--set");
        extra.push(s.as_str());
    }
    let launch = Launch::start(&manifest, ns, &extra);
    for who in components {
        launch.lines.wait_for(who, Duration::from_secs(40), |l| {
            l.contains(&format!("{who} is up"))
        });
    }
    launch
}

/// Answers yes on `game/answer`, as from the panel, to every "Did you say ...?" in `says`, in
/// the background.
fn answer_yes_to_questions(says: &Log<SayRequest>, answers: interfaces::Publisher<Answer>) {
    let says = says.0.clone();
    tokio::spawn(async move {
        let mut seen = 0;
        loop {
            let asks: Vec<_> = says.lock().unwrap().iter().skip(seen).cloned().collect();
            seen += asks.len();
            for a in asks {
                if a.text.to_lowercase().contains("did you say") {
                    let _ = answers
                        .publish(&mut Answer {
                            yes: true,
                            ..Default::default()
                        })
                        .await;
                }
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    });
}

fn said(log: &Log<SayRequest>) -> Vec<String> {
    log.all().into_iter().map(|s| s.text).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_scripted_attempt_with_voice_and_bus_commands() {
    let ns = unique_namespace("coach");
    let launch = launch_coach(
        &ns,
        &[
            "time_scale=2".into(),
            // 10 s of INITIAL, READY and SET each (5 s of real time each).
            "pre_game_s=30".into(),
            // The opponents stand still (obstacles only) unless ROBOCOG_COACH_OPPONENTS=active:
            // with them playing, the defender often takes the ball, and the goal is not reliable.
            format!(
                "passive_opponents={}",
                std::env::var("ROBOCOG_COACH_OPPONENTS").map_or(true, |v| v != "active")
            ),
        ],
        &["nao_bridge", "executive", "speech_recognition", "dialogs"],
    );
    let bus = Bus::open(&launch.connect_args(), "test-coach")
        .await
        .unwrap();
    let truth = Log::<FieldTruth>::follow(&bus, &topics::SIM_FIELD_TRUTH).await;
    let says = Log::<SayRequest>::follow(&bus, &topics::SPEECH_SAY).await;
    let games = Log::<GameState>::follow(&bus, &topics::NAO_GAME_STATE).await;
    let worlds = Log::<NaoWorldModel>::follow(&bus, &topics::NAO_WORLD_MODEL).await;
    let sent = Log::<NaoCommand>::follow(&bus, &topics::NAO_COMMAND).await;
    let transitions = Log::<interfaces::msg::executive::StateTransition>::follow(
        &bus,
        &topics::EXECUTIVE_TRANSITIONS,
    )
    .await;
    let heard =
        Log::<interfaces::msg::speech::Utterance>::follow(&bus, &topics::SPEECH_UTTERANCE).await;
    let voice_commands =
        Log::<interfaces::msg::command::GameCommand>::follow(&bus, &topics::GAME_COMMAND).await;
    let speaking = Log::<SpeakingEvent>::follow(&bus, &topics::SPEECH_SPEAKING).await;
    let requests = bus.publisher(&topics::COACH_REQUEST).await.unwrap();
    let audio = bus.publisher(&topics::AUDIO_IN).await.unwrap();
    let answers = bus.publisher(&topics::GAME_ANSWER).await.unwrap();
    // The dialog may ask "Did you say ...?": the test answers yes from the panel.
    answer_yes_to_questions(&says, answers);
    let field = eventually("field pid", Duration::from_secs(10), || {
        component_pid(&launch, "spl_field")
    });
    let t = Duration::from_secs(15);
    let state_is = |s: u8| move |g: &GameState| g.state == s;

    // 1. Before PLAYING, "stop" by voice: a warm-up for the recognizer, and no motion.
    games
        .wait_from("a GameController state", 0, t, |_| true)
        .await;
    let m = says.len();
    say_into_the_microphone(&audio, "stop").await;
    says.wait_from("the answer to stop", m, t, |s| s.text == "Stopping.")
        .await;
    truth
        .wait_from("Stop at the robot", 0, t, |f| {
            f.last_command.first() == Some(&10.0)
        })
        .await;

    // 2. SET: "ask for the ball" by voice is a motion command: refused, the refusal spoken,
    // nothing sent, the request kept.
    games
        .wait_from("SET", 0, Duration::from_secs(30), state_is(2))
        .await;
    wait_until_quiet(&says, &speaking).await;
    let before = truth.last().unwrap().commands_received;
    let m = says.len();
    let v = voice_commands.len();
    say_into_the_microphone(&audio, "ask for the ball").await;
    voice_commands
        .wait_from("ask for the ball from the dialog", v, t, |c| {
            c.command == interfaces::msg::command::Command::AskForBall
        })
        .await;
    let refusal = says
        .wait_from("the refusal in SET", m, t, |s| s.text.contains("SET"))
        .await;
    assert_eq!(
        refusal.text,
        "I cannot ask for the ball now: the game is in SET. I will do it when we play."
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        truth.last().unwrap().commands_received,
        before,
        "sent in SET"
    );
    assert_eq!(
        games.last().unwrap().state,
        2,
        "SET was over before the refusal"
    );

    // 3. PLAYING: the kept request is done; the teammate passes to the controlled robot.
    let m = says.len();
    truth
        .wait_from("PLAYING", 0, Duration::from_secs(30), |f| f.game_state == 3)
        .await;
    says.wait_from("the kept command", m, t, |s| {
        s.text == "We are playing. Asking my teammate for the ball."
    })
    .await;
    // The machine's live configuration can be queried.
    let config = bus
        .call(
            &topics::EXECUTIVE_CONFIGURATION,
            &interfaces::msg::executive::ConfigurationRequest::default(),
            Duration::from_secs(2),
        )
        .await
        .unwrap();
    assert_eq!(config.machine, "coach");
    assert!(
        config.active.iter().any(|a| a == "coach/playing"),
        "{config:?}"
    );
    assert!(
        config.step > 1 && config.mermaid.contains("stateDiagram"),
        "{config:?}"
    );
    truth
        .wait_from("AskForTheBall at the robot", 0, t, |f| {
            f.last_command.first() == Some(&7.0)
        })
        .await;
    let first_pass = truth
        .wait_from("the teammate's pass", 0, Duration::from_secs(20), |f| {
            f.passes >= 1
        })
        .await;
    println!(
        "pass 1 completed at t = {:.1} s (simulated), score {}",
        first_pass.time_s, first_pass.score
    );

    // 4. A kick aimed at our own goal is refused; nothing reaches the robot.
    let m = says.len();
    let c = truth.last().unwrap().commands_received;
    let n = sent.len();
    requests
        .publish(&mut CoachRequest {
            command: NaoCommand {
                body: NaoBody::Kick,
                source: "test".into(),
                ..Default::default()
            },
            aimed: true,
            aim: FieldPoint {
                x_mm: -4500.0,
                y_mm: 0.0,
            },
            ..Default::default()
        })
        .await
        .unwrap();
    says.wait_from("the own-goal refusal", m, t, |s| {
        s.text == "I will not kick towards our own goal."
    })
    .await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(sent.len(), n, "a command was sent: {:?}", sent.all());
    assert_eq!(truth.last().unwrap().commands_received, c);

    // 5. "go to the ball and dribble" from the bus; the controlled robot falls; when it is up,
    // the dribble is sent again.
    let m = says.len();
    requests
        .publish(&mut CoachRequest {
            command: NaoCommand {
                body: NaoBody::GoToBallAndDribble,
                source: "test".into(),
                ..Default::default()
            },
            ..Default::default()
        })
        .await
        .unwrap();
    says.wait_from("the dribble", m, t, |s| {
        s.text == "Going to the ball to dribble."
    })
    .await;
    truth
        .wait_from("the dribble at the robot", 0, t, |f| {
            f.controlled_body == "GoToBallAndDribble"
        })
        .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let m = says.len();
    let c = truth.last().unwrap().commands_received;
    signal(field, "USR1");
    says.wait_from("the fall", m, t, |s| {
        s.text == "I fell. I will get up and carry on."
    })
    .await;
    says.wait_from("the resume", m, t, |s| {
        s.text == "I am up again. Resuming. Going to the ball to dribble."
    })
    .await;
    let resumed = truth
        .wait_from("the resumed dribble at the robot", 0, t, |f| {
            f.commands_received > c && f.last_command.first() == Some(&3.0)
        })
        .await;
    assert_eq!(resumed.controlled_body, "GoToBallAndDribble");

    // 6. The teammate falls: a pass becomes a dribble, and the robot says why.
    let w = worlds.len();
    signal(field, "USR2");
    worlds
        .wait_from("the teammate down", w, t, |w| {
            w.robots.iter().any(|r| r.player_number == 1 && r.fallen)
        })
        .await;
    let m = says.len();
    let c = truth.last().unwrap().commands_received;
    requests
        .publish(&mut CoachRequest {
            command: NaoCommand {
                body: NaoBody::Pass,
                source: "test".into(),
                ..Default::default()
            },
            ..Default::default()
        })
        .await
        .unwrap();
    says.wait_from("the dribble explained", m, t, |s| {
        s.text == "I see no teammate to pass to: I will go to the ball and dribble."
    })
    .await;
    truth
        .wait_from("the dribble at the robot", 0, t, |f| {
            f.commands_received > c && f.controlled_body == "GoToBallAndDribble"
        })
        .await;

    // 7. A pass from the bus once the teammate is up again: the robot passes, and the
    // autonomous teammate scores. A goal is 2 points, a pass 1; the controlled robot's own
    // goals do not count, so score - passes >= 2 means the teammate scored.
    let w = worlds.len();
    worlds
        .wait_from("the teammate up again", w, t, |w| {
            w.robots
                .iter()
                .any(|r| r.player_number == 1 && !r.fallen && r.age_s < 1.0)
        })
        .await;
    truth
        .wait_from("the ball at the controlled robot", 0, t, |f| {
            let d = (f.ball.x_mm - f.controlled.x_mm).hypot(f.ball.y_mm - f.controlled.y_mm);
            d < 400.0
        })
        .await;
    let m = says.len();
    let passes_before = truth.last().unwrap().passes;
    println!(
        "pass requested at t = {:.1} s",
        truth.last().unwrap().time_s
    );
    requests
        .publish(&mut CoachRequest {
            command: NaoCommand {
                body: NaoBody::Pass,
                source: "test".into(),
                ..Default::default()
            },
            ..Default::default()
        })
        .await
        .unwrap();
    says.wait_from("the answer to pass", m, t, |s| {
        s.text == "Passing to my teammate."
    })
    .await;
    truth
        .wait_from("Pass at the robot", 0, t, |f| {
            f.last_command.first() == Some(&6.0)
        })
        .await;
    let end = truth
        .wait_from("the goal", 0, Duration::from_secs(40), |f| {
            f.game_state == 4 || i32::from(f.score) - f.passes as i32 >= 2
        })
        .await;
    let last = truth.last().unwrap();
    for l in launch.lines.all() {
        if l.contains("spl_field") && l.contains(" t=") && !l.contains("Touch") {
            println!("{l}");
        }
    }
    println!(
        "end at t = {:.1} s: score {}, passes {} (before the last pass: {})",
        last.time_s, last.score, last.passes, passes_before
    );
    // The teammate's pass (step 3) counted; the controlled robot's pass back may be too short
    // to count (a pass must travel 1 m before the teammate touches it).
    assert!(last.passes >= 1, "no pass completed");
    assert!(
        i32::from(end.score) - end.passes as i32 >= 2,
        "no goal by the teammate: {end:?}"
    );

    // What the recognizer heard.
    let texts: Vec<String> = heard.all().into_iter().map(|u| u.text).collect();
    assert!(
        texts.iter().any(|t| t == "stop") && texts.iter().any(|t| t == "ask for the ball"),
        "{texts:?}"
    );

    // Every step of the machine was published, and the transcript reads right.
    let tr = transitions.all();
    assert!(tr.iter().all(|s| s.machine == "coach"));
    for ev in [
        "game:playing",
        "robot:fell",
        "robot:up",
        "request:pass",
        "request:kick",
    ] {
        assert!(tr.iter().any(|s| s.event == ev), "no {ev} step: {tr:?}");
    }
    assert!(tr.iter().any(|s| s.active == ["coach/robot_down"]));
    println!("said:\n  {}", said(&says).join("\n  "));
}

/// A lost link and a GameController penalty, on the same attempt (no voice; time 1:1):
///
/// 1. PLAYING: "go to the ball and dribble" from the bus reaches the robot.
/// 2. The field stops (SIGSTOP: no packet from either robot, the field's time stands still):
///    the bridge publishes "robot not responding", the machine goes to `coach/link_lost` and
///    says so; the field continues (SIGCONT): the dribble is resumed, said and sent again.
/// 3. The GameController penalises the controlled robot (scripted, 4 s into PLAYING, for 5 s):
///    the machine says so, refuses a motion command with the reason (kept), and when the
///    penalty is over does the kept command. (The teammate is knocked over meanwhile: alone
///    against passive opponents it would score and end the attempt first.)
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_lost_link_and_a_penalty_interrupt_and_resume_the_command() {
    use interfaces::msg::nao::{LinkChange, NaoLinkEvent};
    let ns = unique_namespace("coach-interrupt");
    let launch = launch_coach(
        &ns,
        &[
            "pre_game_s=6".into(),
            "passive_opponents=true".into(),
            "penalty_at_s=4".into(),
            "penalty_s=5".into(),
        ],
        &["nao_bridge", "executive"],
    );
    let bus = Bus::open(&launch.connect_args(), "test-coach-interrupt")
        .await
        .unwrap();
    let truth = Log::<FieldTruth>::follow(&bus, &topics::SIM_FIELD_TRUTH).await;
    let says = Log::<SayRequest>::follow(&bus, &topics::SPEECH_SAY).await;
    let links = Log::<NaoLinkEvent>::follow(&bus, &topics::NAO_LINK).await;
    let sent = Log::<NaoCommand>::follow(&bus, &topics::NAO_COMMAND).await;
    let statuses = Log::<CoachStatus>::follow(&bus, &topics::COACH_STATUS).await;
    let requests = bus.publisher(&topics::COACH_REQUEST).await.unwrap();
    let field = eventually("field pid", Duration::from_secs(10), || {
        component_pid(&launch, "spl_field")
    });
    let t = Duration::from_secs(15);
    let request = |body: NaoBody| CoachRequest {
        command: NaoCommand {
            body,
            source: "test".into(),
            ..Default::default()
        },
        ..Default::default()
    };
    let active = || async {
        bus.call(
            &topics::EXECUTIVE_CONFIGURATION,
            &interfaces::msg::executive::ConfigurationRequest::default(),
            Duration::from_secs(2),
        )
        .await
        .unwrap()
        .active
    };

    // 1. PLAYING: the dribble reaches the robot. (The Executive hears PLAYING from the
    // GameController, at 2 Hz, up to half a second after the field's truth says so.)
    statuses
        .wait_from(
            "the Executive in PLAYING",
            0,
            Duration::from_secs(30),
            |s| s.state == "coach/playing",
        )
        .await;
    let m = says.len();
    requests
        .publish(&mut request(NaoBody::GoToBallAndDribble))
        .await
        .unwrap();
    says.wait_from("the dribble", m, t, |s| {
        s.text == "Going to the ball to dribble."
    })
    .await;
    truth
        .wait_from("the dribble at the robot", 0, t, |f| {
            f.controlled_body == "GoToBallAndDribble"
        })
        .await;

    // 2. The link is lost, then back: the dribble is resumed.
    let (m, l) = (says.len(), links.len());
    let c = truth.last().unwrap().commands_received;
    signal(field, "STOP");
    let lost = links
        .wait_from("robot 2 not responding", l, t, |e| {
            e.player_number == 2 && e.change == LinkChange::RobotNotResponding
        })
        .await;
    assert!(lost.silent_for_s >= 1.0, "{lost:?}");
    says.wait_from("the lost link said", m, t, |s| {
        s.text == "The robot is not responding."
    })
    .await;
    let state = active().await;
    assert!(state.iter().any(|a| a == "coach/link_lost"), "{state:?}");
    let n = sent.len();
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(sent.len(), n, "sent to a robot that does not answer");
    signal(field, "CONT");
    links
        .wait_from("robot 2 back", l, t, |e| {
            e.player_number == 2 && e.change == LinkChange::Restored
        })
        .await;
    says.wait_from("the link back and the resume said", m, t, |s| {
        s.text == "The robot is responding again. Resuming. Going to the ball to dribble."
    })
    .await;
    let resumed = truth
        .wait_from("the dribble sent again", 0, t, |f| f.commands_received > c)
        .await;
    assert_eq!(resumed.controlled_body, "GoToBallAndDribble");
    assert_eq!(resumed.last_command.first(), Some(&3.0));

    // 3. The penalty: said; a motion command refused with the reason and kept; done after.
    let m = says.len();
    says.wait_from("the penalty said", m, t, |s| s.text == "I am penalised.")
        .await;
    // The teammate, striker while the controlled robot is out, must not end the attempt with
    // a goal before the penalty is over: it falls (and is up after the penalty).
    signal(field, "USR2");
    let state = active().await;
    assert!(state.iter().any(|a| a == "coach/penalised"), "{state:?}");
    let c = truth.last().unwrap().commands_received;
    let m = says.len();
    requests
        .publish(&mut request(NaoBody::SearchTheBall))
        .await
        .unwrap();
    let refusal = says
        .wait_from("the refusal", m, t, |s| s.text.contains("penalised"))
        .await;
    assert_eq!(
        refusal.text,
        "I cannot search for the ball now: I am penalised. I will do it when I am back."
    );
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        truth.last().unwrap().commands_received,
        c,
        "sent while penalised"
    );
    let over = says
        .wait_from("the end of the penalty", m, t, |s| {
            s.text.starts_with("My penalty is over.")
        })
        .await;
    println!("after the penalty: {:?}", over.text);
    truth
        .wait_from("the kept command at the robot", 0, t, |f| {
            f.commands_received > c && f.controlled_body == "SearchTheBall"
        })
        .await;
    println!("said:\n  {}", said(&says).join("\n  "));
}

// ----- Faults: a component killed in the middle of a game (issue 19, items 1 and 4) ---------
//
// Each test plays a short attempt (the field twice as fast as real time, the opponents and our
// autonomous teammate standing still, so nothing ends it early), kills (SIGKILL) one component
// of the coach graph at a moment that matters, and checks that the launcher restarted it, that
// every command the coach gave after the kill reached the robot as asked (`sim/field_truth`:
// what the robot took) with its answer said once (`speech/say`), and that no command had to be
// given twice: each is given once, and the robot took exactly those. `spl_field` is the robots
// and the field (hardware): a lost robot link is the SIGSTOP test above.

/// A coach graph under test, and what the test sees of it.
struct Attempt {
    launch: Launch,
    bus: Bus,
    truth: Log<FieldTruth>,
    says: Log<SayRequest>,
    speaking: Log<SpeakingEvent>,
    statuses: Log<CoachStatus>,
    requests: interfaces::Publisher<CoachRequest>,
    audio: interfaces::Publisher<AudioChunk>,
}

/// Every wait of the fault tests is bounded by this.
const T: Duration = Duration::from_secs(15);

/// Where the robot walks while a component is killed: about 3 m from its start (6 s of real
/// time at twice the speed).
const FAR: FieldPoint = FieldPoint {
    x_mm: -3000.0,
    y_mm: 1500.0,
};

impl Attempt {
    /// The coach graph with `sets`, twice as fast, nothing that ends the attempt early; the
    /// test answers "yes" to any "Did you say ...?".
    async fn start(tag: &str, sets: &[&str]) -> Attempt {
        let ns = unique_namespace(tag);
        let mut all: Vec<String> = [
            "time_scale=2",
            "passive_opponents=true",
            "passive_teammate=true",
        ]
        .iter()
        .chain(sets)
        .map(|s| s.to_string())
        .collect();
        if !sets.iter().any(|s| s.starts_with("pre_game_s=")) {
            all.push("pre_game_s=4".into());
        }
        // The speech components are waited for when the coach first speaks ([`Self::speak`]):
        // on a busy machine the recognizer's model takes seconds to load, and the game goes on.
        let mut up = vec!["nao_bridge", "executive"];
        if sets.contains(&"panel=true") {
            up.push("command_generator");
        }
        let launch = tokio::task::block_in_place(|| launch_coach(&ns, &all, &up));
        let bus = Bus::open(&launch.connect_args(), &format!("test-{tag}"))
            .await
            .unwrap();
        let attempt = Attempt {
            truth: Log::follow(&bus, &topics::SIM_FIELD_TRUTH).await,
            says: Log::follow(&bus, &topics::SPEECH_SAY).await,
            speaking: Log::follow(&bus, &topics::SPEECH_SPEAKING).await,
            statuses: Log::follow(&bus, &topics::COACH_STATUS).await,
            requests: bus.publisher(&topics::COACH_REQUEST).await.unwrap(),
            audio: bus.publisher(&topics::AUDIO_IN).await.unwrap(),
            launch,
            bus,
        };
        let answers = attempt.bus.publisher(&topics::GAME_ANSWER).await.unwrap();
        answer_yes_to_questions(&attempt.says, answers);
        attempt
    }

    /// Waits until the Executive knows the game is in `state` (and not penalised).
    async fn game_state(&self, state: u8, what: &str) {
        self.statuses
            .wait_from(what, 0, Duration::from_secs(30), |s| {
                s.game_known && s.game_state == state && !s.penalised
            })
            .await;
    }

    /// A coach request from the bus (the panel's topic).
    async fn request(&self, body: NaoBody, head: NaoHead, target: FieldPoint) {
        self.requests
            .publish(&mut CoachRequest {
                command: NaoCommand {
                    body,
                    head,
                    target,
                    source: "test".into(),
                    ..Default::default()
                },
                ..Default::default()
            })
            .await
            .unwrap();
    }

    async fn body(&self, body: NaoBody) {
        self.request(body, Default::default(), FieldPoint::default())
            .await;
    }

    /// `text` said into the microphone once the robot listens (the recognizer and the dialog
    /// are subscribed) and is quiet (the dialog does not listen to the robot's own voice).
    async fn speak(&self, text: &str) {
        self.listens().await;
        wait_until_quiet(&self.says, &self.speaking).await;
        say_into_the_microphone(&self.audio, text).await;
    }

    /// Waits until the recognizer hears the microphone and the dialog the recognizer.
    async fn listens(&self) {
        self.reads("speech_recognition", &topics::AUDIO_IN).await;
        self.reads("dialogs", &topics::SPEECH_UTTERANCE).await;
    }

    /// The robot's answer `text`, said after index `from` of `speech/say`.
    async fn answered(&self, from: usize, text: &str) {
        self.says
            .wait_from(&format!("the answer {text:?}"), from, T, |s| s.text == text)
            .await;
    }

    /// The robot took a command with `body` and `head` bytes (`sim/field_truth`), after `from`
    /// commands; returns how many it has taken.
    async fn took(&self, what: &str, from: u64, body: f32, head: f32) -> u64 {
        self.truth
            .wait_from(what, 0, T, |f| {
                f.commands_received > from
                    && f.last_command.first() == Some(&body)
                    && f.last_command.get(1) == Some(&head)
            })
            .await
            .commands_received
    }

    fn commands_taken(&self) -> u64 {
        self.truth.last().map_or(0, |f| f.commands_received)
    }

    /// The robot walks to [`FAR`] (answered and taken): the command under way.
    async fn walk_far(&self) -> u64 {
        let (m, c) = (self.says.len(), self.commands_taken());
        self.request(NaoBody::GoToPosition, Default::default(), FAR)
            .await;
        self.answered(m, "Going to the position.").await;
        self.took("GoToPosition at the robot", c, 1.0, 0.0).await
    }

    /// SIGKILL to `name`; returns once the launcher said it restarts it.
    fn kill(&self, name: &str) -> usize {
        let ups = self.ups(name);
        let pid = tokio::task::block_in_place(|| {
            eventually(&format!("{name}'s pid"), T, || {
                component_pid(&self.launch, name)
            })
        });
        self.kill_frozen(name, pid);
        ups
    }

    /// An attempt in PLAYING with the panel on a free port; returns it and the panel's address.
    async fn with_panel(tag: &str) -> (Attempt, String) {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let addr = format!("127.0.0.1:{port}");
        let listen = format!("panel_listen={addr}");
        let a = Attempt::start(tag, &["panel=true", &listen]).await;
        a.game_state(3, "PLAYING").await;
        (a, addr)
    }

    /// The robot walks to [`FAR`], asked from the page at `addr` (answered and taken).
    async fn walk_far_from_the_page(&self, addr: &str) -> u64 {
        let (m, c) = (self.says.len(), self.commands_taken());
        panel_command(
            addr,
            r#"{"type":"nao","body":"GoToPosition","target":{"x_mm":-3000,"y_mm":1500}}"#,
        )
        .await;
        self.answered(m, "Going to the position.").await;
        self.took("GoToPosition at the robot", c, 1.0, 0.0).await
    }

    /// SIGSTOP to `name`: alive on the bus (its tokens stay), acting on nothing. Returns its
    /// pid and its starts so far.
    fn freeze(&self, name: &str) -> (u32, usize) {
        let ups = self.ups(name);
        let pid = tokio::task::block_in_place(|| {
            eventually(&format!("{name}'s pid"), T, || {
                component_pid(&self.launch, name)
            })
        });
        signal(pid, "STOP");
        (pid, ups)
    }

    /// SIGKILL to `name`, frozen as `pid`; returns once the launcher said it restarts it.
    fn kill_frozen(&self, name: &str, pid: u32) {
        signal(pid, "KILL");
        tokio::task::block_in_place(|| {
            self.launch
                .lines
                .wait_for(&format!("{name} restarted"), T, |l| {
                    l.contains(&format!("{name} stopped")) && l.contains("restart 1/")
                })
        });
    }

    fn ups(&self, name: &str) -> usize {
        self.launch
            .lines
            .count(|l| l.contains(&format!("robocog | {name} is up")))
    }

    /// Waits until `name` is up again (after `ups` starts).
    fn back(&self, name: &str, ups: usize) {
        tokio::task::block_in_place(|| {
            self.launch
                .lines
                .wait_until(&format!("{name} up again"), T, |lines| {
                    lines
                        .iter()
                        .filter(|l| l.contains(&format!("robocog | {name} is up")))
                        .count()
                        > ups
                })
        });
    }

    /// Waits until component `name` subscribes to `topic` (at most 40 s: a speech model loading
    /// on a busy machine).
    async fn reads<M: interfaces::Message>(&self, name: &str, topic: &Topic<M>) {
        let readers = interfaces::liveliness::Readers::watch(&self.bus, topic)
            .await
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(40);
        while !readers.now().contains(name) {
            assert!(
                Instant::now() < deadline,
                "{name} did not subscribe to {} again",
                topic.name()
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// How often `text` was said from index `from` on.
    fn said_count(&self, from: usize, text: &str) -> usize {
        self.says
            .all()
            .iter()
            .skip(from)
            .filter(|s| s.text == text)
            .count()
    }

    fn transcript(&self) -> String {
        said(&self.says).join("\n  ")
    }

    /// The two commands every fault test gives after the kill, each once: "look left" (`how`),
    /// then "stop" from the bus. Both reach the robot, each answer is said once, and the robot
    /// takes exactly these two commands after `taken`.
    async fn look_left_then_stop(&self, taken: u64, how: How<'_>) {
        let m = self.says.len();
        match how {
            How::Voice => self.speak("look left").await,
            How::VoiceAfter(pause) => {
                self.listens().await;
                tokio::time::sleep(pause).await;
                say_into_the_microphone(&self.audio, "look left").await;
            }
            How::Panel(addr) => {
                panel_command(
                    addr,
                    r#"{"type":"command","game":"coach","command":"LookLeft"}"#,
                )
                .await
            }
            How::Bus => {
                self.request(NaoBody::Keep, NaoHead::LookLeft, FieldPoint::default())
                    .await
            }
        }
        self.answered(m, "Looking left.").await;
        let n = self.took("LookLeft at the robot", taken, 0.0, 3.0).await;
        assert_eq!(
            n,
            taken + 1,
            "the robot took other commands: {}",
            self.transcript()
        );
        let m2 = self.says.len();
        self.body(NaoBody::Stop).await;
        self.answered(m2, "Stopping.").await;
        let n = self.took("Stop at the robot", n, 10.0, 0.0).await;
        assert_eq!(
            n,
            taken + 2,
            "the robot took other commands: {}",
            self.transcript()
        );
        self.truth
            .wait_from("the robot standing", 0, T, |f| f.controlled_body == "Stop")
            .await;
        tokio::time::sleep(Duration::from_millis(300)).await;
        assert_eq!(self.commands_taken(), taken + 2);
        for text in ["Looking left.", "Stopping."] {
            assert_eq!(
                self.said_count(m, text),
                1,
                "{text:?} not said once:\n  {}",
                self.transcript()
            );
        }
        assert_eq!(
            self.said_count(0, "Sorry, I could not do that. Please say it again."),
            0,
            "a command was dropped:\n  {}",
            self.transcript()
        );
    }
}

/// How the coach says "look left".
enum How<'a> {
    /// By voice, once the robot is quiet.
    Voice,
    /// By voice, after this pause (when the robot's last sentence never ends).
    VoiceAfter(Duration),
    /// On the panel at this address.
    Panel(&'a str),
    /// From the bus, at once.
    Bus,
}

/// One command sent to the panel's WebSocket at `addr` (a page's request), as a browser sends it.
async fn panel_command(addr: &str, json: &str) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    // A panel that was just restarted may not listen yet: the page tries again (nothing sent).
    let deadline = Instant::now() + T;
    let mut s = loop {
        match tokio::net::TcpStream::connect(addr).await {
            Ok(s) => break s,
            Err(e) => {
                assert!(
                    Instant::now() < deadline,
                    "the panel at {addr} refuses: {e}"
                );
                tokio::time::sleep(Duration::from_millis(100)).await;
            }
        }
    };
    let upgrade = format!(
        "GET /ws HTTP/1.1\r\nHost: {addr}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    );
    s.write_all(upgrade.as_bytes()).await.unwrap();
    let mut head = Vec::new();
    let mut b = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        tokio::time::timeout(T, s.read_exact(&mut b))
            .await
            .expect("the panel's answer")
            .unwrap();
        head.push(b[0]);
    }
    assert!(
        head.starts_with(b"HTTP/1.1 101"),
        "{}",
        String::from_utf8_lossy(&head)
    );
    // One masked text frame (a client's frames are masked).
    let payload = json.as_bytes();
    assert!(payload.len() < 126);
    let mask = [0x5a, 0x17, 0xc3, 0x08];
    let mut frame = vec![0x81, 0x80 | payload.len() as u8];
    frame.extend(mask);
    frame.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
    s.write_all(&frame).await.unwrap();
    // Read what the panel sends for a moment (its reply among the states), then close.
    let mut sink = vec![0u8; 65536];
    let _ = tokio::time::timeout(Duration::from_millis(500), async {
        while s.read(&mut sink).await.is_ok_and(|n| n > 0) {}
    })
    .await;
    let _ = s.write_all(&[0x88, 0x80, 0, 0, 0, 0]).await;
}

/// Asserts the launcher restarted `name` once.
fn restarted_once(a: &Attempt, name: &str) {
    let out = a.launch.lines.all();
    let restarts = out
        .iter()
        .filter(|l| l.contains(&format!("{name} stopped")) && l.contains("restart "))
        .count();
    assert_eq!(restarts, 1, "{name} restarts:\n{}", out.join("\n"));
}

/// An attempt in PLAYING with the robot walking to [`FAR`], and `name` killed (SIGKILL) and
/// being restarted by the launcher: the attempt, the commands the robot took before the kill,
/// and `name`'s starts before it.
async fn killed_while_walking(name: &str) -> (Attempt, u64, usize) {
    let a = Attempt::start(&format!("coach-kill-{name}"), &[]).await;
    a.game_state(3, "PLAYING").await;
    a.listens().await;
    a.walk_far().await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let taken = a.commands_taken();
    let ups = a.kill(name);
    (a, taken, ups)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_speech_recognition_is_restarted_and_the_coach_is_heard() {
    let name = "speech_recognition";
    let (a, taken, ups) = killed_while_walking(name).await;
    // The dialog tells the coach it cannot hear her, then that it can.
    a.answered(0, "I can't hear you for a moment. Please wait.")
        .await;
    a.back(name, ups);
    a.reads(name, &topics::AUDIO_IN).await;
    a.answered(0, "I can hear you again.").await;
    a.look_left_then_stop(taken, How::Voice).await;
    restarted_once(&a, name);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_dialog_is_restarted_and_the_coach_is_heard() {
    let name = "dialogs";
    let (a, taken, ups) = killed_while_walking(name).await;
    a.back(name, ups);
    a.reads(name, &topics::SPEECH_UTTERANCE).await;
    a.look_left_then_stop(taken, How::Voice).await;
    restarted_once(&a, name);
}

/// The world model killed while the robot walks: restarted, it serves the field again, and
/// the bridge's mirror goes on into it: the controlled robot's node follows the robot sent
/// back to its start.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_world_model_is_restarted_and_mirrors_the_field_again() {
    use interfaces::msg::dr::TransformRequest;
    let name = "deep_representation";
    let (a, taken, ups) = killed_while_walking(name).await;
    a.back(name, ups);
    let m = a.says.len();
    let home = FieldPoint::new(-1500.0, -1200.0);
    a.request(NaoBody::GoToPosition, NaoHead::Keep, home).await;
    a.answered(m, "Going to the position.").await;
    let taken = a.took("the walk home at the robot", taken, 1.0, 0.0).await;
    let from = a.truth.last().unwrap().controlled;
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let req = TransformRequest {
            target: "field".into(),
            source: "nao_2".into(),
            ..Default::default()
        };
        let dr = a
            .bus
            .call(&topics::DR_TRANSFORM, &req, Duration::from_secs(1))
            .await;
        let truth = a.truth.last().unwrap().controlled;
        let moved = (truth.x_mm - from.x_mm).hypot(truth.y_mm - from.y_mm);
        if let Ok(r) = &dr {
            let [x, y, _] = r.transform.translation_m;
            let off =
                (x * 1000.0 - f64::from(truth.x_mm)).hypot(y * 1000.0 - f64::from(truth.y_mm));
            if off < 300.0 && moved > 300.0 {
                println!(
                    "the restarted DR's nao_2 is {off:.0} mm from the robot, {moved:.0} mm on"
                );
                break;
            }
        }
        assert!(
            Instant::now() < deadline,
            "the restarted DR does not follow the robot: {dr:?}, truth {truth:?}, from {from:?}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    a.look_left_then_stop(taken, How::Voice).await;
    restarted_once(&a, name);
}

/// The speech generator killed in the middle of a sentence (the answer to the walk): restarted,
/// it speaks again, and the dialog, which took the robot as speaking, listens again (the
/// sentence counts as spoken for its audio's length at most).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_speech_generator_killed_mid_sentence_is_restarted_and_the_coach_is_heard() {
    let name = "speech_generator";
    let a = Attempt::start("coach-kill-speech-generator", &[]).await;
    a.game_state(3, "PLAYING").await;
    let (m, e) = (a.says.len(), a.speaking.len());
    let c = a.commands_taken();
    a.request(NaoBody::GoToPosition, Default::default(), FAR)
        .await;
    a.answered(m, "Going to the position.").await;
    a.speaking
        .wait_from("the answer spoken", e, T, |s| {
            s.text == "Going to the position." && s.state == SpeakingState::Started
        })
        .await;
    let ups = a.kill(name);
    let taken = a.took("GoToPosition at the robot", c, 1.0, 0.0).await;
    a.back(name, ups);
    a.reads(name, &topics::SPEECH_SAY).await;
    // The killed sentence never ends: the person waits about as long as it would have lasted
    // (1.5 s) and speaks.
    a.look_left_then_stop(taken, How::VoiceAfter(Duration::from_millis(2000)))
        .await;
    a.speaking
        .wait_from("the restarted generator speaking", e, T, |s| {
            s.text == "Stopping." && s.state == SpeakingState::Finished
        })
        .await;
    restarted_once(&a, name);
}

/// The bridge killed while the robot walks, and "look left" given from the bus at once, while
/// no bridge listens: the Executive answers, holds the command and sends it when the restarted
/// bridge subscribes (before, it went nowhere: the robot never got it); the robot, which keeps
/// its last command, walks on meanwhile.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_bridge_is_restarted_and_a_command_given_meanwhile_reaches_the_robot() {
    let name = "nao_bridge";
    let a = Attempt::start("coach-kill-bridge", &[]).await;
    a.game_state(3, "PLAYING").await;
    a.walk_far().await;
    // Clear of the Executive's resend window (a command published just before a bridge goes).
    tokio::time::sleep(Duration::from_millis(1000)).await;
    let taken = a.commands_taken();
    let ups = a.kill(name);
    a.look_left_then_stop(taken, How::Bus).await;
    assert!(a.ups(name) > ups);
    tokio::task::block_in_place(|| {
        a.launch
            .lines
            .wait_for("the command held for the bridge", T, |l| {
                l.contains("executive") && l.contains("held until a bridge listened")
            })
    });
    restarted_once(&a, name);
}

/// The panel killed while the robot walks: restarted on the same address, a page that opens it
/// again sends "look left", which reaches the robot.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_panel_is_restarted_and_takes_commands_again() {
    let name = "command_generator";
    let (a, addr) = Attempt::with_panel("coach-kill-panel").await;
    a.walk_far_from_the_page(&addr).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let taken = a.commands_taken();
    let ups = a.kill(name);
    a.back(name, ups);
    a.reads("executive", &topics::COACH_REQUEST).await;
    a.look_left_then_stop(taken, How::Panel(&addr)).await;
    restarted_once(&a, name);
}

/// The coach Executive killed (SIGKILL) at a moment of the attempt: restarted by the launcher,
/// it takes the game up from its state folder, says one line about it, and repeats nothing it
/// had said. Returns the index of `speech/say` at the kill.
async fn the_executive_killed(a: &Attempt) -> usize {
    let m = a.says.len();
    let ups = a.kill("executive");
    a.back("executive", ups);
    a.answered(m, "Sorry, I'm back.").await;
    // (The process's own log line may come through the launcher after its voice on the bus.)
    tokio::task::block_in_place(|| {
        a.launch
            .lines
            .wait_for("the restarted Executive taking the game up", T, |l| {
                l.contains("the Executive restarted: taking the game up again")
            })
    });
    m
}

/// What every Executive kill test ends with: one "Sorry, I'm back.", nothing said twice that
/// the coach did not ask twice (the answers in `once`), one restart.
fn checked_once(a: &Attempt, once: &[&str]) {
    for text in once.iter().chain(&["Sorry, I'm back."]) {
        assert_eq!(
            a.said_count(0, text),
            1,
            "{text:?} not said once:\n  {}",
            a.transcript()
        );
    }
    restarted_once(a, "executive");
    for l in a.launch.lines.all() {
        if l.contains("executive |") && (l.contains("[resumed]") || l.contains("game's state")) {
            println!("{l}");
        }
    }
    println!("said:\n  {}", a.transcript());
}

/// (a) A command under way in PLAYING: the robot walks to a point when the Executive is
/// killed. The restarted one does not send it again (the robot keeps it), knows it (its status
/// shows it, done once the robot is there), and carries out the next commands.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_coach_executive_takes_up_a_command_under_way() {
    let a = Attempt::start("coach-kill-exec-walking", &[]).await;
    a.game_state(3, "PLAYING").await;
    a.walk_far().await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let taken = a.commands_taken();
    let s = a.statuses.len();
    let m = the_executive_killed(&a).await;
    // The new process knows the walk, and sees it done; the robot got nothing again.
    let st = a
        .statuses
        .wait_from("the walk in the restarted Executive's status", s, T, |st| {
            st.has_last && st.last_command.body == NaoBody::GoToPosition
        })
        .await;
    assert_eq!(st.last_command.target, FAR);
    let arrived = a
        .truth
        .wait_from("the robot at the point", 0, Duration::from_secs(20), |f| {
            (f.controlled.x_mm - FAR.x_mm).hypot(f.controlled.y_mm - FAR.y_mm) < 400.0
        })
        .await;
    assert_eq!(arrived.commands_received, taken, "the walk was sent again");
    a.statuses
        .wait_from("the walk done", s, T, |st| st.has_last && st.last_done)
        .await;
    a.look_left_then_stop(taken, How::Voice).await;
    assert_eq!(a.said_count(m, "Going to the position."), 0);
    checked_once(&a, &["Going to the position."]);
}

/// (b) A command pending: "ask for the ball" in SET is refused and kept for PLAYING, and the
/// Executive is killed while it waits. The restarted one does it when the game plays, once,
/// and not before.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_coach_executive_keeps_a_command_for_playing() {
    // INITIAL, READY and SET 4 s each (real time): SET begins well after the graph is up.
    let a = Attempt::start("coach-kill-exec-pending", &["pre_game_s=24"]).await;
    a.game_state(2, "SET").await;
    let (m, taken) = (a.says.len(), a.commands_taken());
    a.body(NaoBody::AskForTheBall).await;
    let refusal = "I cannot ask for the ball now: the game is in SET. I will do it when we play.";
    a.answered(m, refusal).await;
    a.statuses
        .wait_from("the request kept", 0, T, |st| {
            st.has_pending && st.pending.body == NaoBody::AskForTheBall
        })
        .await;
    the_executive_killed(&a).await;
    let kept = "We are playing. Asking my teammate for the ball.";
    a.answered(m, kept).await;
    let took = a
        .truth
        .wait_from("AskForTheBall at the robot", 0, T, |f| {
            f.commands_received > taken
        })
        .await;
    assert_eq!(took.last_command.first(), Some(&7.0), "{took:?}");
    assert_eq!(took.game_state, 3, "sent before PLAYING");
    assert_eq!(took.commands_received, taken + 1);
    let taken = taken + 1;
    a.look_left_then_stop(taken, How::Voice).await;
    checked_once(&a, &[refusal, kept]);
}

/// (c) Penalised: the GameController penalises the robot, a search for the ball is refused
/// and kept, and the Executive is killed. The restarted one does not announce the penalty
/// again, and when it is over does the kept request, once.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_killed_coach_executive_while_penalised_carries_on_after_the_penalty() {
    // The penalty 4 s into PLAYING, for 14 s (simulated; 2 s and 7 s of real time). On a busy
    // machine the graph may be up only after it began: the test goes by the Executive's status.
    let a = Attempt::start(
        "coach-kill-exec-penalised",
        &["penalty_at_s=4", "penalty_s=14"],
    )
    .await;
    a.statuses
        .wait_from("the Executive penalised", 0, Duration::from_secs(30), |s| {
            s.state == "coach/penalised"
        })
        .await;
    let (m, taken) = (a.says.len(), a.commands_taken());
    a.body(NaoBody::SearchTheBall).await;
    let refusal = "I cannot search for the ball now: I am penalised. I will do it when I am back.";
    a.answered(m, refusal).await;
    let killed_at = the_executive_killed(&a).await;
    let over = "My penalty is over. Searching for the ball.";
    a.says
        .wait_from("the end of the penalty", m, Duration::from_secs(20), |s| {
            s.text == over
        })
        .await;
    let n = a.took("SearchTheBall at the robot", taken, 9.0, 0.0).await;
    assert_eq!(n, taken + 1, "{}", a.transcript());
    a.look_left_then_stop(n, How::Voice).await;
    assert_eq!(
        a.said_count(killed_at, "I am penalised."),
        0,
        "the penalty announced again:\n  {}",
        a.transcript()
    );
    checked_once(&a, &[refusal, over]);
}

/// (d) Commands the Executive never acted on. It is frozen (SIGSTOP) when the panel sends "look
/// left", which reaches its socket and not its game, then killed; "stop" is given on the panel
/// while it restarts. The panel sends the first again (its reader went just after it) and holds
/// the second; the restarted Executive carries out each once, in order, and not the walk it did
/// before the kill (sent again too when it was in the panel's resend window, and known by its
/// stamp).
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn panel_commands_the_executive_never_acted_on_are_carried_out_once_after_its_restart() {
    let (a, addr) = Attempt::with_panel("coach-exec-unacted").await;
    a.reads("executive", &topics::COACH_REQUEST).await;
    let m = a.says.len();
    let taken = a.walk_far_from_the_page(&addr).await;

    let (pid, ups) = a.freeze("executive");
    panel_command(
        &addr,
        r#"{"type":"command","game":"coach","command":"LookLeft"}"#,
    )
    .await;
    assert_eq!(
        a.said_count(m, "Looking left."),
        0,
        "a frozen Executive answered"
    );
    a.kill_frozen("executive", pid);
    panel_command(&addr, r#"{"type":"nao","body":"Stop"}"#).await;
    a.back("executive", ups);
    a.answered(m, "Sorry, I'm back.").await;
    a.answered(m, "Looking left.").await;
    a.answered(m, "Stopping.").await;
    a.truth
        .wait_from("the robot standing", 0, T, |f| {
            f.controlled_body == "Stop" && f.commands_received >= taken + 2
        })
        .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(
        a.commands_taken(),
        taken + 2,
        "the robot took other commands: {}",
        a.transcript()
    );
    checked_once(
        &a,
        &["Going to the position.", "Looking left.", "Stopping."],
    );
    for l in a.launch.lines.all() {
        if l.contains("command_generator |") && (l.contains("holding") || l.contains("again")) {
            println!("{l}");
        }
    }
}

/// Words the dialog never acted on: it is frozen (SIGSTOP) when the coach says "look left", which
/// the recognizer hears and sends to it, then killed. The recognizer sends the words again to the
/// restarted dialog (its reader went just after them), which carries the command out: the coach
/// does not repeat herself, and the robot takes it once.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn words_the_dialog_never_acted_on_are_carried_out_after_its_restart() {
    let name = "dialogs";
    let a = Attempt::start("coach-dialog-unacted", &[]).await;
    a.game_state(3, "PLAYING").await;
    a.listens().await;
    a.walk_far().await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let taken = a.commands_taken();
    let (pid, ups) = a.freeze(name);
    let m = a.says.len();
    a.speak("look left").await;
    tokio::task::block_in_place(|| {
        a.launch
            .lines
            .wait_for("the recognizer hearing \"look left\"", T, |l| {
                l.contains("speech_recognition |") && l.contains("heard \"look left\"")
            })
    });
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(a.said_count(m, "Looking left."), 0, "a frozen dialog acted");
    a.kill_frozen(name, pid);
    a.back(name, ups);
    a.answered(0, "Looking left.").await;
    let n = a.took("LookLeft at the robot", taken, 0.0, 3.0).await;
    assert_eq!(n, taken + 1, "{}", a.transcript());
    let m = a.says.len();
    a.body(NaoBody::Stop).await;
    a.answered(m, "Stopping.").await;
    a.took("Stop at the robot", n, 10.0, 0.0).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(a.commands_taken(), taken + 2, "{}", a.transcript());
    assert_eq!(a.said_count(0, "Looking left."), 1, "{}", a.transcript());
    restarted_once(&a, name);
    for l in a.launch.lines.all() {
        if l.contains("speech_recognition |") && (l.contains("again") || l.contains("holding")) {
            println!("{l}");
        }
    }
}

/// Push-to-talk, as in a RoboCup hall (`push_to_talk=true`): a command said while the operator
/// does not hold the talk key is the hall's talk, never decoded; the command she says while
/// holding it (the panel's key, sent again every half second, as the page does) is carried out.
#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn with_push_to_talk_only_what_is_said_while_the_key_is_held_is_heard() {
    use interfaces::msg::command::{Command, CommandSource, GameCommand};
    use interfaces::msg::speech::{TALK_KEY_REPEAT_S, TalkKey, Utterance};
    let ns = unique_namespace("talk");
    let launch = launch_coach(
        &ns,
        // The coach is an espeak-ng voice here: the model adapted on those voices hears her.
        &["push_to_talk=true".into(), "acoustic_model=adapted".into()],
        &["speech_recognition", "dialogs", "executive"],
    );
    launch
        .lines
        .wait_for("push-to-talk", Duration::from_secs(10), |l| {
            l.contains("speech_recognition |") && l.contains("push-to-talk: only what is heard")
        });
    let bus = Bus::open(&launch.connect_args(), "test-talk")
        .await
        .unwrap();
    let heard = Log::<Utterance>::follow(&bus, &topics::SPEECH_UTTERANCE).await;
    let commands = Log::<GameCommand>::follow(&bus, &topics::GAME_COMMAND).await;
    let says = Log::<SayRequest>::follow(&bus, &topics::SPEECH_SAY).await;
    let audio = bus.publisher(&topics::AUDIO_IN).await.unwrap();
    let talk = bus.publisher(&topics::SPEECH_TALK).await.unwrap();
    let answers = bus.publisher(&topics::GAME_ANSWER).await.unwrap();
    let key = |held: bool| TalkKey {
        held,
        source: "test".into(),
        ..TalkKey::default()
    };
    // A "Did you say ...?" is answered yes, as from the panel.
    answer_yes_to_questions(&says, answers);

    // Someone near the microphone says a command; nobody holds the key.
    say_into_the_microphone(&audio, Command::Kick.phrase()).await;

    // The operator holds the key (sent again while held), says hers, and lets go.
    let (stop, mut stopped) = tokio::sync::watch::channel(false);
    let holder = {
        let talk = bus.publisher(&topics::SPEECH_TALK).await.unwrap();
        let down = key(true);
        tokio::spawn(async move {
            loop {
                // Each a fresh copy: the bus stamps it with when it is sent.
                talk.publish(&mut down.clone()).await.unwrap();
                tokio::select! {
                    _ = tokio::time::sleep(Duration::from_secs_f64(TALK_KEY_REPEAT_S)) => {}
                    _ = stopped.changed() => return,
                }
            }
        })
    };
    launch
        .lines
        .wait_for("the key down", Duration::from_secs(10), |l| {
            l.contains("speech_recognition |") && l.contains("talk key down (test)")
        });
    say_into_the_microphone(&audio, Command::Pass.phrase()).await;
    stop.send(true).unwrap();
    holder.await.unwrap();
    talk.publish(&mut key(false)).await.unwrap();

    // Hers is heard.
    let pass = heard
        .wait_from("her command", 0, Duration::from_secs(30), |u| {
            u.command == Command::Pass
        })
        .await;
    commands
        .wait_from("her command carried out", 0, Duration::from_secs(30), |c| {
            c.command == Command::Pass && c.source == CommandSource::Voice
        })
        .await;
    launch
        .lines
        .wait_for("the key up", Duration::from_secs(10), |l| {
            l.contains("speech_recognition |") && l.contains("talk key up (test)")
        });
    // The audio is heard in order: by the time hers was decoded, the other command had been
    // heard too, and it opened no utterance at all.
    let utterances: Vec<(String, Command)> = heard
        .all()
        .iter()
        .map(|u| (u.text.clone(), u.command))
        .collect();
    assert_eq!(utterances.len(), 1, "heard {utterances:?} (hers: {pass:?})");
    assert!(
        commands.all().iter().all(|c| c.command != Command::Kick),
        "a command said without the key was carried out: {:?}",
        commands.all()
    );
}
