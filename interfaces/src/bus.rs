//! The typed bus over zenoh: publishers, subscribers, services, liveliness.
//!
//! A [`Bus`] is one component's zenoh session, bound to a namespace. Everything it declares is
//! typed by the [`Topic`] or [`Service`] constant it is given, and announced by a liveliness token
//! (see [`crate::liveliness`]).
//!
//! - Payloads are CDR ([`crate::codec`]); each sample's encoding is `application/cdr` with the
//!   message's type name as schema ([`crate::raw::encoding_for`]), so any tool can decode it by
//!   name. Tools that handle payloads whose type they only know by name (record, replay, the
//!   topic tools, the viewer) use the raw subscriptions and publishers of [`crate::raw`].
//! - Payloads from [`SHM_THRESHOLD`] bytes up (camera frames) are written once, straight into a
//!   zenoh shared-memory buffer; a subscriber on the same host reads them without a copy through
//!   the network stack. Each subscriber counts the samples that really arrived in shared memory
//!   ([`Subscriber::shm_received`], and the bus counter `shm_received/<topic>`).
//! - Big messages can also be read in place: [`Subscriber::recv_borrowed`] hands out a
//!   [`Received`] whose [`Received::view`] is the message with its byte buffers borrowed from the
//!   payload (for a frame in shared memory, from the publisher's buffer: no copy at all), checked
//!   and counted exactly as [`Subscriber::recv`] does. [`Publisher::publish_view`] encodes a view
//!   of the producer's own buffers (one copy, into shared memory), and [`Publisher::relay`]
//!   forwards a received payload as it is.
//! - A payload that does not decode as the topic's type is counted (per topic, in the bus'
//!   [`Counters`], published on `diagnostics`) and logged at most once a second per topic; the
//!   subscriber carries on.
//! - Service calls carry a time-out; a handler's error travels back typed ([`ServiceError`]).

use crate::args::ConnectArgs;
use crate::attachment::Attachment;
use crate::codec::{self, CodecError};
use crate::header::Clock;
use crate::liveliness::{self, Token};
use crate::msg::{Borrowable, Message};
use crate::ratelimit::RateLimiter;
use crate::topic::{self, Service, Topic};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::future::Future;
use std::marker::PhantomData;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::bytes::ZBytes;
use zenoh::liveliness::LivelinessToken;
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;
use zenoh::shm::{GarbageCollect, PosixShmProviderBackend, ShmProvider, ShmProviderBuilder};

/// Payloads of this many bytes or more go through shared memory when it is enabled.
pub const SHM_THRESHOLD: usize = 64 * 1024;
/// Size of each process' shared-memory pool: room for a dozen RGB-D frames in flight.
pub const SHM_POOL_BYTES: usize = 32 * 1024 * 1024;
/// Default depth of a subscriber's queue; a full queue blocks the sender (no silent loss).
pub const DEFAULT_QUEUE: usize = 256;

/// Errors of the bus.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    #[error("invalid name {0:?}: use letters, digits, '_', '-' (and '/' inside topic names)")]
    InvalidName(String),
    #[error("bad zenoh configuration: {0}")]
    Config(String),
    #[error(
        "cannot join the bus at {endpoints}: {reason}\n  (is `robocog launch` running? pass --connect <endpoint> or set ROBOCOG_CONNECT)"
    )]
    Connect { endpoints: String, reason: String },
    #[error("zenoh error while {what}: {reason}")]
    Zenoh { what: String, reason: String },
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error("the subscription to {0} is closed")]
    Closed(String),
}

fn zerr(what: impl Into<String>) -> impl FnOnce(zenoh::Error) -> BusError {
    let what = what.into();
    move |e| BusError::Zenoh {
        what,
        reason: e.to_string(),
    }
}

/// Named counters of a component: decode failures, drops, fallbacks. Published on `diagnostics`.
#[derive(Debug, Default)]
pub struct Counters {
    map: Mutex<BTreeMap<String, Arc<AtomicU64>>>,
}

impl Counters {
    /// The counter `name`, created at 0 when new.
    pub fn counter(&self, name: &str) -> Arc<AtomicU64> {
        let mut map = self.map.lock().unwrap_or_else(|p| p.into_inner());
        map.entry(name.to_string()).or_default().clone()
    }
    /// Add one to counter `name`.
    pub fn incr(&self, name: &str) {
        self.counter(name).fetch_add(1, Ordering::Relaxed);
    }
    /// Every counter and its value, sorted by name.
    pub fn snapshot(&self) -> Vec<(String, u64)> {
        let map = self.map.lock().unwrap_or_else(|p| p.into_inner());
        map.iter()
            .map(|(k, v)| (k.clone(), v.load(Ordering::Relaxed)))
            .collect()
    }
}

struct Inner {
    session: zenoh::Session,
    namespace: String,
    component: String,
    host: String,
    clock: Clock,
    counters: Arc<Counters>,
    shm_enabled: bool,
    shm: OnceLock<Option<Arc<ShmProvider<PosixShmProviderBackend>>>>,
    /// The component's liveliness token, once declared.
    token: tokio::sync::Mutex<Option<LivelinessToken>>,
    /// Services still to be served before the component announces itself (see
    /// [`BusOptions::ready_after_services`]); `None` once announced or when it never will be.
    pending_services: tokio::sync::Mutex<Option<std::collections::HashSet<String>>>,
    since_ms: i64,
}

/// One process' connection to the bus (cheap to clone).
#[derive(Clone)]
pub struct Bus {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for Bus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bus")
            .field("namespace", &self.inner.namespace)
            .field("component", &self.inner.component)
            .finish()
    }
}

/// How a [`Bus`] opens.
#[derive(Debug, Clone, Default)]
pub struct BusOptions {
    /// Declare the component's liveliness token (components do; command-line tools do not, so
    /// they never show up in `robocog component list`).
    pub announce: bool,
    /// Announce only once all these services are served (so a component is "up" for the
    /// launcher when its services answer, not before). Empty: announce at once.
    pub ready_after_services: Vec<String>,
    pub clock: Clock,
}

impl Bus {
    /// Join the bus as component `component` (its liveliness token is declared).
    pub async fn open(args: &ConnectArgs, component: &str) -> Result<Bus, BusError> {
        Self::open_with(
            args,
            component,
            BusOptions {
                announce: true,
                ..Default::default()
            },
        )
        .await
    }

