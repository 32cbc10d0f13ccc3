//! Fair service queues: each caller's requests wait in a bounded queue of their own, and the
//! queues are served in turn, so a caller flooding a service delays only itself.

use std::collections::{BTreeMap, VecDeque};

/// Requests waiting for a service, one bounded queue per caller, served round-robin.
#[derive(Debug)]
pub(crate) struct FairQueue<T> {
    per_caller: usize,
    queues: BTreeMap<String, VecDeque<T>>,
    /// The callers with requests waiting, in the order they are served next.
    turn: VecDeque<String>,
}

impl<T> FairQueue<T> {
    /// At most `per_caller` requests of one caller wait at a time (at least one).
    pub(crate) fn new(per_caller: usize) -> Self {
        Self {
            per_caller: per_caller.max(1),
            queues: BTreeMap::new(),
            turn: VecDeque::new(),
        }
    }

    /// Queues `item` from `caller`, or gives it back when that caller already has its share
    /// waiting.
    pub(crate) fn push(&mut self, caller: &str, item: T) -> Result<(), T> {
        let q = self.queues.entry(caller.to_string()).or_default();
        if q.len() >= self.per_caller {
            return Err(item);
        }
        if q.is_empty() {
            self.turn.push_back(caller.to_string());
        }
        q.push_back(item);
        Ok(())
    }

    /// The next request: the oldest of the caller whose turn it is.
    pub(crate) fn pop(&mut self) -> Option<(String, T)> {
        let caller = self.turn.pop_front()?;
        let q = self.queues.get_mut(&caller)?;
        let item = q.pop_front()?;
        if q.is_empty() {
            self.queues.remove(&caller);
        } else {
            self.turn.push_back(caller.clone());
        }
        Some((caller, item))
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.turn.is_empty()
    }
}

/// What a robocog caller attaches to a service request: who calls, and until when it waits for
/// the reply (ns since the epoch, the caller's system clock). Other zenoh clients attach nothing
/// (or something else): they share one queue, [`FOREIGN`].
const TAG: &[u8; 4] = b"rc1;";

/// The queue of callers that do not say who they are.
pub(crate) const FOREIGN: &str = "(foreign)";

/// The attachment of a request from `caller` that waits until `deadline_ns`.
pub(crate) fn encode_caller(caller: &str, deadline_ns: i64) -> Vec<u8> {
    let mut v = Vec::with_capacity(12 + caller.len());
    v.extend_from_slice(TAG);
    v.extend_from_slice(&deadline_ns.to_le_bytes());
    v.extend_from_slice(caller.as_bytes());
    v
}

/// The caller and deadline of a request's attachment, when a robocog caller sent it.
pub(crate) fn decode_caller(attachment: &[u8]) -> Option<(String, i64)> {
    let rest = attachment.strip_prefix(TAG)?;
    let (deadline, name) = rest.split_first_chunk::<8>()?;
    let name = std::str::from_utf8(name).ok()?;
    if name.is_empty() || name.len() > 128 || name.chars().any(char::is_control) {
        return None;
    }
    Some((name.to_string(), i64::from_le_bytes(*deadline)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn callers_are_served_in_turn_whatever_one_of_them_queued() {
        let mut q = FairQueue::new(100);
        for i in 0..50 {
            q.push("flood", i).unwrap();
        }
        q.push("game", 1000).unwrap();
        q.push("panel", 2000).unwrap();
        let order: Vec<_> = std::iter::from_fn(|| q.pop()).take(4).collect();
        assert_eq!(
            order,
            vec![
                ("flood".into(), 0),
                ("game".into(), 1000),
                ("panel".into(), 2000),
                ("flood".into(), 1)
            ]
        );
        let rest: Vec<_> = std::iter::from_fn(|| q.pop()).collect();
        assert_eq!(rest.len(), 48);
        assert!(rest.iter().all(|(c, _)| c == "flood"));
        assert!(q.is_empty());
    }

    #[test]
    fn a_caller_past_its_share_gets_its_request_back() {
        let mut q = FairQueue::new(2);
        assert!(q.push("a", 1).is_ok());
        assert!(q.push("a", 2).is_ok());
        assert_eq!(q.push("a", 3), Err(3));
        assert!(
            q.push("b", 4).is_ok(),
            "another caller has a share of its own"
        );
        assert_eq!(q.pop(), Some(("a".into(), 1)));
        assert!(q.push("a", 5).is_ok(), "room again once one was served");
    }

    #[test]
    fn the_caller_attachment_round_trips_and_garbage_is_foreign() {
        let a = encode_caller("executive", 1_700_000_000_123_456_789);
        assert_eq!(
            decode_caller(&a),
            Some(("executive".into(), 1_700_000_000_123_456_789))
        );
        assert_eq!(decode_caller(b""), None);
        assert_eq!(decode_caller(b"rc1;1234"), None, "a deadline and no name");
        assert_eq!(decode_caller(&[0u8; 33]), None, "an rmw_zenoh attachment");
        let mut bad = encode_caller("x", 0);
        bad.push(0xff);
        assert_eq!(decode_caller(&bad), None, "a name that is not UTF-8");
    }
}
