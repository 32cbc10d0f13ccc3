#![allow(clippy::unwrap_used)]
//! A foreign client on the bus. Both games' graphs run as they ship; a client that is not a
//! robocog component publishes garbage, with the right encoding (`application/cdr;<type>`), on
//! every topic some component subscribes to, and sends garbage to every service, as a buggy
//! tool, an older build or a hostile process on the network would. Every payload is one the
//! codec must refuse: empty, shorter than the encapsulation header, another encapsulation, and a
//! good header whose first length field (the header's frame id) says 2^32-1 bytes.
//!
//! What a user needs: no component stops or restarts, each one counts what it dropped
//! (`decode_errors/<topic>` on `diagnostics`, so an operator sees where the garbage came in; a
//! latest-value subscription may drop some of it unread, counted in `queue_dropped/<topic>`),
//! every service answers `BadRequest` and goes on answering, and the game is still played: the
//! touch game's scenario completes with no repeated command.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::liveliness::Token;
use interfaces::msg::diag::Diagnostics;
use interfaces::msg::dr::{GetNodeRequest, TransformRequest};
use interfaces::raw::RawReply;
use interfaces::{Bus, ErrorCode, topics};
use robocog_tests::*;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::Duration;
use tokio::time::Instant;

/// Who may be attacked: every component of the graph. The test's own bus is not a component.
const ME: &str = "foreign";

/// Payloads no message type decodes (checked against every registered type below).
fn garbage() -> Vec<Vec<u8>> {
    // A good encapsulation, a header's stamp (sec, nanosec), then its frame id's length: 2^32-1.
    let huge_length = [&interfaces::codec::CDR_LE_HEADER[..], &[0; 8], &[0xff; 4]].concat();
    vec![
        vec![],
        vec![0x00, 0x01],
        vec![0xff, 0xfe, 0x00, 0x00, 0xde, 0xad, 0xbe, 0xef],
        huge_length,
    ]
}

/// The garbage must really be garbage for the type, or the test would prove nothing.
fn undecodable(type_name: &str, payload: &[u8]) -> bool {
    match interfaces::msg::lookup(type_name) {
        Ok(entry) => (entry.to_json)(payload).is_err(),
        // A type this build does not know is refused by any subscriber of this build.
        Err(_) => true,
    }
}