    /// Join the bus with explicit options.
    pub async fn open_with(
        args: &ConnectArgs,
        component: &str,
        options: BusOptions,
    ) -> Result<Bus, BusError> {
        if !topic::is_valid_segment(&args.namespace) {
            return Err(BusError::InvalidName(args.namespace.clone()));
        }
        if !topic::is_valid_segment(component) {
            return Err(BusError::InvalidName(component.to_string()));
        }
        let config = args.zenoh_config()?;
        let session = zenoh::open(config).await.map_err(|e| BusError::Connect {
            endpoints: args.endpoints().join(","),
            reason: e.to_string(),
        })?;
        let host = gethostname::gethostname()
            .to_string_lossy()
            .replace(['/', '*', '$', '?', '#'], "_");
        let since_ms = crate::header::system_now_ns() / 1_000_000;
        let pending = (options.announce && !options.ready_after_services.is_empty())
            .then(|| options.ready_after_services.iter().cloned().collect());
        let bus = Bus {
            inner: Arc::new(Inner {
                session,
                namespace: args.namespace.clone(),
                component: component.to_string(),
                host,
                clock: options.clock,
                counters: Arc::new(Counters::default()),
                shm_enabled: !args.no_shm,
                shm: OnceLock::new(),
                token: tokio::sync::Mutex::new(None),
                pending_services: tokio::sync::Mutex::new(pending),
                since_ms,
            }),
        };
        if options.announce && options.ready_after_services.is_empty() {
            bus.announce().await?;
        }
        Ok(bus)
    }

    /// Declare the component's liveliness token: from now on it is up.
    async fn announce(&self) -> Result<(), BusError> {
        let key = liveliness::component_key(
            &self.inner.namespace,
            &self.inner.component,
            &self.inner.host,
            std::process::id(),
            self.inner.since_ms,
        );
        let token = self
            .inner
            .session
            .liveliness()
            .declare_token(key)
            .await
            .map_err(zerr("declaring the component's liveliness token"))?;
        *self.inner.token.lock().await = Some(token);
        Ok(())
    }

    /// Service `name` is now served; announce the component when it was the last one awaited.
    async fn service_ready(&self, name: &str) -> Result<(), BusError> {
        let mut pending = self.inner.pending_services.lock().await;
        let done = match pending.as_mut() {
            Some(set) => {
                set.remove(name);
                set.is_empty()
            }
            None => false,
        };
        if done {
            *pending = None;
            drop(pending);
            self.announce().await?;
        }
        Ok(())
    }

    pub fn namespace(&self) -> &str {
        &self.inner.namespace
    }
    pub fn component(&self) -> &str {
        &self.inner.component
    }
    pub fn host(&self) -> &str {
        &self.inner.host
    }
    pub fn clock(&self) -> &Clock {
        &self.inner.clock
    }
    pub fn counters(&self) -> &Arc<Counters> {
        &self.inner.counters
    }
    /// The underlying zenoh session, for what the typed API does not cover (benchmarks, tools).
    pub fn session(&self) -> &zenoh::Session {
        &self.inner.session
    }
    /// The zenoh key of a topic of this namespace.
    pub fn topic_key(&self, name: &str) -> String {
        topic::topic_key(&self.inner.namespace, name)
    }

    fn shm_provider(&self) -> Option<Arc<ShmProvider<PosixShmProviderBackend>>> {
        if !self.inner.shm_enabled {
            return None;
        }
        self.inner
            .shm
            .get_or_init(
                || match ShmProviderBuilder::default_backend(SHM_POOL_BYTES).wait() {
                    Ok(p) => Some(Arc::new(p)),
                    Err(e) => {
                        tracing::warn!(
                            "shared memory unavailable, large payloads will be copied: {e}"
                        );
                        None
                    }
                },
            )
            .clone()
    }

    async fn token(&self, key: String) -> Result<LivelinessToken, BusError> {
        self.inner
            .session
            .liveliness()
            .declare_token(key)
            .await
            .map_err(zerr("declaring a liveliness token"))
    }

    /// Declare a publisher on `topic`.
    pub async fn publisher<T: Message>(&self, topic: &Topic<T>) -> Result<Publisher<T>, BusError> {
        self.publisher_named(topic.name()).await
    }

    /// Declare a publisher of `T` on a topic name chosen at run time (tools, replay). The name is
    /// checked; prefer [`Bus::publisher`] with a constant.
    pub async fn publisher_named<T: Message>(&self, name: &str) -> Result<Publisher<T>, BusError> {
        if !topic::is_valid_name(name) {
            return Err(BusError::InvalidName(name.to_string()));
        }
        let key = self.topic_key(name);
        let inner = self
            .inner
            .session
            .declare_publisher(key)
            .encoding(crate::raw::encoding_for(T::TYPE_NAME))
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(zerr(format!("declaring a publisher on {name}")))?;
        let token = self
            .token(liveliness::publisher_key(
                self.namespace(),
                self.component(),
                T::TYPE_NAME,
                name,
            ))
            .await?;
        let shm = self.shm_provider();
        let gid = crate::attachment::gid(&format!("{:?}/{}", inner.id(), inner.key_expr()));
        Ok(Publisher {
            inner,
            seq: AtomicU64::new(0),
            gid,
            clock: self.inner.clock.clone(),
            shm,
            shm_fallbacks: self.inner.counters.counter(&format!("shm_fallback/{name}")),
            _token: token,
            _type: PhantomData,
        })
    }

    /// Subscribe to `topic` with the default queue depth.
    pub async fn subscriber<T: Message>(
        &self,
        topic: &Topic<T>,
    ) -> Result<Subscriber<T>, BusError> {
        self.subscriber_named(topic.name(), DEFAULT_QUEUE).await
    }

