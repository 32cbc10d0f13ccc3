//! Raw subscriptions and publications: payloads whose type is known by its name only.
//!
//! The tools that carry any message without decoding it (`robocog record`, `replay`, `topic`, the
//! viewer's intake) take and give CDR bytes with the type name each sample carries in its
//! encoding (`application/cdr;<type name>`, the convention every [`crate::Publisher`] follows).
//! This module is the one place that knows that convention and the keys of topics:
//!
//! - [`encoding_for`] and [`type_name_of`] write and read the encoding;
//! - [`Bus::raw_subscriber`] subscribes to a topic or a pattern of topics ([`EVERY_TOPIC`], or
//!   `*` and `**` chunks) into a bounded queue of [`RawSample`]s (topic, type name, payload,
//!   receipt time); a full queue drops its oldest sample, counted in `queue_dropped/<pattern>`
//!   like a typed subscriber's;
//! - [`Bus::raw_listener`] hands each [`RawSample`] to a callback on zenoh's receive path instead,
//!   for callers that queue by their own rules (the recorder's and the viewer's per-topic shares);
//! - [`Bus::raw_publisher`] publishes bytes on a topic with a type name given at run time,
//!   announced by a publisher liveliness token like a component's.
//!
//! - [`Bus::raw_call`] sends a request payload to a service by name and hands back its
//!   [`RawReply`]: the typed error, or the reply to decode (for tools, and for tests that speak to
//!   a service as a foreign client would).
//!
//! Raw subscriptions declare no liveliness token: the tools watch the graph without showing in
//! it as subscribers.

use crate::bus::{Bus, BusError, CallError, ServiceError, WireReply, offer_dropping_oldest};
use crate::codec::{self, CodecError};
use crate::liveliness;
use crate::msg::Message;
use crate::ratelimit::RateLimiter;
use crate::topic;
use std::borrow::Cow;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use zenoh::bytes::{Encoding, ZBytes};
use zenoh::liveliness::LivelinessToken;
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;

/// The topic pattern of every topic of the namespace.
pub const EVERY_TOPIC: &str = "**";

/// The encoding's name part: CDR, as [`crate::codec`] writes it.
const CDR: &str = "application/cdr";

/// The encoding of a sample of type `type_name` (`application/cdr;robocog.Text`).
pub fn encoding_for(type_name: &str) -> Encoding {
    Encoding::APPLICATION_CDR.with_schema(type_name.to_string())
}

/// The type name an encoding carries (`application/cdr;robocog.Text` gives `robocog.Text`);
/// `None` when it is not CDR or names no usable type.
pub fn type_name_of(encoding: &str) -> Option<&str> {
    let (mime, schema) = encoding.split_once(';')?;
    (mime == CDR && is_valid_type_name(schema)).then_some(schema)
}

/// Whether `s` can be a type name on the bus (it goes into liveliness keys): not empty, no
/// white space, none of `/ * $ ? # ;`.
pub fn is_valid_type_name(s: &str) -> bool {
    !s.is_empty()
        && !s
            .chars()
            .any(|c| c.is_whitespace() || matches!(c, '/' | '*' | '$' | '?' | '#' | ';'))
}

/// One sample as it arrived: its topic, the type name of its encoding, its payload untouched.
#[derive(Debug, Clone)]
pub struct RawSample {
    /// The topic's name in the namespace (`vision/ball`).
    pub topic: String,
    /// The type name its encoding carries; `None` when the encoding names none (a publisher
    /// that is not robocog's).
    pub type_name: Option<String>,
    /// When it was received (system time, ns since the epoch).
    pub receipt_ns: i64,
    /// Its publisher's sequence number, from the sample's attachment (`None`: no well-formed
    /// attachment, a publisher that is not robocog's).
    pub seq: Option<u64>,
    payload: ZBytes,
}

