//! Typed subscriptions: [`Bus::subscriber`], [`Subscriber`], and the clock follower.

use super::*;

impl Bus {
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
    #[expect(
        clippy::disallowed_methods,
        reason = "the log limiter of bad clock messages paces what a person reads, on the wall"
    )]
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
    #[expect(
        clippy::disallowed_methods,
        reason = "a wait on the transport: a virtual clock that no one moves must not hold a reader forever"
    )]
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
    #[expect(
        clippy::disallowed_methods,
        reason = "the log limiter paces what a person reads, on the wall"
    )]
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