    /// Subscribe to a topic name chosen at run time, with a queue of `queue` samples.
    pub async fn subscriber_named<T: Message>(
        &self,
        name: &str,
        queue: usize,
    ) -> Result<Subscriber<T>, BusError> {
        if !topic::is_valid_name(name) {
            return Err(BusError::InvalidName(name.to_string()));
        }
        let key = self.topic_key(name);
        // A full queue drops its oldest sample (counted, logged rate-limited) instead of blocking
        // zenoh's receive path: a slow consumer must never stall the other subscriptions of the
        // process, nor the publishers.
        let (tx, rx) = flume::bounded::<Sample>(queue.max(1));
        let evict = rx.clone();
        let dropped = self
            .inner
            .counters
            .counter(&format!("queue_dropped/{name}"));
        let drop_limiter = Mutex::new(RateLimiter::new(Duration::from_secs(1)));
        let topic_name = name.to_string();
        let inner = self
            .inner
            .session
            .declare_subscriber(key)
            .callback(move |sample| {
                offer_dropping_oldest(&tx, &evict, sample, &dropped, &drop_limiter, &topic_name)
            })
            .await
            .map_err(zerr(format!("subscribing to {name}")))?;
        let token = self
            .token(liveliness::subscriber_key(
                self.namespace(),
                self.component(),
                T::TYPE_NAME,
                name,
            ))
            .await?;
        Ok(Subscriber {
            _inner: inner,
            queue: rx,
            topic: name.to_string(),
            decode_errors: self
                .inner
                .counters
                .counter(&format!("decode_errors/{name}")),
            received: AtomicU64::new(0),
            shm_received: AtomicU64::new(0),
            shm_counter: OnceLock::new(),
            counters: self.inner.counters.clone(),
            limiter: Mutex::new(RateLimiter::new(Duration::from_secs(1))),
            _token: token,
            _type: PhantomData,
        })
    }

    /// Set this bus' (virtual) clock from the `clock` topic for as long as the returned handle
    /// lives. Each message moves the clock in zenoh's receive callback, before any later sample
    /// is queued for a subscriber: a message that arrives after `clock` says T (a replay
    /// publishes the clock before the messages of that time) finds the clock at T or later. A
    /// payload that does not decode is counted like a subscriber's (`decode_errors/clock`).
    pub async fn follow_clock(&self) -> Result<ClockFollower, BusError> {
        use crate::msg::std_msgs::ClockTime;
        let name = crate::topics::CLOCK.name();
        let clock = self.inner.clock.clone();
        let errors = self
            .inner
            .counters
            .counter(&format!("decode_errors/{name}"));
        let limiter = Mutex::new(RateLimiter::new(Duration::from_secs(1)));
        let inner = self
            .inner
            .session
            .declare_subscriber(self.topic_key(name))
            .callback(move |sample| {
                match codec::decode::<ClockTime>(&sample.payload().to_bytes(), ClockTime::TYPE_NAME)
                {
                    Ok(t) => clock.set_ns(t.time_ns),
                    Err(e) => {
                        let n = errors.fetch_add(1, Ordering::Relaxed) + 1;
                        let mut l = limiter.lock().unwrap_or_else(|p| p.into_inner());
                        if let Some(suppressed) = l.allow(Instant::now()) {
                            tracing::warn!(total = n, suppressed, "a bad clock message: {e}");
                        }
                    }
                }
            })
            .await
            .map_err(zerr(format!("subscribing to {name}")))?;
        let token = self
            .token(liveliness::subscriber_key(
                self.namespace(),
                self.component(),
                ClockTime::TYPE_NAME,
                name,
            ))
            .await?;
        Ok(ClockFollower {
            _inner: inner,
            _token: token,
        })
    }

    /// Serve `service`: every request is decoded and handed to `handler`, whose result (or typed
    /// error) goes back to the caller. A request that does not decode gets a `BadRequest` reply.
    pub async fn serve<Req, Rep, F, Fut>(
        &self,
        service: &Service<Req, Rep>,
        handler: F,
    ) -> Result<ServiceHandle, BusError>
    where
        Req: Message,
        Rep: Message,
        F: Fn(Req) -> Fut + Send + Sync + 'static,
        Fut: Future<Output = Result<Rep, ServiceError>> + Send + 'static,
    {
        let name = service.name();
        let key = topic::service_key(self.namespace(), name);
        let queryable = self
            .inner
            .session
            .declare_queryable(key)
            .with(zenoh::handlers::FifoChannel::new(DEFAULT_QUEUE))
            .await
            .map_err(zerr(format!("serving {name}")))?;
        let token = self
            .token(liveliness::service_key(
                self.namespace(),
                self.component(),
                Req::TYPE_NAME,
                Rep::TYPE_NAME,
                name,
            ))
            .await?;
        let handler = Arc::new(handler);
        let bad_requests = self.inner.counters.counter(&format!("bad_requests/{name}"));
        let task = tokio::spawn(async move {
            while let Ok(query) = queryable.recv_async().await {
                let handler = handler.clone();
                let bad_requests = bad_requests.clone();
                tokio::spawn(async move {
                    let request = match query.payload() {
                        Some(p) => codec::decode::<Req>(&p.to_bytes(), Req::TYPE_NAME)
                            .map_err(|e| ServiceError::bad_request(e.to_string())),
                        None => Err(ServiceError::bad_request("the request has no payload")),
                    };
                    let reply: WireReply<Rep> = match request {
                        Ok(req) => handler(req).await.into(),
                        Err(e) => {
                            bad_requests.fetch_add(1, Ordering::Relaxed);
                            Err::<Rep, _>(e).into()
                        }
                    };
                    match codec::encode(&reply, Rep::TYPE_NAME) {
                        Ok(bytes) => {
                            let key = query.key_expr().clone();
                            if let Err(e) = query.reply(key, bytes).await {
                                tracing::warn!("could not send a reply: {e}");
                            }
                        }
                        Err(e) => tracing::error!("could not encode a reply: {e}"),
                    }
                });
            }
        });
        self.service_ready(name).await?;
        Ok(ServiceHandle {
            task,
            _token: token,
        })
    }

    /// Call `service` with `request`, waiting at most `timeout` for the reply.
    pub async fn call<Req: Message, Rep: Message>(
        &self,
        service: &Service<Req, Rep>,
        request: &Req,
        timeout: Duration,
    ) -> Result<Rep, CallError> {
        let bytes = codec::encode(request, Req::TYPE_NAME).map_err(CallError::Codec)?;
        let reply = self
            .call_payload(service.name(), Req::TYPE_NAME, bytes, timeout)
            .await?;
        let wire: WireReply<Rep> =
            codec::decode(&reply, Rep::TYPE_NAME).map_err(CallError::Codec)?;
        match wire {
            WireReply::Ok(rep) => Ok(rep),
            WireReply::Err(e) => Err(CallError::Remote(e)),
        }
    }

