//! Typed publishers: [`Bus::publisher`], [`Publisher`], and messages read in place ([`Received`]).

use super::*;

impl Bus {
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
    pub(super) payload: Payload,
    /// The sequence number from the sample's attachment (0 without one).
    pub(super) seq: u64,
    pub(super) _type: PhantomData<fn() -> T>,
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
pub(super) enum Payload {
    /// Where zenoh delivered it: a shared-memory buffer, or one network buffer.
    InPlace(ZBytes),
    /// It arrived in fragments: gathered into one buffer (one copy).
    Gathered(Vec<u8>),
}

impl Payload {
    pub(super) fn of(bytes: &ZBytes) -> Payload {
        let mut slices = bytes.slices();
        match (slices.next(), slices.next()) {
            (_, None) => Payload::InPlace(bytes.clone()),
            _ => Payload::Gathered(bytes.to_bytes().into_owned()),
        }
    }

    pub(super) fn bytes(&self) -> &[u8] {
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
