//! The utterance queue: which request to speak next, and what an urgent one does.
//!
//! - Requests wait in priority order (`Urgent` > `High` > `Normal` > `Low`), first come first
//!   served within a priority.
//! - An `Urgent` request interrupts whatever is being said unless that is urgent too, and is
//!   spoken next; the interrupted utterance is not resumed.
//! - The queue holds at most `capacity` waiting requests; when full, the lowest-priority, newest
//!   waiting request is dropped (possibly the new one).
//! - A request with the id and text of one being spoken or waiting is the same request sent
//!   again (a caller that lost sight of the generator, say while the bus' router restarted,
//!   sends again what it did not hear finish): it is taken once, not said twice.
//!
//! Pure logic: the component feeds requests and "finished" notices and acts on the returned
//! [`Event`]s.

use interfaces::msg::speech::{Priority, SayRequest};

/// What the component must do or report.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// The request is waiting.
    Queued(SayRequest),
    /// The request was dropped (queue full) before being spoken.
    Dropped(SayRequest),
    /// Stop speaking this one now (an urgent request came).
    Interrupt(SayRequest),
    /// The request is already being spoken or waiting (sent again): nothing else happens.
    Again(SayRequest),
}

#[derive(Debug)]
pub struct SpeechQueue {
    waiting: Vec<(u64, SayRequest)>,
    speaking: Option<SayRequest>,
    capacity: usize,
    arrivals: u64,
}

impl SpeechQueue {
    pub fn new(capacity: usize) -> Self {
        Self {
            waiting: Vec::new(),
            speaking: None,
            capacity: capacity.max(1),
            arrivals: 0,
        }
    }

    /// A new request.
    pub fn push(&mut self, req: SayRequest) -> Vec<Event> {
        let same = |r: &SayRequest| r.id == req.id && r.text == req.text;
        if req.id != 0
            && (self.speaking.as_ref().is_some_and(same)
                || self.waiting.iter().any(|(_, r)| same(r)))
        {
            return vec![Event::Again(req)];
        }
        let mut events = Vec::new();
        if req.priority == Priority::Urgent
            && let Some(cur) = &self.speaking
            && cur.priority != Priority::Urgent
        {
            events.push(Event::Interrupt(cur.clone()));
            self.speaking = None;
        }
        self.arrivals += 1;
        self.waiting.push((self.arrivals, req.clone()));
        events.push(Event::Queued(req));
        if self.waiting.len() > self.capacity {
            // The lowest priority, newest among them.
            if let Some(i) = self
                .waiting
                .iter()
                .enumerate()
                .min_by_key(|(_, (n, r))| (r.priority, std::cmp::Reverse(*n)))
                .map(|(i, _)| i)
            {
                let (_, r) = self.waiting.remove(i);
                events.push(Event::Dropped(r));
            }
        }
        events
    }

    /// If nothing is being spoken, take the next request to speak.
    pub fn start_next(&mut self) -> Option<SayRequest> {
        if self.speaking.is_some() {
            return None;
        }
        let i = self
            .waiting
            .iter()
            .enumerate()
            .max_by_key(|(_, (n, r))| (r.priority, std::cmp::Reverse(*n)))
            .map(|(i, _)| i)?;
        let (_, r) = self.waiting.remove(i);
        self.speaking = Some(r.clone());
        Some(r)
    }

    /// The current utterance ended (finished or failed).
    pub fn done(&mut self) {
        self.speaking = None;
    }

    pub fn speaking(&self) -> Option<&SayRequest> {
        self.speaking.as_ref()
    }
    pub fn waiting(&self) -> usize {
        self.waiting.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(id: u64, priority: Priority) -> SayRequest {
        SayRequest {
            id,
            text: format!("utterance {id}"),
            priority,
            ..Default::default()
        }
    }

    #[test]
    fn priority_then_arrival_order() {
        let mut q = SpeechQueue::new(10);
        q.push(req(1, Priority::Normal));
        q.push(req(2, Priority::Low));
        q.push(req(3, Priority::High));
        q.push(req(4, Priority::Normal));
        let mut order = vec![];
        while let Some(r) = q.start_next() {
            order.push(r.id);
            assert!(q.start_next().is_none(), "one at a time");
            q.done();
        }
        assert_eq!(order, vec![3, 1, 4, 2]);
    }

    #[test]
    fn a_request_sent_again_while_queued_or_spoken_is_said_once() {
        let mut q = SpeechQueue::new(10);
        q.push(req(2, Priority::Normal));
        q.push(req(3, Priority::Normal));
        assert_eq!(q.start_next().map(|r| r.id), Some(2));
        // Both sent again (the caller lost sight of the generator): neither is queued twice.
        assert_eq!(
            q.push(req(2, Priority::Normal)),
            [Event::Again(req(2, Priority::Normal))]
        );
        assert_eq!(
            q.push(req(3, Priority::Normal)),
            [Event::Again(req(3, Priority::Normal))]
        );
        assert_eq!(q.waiting(), 1);
        q.done();
        assert_eq!(q.start_next().map(|r| r.id), Some(3));
        q.done();
        assert!(q.start_next().is_none());
        // Once said, the same request again is said again (the caller asked for it after the end).
        q.push(req(3, Priority::Normal));
        assert_eq!(q.start_next().map(|r| r.id), Some(3));
        // Another text under the same id is another request.
        let mut other = req(3, Priority::Normal);
        other.text = "something else".into();
        assert!(matches!(q.push(other)[..], [Event::Queued(_)]));
    }

    #[test]
    fn urgent_interrupts_and_goes_first_but_not_another_urgent() {
        let mut q = SpeechQueue::new(10);
        q.push(req(1, Priority::Normal));
        q.push(req(2, Priority::High));
        assert_eq!(q.start_next().unwrap().id, 2);
        let ev = q.push(req(3, Priority::Urgent));
        assert_eq!(ev[0], Event::Interrupt(req(2, Priority::High)));
        assert_eq!(q.start_next().unwrap().id, 3);
        // An urgent one does not cut another urgent one: it waits.
        let ev = q.push(req(4, Priority::Urgent));
        assert_eq!(ev, vec![Event::Queued(req(4, Priority::Urgent))]);
        assert!(q.start_next().is_none());
        q.done();
        assert_eq!(q.start_next().unwrap().id, 4);
        q.done();
        // The interrupted one is not resumed; the normal one is still there.
        assert_eq!(q.start_next().unwrap().id, 1);
    }

    #[test]
    fn a_full_queue_drops_the_least_important_newest() {
        let mut q = SpeechQueue::new(2);
        q.push(req(1, Priority::Low));
        q.push(req(2, Priority::Normal));
        let ev = q.push(req(3, Priority::High));
        assert_eq!(ev.last(), Some(&Event::Dropped(req(1, Priority::Low))));
        let ev = q.push(req(4, Priority::Low));
        assert_eq!(ev.last(), Some(&Event::Dropped(req(4, Priority::Low))));
        assert_eq!(q.waiting(), 2);
    }
}
