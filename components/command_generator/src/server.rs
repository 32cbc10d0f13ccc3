//! The HTTP side: the embedded page, and one WebSocket per open page.
//!
//! [`Hub`] is the meeting point of the bus and the pages: the bus side stores the latest value of
//! each state topic ([`Hub::set_state`]) and pushes events ([`Hub::event`]); each page's
//! connection sends what changed, each state key at most at its own rate, so a fast topic cannot
//! flood a browser. Requests from a page are checked ([`crate::protocol`]) and accepted ones are
//! handed to the bus side through a bounded queue ([`Hub::new`]'s receiver).
//!
//! Access: when a token is configured, `/` and `/ws` need `?token=<token>` (the page passes on
//! the one in its own address). A WebSocket whose `Origin` header names another host than the
//! one it connected to is refused (another site's page in the same browser cannot drive the
//! robot).

use crate::panel::{Entry, Outgoing, Panel};
use crate::protocol::{self, MAX_MESSAGE_BYTES, Request, RequestError, parse_request};
use axum::Router;
use axum::extract::ws::{Message as WsMessage, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use interfaces::bus::Counters;
use interfaces::ratelimit::RateLimiter;
use serde_json::json;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::{broadcast, mpsc};

/// WebSocket messages above this size close the connection (the transport refuses to buffer
/// them); between [`MAX_MESSAGE_BYTES`] and this, they are read and refused with a reason.
pub const HARD_MESSAGE_LIMIT: usize = 1024 * 1024;
/// Recent events replayed to a page that connects (so it shows the last things said).
pub const EVENT_REPLAY: usize = 50;
/// How often a connection looks for changed state (and so the finest state rate), ms.
pub const TICK_MS: u64 = 40;
/// A page that does not take a message for this long is dropped.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(5);

const INDEX_HTML: &str = include_str!("../web/index.html");
const APP_JS: &str = include_str!("../web/app.js");
const STYLE_CSS: &str = include_str!("../web/style.css");

#[derive(Debug, Clone)]
enum Payload {
    Text(Utf8Bytes),
    /// A camera image: its `vision/rgbd` description (JSON), then the JPEG.
    Camera(Utf8Bytes, axum::body::Bytes),
}

#[derive(Debug)]
struct Slot {
    version: u64,
    payload: Payload,
    min_interval: Duration,
}

#[derive(Debug)]
struct Events {
    recent: VecDeque<Utf8Bytes>,
    tx: broadcast::Sender<Utf8Bytes>,
}

/// Shared by the bus side and every page connection.
#[derive(Debug)]
pub struct Hub {
    states: Mutex<BTreeMap<String, Slot>>,
    events: Mutex<Events>,
    panel: Mutex<Panel>,
    out: mpsc::Sender<Outgoing>,
    counters: Arc<Counters>,
    token: Option<String>,
    limiter: Mutex<RateLimiter>,
}

impl Hub {
    /// A hub and the queue of accepted commands the bus side publishes. `token`: required on
    /// `/` and `/ws` when set.
    pub fn new(
        counters: Arc<Counters>,
        token: Option<String>,
    ) -> (Arc<Hub>, mpsc::Receiver<Outgoing>) {
        let (out, rx) = mpsc::channel(64);
        let (tx, _) = broadcast::channel(256);
        let hub = Hub {
            states: Mutex::new(BTreeMap::new()),
            events: Mutex::new(Events {
                recent: VecDeque::new(),
                tx,
            }),
            panel: Mutex::new(Panel::new()),
            out,
            counters,
            token: token.filter(|t| !t.is_empty()),
            limiter: Mutex::new(RateLimiter::new(Duration::from_secs(1))),
        };
        (Arc::new(hub), rx)
    }

    /// Store the latest value of a state (`key` is usually the topic, or topic/robot), sent to
    /// each page at most every `min_interval`. `json` is the whole message for the page.
    pub fn set_state(&self, key: &str, min_interval: Duration, json: String) {
        self.set(key, min_interval, Payload::Text(json.into()));
    }

    /// Store the latest camera image: `meta` (the `vision/rgbd` state message) is sent as text
    /// right before the JPEG, which goes as a binary WebSocket message.
    pub fn set_camera(&self, min_interval: Duration, meta: String, jpeg: Vec<u8>) {
        self.set(
            "vision/rgbd",
            min_interval,
            Payload::Camera(meta.into(), jpeg.into()),
        );
    }

    fn set(&self, key: &str, min_interval: Duration, payload: Payload) {
        let mut states = lock(&self.states);
        let slot = states.entry(key.to_string()).or_insert(Slot {
            version: 0,
            payload: Payload::Text(Utf8Bytes::from_static("")),
            min_interval,
        });
        slot.version += 1;
        slot.payload = payload;
        slot.min_interval = min_interval;
    }

    /// Send an event to every page (and keep it for pages that connect later).
    pub fn event(&self, json: String) {
        let text: Utf8Bytes = json.into();
        let mut ev = lock(&self.events);
        if ev.recent.len() == EVENT_REPLAY {
            ev.recent.pop_front();
        }
        ev.recent.push_back(text.clone());
        // No receiver (no page open) is not an error.
        let _ = ev.tx.send(text);
    }

    fn subscribe_events(&self) -> (Vec<Utf8Bytes>, broadcast::Receiver<Utf8Bytes>) {
        let ev = lock(&self.events);
        (ev.recent.iter().cloned().collect(), ev.tx.subscribe())
    }

    /// Whether `given` is the configured token (always true when none is configured).
    pub fn authorized(&self, given: Option<&str>) -> bool {
        match &self.token {
            None => true,
            Some(t) => given.is_some_and(|g| constant_time_eq(g.as_bytes(), t.as_bytes())),
        }
    }

    /// Handle one text request from a page: check it, forward it if accepted, record it in the
    /// history. Returns the reply for that page (the history goes to every page as an event).
    pub fn handle_text(&self, text: &str) -> String {
        self.handle_page_text(text).0
    }

    /// [`Self::handle_text`], and the talk key's state when the request was the talk key (so
    /// the page's connection knows to let it up if the page goes).
    fn handle_page_text(&self, text: &str) -> (String, Option<bool>) {
        match parse_request(text) {
            Ok((id, request)) => {
                let talk = match request {
                    Request::Talk(held) => Some(held),
                    _ => None,
                };
                (self.handle_request(id, request), talk)
            }
            Err(e) => (
                self.refuse(protocol::request_id(text), &protocol::describe(text), &e),
                None,
            ),
        }
    }

    /// A page that held the talk key went away: the key comes up.
    fn release_talk(&self) {
        tracing::info!("a page went while holding the talk key: letting it up");
        self.handle_request(0, Request::Talk(false));
    }

    /// Refuse a request that could not be read as text (binary, over the limit).
    pub fn handle_unreadable(&self, error: &RequestError) -> String {
        self.refuse(0, "", error)
    }

    fn handle_request(&self, id: u64, request: Request) -> String {
        let mut panel = lock(&self.panel);
        let (out, mut entry) = panel.accept(request, now_ms());
        let has_messages = !out.is_empty();
        let mut ok = true;
        if entry.seq == 0 {
            // A held talk key sent again: forwarded, not recorded.
            drop(panel);
            if self.out.try_send(out).is_err() {
                self.counters.incr("rejected/bus_busy");
                ok = false;
            }
            return reply_json(id, ok, &entry);
        }
        if has_messages && let Err(e) = self.out.try_send(out) {
            ok = false;
            self.counters.incr("rejected/bus_busy");
            tracing::warn!("a panel command was not sent: the bus side is not keeping up ({e})");
            let reason = "not sent: the panel's bus link is not keeping up, try again";
            if let Some(e) = panel.mark_refused(entry.seq, reason) {
                entry = e;
            }
        }
        if ok {
            self.counters.incr("commands/accepted");
            tracing::info!("panel: {} ({:?})", entry.label, entry.status);
        }
        let history = history_json(&panel);
        drop(panel);
        self.event(history);
        reply_json(id, ok, &entry)
    }

    fn refuse(&self, id: u64, what: &str, error: &RequestError) -> String {
        self.counters.incr(&format!("rejected/{}", error.name()));
        #[expect(
            clippy::disallowed_methods,
            reason = "the log limiter paces what a person reads, on the wall"
        )]
        let suppressed = lock(&self.limiter).allow(Instant::now());
        if let Some(suppressed) = suppressed {
            tracing::warn!(suppressed, "refused a panel request: {error}");
        }
        let mut panel = lock(&self.panel);
        let entry = panel.refuse(what, error, now_ms());
        let history = history_json(&panel);
        drop(panel);
        self.event(history);
        reply_json(id, false, &entry)
    }

    fn hello(&self) -> String {
        let panel = lock(&self.panel);
        json!({
            "type": "hello",
            "catalog": crate::catalog::catalog_json(),
            "strategy": format!("{:?}", panel.strategy()),
            "max_message_bytes": MAX_MESSAGE_BYTES,
            "server_time_ms": now_ms(),
            "stale_after_ms": crate::coach_status::STALE_AFTER_MS,
        })
        .to_string()
    }

    fn history(&self) -> String {
        history_json(&lock(&self.panel))
    }
}

