//! A stream that a late reader can catch up on: [`Bus::recent_publisher`] keeps what it published
//! in the last `window` and serves it; [`Bus::recent`] asks for it. A speech recognizer restarted
//! in the middle of a word hears the word all the same. (ROS 2 calls this transient-local
//! durability, kept by count; this one is kept by time, as audio is.)
//!
//! The kept samples are served on the topic's key followed by `/@recent` (a verbatim chunk: no
//! wildcard subscription or query of the topics matches it), one reply per sample, oldest
//! first, those stamped after the query's `after` parameter (ns on the publisher's clock).

use super::*;
use std::collections::VecDeque;

/// The samples kept: (stamp ns, encoded bytes), oldest first.
type Kept = Arc<Mutex<VecDeque<(i64, Vec<u8>)>>>;

/// The key the kept samples of the topic with key `topic_key` are served on.
fn recent_key(topic_key: &str) -> String {
    format!("{topic_key}/@recent")
}

impl Bus {
    /// Declare a publisher on `topic` that keeps what it published in the last `window` (by the
    /// samples' stamps) and serves it to [`Bus::recent`].
    pub async fn recent_publisher<T: Message>(
        &self,
        topic: &Topic<T>,
        window: Duration,
    ) -> Result<RecentPublisher<T>, BusError> {
        let publisher = self.publisher(topic).await?;
        let kept: Kept = Arc::default();
        let key = recent_key(&self.topic_key(topic.name()));
        let queryable = self
            .inner
            .session
            .declare_queryable(key.clone())
            .with(zenoh::handlers::FifoChannel::new(DEFAULT_QUEUE))
            .await
            .map_err(zerr(format!(
                "serving the recent samples of {}",
                topic.name()
            )))?;
        let served = kept.clone();
        let encoding = crate::raw::encoding_for(T::TYPE_NAME);
        let task = tokio::spawn(async move {
            while let Ok(query) = queryable.recv_async().await {
                let after = query
                    .parameters()
                    .get("after")
                    .and_then(|a| a.parse::<i64>().ok())
                    .unwrap_or(i64::MIN);
                let samples: Vec<(i64, Vec<u8>)> = served
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .iter()
                    .filter(|(stamp, _)| *stamp > after)
                    .cloned()
                    .collect();
                for (_, bytes) in samples {
                    if let Err(e) = query
                        .reply(key.clone(), bytes)
                        .encoding(encoding.clone())
                        .await
                    {
                        tracing::debug!("a late reader left before its catch-up was sent: {e}");
                        break;
                    }
                }
            }
        });
        Ok(RecentPublisher {
            publisher,
            kept,
            window_ns: i64::try_from(window.as_nanos()).unwrap_or(i64::MAX),
            task,
        })
    }

    /// The samples kept by `topic`'s [`RecentPublisher`]s (every publisher that keeps them)
    /// stamped after `after_ns`, oldest first; waits at most `timeout` for them. Samples that do
    /// not decode are left out and counted (`decode_errors/<topic>@recent`).
    #[expect(
        clippy::disallowed_methods,
        reason = "a transport time-out, on the wall as zenoh's own query time-out is"
    )]
    pub async fn recent<T: Message>(
        &self,
        topic: &Topic<T>,
        after_ns: i64,
        timeout: Duration,
    ) -> Result<Vec<T>, BusError> {
        let key = recent_key(&self.topic_key(topic.name()));
        let replies = self
            .inner
            .session
            .get(format!("{key}?after={after_ns}"))
            // Every sample is its own reply on the same key: none may be merged into another.
            .consolidation(zenoh::query::ConsolidationMode::None)
            .timeout(timeout)
            .await
            .map_err(zerr(format!(
                "asking for the recent samples of {}",
                topic.name()
            )))?;
        let deadline = Instant::now() + timeout + Duration::from_millis(200);
        let mut out: Vec<T> = Vec::new();
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match tokio::time::timeout(left, replies.recv_async()).await {
                Ok(Ok(reply)) => {
                    let Ok(sample) = reply.into_result() else {
                        continue;
                    };
                    match codec::decode::<T>(&sample.payload().to_bytes(), T::TYPE_NAME) {
                        Ok(msg) => out.push(msg),
                        Err(e) => {
                            self.inner
                                .counters
                                .incr(&format!("decode_errors/{}@recent", topic.name()));
                            tracing::warn!(
                                "a recent sample of {} did not decode: {e}",
                                topic.name()
                            );
                        }
                    }
                }
                // Every publisher answered (the channel closed), or the time is up.
                Ok(Err(_)) | Err(_) => break,
            }
        }
        out.sort_by_key(|m| m.header().stamp_ns);
        Ok(out)
    }
}

/// A publisher that keeps its last window of samples for late readers ([`Bus::recent`]).
/// Dropping it withdraws them.
pub struct RecentPublisher<T: Message> {
    publisher: Publisher<T>,
    kept: Kept,
    window_ns: i64,
    task: tokio::task::JoinHandle<()>,
}

impl<T: Message> std::fmt::Debug for RecentPublisher<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Recent{:?}", self.publisher)
    }
}

impl<T: Message> Drop for RecentPublisher<T> {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl<T: Message> RecentPublisher<T> {
    /// Stamp and publish `msg` (as [`Publisher::publish`]), and keep it for the window.
    pub async fn publish(&self, msg: &mut T) -> Result<(), BusError> {
        self.publisher.publish(msg).await?;
        let stamp = msg.header().stamp_ns;
        let bytes = codec::encode(&*msg, T::TYPE_NAME)?;
        let mut kept = self.kept.lock().unwrap_or_else(|p| p.into_inner());
        kept.push_back((stamp, bytes));
        while kept
            .front()
            .is_some_and(|(s, _)| *s < stamp.saturating_sub(self.window_ns))
        {
            kept.pop_front();
        }
        Ok(())
    }
}
