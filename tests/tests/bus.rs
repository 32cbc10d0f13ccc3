#![allow(clippy::unwrap_used)]
//! The typed bus between real processes, over the launcher's router.
#![expect(
    clippy::disallowed_methods,
    reason = "process tests wait on real processes, with a time-out on every wait"
)]

use interfaces::msg::std_msgs::Text;
use interfaces::{Bus, CallError, ErrorCode, topics};
use robocog_tests::*;
use std::time::Duration;

const TALK_AND_LISTEN: &str = r#"
[[component]]
name = "talker"
binary = "@FIXTURE@"
args = ["--role", "talker", "--rate", "20"]

[[component]]
name = "listener"
binary = "@FIXTURE@"
args = ["--role", "listener"]
"#;

#[test]
fn two_components_exchange_typed_messages() {
    let ns = unique_namespace("exchange");
    let m = write_manifest(&scratch(&ns), "graph.toml", TALK_AND_LISTEN);
    let launch = Launch::start(&m, &ns, &[]);
    let line = launch.lines.wait_for(
        "a typed message at the listener",
        Duration::from_secs(20),
        |l| l.contains("listener |") && l.contains("received: hello"),
    );
    assert!(line.contains("(seq "), "{line}");
    // Messages keep flowing, in order.
    launch
        .lines
        .wait_until("five messages", Duration::from_secs(10), |lines| {
            lines
                .iter()
                .filter(|l| l.contains("received: hello"))
                .count()
                >= 5
        });
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn request_reply_with_time_out_and_typed_errors() {
    let ns = unique_namespace("reqrep");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "echo"
binary = "@FIXTURE@"
args = ["--role", "echo-server", "--delay-ms", "300"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("echo up", Duration::from_secs(20), |l| {
            l.contains("echo is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-client")
        .await
        .unwrap();

    let req = Text {
        text: "ping".into(),
        ..Default::default()
    };
    let rep = bus
        .call(&topics::ECHO, &req, Duration::from_secs(5))
        .await
        .unwrap();
    assert_eq!(rep.text, "PING");

    // The server takes 300 ms: a 100 ms time-out expires, and says so.
    let started = std::time::Instant::now();
    match bus
        .call(&topics::ECHO, &req, Duration::from_millis(100))
        .await
    {
        Err(CallError::Timeout { .. }) => {}
        other => panic!("expected a time-out, got {other:?}"),
    }
    assert!(started.elapsed() < Duration::from_secs(2));

    // The handler's error comes back typed.
    let empty = Text::default();
    match bus
        .call(&topics::ECHO, &empty, Duration::from_secs(5))
        .await
    {
        Err(CallError::Remote(e)) => assert_eq!(e.code, ErrorCode::BadRequest),
        other => panic!("expected a BadRequest, got {other:?}"),
    }

    // In another namespace, nobody serves it: a quick NoServer, not a long wait.
    let mut other = launch.connect_args();
    other.namespace = format!("{ns}-other");
    let lonely = Bus::open(&other, "test-client").await.unwrap();
    let started = std::time::Instant::now();
    match lonely
        .call(&topics::ECHO, &req, Duration::from_secs(3))
        .await
    {
        Err(CallError::NoServer(_)) | Err(CallError::Timeout { .. }) => {}
        other => panic!("expected no server, got {other:?}"),
    }
    assert!(started.elapsed() <= Duration::from_secs(4));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_malformed_payload_is_counted_and_the_subscriber_carries_on() {
    let ns = unique_namespace("malformed");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "listener"
binary = "@FIXTURE@"
args = ["--role", "listener"]
external_inputs = ["chatter"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("listener up", Duration::from_secs(20), |l| {
            l.contains("listener is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-prober")
        .await
        .unwrap();
    let diag = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    let publisher = bus.publisher(&topics::CHATTER).await.unwrap();
    let key = bus.topic_key(topics::CHATTER.name());
    // Give the router a moment to learn the listener's subscription.
    tokio::time::sleep(Duration::from_millis(500)).await;

    // Garbage, a wrong encapsulation, a truncated body: three bad payloads.
    for bad in [
        vec![1u8, 2, 3],
        vec![0xde, 0xad, 0xbe, 0xef, 0, 0, 0, 0],
        vec![0, 1, 0, 0, 200, 0, 0],
    ] {
        bus.session().put(&key, bad).await.unwrap();
    }
    let mut good = Text {
        text: "after the garbage".into(),
        ..Default::default()
    };
    publisher.publish(&mut good).await.unwrap();
    launch.lines.wait_for(
        "the good message after the bad ones",
        Duration::from_secs(10),
        |l| l.contains("received: after the garbage"),
    );
    let warned = launch
        .lines
        .wait_for("a drop warning", Duration::from_secs(5), |l| {
            l.contains("dropped a payload")
        });
    assert!(warned.contains("chatter"), "{warned}");

    // The listener's diagnostics count the three drops.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    loop {
        let d = tokio::time::timeout_at(deadline, diag.recv())
            .await
            .expect("diagnostics in time")
            .unwrap();
        if d.component == "listener" && d.get("decode_errors/chatter") == 3 {
            break;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_subscriber_drops_its_oldest_samples_and_stalls_nobody() {
    let ns = unique_namespace("slowsub");
    let m = write_manifest(
        &scratch(&ns),
        "graph.toml",
        r#"
[[component]]
name = "idle"
binary = "@FIXTURE@"
args = ["--role", "idle"]
"#,
    );
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("idle up", Duration::from_secs(20), |l| {
            l.contains("idle is up")
        });
    let sender = Bus::open(&launch.connect_args(), "test-sender")
        .await
        .unwrap();
    let receiver = Bus::open(&launch.connect_args(), "test-receiver")
        .await
        .unwrap();
    // Two subscriptions in one process: one never read (queue of 4), one read as it comes.
    let slow = receiver
        .subscriber_named::<Text>(topics::CHATTER.name(), 4)
        .await
        .unwrap();
    let fast = receiver.subscriber(&topics::CHATTER).await.unwrap();
    let publisher = sender.publisher(&topics::CHATTER).await.unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    const N: usize = 200; // under the fast subscriber's default queue (256)
    for i in 0..N {
        let mut t = Text {
            text: format!("{i}"),
            ..Default::default()
        };
        publisher.publish(&mut t).await.unwrap();
    }
    // The fast subscriber gets every message although the slow one's queue overflowed.
    for i in 0..N {
        let t = fast
            .recv_timeout(Duration::from_secs(5))
            .await
            .unwrap()
            .unwrap_or_else(|| {
                panic!("message {i} never came: the slow queue stalled the session")
            });
        assert_eq!(t.text, format!("{i}"));
    }
    // The slow one kept the newest four, and the drops are counted.
    let kept: Vec<String> = std::iter::from_fn(|| slow.try_recv().map(|t| t.text)).collect();
    let want: Vec<String> = (N - 4..N).map(|i| i.to_string()).collect();
    assert_eq!(kept, want);
    let dropped = receiver
        .counters()
        .snapshot()
        .into_iter()
        .find(|(k, _)| k == "queue_dropped/chatter")
        .map(|(_, v)| v);
    assert_eq!(dropped, Some((N - 4) as u64));
}