impl RawSample {
    /// The sample of zenoh's `sample`, when its key is one of namespace `ns`'s topics.
    fn of(ns: &str, sample: &Sample) -> Option<RawSample> {
        let topic = topic::topic_name(ns, sample.key_expr().as_str())?;
        Some(RawSample {
            topic: topic.to_string(),
            type_name: type_name_of(&sample.encoding().to_string()).map(str::to_string),
            receipt_ns: crate::header::system_now_ns(),
            seq: crate::attachment::Attachment::sequence_of(sample.attachment()),
            payload: sample.payload().clone(),
        })
    }

    /// The payload's length in bytes.
    pub fn payload_len(&self) -> usize {
        self.payload.len()
    }

    /// The payload (borrowed when it arrived in one piece, else gathered).
    pub fn payload(&self) -> Cow<'_, [u8]> {
        self.payload.to_bytes()
    }

    /// The payload, copied out.
    pub fn into_payload(self) -> Vec<u8> {
        self.payload.to_bytes().into_owned()
    }
}

/// A raw subscription with a bounded queue (see [`Bus::raw_subscriber`]); dropping it ends it.
pub struct RawSubscriber {
    _inner: zenoh::pubsub::Subscriber<()>,
    queue: flume::Receiver<RawSample>,
    pattern: String,
    dropped: Arc<AtomicU64>,
}

impl std::fmt::Debug for RawSubscriber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RawSubscriber({})", self.pattern)
    }
}

impl RawSubscriber {
    /// The next sample; `Err` only when the subscription is closed.
    pub async fn recv(&self) -> Result<RawSample, BusError> {
        self.queue
            .recv_async()
            .await
            .map_err(|_| BusError::Closed(self.pattern.clone()))
    }

    /// The next sample, or `None` after `timeout`.
    #[expect(
        clippy::disallowed_methods,
        reason = "a wait on the transport: a virtual clock that no one moves must not hold a reader forever"
    )]
    pub async fn recv_timeout(&self, timeout: Duration) -> Result<Option<RawSample>, BusError> {
        match tokio::time::timeout(timeout, self.recv()).await {
            Ok(r) => r.map(Some),
            Err(_) => Ok(None),
        }
    }

    /// A sample already queued, if any (never waits).
    pub fn try_recv(&self) -> Option<RawSample> {
        self.queue.try_recv().ok()
    }

    /// How many samples the full queue dropped so far (also the bus counter
    /// `queue_dropped/<pattern>`).
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// A raw subscription that hands each sample to a callback (see [`Bus::raw_listener`]); dropping
/// it ends it.
pub struct RawListener {
    inner: zenoh::pubsub::Subscriber<()>,
}

impl std::fmt::Debug for RawListener {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RawListener({})", self.inner.key_expr())
    }
}

impl RawListener {
    /// End the subscription; once this returns, the callback is not called again.
    pub async fn undeclare(self) -> Result<(), BusError> {
        self.inner.undeclare().await.map_err(|e| BusError::Zenoh {
            what: "ending a subscription".into(),
            reason: e.to_string(),
        })
    }
}

/// A publisher of bytes with a type name given at run time (see [`Bus::raw_publisher`]).
/// Dropping it withdraws its liveliness token.
pub struct RawPublisher {
    inner: zenoh::pubsub::Publisher<'static>,
    seq: std::sync::atomic::AtomicU64,
    gid: [u8; 16],
    topic: String,
    type_name: String,
    _token: LivelinessToken,
}

impl std::fmt::Debug for RawPublisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RawPublisher<{}>({})", self.type_name, self.topic)
    }
}

impl RawPublisher {
    /// Publish `payload` (CDR bytes of the publisher's type) as it is, with the next sequence
    /// number of this publisher.
    pub async fn put(&self, payload: Vec<u8>) -> Result<(), BusError> {
        let seq = self.seq.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.put_with_seq(payload, seq).await
    }

    /// Publish `payload` as it is with sequence number `seq` (replay gives the recorded one).
    pub async fn put_with_seq(&self, payload: Vec<u8>, seq: u64) -> Result<(), BusError> {
        let attachment = crate::attachment::Attachment {
            sequence: seq as i64,
            source_timestamp_ns: crate::header::system_now_ns(),
            gid: self.gid,
        };
        self.inner
            .put(payload)
            .attachment(attachment.encode().to_vec())
            .await
            .map_err(|e| BusError::Zenoh {
                what: format!("publishing on {}", self.topic),
                reason: e.to_string(),
            })
    }

