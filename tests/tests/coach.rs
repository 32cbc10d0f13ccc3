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
//! Needs the workspace's binaries built and `espeak-ng` installed.

use interfaces::msg::command::Answer;
use interfaces::msg::nao::{
    CoachRequest, FieldPoint, FieldTruth, GameState, NaoBody, NaoCommand, NaoWorldModel,
};
use interfaces::msg::speech::{AudioChunk, SayRequest, SpeakingEvent, SpeakingState};
use interfaces::{Bus, Message, Subscriber, Topic, topics};
use robocog_tests::*;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Everything received on a topic, drained in the background (subscriber queues are bounded).
struct Log<T>(Arc<Mutex<Vec<T>>>);

impl<T: Message + Clone + Send + std::fmt::Debug + 'static> Log<T> {
    async fn follow(bus: &Bus, topic: &Topic<T>) -> Log<T> {
        let sub: Subscriber<T> = bus.subscriber(topic).await.unwrap();
        let v = Arc::new(Mutex::new(Vec::new()));
        let w = v.clone();
        tokio::spawn(async move {
            while let Ok(m) = sub.recv().await {
                w.lock().unwrap().push(m);
            }
        });
        Log(v)
    }
    fn all(&self) -> Vec<T> {
        self.0.lock().unwrap().clone()
    }
    fn len(&self) -> usize {
        self.0.lock().unwrap().len()
    }
    fn last(&self) -> Option<T> {
        self.0.lock().unwrap().last().cloned()
    }
    /// The first message from index `from` on that satisfies `pred`, waiting at most `timeout`.
    async fn wait_from(
        &self,
        what: &str,
        from: usize,
        timeout: Duration,
        pred: impl Fn(&T) -> bool,
    ) -> T {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(m) = self.0.lock().unwrap().iter().skip(from).find(|m| pred(m)) {
                return m.clone();
            }
            if Instant::now() >= deadline {
                let tail = {
                    let v = self.0.lock().unwrap();
                    let tail: Vec<_> = v.iter().skip(v.len().saturating_sub(12)).collect();
                    format!("{tail:#?}")
                };
                panic!(
                    "timed out after {timeout:?} waiting for {what}; the last messages:\n{tail}"
                );
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
}

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
    {
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

    // 1. PLAYING: the dribble reaches the robot.
    truth
        .wait_from("PLAYING", 0, Duration::from_secs(30), |f| f.game_state == 3)
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