fn history_json(panel: &Panel) -> String {
    let entries: Vec<&Entry> = panel.history().collect();
    json!({ "type": "history", "entries": entries }).to_string()
}

fn reply_json(id: u64, ok: bool, entry: &Entry) -> String {
    json!({ "type": "reply", "id": id, "ok": ok, "entry": entry }).to_string()
}

/// The panel's clock: milliseconds since the Unix epoch (0 if the clock is before 1970).
#[expect(
    clippy::disallowed_methods,
    reason = "the times a person's page shows and ages against its browser's own Date.now(): the \
              wall, as the browser's"
)]
pub fn now_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The panel's routes: `/` (the page), `/app.js`, `/style.css`, `/ws` (the live connection).
pub fn router(hub: Arc<Hub>) -> Router {
    Router::new()
        .route("/", get(index))
        .route(
            "/app.js",
            get(|| async { asset("text/javascript; charset=utf-8", APP_JS) }),
        )
        .route(
            "/style.css",
            get(|| async { asset("text/css; charset=utf-8", STYLE_CSS) }),
        )
        .route("/ws", get(websocket))
        .with_state(hub)
}

fn asset(content_type: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn index(State(hub): State<Arc<Hub>>, Query(q): Query<HashMap<String, String>>) -> Response {
    if !hub.authorized(q.get("token").map(String::as_str)) {
        hub.counters.incr("rejected/token");
        return (
            StatusCode::UNAUTHORIZED,
            "this panel needs its access token: open /?token=<token>\n",
        )
            .into_response();
    }
    asset("text/html; charset=utf-8", INDEX_HTML)
}

/// Whether the `Origin` header (if any) names the host the request was sent to.
fn same_origin(headers: &HeaderMap) -> bool {
    let Some(origin) = headers.get(header::ORIGIN) else {
        return true; // not a browser page (a tool, a test)
    };
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    let origin = origin.to_str().unwrap_or("");
    let origin_host = origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
        .unwrap_or("");
    !host.is_empty() && origin_host == host
}

async fn websocket(
    State(hub): State<Arc<Hub>>,
    Query(q): Query<HashMap<String, String>>,
    headers: HeaderMap,
    ws: WebSocketUpgrade,
) -> Response {
    if !hub.authorized(q.get("token").map(String::as_str)) {
        hub.counters.incr("rejected/token");
        return (StatusCode::UNAUTHORIZED, "missing or wrong token\n").into_response();
    }
    if !same_origin(&headers) {
        hub.counters.incr("rejected/origin");
        tracing::warn!(
            "refused a WebSocket from another site's page (origin {:?})",
            headers.get(header::ORIGIN)
        );
        return (StatusCode::FORBIDDEN, "cross-origin WebSocket refused\n").into_response();
    }
    ws.max_message_size(HARD_MESSAGE_LIMIT)
        .max_frame_size(HARD_MESSAGE_LIMIT)
        .on_upgrade(move |socket| async move {
            hub.counters.incr("pages/connected");
            let mut talking = false;
            if let Err(e) = connection(socket, &hub, &mut talking).await {
                tracing::info!("a page disconnected: {e}");
            }
            if talking {
                hub.release_talk();
            }
        })
}

#[expect(
    clippy::disallowed_methods,
    reason = "a transport time-out: how long a page's WebSocket may take a message"
)]
async fn send(socket: &mut WebSocket, msg: WsMessage) -> Result<(), String> {
    match tokio::time::timeout(SEND_TIMEOUT, socket.send(msg)).await {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(format!("send failed: {e}")),
        Err(_) => Err(format!("the page took no message for {SEND_TIMEOUT:?}")),
    }
}