    /// Whether a subscription matches the topic now (a one-shot publication waits for one).
    pub async fn has_subscribers(&self) -> bool {
        self.inner
            .matching_status()
            .await
            .map(|m| m.matching())
            .unwrap_or(false)
    }

    pub fn topic(&self) -> &str {
        &self.topic
    }

    pub fn type_name(&self) -> &str {
        &self.type_name
    }
}

impl Bus {
    /// The zenoh key expression of topic pattern `pattern` of this namespace (checked).
    fn pattern_key(&self, pattern: &str) -> Result<String, BusError> {
        if !topic::is_valid_pattern(pattern) {
            return Err(BusError::InvalidName(pattern.to_string()));
        }
        Ok(self.topic_key(pattern))
    }

    /// Subscribe to the topics `pattern` names (a topic name, [`EVERY_TOPIC`], or a name with `*`
    /// and `**` chunks) whatever their type, into a queue of `queue` samples. A full queue drops
    /// its oldest sample, counted in `queue_dropped/<pattern>` and logged rate-limited.
    pub async fn raw_subscriber(
        &self,
        pattern: &str,
        queue: usize,
    ) -> Result<RawSubscriber, BusError> {
        let key = self.pattern_key(pattern)?;
        let (tx, rx) = flume::bounded::<RawSample>(queue.max(1));
        let evict = rx.clone();
        let dropped = self.counters().counter(&format!("queue_dropped/{pattern}"));
        let counted = dropped.clone();
        let limiter = Mutex::new(RateLimiter::new(Duration::from_secs(1)));
        let ns = self.namespace().to_string();
        let name = pattern.to_string();
        let inner = self
            .session()
            .declare_subscriber(key)
            .callback(move |sample| {
                if let Some(s) = RawSample::of(&ns, &sample) {
                    offer_dropping_oldest(&tx, &evict, s, &counted, &limiter, &name);
                }
            })
            .await
            .map_err(|e| BusError::Zenoh {
                what: format!("subscribing to {pattern}"),
                reason: e.to_string(),
            })?;
        Ok(RawSubscriber {
            _inner: inner,
            queue: rx,
            pattern: pattern.to_string(),
            dropped,
        })
    }

    /// Subscribe to the topics `pattern` names (as [`Bus::raw_subscriber`]), handing each sample
    /// to `callback`. It runs on zenoh's receive path: it must return at once (queue the sample
    /// or drop it, never wait).
    pub async fn raw_listener<F>(&self, pattern: &str, callback: F) -> Result<RawListener, BusError>
    where
        F: Fn(RawSample) + Send + Sync + 'static,
    {
        let key = self.pattern_key(pattern)?;
        let ns = self.namespace().to_string();
        let inner = self
            .session()
            .declare_subscriber(key)
            .callback(move |sample| {
                if let Some(s) = RawSample::of(&ns, &sample) {
                    callback(s);
                }
            })
            .await
            .map_err(|e| BusError::Zenoh {
                what: format!("subscribing to {pattern}"),
                reason: e.to_string(),
            })?;
        Ok(RawListener { inner })
    }