    /// Send one request payload (already encoded, of type `req_type`) to service `name` and
    /// return the first reply's payload: a wire reply, decoded by [`Bus::call`] or
    /// [`crate::raw::decode_reply`].
    pub(crate) async fn call_payload(
        &self,
        name: &str,
        req_type: &str,
        bytes: Vec<u8>,
        timeout: Duration,
    ) -> Result<Vec<u8>, CallError> {
        let started = Instant::now();
        let replies = self
            .inner
            .session
            .get(topic::service_key(self.namespace(), name))
            .payload(bytes)
            .encoding(crate::raw::encoding_for(req_type))
            .timeout(timeout)
            .await
            .map_err(|e| CallError::Zenoh(e.to_string()))?;
        let first =
            tokio::time::timeout(timeout + Duration::from_millis(200), replies.recv_async()).await;
        match first {
            Ok(Ok(reply)) => match reply.into_result() {
                Ok(sample) => Ok(sample.payload().to_bytes().into_owned()),
                Err(e) => {
                    let why = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
                    if why.eq_ignore_ascii_case("timeout") {
                        Err(CallError::Timeout {
                            service: name.to_string(),
                            timeout,
                        })
                    } else {
                        Err(CallError::Zenoh(why))
                    }
                }
            },
            // The reply channel closed with nothing in it: before the time-out, nobody serves
            // the service; at the time-out, somebody did not answer in time.
            Ok(Err(_)) if started.elapsed() + Duration::from_millis(20) < timeout => {
                Err(CallError::NoServer(name.to_string()))
            }
            Ok(Err(_)) | Err(_) => Err(CallError::Timeout {
                service: name.to_string(),
                timeout,
            }),
        }
    }

    /// Every liveliness token of this namespace now: the live graph.
    pub async fn graph(&self, wait: Duration) -> Result<Vec<Token>, BusError> {
        let replies = self
            .inner
            .session
            .liveliness()
            .get(liveliness::all(self.namespace()))
            .timeout(wait)
            .await
            .map_err(zerr("querying liveliness"))?;
        let mut tokens = Vec::new();
        while let Ok(reply) = replies.recv_async().await {
            if let Ok(sample) = reply.result()
                && let Some(t) = liveliness::parse(self.namespace(), sample.key_expr().as_str())
            {
                tokens.push(t);
            }
        }
        Ok(tokens)
    }
}

/// Queue `item` without waiting: when the queue is full, drop its oldest item, count it in
/// `dropped` and log it (at most as often as `limiter` allows). Runs in zenoh's receive callback,
/// which must never block: a slow consumer loses its oldest samples instead of stalling the
/// process' other subscriptions and the publishers.
pub(crate) fn offer_dropping_oldest<S>(
    tx: &flume::Sender<S>,
    evict: &flume::Receiver<S>,
    item: S,
    dropped: &AtomicU64,
    limiter: &Mutex<RateLimiter>,
    topic: &str,
) {
    let mut item = item;
    loop {
        match tx.try_send(item) {
            Ok(()) => break,
            Err(flume::TrySendError::Full(back)) => {
                if evict.try_recv().is_ok() {
                    let n = dropped.fetch_add(1, Ordering::Relaxed) + 1;
                    let mut l = limiter.lock().unwrap_or_else(|p| p.into_inner());
                    if let Some(suppressed) = l.allow(Instant::now()) {
                        tracing::warn!(
                            topic = %topic,
                            total = n,
                            suppressed,
                            "subscriber queue full: dropped the oldest sample (the consumer is slower than the publisher)"
                        );
                    }
                }
                item = back;
            }
            Err(flume::TrySendError::Disconnected(_)) => break,
        }
    }
}

/// A typed publisher. Dropping it withdraws its liveliness token.
pub struct Publisher<T: Message> {
    inner: zenoh::pubsub::Publisher<'static>,
    seq: AtomicU64,
    /// The GID in every sample's attachment.
    gid: [u8; 16],
    clock: Clock,
    shm: Option<Arc<ShmProvider<PosixShmProviderBackend>>>,
    shm_fallbacks: Arc<AtomicU64>,
    _token: LivelinessToken,
    _type: PhantomData<fn(T)>,
}

impl<T: Message> std::fmt::Debug for Publisher<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Publisher<{}>({})", T::TYPE_NAME, self.inner.key_expr())
    }
}

impl<T: Message> Publisher<T> {
    /// Stamp `msg` (sequence number always; time when its stamp is 0) and publish it.
    pub async fn publish(&self, msg: &mut T) -> Result<(), BusError> {
        let header = msg.header_mut();
        header.seq = self.seq.fetch_add(1, Ordering::Relaxed);
        if header.stamp_ns == 0 {
            header.stamp_ns = self.clock.now_ns();
        }
        self.put(msg).await
    }

    /// Publish `msg` as it is, header untouched (replay, relays).
    pub async fn put(&self, msg: &T) -> Result<(), BusError> {
        let h = msg.header();
        self.put_value(msg, h.seq, h.stamp_ns).await
    }

    /// The attachment of a sample with this sequence number and stamp.
    fn attachment(&self, seq: u64, stamp_ns: i64) -> Vec<u8> {
        crate::attachment::Attachment {
            sequence: seq as i64,
            source_timestamp_ns: stamp_ns,
            gid: self.gid,
        }
        .encode()
        .to_vec()
    }