/// One page: replies and the history at once, events as they come, states at their rates.
/// `talking`: whether this page holds the talk key.
#[expect(
    clippy::disallowed_methods,
    reason = "paces the sends to one page's WebSocket (transport), as its browser receives them on \
              the wall"
)]
async fn connection(mut socket: WebSocket, hub: &Hub, talking: &mut bool) -> Result<(), String> {
    send(&mut socket, WsMessage::Text(hub.hello().into())).await?;
    send(&mut socket, WsMessage::Text(hub.history().into())).await?;
    let (recent, mut events) = hub.subscribe_events();
    for e in recent {
        send(&mut socket, WsMessage::Text(e)).await?;
    }
    // Per state key: the version sent last and when.
    let mut sent: HashMap<String, (u64, Instant)> = HashMap::new();
    let mut tick = tokio::time::interval(Duration::from_millis(TICK_MS));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            m = socket.recv() => {
                let reply = match m {
                    None => return Ok(()),
                    Some(Err(e)) => {
                        // Over the hard limit, or a broken frame: the transport gives up on
                        // this connection; the server carries on.
                        hub.counters.incr("rejected/connection_error");
                        return Err(format!("{e}"));
                    }
                    Some(Ok(WsMessage::Text(t))) => {
                        let (reply, talk) = hub.handle_page_text(t.as_str());
                        if let Some(held) = talk {
                            *talking = held;
                        }
                        reply
                    }
                    Some(Ok(WsMessage::Binary(b))) => {
                        let e = if b.len() > MAX_MESSAGE_BYTES {
                            RequestError::TooLarge { bytes: b.len() }
                        } else {
                            RequestError::Binary
                        };
                        hub.handle_unreadable(&e)
                    }
                    Some(Ok(WsMessage::Close(_))) => return Ok(()),
                    Some(Ok(_)) => continue, // ping/pong: answered by the transport
                };
                send(&mut socket, WsMessage::Text(reply.into())).await?;
            }
            e = events.recv() => match e {
                Ok(text) => send(&mut socket, WsMessage::Text(text)).await?,
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    hub.counters.counter("events/lagged").fetch_add(n, std::sync::atomic::Ordering::Relaxed);
                    tracing::warn!("a page fell {n} events behind; they were skipped");
                }
                Err(broadcast::error::RecvError::Closed) => return Ok(()),
            },
            _ = tick.tick() => {
                let now = Instant::now();
                let due: Vec<(String, u64, Payload)> = {
                    let states = lock(&hub.states);
                    states
                        .iter()
                        .filter(|(k, s)| match sent.get(*k) {
                            None => s.version > 0,
                            Some((v, at)) => *v != s.version && now.duration_since(*at) >= s.min_interval,
                        })
                        .map(|(k, s)| (k.clone(), s.version, s.payload.clone()))
                        .collect()
                };
                for (key, version, payload) in due {
                    match payload {
                        Payload::Text(t) => send(&mut socket, WsMessage::Text(t)).await?,
                        Payload::Camera(meta, jpeg) => {
                            send(&mut socket, WsMessage::Text(meta)).await?;
                            send(&mut socket, WsMessage::Binary(jpeg)).await?;
                        }
                    }
                    sent.insert(key, (version, now));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origin_must_match_host_when_given() {
        let mut h = HeaderMap::new();
        assert!(same_origin(&h));
        h.insert(header::HOST, "127.0.0.1:8642".parse().expect("header"));
        h.insert(
            header::ORIGIN,
            "http://127.0.0.1:8642".parse().expect("header"),
        );
        assert!(same_origin(&h));
        h.insert(
            header::ORIGIN,
            "http://evil.example".parse().expect("header"),
        );
        assert!(!same_origin(&h));
        h.insert(header::ORIGIN, "null".parse().expect("header"));
        assert!(!same_origin(&h));
    }

    #[test]
    fn tokens_compare_whole() {
        let (hub, _rx) = Hub::new(Arc::default(), Some("s3cret-token-123".into()));
        assert!(hub.authorized(Some("s3cret-token-123")));
        assert!(!hub.authorized(Some("s3cret-token-12")));
        assert!(!hub.authorized(Some("")));
        assert!(!hub.authorized(None));
        let (open, _rx) = Hub::new(Arc::default(), None);
        assert!(open.authorized(None));
    }

    #[test]
    fn refused_requests_are_counted_and_never_queued() {
        let counters: Arc<Counters> = Arc::default();
        let (hub, mut rx) = Hub::new(counters.clone(), None);
        let reply = hub.handle_text("{not json");
        assert!(
            reply.contains("\"ok\":false") && reply.contains("malformed message"),
            "{reply}"
        );
        let reply = hub.handle_text(
            r#"{"id":9,"type":"command","game":"coach","command":"GoToPosition","target":{"x_mm":9000,"y_mm":0}}"#,
        );
        assert!(
            reply.contains("\"id\":9") && reply.contains("outside the field"),
            "{reply}"
        );
        assert!(rx.try_recv().is_err());
        let reply =
            hub.handle_text(r#"{"id":10,"type":"command","game":"coach","command":"Kick"}"#);
        assert!(reply.contains("\"ok\":true"), "{reply}");
        let out = rx.try_recv().expect("queued");
        assert!(out.nao.is_some() && out.game.is_some());
        let snap: BTreeMap<String, u64> = counters.snapshot().into_iter().collect();
        assert_eq!(snap.get("rejected/malformed"), Some(&1));
        assert_eq!(snap.get("rejected/target_outside_field"), Some(&1));
        assert_eq!(snap.get("commands/accepted"), Some(&1));
    }
}