    /// Declare a publisher of `type_name` payloads on `topic`, announced (its liveliness token) as
    /// a publisher of component `announce_as`. Its samples carry [`encoding_for`]`(type_name)`;
    /// like a typed publisher's, a congested link makes `put` wait rather than drop.
    pub async fn raw_publisher(
        &self,
        topic: &str,
        type_name: &str,
        announce_as: &str,
    ) -> Result<RawPublisher, BusError> {
        if !topic::is_valid_name(topic) {
            return Err(BusError::InvalidName(topic.to_string()));
        }
        if !is_valid_type_name(type_name) {
            return Err(BusError::InvalidName(type_name.to_string()));
        }
        if !topic::is_valid_segment(announce_as) {
            return Err(BusError::InvalidName(announce_as.to_string()));
        }
        let inner = self
            .session()
            .declare_publisher(self.topic_key(topic))
            .encoding(encoding_for(type_name))
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(|e| BusError::Zenoh {
                what: format!("declaring a publisher on {topic}"),
                reason: e.to_string(),
            })?;
        let token = self
            .session()
            .liveliness()
            .declare_token(liveliness::publisher_key(
                self.namespace(),
                announce_as,
                type_name,
                topic,
            ))
            .await
            .map_err(|e| BusError::Zenoh {
                what: format!("declaring the publisher of {topic}"),
                reason: e.to_string(),
            })?;
        let gid = crate::attachment::gid(&format!("{:?}/{}", inner.id(), inner.key_expr()));
        Ok(RawPublisher {
            inner,
            seq: std::sync::atomic::AtomicU64::new(0),
            gid,
            topic: topic.to_string(),
            type_name: type_name.to_string(),
            _token: token,
        })
    }

    /// Call service `name` with a payload of type `type_name` as it is (no check that it decodes:
    /// a tool forwards what it was given, a test sends what a foreign client would), waiting at
    /// most `timeout`. A server's typed error comes back as [`RawReply::Err`], a transport
    /// failure as the [`CallError`] of [`Bus::call`].
    pub async fn raw_call(
        &self,
        name: &str,
        type_name: &str,
        payload: Vec<u8>,
        timeout: Duration,
    ) -> Result<RawReply, CallError> {
        if !topic::is_valid_name(name) {
            return Err(CallError::Zenoh(format!("{name:?} is not a service name")));
        }
        let wire = self.call_payload(name, type_name, payload, timeout).await?;
        decode_reply(wire).map_err(CallError::Codec)
    }
}

impl Bus {
    /// Serve `name`, whose requests are `req_type` and replies `rep_type` known by name only (a
    /// component in another language): `handler` gets each request's payload as it came and
    /// returns the reply, encoded with [`encode_reply`] or [`encode_error_reply`]. The fair
    /// queues, time-outs and liveliness token are [`Bus::serve`]'s.
    pub async fn raw_serve<F, Fut>(
        &self,
        name: &str,
        req_type: &str,
        rep_type: &str,
        handler: F,
    ) -> Result<crate::bus::ServiceHandle, BusError>
    where
        F: Fn(Vec<u8>) -> Fut + Send + Sync + 'static,
        Fut: std::future::Future<Output = Vec<u8>> + Send + 'static,
    {
        if !topic::is_valid_name(name) {
            return Err(BusError::InvalidName(name.to_string()));
        }
        for t in [req_type, rep_type] {
            if !is_valid_type_name(t) {
                return Err(BusError::InvalidName(t.to_string()));
            }
        }
        let handler = Arc::new(handler);
        let answer: crate::bus::service::Answer = Arc::new(move |query| {
            let handler = handler.clone();
            Box::pin(async move {
                let reply = match query.payload() {
                    Some(p) => handler(p.to_bytes().into_owned()).await,
                    None => {
                        encode_error_reply(ServiceError::bad_request("the request has no payload"))
                    }
                };
                let key = query.key_expr().clone();
                if let Err(e) = query.reply(key, reply).await {
                    tracing::warn!("could not send a reply: {e}");
                }
            })
        });
        self.serve_queries(name, req_type, rep_type, answer).await
    }
}

/// A service's reply as it goes on the wire: the value, or the typed error.
pub fn encode_reply<T: Message>(reply: Result<T, ServiceError>) -> Result<Vec<u8>, CodecError> {
    codec::encode(&WireReply::from(reply), T::TYPE_NAME)
}

/// An error reply as it goes on the wire (any reply type reads it: the variant, then the error).
pub fn encode_error_reply(error: ServiceError) -> Vec<u8> {
    let reply: WireReply<()> = WireReply::Err(error);
    // A ServiceError is a code and a string: its encoding cannot fail.
    codec::encode(&reply, "robocog/ServiceError").unwrap_or_default()
}

