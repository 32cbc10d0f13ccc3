#![expect(
    clippy::disallowed_methods,
    reason = "an integration test against a real WebSocket server: time-outs and pacing on the wall clock"
)]
#![allow(clippy::unwrap_used)]
//! The panel's WebSocket without a bus: bad input of every kind is refused with a reason, never
//! queued for the bus, and the server keeps serving; the token and the origin are enforced.

use command_generator::server::{Hub, router};
use futures_util::{SinkExt, StreamExt};
use interfaces::bus::Counters;
use std::sync::Arc;
use std::time::Duration;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

async fn start(
    token: Option<&str>,
) -> (
    String,
    Arc<Counters>,
    tokio::sync::mpsc::Receiver<command_generator::panel::Outgoing>,
) {
    let counters: Arc<Counters> = Arc::default();
    let (hub, rx) = Hub::new(counters.clone(), token.map(String::from));
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    tokio::spawn(async move { axum::serve(listener, router(hub)).await });
    (format!("127.0.0.1:{}", addr.port()), counters, rx)
}

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The next JSON message of `type` `kind`, skipping others, within 5 s.
async fn next_of(ws: &mut Ws, kind: &str) -> serde_json::Value {
    tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match ws.next().await {
                Some(Ok(Message::Text(t))) => {
                    let v: serde_json::Value = serde_json::from_str(t.as_str()).unwrap();
                    if v["type"] == kind {
                        return v;
                    }
                }
                Some(Ok(_)) => {}
                other => panic!("connection ended waiting for {kind}: {other:?}"),
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("no {kind} message within 5 s"))
}

async fn request(ws: &mut Ws, text: String) -> serde_json::Value {
    ws.send(Message::text(text)).await.unwrap();
    next_of(ws, "reply").await
}

