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

mod fair;
mod publisher;
mod recent;
pub(crate) mod service;
mod subscriber;
#[cfg(test)]
#[expect(
    clippy::disallowed_methods,
    reason = "the tests wait for a real zenoh session"
)]
mod tests;

use publisher::Payload;
pub use publisher::{Publisher, Received};
pub use recent::RecentPublisher;
pub(crate) use service::WireReply;
pub use service::{CallError, ErrorCode, PER_CALLER_QUEUE, ServiceError, ServiceHandle};
pub use subscriber::{ClockFollower, Subscriber};

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
#[expect(
    clippy::disallowed_methods,
    reason = "the log limiter paces what a person reads, on the wall; it runs in zenoh's receive callback"
)]
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
