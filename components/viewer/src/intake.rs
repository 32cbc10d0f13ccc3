//! The bounded hand-over from the bus callbacks to the rerun logging thread.
//!
//! A bus callback must return at once (zenoh delivers every subscription of the process from the
//! same threads, and a publisher with blocking congestion control would feel a slow subscriber).
//! [`Intake::offer`] therefore never waits: it queues a copy of the sample, or drops it and counts
//! the drop for its topic when the queue is full or when the topic already holds its share of the
//! queue (so a flood of camera frames cannot crowd out the state transitions).

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};

/// One sample on its way to rerun.
#[derive(Debug, Clone)]
pub struct Sample {
    pub topic: String,
    /// The type name the sample's encoding carries (`robocog.RgbdFrame`).
    pub type_name: String,
    /// The exact CDR bytes of the bus.
    pub payload: Vec<u8>,
    /// When the viewer received it (ns since the epoch).
    pub receipt_ns: i64,
}

/// Makes (or finds) the drop counter of a topic (the bus's diagnostics counters in the component).
pub type CounterFn = Box<dyn Fn(&str) -> Arc<AtomicU64> + Send + Sync>;

struct TopicQueue {
    queued: usize,
    dropped: Arc<AtomicU64>,
}

/// See the module doc.
pub struct Intake {
    tx: Mutex<Option<SyncSender<Sample>>>,
    per_topic: usize,
    topics: Mutex<HashMap<String, TopicQueue>>,
    counter: CounterFn,
}

impl std::fmt::Debug for Intake {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Intake")
            .field("per_topic", &self.per_topic)
            .finish_non_exhaustive()
    }
}

impl Intake {
    /// A queue of `capacity` samples, at most `per_topic` of them from one topic; `counter` gives
    /// the drop counter of a topic.
    pub fn new(
        capacity: usize,
        per_topic: usize,
        counter: CounterFn,
    ) -> (Arc<Self>, Receiver<Sample>) {
        let (tx, rx) = sync_channel(capacity.max(1));
        (
            Arc::new(Self {
                tx: Mutex::new(Some(tx)),
                per_topic: per_topic.max(1),
                topics: Mutex::new(HashMap::new()),
                counter,
            }),
            rx,
        )
    }

    fn topics(&self) -> std::sync::MutexGuard<'_, HashMap<String, TopicQueue>> {
        self.topics.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Queue `sample` without waiting. `false`: dropped (counted) or the intake is closed.
    pub fn offer(&self, sample: Sample) -> bool {
        let mut topics = self.topics();
        let q = match topics.get_mut(&sample.topic) {
            Some(q) => q,
            None => {
                let dropped = (self.counter)(&format!("view_dropped/{}", sample.topic));
                topics
                    .entry(sample.topic.clone())
                    .or_insert(TopicQueue { queued: 0, dropped })
            }
        };
        if q.queued >= self.per_topic {
            q.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        let tx = self.tx.lock().unwrap_or_else(|p| p.into_inner());
        let Some(tx) = tx.as_ref() else {
            return false;
        };
        match tx.try_send(sample) {
            Ok(()) => {
                q.queued += 1;
                true
            }
            Err(TrySendError::Full(_)) => {
                q.dropped.fetch_add(1, Ordering::Relaxed);
                false
            }
            Err(TrySendError::Disconnected(_)) => false,
        }
    }

    /// The consumer took a sample of `topic` off the queue.
    pub fn taken(&self, topic: &str) {
        if let Some(q) = self.topics().get_mut(topic) {
            q.queued = q.queued.saturating_sub(1);
        }
    }

    /// Take no more samples; the consumer drains what is queued and sees the end.
    pub fn close(&self) {
        self.tx.lock().unwrap_or_else(|p| p.into_inner()).take();
    }

    /// Samples dropped so far, per topic (topics with no drop left out).
    pub fn dropped(&self) -> BTreeMap<String, u64> {
        self.topics()
            .iter()
            .map(|(t, q)| (t.clone(), q.dropped.load(Ordering::Relaxed)))
            .filter(|(_, n)| *n > 0)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(topic: &str) -> Sample {
        Sample {
            topic: topic.into(),
            type_name: "robocog.Text".into(),
            payload: vec![0; 8],
            receipt_ns: 1,
        }
    }

    fn intake(capacity: usize, per_topic: usize) -> (Arc<Intake>, Receiver<Sample>) {
        Intake::new(
            capacity,
            per_topic,
            Box::new(|_| Arc::new(AtomicU64::new(0))),
        )
    }

    #[test]
    fn a_full_queue_drops_and_counts_per_topic_without_waiting() {
        let (intake, rx) = intake(4, 4);
        for _ in 0..10 {
            intake.offer(sample("vision/rgbd"));
        }
        assert_eq!(intake.dropped().get("vision/rgbd"), Some(&6));
        assert_eq!(rx.try_iter().count(), 4);
    }

    #[test]
    fn a_flooding_topic_cannot_crowd_out_the_others() {
        let (intake, rx) = intake(8, 3);
        for _ in 0..10 {
            intake.offer(sample("vision/rgbd"));
        }
        assert!(intake.offer(sample("executive/transitions")));
        assert_eq!(intake.dropped().get("vision/rgbd"), Some(&7));
        assert!(!intake.dropped().contains_key("executive/transitions"));
        // Taking one frame off the queue makes room for the next.
        let s = rx.recv().expect("queued");
        intake.taken(&s.topic);
        assert!(intake.offer(sample("vision/rgbd")));
    }

    #[test]
    fn closing_lets_the_consumer_drain_then_end() {
        let (intake, rx) = intake(8, 8);
        intake.offer(sample("a"));
        intake.close();
        assert!(!intake.offer(sample("a")));
        assert_eq!(rx.iter().count(), 1);
    }
}