    /// Encode `value` (a `T`, or a view of one: the same bytes) and publish it with its sequence
    /// number in the attachment: straight into a shared-memory buffer from [`SHM_THRESHOLD`]
    /// bytes up, else into a vector.
    async fn put_value<V: Serialize + Sync>(
        &self,
        value: &V,
        seq: u64,
        stamp_ns: i64,
    ) -> Result<(), BusError> {
        let len = codec::encoded_len(value);
        let attachment = self.attachment(seq, stamp_ns);
        if len >= SHM_THRESHOLD
            && let Some(shm) = &self.shm
        {
            match shm.alloc(len).with_policy::<GarbageCollect>().wait() {
                Ok(mut buf) => {
                    codec::encode_into(value, &mut buf[..len], T::TYPE_NAME)?;
                    return self
                        .inner
                        .put(buf)
                        .attachment(attachment)
                        .await
                        .map_err(zerr("publishing"));
                }
                Err(e) => {
                    self.shm_fallbacks.fetch_add(1, Ordering::Relaxed);
                    tracing::debug!("shared memory pool full ({e:?}), copying this payload");
                }
            }
        }
        let bytes = codec::encode(value, T::TYPE_NAME)?;
        self.inner
            .put(bytes)
            .attachment(attachment)
            .await
            .map_err(zerr("publishing"))
    }

    /// Publish already-encoded CDR bytes (the topic tools and replay, which hold payloads), with
    /// the next sequence number of this publisher.
    pub async fn put_encoded(&self, bytes: Vec<u8>) -> Result<(), BusError> {
        let seq = self.seq.fetch_add(1, Ordering::Relaxed);
        let attachment = self.attachment(seq, self.clock.now_ns());
        self.inner
            .put(bytes)
            .attachment(attachment)
            .await
            .map_err(zerr("publishing"))
    }
}

impl<T: Borrowable> Publisher<T> {
    /// Stamp `view` (as [`Publisher::publish`] does) and publish it. A producer that holds its
    /// pixels in its own buffers borrows them into a view: they are encoded once, straight into
    /// the shared-memory buffer, with no owned message built first. Same bytes as publishing the
    /// owned message.
    pub async fn publish_view(&self, view: &mut T::View<'_>) -> Result<(), BusError> {
        let header = T::view_header_mut(view);
        header.seq = self.seq.fetch_add(1, Ordering::Relaxed);
        if header.stamp_ns == 0 {
            header.stamp_ns = self.clock.now_ns();
        }
        let (seq, stamp_ns) = (header.seq, header.stamp_ns);
        self.put_value(&*view, seq, stamp_ns).await
    }

    /// Publish a received message again as it is, header and sequence number untouched, without
    /// a copy: the same payload (for a frame, the same shared-memory buffer) goes out on this
    /// topic. For relays.
    pub async fn relay(&self, msg: &Received<T>) -> Result<(), BusError> {
        let stamp_ns = codec::decode_borrowed::<T::View<'_>>(msg.payload.bytes(), T::TYPE_NAME)
            .map(|mut v| T::view_header_mut(&mut v).stamp_ns)
            .unwrap_or_default();
        self.inner
            .put(msg.payload.to_zbytes())
            .attachment(self.attachment(msg.seq, stamp_ns))
            .await
            .map_err(zerr("publishing"))
    }
}

/// A message taken from a [`Subscriber`] with [`Subscriber::recv_borrowed`]: the payload stays
/// where zenoh delivered it (for a camera frame, the publisher's shared-memory buffer), and
/// [`Received::view`] reads the message in place, its byte buffers borrowed from the payload.
/// The payload was checked when it was taken from the queue (one that does not decode is counted
/// in `decode_errors/<topic>` and skipped, as [`Subscriber::recv`] does), so the view is always
/// there.
///
/// Holding a `Received` holds its payload: a shared-memory buffer returns to the publisher's pool
/// only once nobody holds it. Drop a frame when done with it.
pub struct Received<T: Borrowable> {
    payload: Payload,
    /// The sequence number from the sample's attachment (0 without one).
    seq: u64,
    _type: PhantomData<fn() -> T>,
}

impl<T: Borrowable> std::fmt::Debug for Received<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Received<{}>({} bytes{})",
            T::TYPE_NAME,
            self.payload.bytes().len(),
            if self.is_shm() { ", shared memory" } else { "" }
        )
    }
}

impl<T: Borrowable> Received<T> {
    /// The message, its byte buffers borrowed from the payload. Decodes the small fields (header,
    /// sizes) each call; the buffers are never copied.
    pub fn view(&self) -> T::View<'_> {
        // The same bytes decoded as the same type when the message was received, and decoding is
        // a pure function of the bytes: this cannot fail, the default is never returned.
        let mut view: T::View<'_> =
            codec::decode_borrowed(self.payload.bytes(), T::TYPE_NAME).unwrap_or_default();
        T::view_header_mut(&mut view).seq = self.seq;
        view
    }

    /// The owned message (copies the buffers).
    pub fn to_message(&self) -> Result<T, CodecError> {
        let mut m: T = codec::decode(self.payload.bytes(), T::TYPE_NAME)?;
        m.header_mut().seq = self.seq;
        Ok(m)
    }

    /// The CDR payload as received.
    pub fn payload(&self) -> &[u8] {
        self.payload.bytes()
    }

    /// Whether the payload is a zenoh shared-memory buffer (read in place, never copied).
    pub fn is_shm(&self) -> bool {
        matches!(&self.payload, Payload::InPlace(z) if z.as_shm().is_some())
    }
}

/// A received payload in one contiguous piece.
enum Payload {
    /// Where zenoh delivered it: a shared-memory buffer, or one network buffer.
    InPlace(ZBytes),
    /// It arrived in fragments: gathered into one buffer (one copy).
    Gathered(Vec<u8>),
}

impl Payload {
    fn of(bytes: &ZBytes) -> Payload {
        let mut slices = bytes.slices();
        match (slices.next(), slices.next()) {
            (_, None) => Payload::InPlace(bytes.clone()),
            _ => Payload::Gathered(bytes.to_bytes().into_owned()),
        }
    }

    fn bytes(&self) -> &[u8] {
        match self {
            Payload::InPlace(z) => z.slices().next().unwrap_or_default(),
            Payload::Gathered(v) => v,
        }
    }

    /// The payload to send again (a reference to the same buffer when in place).
    fn to_zbytes(&self) -> ZBytes {
        match self {
            Payload::InPlace(z) => z.clone(),
            Payload::Gathered(v) => ZBytes::from(v.clone()),
        }
    }
}

/// The subscription that moves a bus' clock (see [`Bus::follow_clock`]); dropping it stops.
pub struct ClockFollower {
    _inner: zenoh::pubsub::Subscriber<()>,
    _token: LivelinessToken,
}