/// A service's reply, decoded as far as it can be without knowing the reply type.
#[derive(Debug, Clone, PartialEq)]
pub enum RawReply {
    /// The service answered with a value: the reply payload as it came, read with
    /// [`RawReply::value`].
    Ok(Vec<u8>),
    /// The service refused or failed the request.
    Err(ServiceError),
}

impl RawReply {
    /// The value of an `Ok` reply as `T`; `None` for an error reply.
    pub fn value<T: Message>(&self) -> Option<Result<T, CodecError>> {
        match self {
            RawReply::Ok(wire) => Some(codec::decode::<WireReply<T>>(wire, T::TYPE_NAME).and_then(
                |w| match w {
                    WireReply::Ok(v) => Ok(v),
                    // Only a payload built by hand gets here: decode_reply read it as a value.
                    WireReply::Err(_) => Err(CodecError::Decode {
                        type_name: T::TYPE_NAME,
                        source: cdr::Error::Message("an error reply, not a value".into()),
                    }),
                },
            )),
            RawReply::Err(_) => None,
        }
    }
}

/// Read a reply payload as far as its kind: an error is decoded whole, a value is kept as it is.
pub fn decode_reply(wire: Vec<u8>) -> Result<RawReply, CodecError> {
    // `()` reads nothing, so this decodes the variant and, for an error, the error itself.
    match codec::decode::<WireReply<()>>(&wire, "reply")? {
        WireReply::Ok(()) => Ok(RawReply::Ok(wire)),
        WireReply::Err(e) => Ok(RawReply::Err(e)),
    }
}

#[cfg(test)]
#[expect(
    clippy::disallowed_methods,
    reason = "the tests wait for a real zenoh session"
)]
mod tests {
    use super::*;
    use crate::ConnectArgs;
    use crate::codec;
    use crate::liveliness::Token;
    use crate::msg::Message;
    use crate::msg::std_msgs::Text;

    #[test]
    fn encodings_round_trip() {
        let enc = encoding_for(Text::TYPE_NAME);
        assert_eq!(
            enc.to_string(),
            format!("application/cdr;{}", Text::TYPE_NAME)
        );
        assert_eq!(type_name_of(&enc.to_string()), Some(Text::TYPE_NAME));
        assert_eq!(
            type_name_of("application/cdr;robocog.body.JointStates"),
            Some("robocog.body.JointStates")
        );
    }

    #[test]
    fn malformed_encodings_name_no_type() {
        for enc in [
            "",
            "application/cdr",
            "application/cdr;",
            "application/json;robocog.Text",
            "zenoh/bytes",
            "application/cdr;robocog/Text",
            "application/cdr;a b",
            "application/cdr;a;b",
            "application/cdr;robocog.*",
        ] {
            assert_eq!(type_name_of(enc), None, "{enc:?}");
        }
        assert!(!is_valid_type_name(""));
        assert!(!is_valid_type_name("a#b"));
        assert!(is_valid_type_name("robocog.Text"));
    }

    async fn two_buses() -> (zenoh::Session, Bus, Bus) {
        let (router, endpoint) = crate::router::open_router("tcp/127.0.0.1:0").await.unwrap();
        let ns = format!("unit-raw-{}", std::process::id());
        let args = ConnectArgs::to_router(&endpoint, &ns);
        let a = Bus::open(&args, "unit-a").await.unwrap();
        let b = Bus::open(&args, "unit-b").await.unwrap();
        (router, a, b)
    }

    fn text(s: &str) -> Text {
        Text {
            text: s.into(),
            ..Default::default()
        }
    }