/// The component tokens of the graph once every one of `names` is up (at most `within`).
async fn components_up(bus: &Bus, names: &[&str], within: Duration) -> Vec<Token> {
    let deadline = Instant::now() + within;
    loop {
        let tokens = bus.graph(Duration::from_secs(2)).await.unwrap();
        let up: BTreeSet<&str> = tokens
            .iter()
            .filter_map(|t| match t {
                Token::Component { name, .. } => Some(name.as_str()),
                _ => None,
            })
            .collect();
        let missing: Vec<&&str> = names.iter().filter(|n| !up.contains(**n)).collect();
        if missing.is_empty() {
            return tokens;
        }
        assert!(
            Instant::now() < deadline,
            "components not up within {within:?}: {missing:?} (up: {up:?})"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

fn pids(tokens: &[Token]) -> BTreeMap<String, u32> {
    tokens
        .iter()
        .filter_map(|t| match t {
            Token::Component { name, pid, .. } => Some((name.clone(), *pid)),
            _ => None,
        })
        .collect()
}

/// What the attack did.
#[derive(Debug, Default)]
struct Attack {
    /// (component, topic) pairs that were sent garbage.
    readers: BTreeSet<(String, String)>,
    /// The topics attacked, with their types.
    topics: BTreeMap<String, String>,
    /// Services attacked, and what each garbage request got back.
    services: BTreeMap<String, Vec<String>>,
}

/// Publish the garbage on every topic a component of `tokens` subscribes to, and send it to every
/// service. Returns what was attacked.
async fn attack(bus: &Bus, tokens: &[Token]) -> Attack {
    let mut attack = Attack::default();
    let mut topics: BTreeSet<(String, String)> = BTreeSet::new();
    for t in tokens {
        match t {
            Token::Subscriber {
                component,
                type_name,
                topic,
            } if component != ME => {
                for g in garbage() {
                    assert!(
                        undecodable(type_name, &g),
                        "{g:02x?} decodes as {type_name}"
                    );
                }
                attack.readers.insert((component.clone(), topic.clone()));
                topics.insert((topic.clone(), type_name.clone()));
            }
            Token::Service {
                component,
                request,
                service,
                ..
            } if component != ME => {
                let mut replies = Vec::new();
                for g in garbage() {
                    assert!(undecodable(request, &g), "{g:02x?} decodes as {request}");
                    let reply = bus
                        .raw_call(service, request, g, Duration::from_secs(5))
                        .await
                        .unwrap_or_else(|e| panic!("{service} ({component}) did not answer: {e}"));
                    replies.push(match reply {
                        RawReply::Err(e) if e.code == ErrorCode::BadRequest => {
                            "BadRequest".to_string()
                        }
                        other => format!("{other:?}"),
                    });
                }
                attack.services.insert(service.clone(), replies);
            }
            _ => {}
        }
    }
    assert!(!attack.readers.is_empty(), "no subscriber in the graph");
    for (topic, type_name) in &topics {
        burst(bus, topic, type_name).await;
        attack.topics.insert(topic.clone(), type_name.clone());
    }
    attack
}

/// The garbage, once, on `topic`.
async fn burst(bus: &Bus, topic: &str, type_name: &str) {
    let publisher = bus.raw_publisher(topic, type_name, ME).await.unwrap();
    for g in garbage() {
        publisher.put(g).await.unwrap();
    }
}

/// Every component's latest counters, gathered in the background.
fn gather_diagnostics(bus: &Bus) -> (tokio::task::JoinHandle<()>, DiagLog) {
    let log = DiagLog::default();
    let bus = bus.clone();
    let into = log.clone();
    let task = tokio::spawn(async move {
        let sub = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
        while let Ok(d) = sub.recv().await {
            into.0.lock().unwrap().insert(d.component.clone(), d);
        }
    });
    (task, log)
}

#[derive(Debug, Default, Clone)]
struct DiagLog(std::sync::Arc<std::sync::Mutex<BTreeMap<String, Diagnostics>>>);

impl DiagLog {
    /// The (component, topic) pairs of `readers` whose component has not yet accounted for the
    /// payloads it was sent (`bursts` of the garbage on each topic): each one is a decode error
    /// or, for a subscription that keeps only its newest samples (the panel's camera keeps 2), a
    /// counted queue drop; and at least one reached the decoder and was refused. With each, whether
    /// all were accounted for but none was refused yet: every one was dropped from the queue.
    fn uncounted(
        &self,
        readers: &BTreeSet<(String, String)>,
        bursts: &BTreeMap<String, u64>,
    ) -> Vec<(String, String, bool)> {
        let latest = self.0.lock().unwrap();
        let per_burst = garbage().len() as u64;
        readers
            .iter()
            .filter_map(|(c, t)| {
                let n = per_burst * bursts.get(t).copied().unwrap_or(1);
                let Some(d) = latest.get(c) else {
                    return Some((c.clone(), t.clone(), false));
                };
                let refused = d.get(&format!("decode_errors/{t}"));
                let dropped = d.get(&format!("queue_dropped/{t}"));
                (refused == 0 || refused + dropped < n).then(|| {
                    let all_dropped = refused == 0 && dropped >= n;
                    (c.clone(), t.clone(), all_dropped)
                })
            })
            .collect()
    }
}

/// Wait until every reader counted the garbage it was sent. A reader that keeps only its newest
/// samples may lose a whole burst to the live samples behind it before it reads one (the
/// camera's frames, on a loaded machine): counted as drops, none decoded. Its topic then gets the
/// burst again, at most once a second, until one reaches its decoder.
async fn every_drop_counted(bus: &Bus, log: &DiagLog, attack: &Attack, within: Duration) {
    let mut bursts: BTreeMap<String, u64> = attack.topics.keys().map(|t| (t.clone(), 1)).collect();
    let deadline = Instant::now() + within;
    let mut last_burst = Instant::now();
    loop {
        let left = log.uncounted(&attack.readers, &bursts);
        if left.is_empty() {
            return;
        }
        assert!(
            Instant::now() < deadline,
            "the payloads were not counted (decode_errors, queue_dropped) within {within:?} by: {:?} (bursts sent: {bursts:?})",
            left.iter()
                .map(|(c, t, _)| format!("{c} on {t}"))
                .collect::<Vec<_>>()
        );
        if last_burst.elapsed() >= Duration::from_secs(1) {
            let again: BTreeSet<&String> = left
                .iter()
                .filter(|(_, _, d)| *d)
                .map(|(_, t, _)| t)
                .collect();
            for t in again {
                burst(bus, t, &attack.topics[t]).await;
                *bursts.entry(t.clone()).or_default() += 1;
                last_burst = Instant::now();
            }
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

fn no_restart(output: &[String]) {
    let restarts: Vec<&String> = output
        .iter()
        .filter(|l| l.contains(" stopped (") || l.contains("failed for good"))
        .collect();
    assert!(
        restarts.is_empty(),
        "a component stopped: {restarts:?}\n{}",
        output.join("\n")
    );
}

fn every_service_refused(attack: &Attack) {
    assert!(!attack.services.is_empty(), "no service in the graph");
    for (service, replies) in &attack.services {
        assert!(
            replies.iter().all(|r| r == "BadRequest"),
            "{service} answered garbage with {replies:?}"
        );
    }
}

/// The touch game: the attack comes as the game starts; the scenario still completes.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_on_every_topic_and_service_of_the_touch_game_stops_nothing() {
    let ns = unique_namespace("foreign-touch");
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/touch_the_ball.toml");
    let mut launch = Launch::start(
        &manifest,
        &ns,
        &["--set", "scenario=still", "--set", "panel_http=127.0.0.1:0"],
    );
    let bus = Bus::open(&launch.connect_args(), ME).await.unwrap();
    let (diag_task, diag) = gather_diagnostics(&bus);
    let names = [
        "deep_representation",
        "joint_motor",
        "body_inverse_kinematics",
        "ball_tracker",
        "rgbd",
        "speech_generator",
        "dialogs",
        "speech_recognition",
        "executive",
        "command_generator",
        "loki_world",
    ];
    let before = components_up(&bus, &names, Duration::from_secs(90)).await;
    let attack = attack(&bus, &before).await;
    every_service_refused(&attack);
    // The DR serves several services; it still answers a good request after the garbage.
    let ball = bus
        .call(
            &topics::DR_GET_NODE,
            &GetNodeRequest {
                name: "ball".into(),
                ..Default::default()
            },
            Duration::from_secs(5),
        )
        .await
        .unwrap();
    assert_eq!(ball.name, "ball");
    every_drop_counted(&bus, &diag, &attack, Duration::from_secs(30)).await;
    let status = launch.wait_exit(Duration::from_secs(180));
    let output = launch.lines.all();
    assert_eq!(
        status.code(),
        Some(0),
        "the scenario did not complete after the garbage:\n{}",
        output.join("\n")
    );
    no_restart(&output);
    let repeated = output
        .iter()
        .filter(|l| l.contains("says it again"))
        .count();
    assert_eq!(
        repeated,
        0,
        "the person had to repeat herself:\n{}",
        output.join("\n")
    );
    diag_task.abort();
}

/// The coach game on the simulated field, with the panel: after the attack every component is
/// the same process, counted its drops, and the bridge and the DR still work.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_on_every_topic_and_service_of_the_coach_game_stops_nothing() {
    let ns = unique_namespace("foreign-coach");
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch/nao_coach.toml");
    let sets = [
        format!("debug_port={}", free_udp_port()),
        format!("gc_port={}", free_udp_port()),
        format!("command_port={}", free_udp_port()),
        "panel_listen=127.0.0.1:0".to_string(),
        "falls_per_min=0".to_string(),
    ];
    let mut extra = Vec::new();
    for s in &sets {
        extra.push("--set");
        extra.push(s.as_str());
    }
    let mut launch = Launch::start(&manifest, &ns, &extra);
    let bus = Bus::open(&launch.connect_args(), ME).await.unwrap();
    let (diag_task, diag) = gather_diagnostics(&bus);
    let names = [
        "spl_field",
        "nao_bridge",
        "deep_representation",
        "speech_generator",
        "dialogs",
        "speech_recognition",
        "executive",
        "command_generator",
    ];
    let before = components_up(&bus, &names, Duration::from_secs(90)).await;
    let attack = attack(&bus, &before).await;
    every_service_refused(&attack);
    every_drop_counted(&bus, &diag, &attack, Duration::from_secs(30)).await;

    // Still the same processes, still working: the bridge relays the field's game state, the DR
    // answers.
    let after = components_up(&bus, &names, Duration::from_secs(5)).await;
    assert_eq!(pids(&before), pids(&after), "a component was replaced");
    let states = bus.subscriber(&topics::NAO_GAME_STATE).await.unwrap();
    let state = states.recv_timeout(Duration::from_secs(10)).await.unwrap();
    assert!(
        state.is_some(),
        "no nao/game_state from the bridge after the garbage"
    );
    let req = TransformRequest {
        target: "world".into(),
        source: "world".into(),
        ..Default::default()
    };
    bus.call(&topics::DR_TRANSFORM, &req, Duration::from_secs(5))
        .await
        .unwrap();

    launch.sigterm();
    let status = launch.wait_exit(Duration::from_secs(30));
    let output = launch.lines.all();
    assert_eq!(status.code(), Some(0), "{}", output.join("\n"));
    no_restart(&output);
    diag_task.abort();
}