impl std::fmt::Debug for ClockFollower {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ClockFollower")
    }
}

/// A typed subscription. Undecodable payloads are counted and skipped.
pub struct Subscriber<T: Message> {
    /// Undeclared when dropped.
    _inner: zenoh::pubsub::Subscriber<()>,
    /// Bounded; full means drop-oldest (`queue_dropped/<topic>`).
    queue: flume::Receiver<Sample>,
    topic: String,
    decode_errors: Arc<AtomicU64>,
    /// Samples taken from the queue (decoded or not).
    received: AtomicU64,
    /// Of those, samples whose payload was a zenoh shared-memory buffer.
    shm_received: AtomicU64,
    /// The bus counter `shm_received/<topic>`, created with the first shared-memory sample.
    shm_counter: OnceLock<Arc<AtomicU64>>,
    counters: Arc<Counters>,
    limiter: Mutex<RateLimiter>,
    _token: LivelinessToken,
    _type: PhantomData<fn() -> T>,
}

impl<T: Message> std::fmt::Debug for Subscriber<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Subscriber<{}>({})", T::TYPE_NAME, self.topic)
    }
}

impl<T: Message> Subscriber<T> {
    /// The next message that decodes; `Err` only when the subscription is closed.
    pub async fn recv(&self) -> Result<T, BusError> {
        loop {
            let sample = self
                .queue
                .recv_async()
                .await
                .map_err(|_| BusError::Closed(self.topic.clone()))?;
            if let Some(msg) = self.decode(&sample) {
                return Ok(msg);
            }
        }
    }

    /// The next message, or `None` after `timeout`.
    pub async fn recv_timeout(&self, timeout: Duration) -> Result<Option<T>, BusError> {
        match tokio::time::timeout(timeout, self.recv()).await {
            Ok(r) => r.map(Some),
            Err(_) => Ok(None),
        }
    }

    /// A message already queued, if any (never waits).
    pub fn try_recv(&self) -> Option<T> {
        while let Ok(sample) = self.queue.try_recv() {
            if let Some(msg) = self.decode(&sample) {
                return Some(msg);
            }
        }
        None
    }

    /// The newest queued message, dropping older ones (for latest-value consumers such as a
    /// controller reading joint states).
    pub fn latest(&self) -> Option<T> {
        let mut last = None;
        while let Some(m) = self.try_recv() {
            last = Some(m);
        }
        last
    }

    /// How many payloads on this topic failed to decode so far.
    pub fn decode_errors(&self) -> u64 {
        self.decode_errors.load(Ordering::Relaxed)
    }

    /// How many samples this subscriber has taken from its queue so far (decoded or not).
    pub fn received(&self) -> u64 {
        self.received.load(Ordering::Relaxed)
    }

    /// How many of [`Subscriber::received`] arrived as a zenoh shared-memory buffer (the
    /// publisher wrote the payload into shared memory, [`SHM_THRESHOLD`] bytes and up, and both
    /// ends and the router between them have shared memory enabled), rather than as bytes copied
    /// through the network stack. The same count is the bus counter `shm_received/<topic>` (on
    /// `diagnostics`), which appears with the first such sample. This is how a test or an
    /// operator sees that frames really travel through shared memory.
    pub fn shm_received(&self) -> u64 {
        self.shm_received.load(Ordering::Relaxed)
    }

    fn decode(&self, sample: &Sample) -> Option<T> {
        self.count_received(sample);
        match codec::decode::<T>(&sample.payload().to_bytes(), T::TYPE_NAME) {
            Ok(mut m) => {
                m.header_mut().seq = Attachment::sequence_of(sample.attachment()).unwrap_or(0);
                Some(m)
            }
            Err(e) => {
                self.count_decode_error(&e);
                None
            }
        }
    }

    /// Counts a sample taken from the queue, and whether it arrived in shared memory.
    fn count_received(&self, sample: &Sample) {
        self.received.fetch_add(1, Ordering::Relaxed);
        if sample.payload().as_shm().is_some() {
            self.shm_received.fetch_add(1, Ordering::Relaxed);
            self.shm_counter
                .get_or_init(|| {
                    self.counters
                        .counter(&format!("shm_received/{}", self.topic))
                })
                .fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Counts a payload that did not decode, and logs it (at most once a second).
    fn count_decode_error(&self, e: &CodecError) {
        let n = self.decode_errors.fetch_add(1, Ordering::Relaxed) + 1;
        let mut limiter = self.limiter.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(suppressed) = limiter.allow(Instant::now()) {
            tracing::warn!(
                topic = %self.topic,
                total = n,
                suppressed,
                "dropped a payload that is not a {}: {e}",
                T::TYPE_NAME
            );
        }
    }
}

impl<T: Borrowable> Subscriber<T> {
    /// The next message that decodes, left in place: its [`Received::view`] borrows the byte
    /// buffers from the payload instead of copying them out (for a frame in shared memory, no
    /// copy at all). Same queue, same counters (`received`, `shm_received`, `decode_errors`) as
    /// [`Subscriber::recv`]; `Err` only when the subscription is closed.
    pub async fn recv_borrowed(&self) -> Result<Received<T>, BusError> {
        loop {
            let sample = self
                .queue
                .recv_async()
                .await
                .map_err(|_| BusError::Closed(self.topic.clone()))?;
            if let Some(msg) = self.check(&sample) {
                return Ok(msg);
            }
        }
    }

    /// [`Subscriber::recv_borrowed`] for a message already queued, if any (never waits).
    pub fn try_recv_borrowed(&self) -> Option<Received<T>> {
        while let Ok(sample) = self.queue.try_recv() {
            if let Some(msg) = self.check(&sample) {
                return Some(msg);
            }
        }
        None
    }

    /// The newest queued message, in place, dropping older ones.
    pub fn latest_borrowed(&self) -> Option<Received<T>> {
        let mut last = None;
        while let Some(m) = self.try_recv_borrowed() {
            last = Some(m);
        }
        last
    }

    /// Counts `sample` and checks that it decodes as a view of `T`.
    fn check(&self, sample: &Sample) -> Option<Received<T>> {
        self.count_received(sample);
        let payload = Payload::of(sample.payload());
        let checked =
            codec::decode_borrowed::<T::View<'_>>(payload.bytes(), T::TYPE_NAME).map(drop);
        match checked {
            Ok(()) => Some(Received {
                payload,
                seq: Attachment::sequence_of(sample.attachment()).unwrap_or(0),
                _type: PhantomData,
            }),
            Err(e) => {
                self.count_decode_error(&e);
                None
            }
        }
    }
}

/// A served service; dropping it stops serving.
pub struct ServiceHandle {
    task: tokio::task::JoinHandle<()>,
    _token: LivelinessToken,
}

impl std::fmt::Debug for ServiceHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ServiceHandle")
    }
}