    /// Waits (at most 10 s) until `f` holds.
    async fn eventually(what: &str, mut f: impl AsyncFnMut() -> bool) {
        let until = std::time::Instant::now() + Duration::from_secs(10);
        while !f().await {
            assert!(std::time::Instant::now() < until, "never: {what}");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn raw_samples_travel_both_ways_over_the_bus() {
        let (_router, a, b) = two_buses().await;
        assert!(matches!(
            b.raw_subscriber("vision//ball", 4).await,
            Err(BusError::InvalidName(_))
        ));
        assert!(matches!(
            a.raw_publisher("chat/in", "robocog.*", "unit-tool").await,
            Err(BusError::InvalidName(_))
        ));

        // Typed out, raw in: every topic of the namespace, topic and type name from the sample.
        let every = b.raw_subscriber(EVERY_TOPIC, 16).await.unwrap();
        let seen = Arc::new(Mutex::new(Vec::<(String, Option<String>)>::new()));
        let listener = {
            let seen = seen.clone();
            b.raw_listener("chat/*", move |s| {
                seen.lock()
                    .unwrap()
                    .push((s.topic.clone(), s.type_name.clone()))
            })
            .await
            .unwrap()
        };
        let typed = a.publisher_named::<Text>("chat/out").await.unwrap();
        let before = crate::header::system_now_ns();
        let mut sent = text("hello");
        eventually("the raw subscription gets a typed message", async || {
            typed.publish(&mut sent).await.unwrap();
            every
                .recv_timeout(Duration::from_millis(100))
                .await
                .unwrap()
                .is_some_and(|s| {
                    s.topic == "chat/out"
                        && s.type_name.as_deref() == Some(Text::TYPE_NAME)
                        && s.receipt_ns >= before
                        && codec::decode::<Text>(&s.payload(), Text::TYPE_NAME)
                            .is_ok_and(|t| t.text == "hello")
                })
        })
        .await;
        eventually("the listener sees it too", async || {
            seen.lock()
                .unwrap()
                .contains(&("chat/out".into(), Some(Text::TYPE_NAME.into())))
        })
        .await;
        listener.undeclare().await.unwrap();

        // Raw out, typed in: the encoding and the publisher's token come from interfaces.
        let typed_in = b.subscriber_named::<Text>("chat/in", 16).await.unwrap();
        let raw = a
            .raw_publisher("chat/in", Text::TYPE_NAME, "unit-tool")
            .await
            .unwrap();
        eventually("the raw publisher sees the subscriber", async || {
            raw.has_subscribers().await
        })
        .await;
        let bytes = codec::encode(&text("raw"), Text::TYPE_NAME).unwrap();
        eventually("the typed subscriber decodes a raw payload", async || {
            raw.put(bytes.clone()).await.unwrap();
            typed_in
                .recv_timeout(Duration::from_millis(100))
                .await
                .unwrap()
                .is_some_and(|t| t.text == "raw")
        })
        .await;
        let graph = b.graph(Duration::from_millis(500)).await.unwrap();
        assert!(
            graph.iter().any(|t| matches!(t,
            Token::Publisher { component, type_name, topic }
                if component == "unit-tool" && type_name == Text::TYPE_NAME && topic == "chat/in"))
        );
        // Raw subscriptions do not show in the graph.
        assert!(!graph.iter().any(|t| matches!(t,
            Token::Subscriber { component, topic, .. } if component == "unit-b" && topic != "chat/in")));
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_full_raw_queue_drops_the_oldest_and_counts() {
        let (_router, a, b) = two_buses().await;
        let sub = b.raw_subscriber("flood", 2).await.unwrap();
        let typed = a.publisher_named::<Text>("flood").await.unwrap();
        let mut n = 0u64;
        eventually("drops are counted", async || {
            n += 1;
            typed.publish(&mut text(&n.to_string())).await.unwrap();
            sub.dropped() >= 3
        })
        .await;
        let counted = b
            .counters()
            .snapshot()
            .into_iter()
            .find(|(k, _)| k == "queue_dropped/flood")
            .map(|(_, v)| v);
        assert!(counted.is_some_and(|v| v >= 3));
        // The queue holds the newest samples.
        let first = sub.try_recv().unwrap();
        let second = sub.try_recv().unwrap();
        let n_of = |s: &RawSample| {
            codec::decode::<Text>(&s.payload(), Text::TYPE_NAME)
                .unwrap()
                .text
                .parse::<u64>()
                .unwrap()
        };
        assert!(n_of(&first) < n_of(&second));
        assert!(n_of(&first) > 1);
    }
}