#[tokio::test]
async fn bad_input_is_refused_with_reasons_and_the_server_keeps_serving() {
    let (addr, counters, mut rx) = start(None).await;
    let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/ws"))
        .await
        .unwrap();
    let hello = next_of(&mut ws, "hello").await;
    assert!(hello["catalog"]["coach"].as_array().unwrap().len() >= 10);

    let r = request(&mut ws, "{\"type\":\"command\",".into()).await;
    assert_eq!(r["ok"], false);
    assert!(
        r["entry"]["reason"]
            .as_str()
            .unwrap()
            .starts_with("malformed message"),
        "{r}"
    );
    let r = request(
        &mut ws,
        r#"{"id":7,"type":"command","game":"coach","command":"Teleport"}"#.into(),
    )
    .await;
    assert_eq!(
        (r["id"].as_u64(), r["ok"].as_bool()),
        (Some(7), Some(false))
    );
    assert_eq!(r["entry"]["reason"], "unknown command \"Teleport\"");
    let r = request(
        &mut ws,
        r#"{"id":8,"type":"command","game":"coach","command":"GoToPosition","target":{"x_mm":0,"y_mm":4000}}"#.into(),
    )
    .await;
    assert!(
        r["entry"]["reason"]
            .as_str()
            .unwrap()
            .contains("outside the field"),
        "{r}"
    );
    // Over the panel's limit but under the transport's: read, refused with the reason.
    let big = format!(
        r#"{{"id":9,"type":"answer","yes":true,"pad":"{}"}}"#,
        "x".repeat(200_000)
    );
    let r = request(&mut ws, big).await;
    assert!(
        r["entry"]["reason"]
            .as_str()
            .unwrap()
            .starts_with("message too large"),
        "{r}"
    );
    ws.send(Message::binary(vec![1u8, 2, 3])).await.unwrap();
    let r = next_of(&mut ws, "reply").await;
    assert!(
        r["entry"]["reason"].as_str().unwrap().contains("binary"),
        "{r}"
    );
    assert!(rx.try_recv().is_err(), "nothing refused may reach the bus");

    // The same connection still takes a good command.
    let r = request(
        &mut ws,
        r#"{"id":10,"type":"command","game":"coach","command":"Kick"}"#.into(),
    )
    .await;
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(
        rx.try_recv().unwrap().nao.unwrap().body,
        interfaces::msg::nao::NaoBody::Kick
    );

    // Over the transport's limit: that connection is closed; a new one is served.
    let huge = "y".repeat(2 * 1024 * 1024);
    let _ = ws.send(Message::text(huge)).await;
    let closed = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match ws.next().await {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return true,
                Some(Ok(_)) => {}
            }
        }
    })
    .await
    .unwrap();
    assert!(closed);
    let (mut ws2, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/ws"))
        .await
        .unwrap();
    let r = request(&mut ws2, r#"{"id":1,"type":"answer","yes":false}"#.into()).await;
    assert_eq!(r["ok"], true, "{r}");
    assert!(!rx.try_recv().unwrap().answer.unwrap().yes);

    let snap: std::collections::BTreeMap<String, u64> = counters.snapshot().into_iter().collect();
    for k in [
        "rejected/malformed",
        "rejected/unknown_command",
        "rejected/target_outside_field",
        "rejected/too_large",
        "rejected/binary",
    ] {
        assert_eq!(snap.get(k), Some(&1), "{k}: {snap:?}");
    }
    assert_eq!(snap.get("commands/accepted"), Some(&2));
}

#[tokio::test]
async fn the_token_and_the_origin_are_enforced() {
    let (addr, _c, _rx) = start(Some("a-long-enough-token")).await;
    assert!(
        tokio_tungstenite::connect_async(format!("ws://{addr}/ws"))
            .await
            .is_err()
    );
    assert!(
        tokio_tungstenite::connect_async(format!("ws://{addr}/ws?token=wrong"))
            .await
            .is_err()
    );
    let (mut ws, _) =
        tokio_tungstenite::connect_async(format!("ws://{addr}/ws?token=a-long-enough-token"))
            .await
            .unwrap();
    next_of(&mut ws, "hello").await;
    // Another site's page in the same browser.
    let mut req = format!("ws://{addr}/ws?token=a-long-enough-token")
        .into_client_request()
        .unwrap();
    req.headers_mut()
        .insert("origin", "http://evil.example".parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_err());
    let mut req = format!("ws://{addr}/ws?token=a-long-enough-token")
        .into_client_request()
        .unwrap();
    req.headers_mut()
        .insert("origin", format!("http://{addr}").parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_ok());
}

/// `coach/status` at 20 Hz reaches a page at most at its rate (4 a second), in the page's shape,
/// the latest value winning; `hello` carries the clock and staleness the page needs.
#[tokio::test]
async fn the_coach_status_reaches_the_page_throttled_and_latest_first() {
    use command_generator::coach_status::{STALE_AFTER_MS, view};
    use command_generator::component::STATE_RATES;
    use interfaces::msg::nao::CoachStatus;

    let (hub, _rx) = Hub::new(Arc::default(), None);
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let addr = listener.local_addr().unwrap();
    let server_hub = hub.clone();
    tokio::spawn(async move { axum::serve(listener, router(server_hub)).await });
    let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/ws"))
        .await
        .unwrap();
    let hello = next_of(&mut ws, "hello").await;
    assert_eq!(hello["stale_after_ms"], STALE_AFTER_MS);
    assert!(hello["server_time_ms"].as_u64().unwrap() > 1_600_000_000_000);

    let hz = STATE_RATES
        .iter()
        .find(|(t, _)| *t == "coach/status")
        .expect("a rate for coach/status")
        .1;
    assert!(hz <= 5.0, "a few updates a second at most, not {hz}");
    let every = Duration::from_secs_f64(1.0 / hz);
    let publisher = {
        let hub = hub.clone();
        tokio::spawn(async move {
            for seq in 0..=40u64 {
                let mut s = CoachStatus {
                    state: "coach/playing".into(),
                    ball_last_seen_s: seq as f64 / 10.0,
                    obstacle_last_seen_s: -1.0,
                    ..Default::default()
                };
                s.header.seq = seq;
                let json = serde_json::to_string(&view(&s, 1)).unwrap();
                hub.set_state("coach/status", every, json);
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        })
    };
    let started = std::time::Instant::now();
    let mut seen = Vec::new();
    while started.elapsed() < Duration::from_secs(5) {
        let m = next_of(&mut ws, "coach_status").await;
        seen.push((started.elapsed(), m["seq"].as_u64().unwrap()));
        if m["seq"] == 40 {
            assert_eq!(m["ball_last_seen_s"], 4.0);
            assert!(m["obstacle_last_seen_s"].is_null() && m["pending"].is_null());
            break;
        }
    }
    publisher.await.unwrap();
    // 41 statuses in about 2 s: the page got about 4 a second, increasing, ending on the latest.
    assert!(seen.len() >= 3 && seen.len() <= 12, "{seen:?}");
    assert!(seen.windows(2).all(|w| w[1].1 > w[0].1), "{seen:?}");
    assert!(
        seen.windows(2)
            .all(|w| w[1].0 - w[0].0 >= every - Duration::from_millis(60)),
        "{seen:?}"
    );
    assert_eq!(seen.last().unwrap().1, 40, "{seen:?}");
}