impl Drop for ServiceHandle {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Why a service refused or failed a request; travels back to the caller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
#[error("{code:?}: {message}")]
pub struct ServiceError {
    pub code: ErrorCode,
    pub message: String,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ErrorCode {
    /// The request is malformed or its values are invalid.
    BadRequest,
    /// It names something that does not exist (a frame, a joint, a node).
    NotFound,
    /// Valid, but refused (a limit, a rule, an owner).
    Refused,
    /// The server failed.
    Internal,
}

impl ServiceError {
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
        }
    }
    pub fn bad_request(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::BadRequest, message)
    }
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::NotFound, message)
    }
    pub fn refused(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::Refused, message)
    }
}

/// A reply on the wire: the value or the error (CDR: the variant index, a `u32`, then the
/// value or the [`ServiceError`]).
#[derive(Debug, Serialize, Deserialize)]
pub(crate) enum WireReply<T> {
    Ok(T),
    Err(ServiceError),
}

impl<T> From<Result<T, ServiceError>> for WireReply<T> {
    fn from(r: Result<T, ServiceError>) -> Self {
        match r {
            Ok(v) => WireReply::Ok(v),
            Err(e) => WireReply::Err(e),
        }
    }
}

/// Why a call failed.
#[derive(Debug, thiserror::Error)]
pub enum CallError {
    #[error("no component serves {0} in this namespace")]
    NoServer(String),
    #[error("{service} did not answer within {timeout:?}")]
    Timeout { service: String, timeout: Duration },
    #[error("the service answered with an error: {0}")]
    Remote(ServiceError),
    #[error(transparent)]
    Codec(CodecError),
    #[error("zenoh error: {0}")]
    Zenoh(String),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::vision::{Intrinsics, RgbdFrame};
    use crate::topics;

    async fn two_buses() -> (zenoh::Session, Bus, Bus) {
        let (router, endpoint) = crate::router::open_router("tcp/127.0.0.1:0").await.unwrap();
        let ns = format!("unit-bus-{}", std::process::id());
        let args = ConnectArgs::to_router(&endpoint, &ns);
        let a = Bus::open(&args, "unit-a").await.unwrap();
        let b = Bus::open(&args, "unit-b").await.unwrap();
        (router, a, b)
    }

    fn frame(seq_tag: u8) -> RgbdFrame {
        let mut f = RgbdFrame::blank(640, 480, Intrinsics::default());
        f.header.frame_id = "head_rgbd_optical_frame".into();
        f.header.stamp_ns = 1;
        f.rgb.fill(seq_tag);
        f.depth_mm.fill(seq_tag.wrapping_add(1));
        f
    }

    async fn next(sub: &Subscriber<RgbdFrame>) -> Received<RgbdFrame> {
        tokio::time::timeout(Duration::from_secs(10), sub.recv_borrowed())
            .await
            .expect("a frame within 10 s")
            .unwrap()
    }

    /// A foreign client's request that does not decode gets a `BadRequest` reply, counted in
    /// `bad_requests/<service>`, and the service goes on answering; a good raw request gets the
    /// value back.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn raw_calls_get_bad_request_for_garbage_and_the_value_otherwise() {
        use crate::msg::std_msgs::Text;
        use crate::raw::RawReply;
        let (_router, server, client) = two_buses().await;
        let _served = server
            .serve(&topics::ECHO, |req: Text| async move { Ok(req) })
            .await
            .unwrap();
        let t = Duration::from_secs(5);
        let hello = Text {
            text: "hello".into(),
            ..Text::default()
        };
        let bytes = codec::encode(&hello, "robocog.Text").unwrap();
        // The server's queryable reaches the client through the router a moment after `serve`
        // returns: until then a call finds nobody (and reaches no counter).
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            match client
                .raw_call("echo", "robocog.Text", bytes.clone(), t)
                .await
            {
                Err(CallError::NoServer(_)) if Instant::now() < deadline => {
                    tokio::time::sleep(Duration::from_millis(20)).await
                }
                other => {
                    other.unwrap();
                    break;
                }
            }
        }
        let garbage: [Vec<u8>; 4] = [
            vec![],
            vec![0x00, 0x01],
            vec![0xff, 0xff, 0x00, 0x00, 1, 2, 3, 4],
            // A good encapsulation, a header's stamp, and then its frame id's length: 2^32-1.
            [&codec::CDR_LE_HEADER[..], &[0; 8], &[0xff; 4]].concat(),
        ];
        for g in garbage {
            let reply = client
                .raw_call("echo", "robocog.Text", g.clone(), t)
                .await
                .unwrap();
            match reply {
                RawReply::Err(e) => assert_eq!(e.code, ErrorCode::BadRequest, "{g:02x?}: {e}"),
                RawReply::Ok(_) => panic!("{g:02x?} was answered with a value"),
            }
        }
        assert_eq!(
            server
                .counters()
                .counter("bad_requests/echo")
                .load(Ordering::Relaxed),
            4
        );
        let reply = client
            .raw_call("echo", "robocog.Text", bytes, t)
            .await
            .unwrap();
        let back: Text = reply.value().unwrap().unwrap();
        assert_eq!(back.text, "hello");
        let typed = client.call(&topics::ECHO, &hello, t).await.unwrap();
        assert_eq!(typed.text, "hello");
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn frames_are_read_in_place_and_bad_payloads_are_counted_drops() {
        let (_router, a, b) = two_buses().await;
        let frames = b.subscriber(&topics::BENCH_FRAME).await.unwrap();
        let publisher = a.publisher(&topics::BENCH_FRAME).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;

        let mut sent = frame(7);
        publisher.publish(&mut sent).await.unwrap();
        let got = next(&frames).await;
        assert!(got.is_shm(), "a 1.5 MB frame travels in shared memory");
        let view = got.view();
        assert_eq!(view.header, sent.header);
        assert!(view.is_consistent());
        assert!(view.rgb.iter().all(|&b| b == 7) && view.depth_mm.iter().all(|&b| b == 8));
        assert_eq!(got.to_message().unwrap(), sent);
        assert_eq!((frames.received(), frames.shm_received()), (1, 1));
        drop(got);

        // Garbage on the topic: truncated, lengths of 2^32-1, no header. Each is a counted drop
        // (and no multi-GiB allocation); the good frame after them comes through.
        let good = codec::encode(&frame(1), RgbdFrame::TYPE_NAME).unwrap();
        // The colour image's length field: the first 640 x 480 x 3 in the payload.
        let rgb_len_at = good
            .windows(4)
            .position(|w| w == (640u32 * 480 * 3).to_le_bytes())
            .unwrap();
        let mut huge_rgb = good.clone();
        huge_rgb[rgb_len_at..rgb_len_at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let mut huge_id = good.clone();
        huge_id[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        let garbage = [
            good[..good.len() - 1].to_vec(),
            good[..100].to_vec(),
            huge_rgb,
            huge_id,
            vec![0, 1],
            Vec::new(),
        ];
        let n_bad = garbage.len() as u64;
        for g in garbage {
            publisher.put_encoded(g).await.unwrap();
        }
        let mut sent = frame(9);
        publisher.publish(&mut sent).await.unwrap();
        let got = next(&frames).await;
        assert_eq!(got.view().header.seq, sent.header.seq);
        assert_eq!(got.view().rgb[0], 9);
        assert_eq!(frames.decode_errors(), n_bad);
        assert_eq!(frames.received(), 2 + n_bad);
        let counters: BTreeMap<String, u64> = b.counters().snapshot().into_iter().collect();
        assert_eq!(counters.get("decode_errors/bench/frame"), Some(&n_bad));
        // Both good frames came in shared memory (big garbage may too: zenoh moves large
        // payloads into shared memory by itself); the bus counter agrees with the subscriber's.
        assert!(frames.shm_received() >= 2);
        assert_eq!(
            counters.get("shm_received/bench/frame"),
            Some(&frames.shm_received())
        );
        assert!(frames.try_recv_borrowed().is_none());
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_bus_clock_is_moved_by_the_clock_topic_before_the_messages_after_it() {
        use crate::msg::std_msgs::{ClockTime, Text};
        let (router, endpoint) = crate::router::open_router("tcp/127.0.0.1:0").await.unwrap();
        let ns = format!("unit-clock-{}", std::process::id());
        let args = ConnectArgs::to_router(&endpoint, &ns);
        let a = Bus::open(&args, "unit-replay").await.unwrap();
        let options = BusOptions {
            announce: true,
            clock: Clock::virtual_unset(),
            ..Default::default()
        };
        let b = Bus::open_with(&args, "unit-follower", options)
            .await
            .unwrap();
        let _follow = b.follow_clock().await.unwrap();
        let text = b.subscriber(&topics::CHATTER).await.unwrap();
        let clock = a.publisher(&topics::CLOCK).await.unwrap();
        let chatter = a.publisher(&topics::CHATTER).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;
        assert!(!b.clock().is_started());
        for i in 1..=50i64 {
            let t = 1_700_000_000_000_000_000 + i * 1_000_000;
            clock
                .publish(&mut ClockTime {
                    time_ns: t,
                    ..Default::default()
                })
                .await
                .unwrap();
            chatter
                .publish(&mut Text {
                    text: t.to_string(),
                    ..Default::default()
                })
                .await
                .unwrap();
        }
        for _ in 1..=50 {
            let m = tokio::time::timeout(Duration::from_secs(10), text.recv())
                .await
                .unwrap()
                .unwrap();
            let t: i64 = m.text.parse().unwrap();
            assert!(
                b.clock().now_ns() >= t,
                "a message sent after the clock said {t} finds the clock there"
            );
        }
        assert_eq!(b.clock().now_ns(), 1_700_000_000_050_000_000);
        drop(router);
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn relay_forwards_the_same_bytes_and_the_queue_drops_the_oldest() {
        let (_router, a, b) = two_buses().await;
        let frames = b
            .subscriber_named::<RgbdFrame>(topics::BENCH_FRAME.name(), 2)
            .await
            .unwrap();
        let back = a.subscriber(&topics::BENCH_FRAME_BACK).await.unwrap();
        let publisher = a.publisher(&topics::BENCH_FRAME).await.unwrap();
        let relay = b.publisher(&topics::BENCH_FRAME_BACK).await.unwrap();
        tokio::time::sleep(Duration::from_millis(300)).await;

        // Five frames into a queue of two: the three oldest are dropped and counted.
        for tag in 0..5 {
            publisher.publish(&mut frame(tag)).await.unwrap();
        }
        let deadline = Instant::now() + Duration::from_secs(10);
        let dropped = b.counters().counter("queue_dropped/bench/frame");
        while dropped.load(Ordering::Relaxed) < 3 && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert_eq!(dropped.load(Ordering::Relaxed), 3);
        let newest = frames.latest_borrowed().expect("the newest frame");
        assert_eq!(newest.view().rgb[0], 4);
        assert_eq!(newest.view().header.seq, 4);

        // Relayed as it is: the same payload, header untouched; an owned subscriber decodes it.
        relay.relay(&newest).await.unwrap();
        let echoed = tokio::time::timeout(Duration::from_secs(10), back.recv())
            .await
            .unwrap()
            .unwrap();
        assert_eq!(echoed, newest.to_message().unwrap());

        // publish_view: stamped by this publisher, same bytes as the owned frame otherwise.
        let mut view = newest.view();
        relay.publish_view(&mut view).await.unwrap();
        let again = tokio::time::timeout(Duration::from_secs(10), back.recv())
            .await
            .unwrap()
            .unwrap();
        assert_eq!(
            again.header.seq, 0,
            "stamped by the relay (relay() stamps nothing)"
        );
        assert_eq!(again.rgb, echoed.rgb);
        assert_eq!(again.depth_mm, echoed.depth_mm);
    }
}
