//! Commands for a reader that may be restarting: the sender's side of "no command is lost while a
//! component recovers".
//!
//! A command topic (`game/command`, `coach/request`, `game/answer`) has one component that acts on
//! it (the Executive, the dialog). While none of its readers subscribes ([`crate::liveliness::Readers`]:
//! it was killed and the launcher restarts it), an [`Outbox`] holds what is offered, and hands it
//! back, in order, as soon as a reader is back. A command held longer than its limit is dropped
//! and handed back so the sender can say so.
//!
//! A reader can also die after a command reached it and before it acted on it. So the commands
//! sent in the last [`Outbox::resend_window`] before the readers went away are held again and sent
//! again. Every command keeps the stamp it was given when first offered (`header.stamp_ns`, from
//! the sender's clock); a reader that keeps the stamps it acted on (the Executive keeps them in its
//! state folder) knows a command it already carried out and does not do it twice.
//!
//! Time is the sender's [`Clock`]: a test drives it.

use crate::clock::{Clock, Moment};
use crate::msg::Message;
use std::collections::VecDeque;
use std::time::Duration;

/// What became of an offered command.
#[derive(Debug, Clone, PartialEq)]
pub enum Offered<T> {
    /// A reader listens: publish this now (stamped; keep the stamp).
    Send(T),
    /// Nobody reads the topic: held. `first` when no other new command was held (the moment to
    /// tell the person to wait); `evicted`, the oldest held command, when the outbox was full.
    Held {
        first: bool,
        evicted: Option<Released<T>>,
    },
}

/// A command handed back to be published, with how long it waited.
#[derive(Debug, Clone, PartialEq)]
pub struct Released<T> {
    pub msg: T,
    pub waited: Duration,
    /// It had been sent once before its reader went away (the reader may have acted on it).
    pub again: bool,
}

#[derive(Debug, Clone)]
struct Held<T> {
    msg: T,
    since: Moment,
    again: bool,
}

impl<T> Held<T> {
    fn released(self, now: Moment) -> Released<T> {
        Released {
            waited: now.duration_since(self.since),
            again: self.again,
            msg: self.msg,
        }
    }
}

/// Holds commands while their topic has no reader; see the module.
#[derive(Debug, Clone)]
pub struct Outbox<T> {
    clock: Clock,
    present: bool,
    held: VecDeque<Held<T>>,
    /// Sent, with when: the last `resend_window` of them.
    recent: VecDeque<(T, Moment)>,
    max_hold: Duration,
    resend_window: Duration,
    max_len: usize,
}

impl<T: Message> Outbox<T> {
    /// Sent commands this recent are sent again when their reader goes away: a reader killed
    /// just after one arrived may not have acted on it.
    pub const DEFAULT_RESEND_WINDOW: Duration = Duration::from_secs(2);
    /// At most this many commands are held; the oldest goes first.
    pub const DEFAULT_MAX_LEN: usize = 8;

    /// An outbox on `clock` whose commands wait at most `max_hold` for a reader. It starts with
    /// no reader: tell it with [`Outbox::readers`].
    pub fn new(clock: Clock, max_hold: Duration) -> Outbox<T> {
        Outbox {
            clock,
            present: false,
            held: VecDeque::new(),
            recent: VecDeque::new(),
            max_hold,
            resend_window: Self::DEFAULT_RESEND_WINDOW,
            max_len: Self::DEFAULT_MAX_LEN,
        }
    }

    /// With another resend window (zero: never send again).
    pub fn with_resend_window(mut self, window: Duration) -> Outbox<T> {
        self.resend_window = window;
        self
    }

    /// With room for `n` held commands (at least one).
    pub fn with_max_len(mut self, n: usize) -> Outbox<T> {
        self.max_len = n.max(1);
        self
    }

    /// The resend window.
    pub fn resend_window(&self) -> Duration {
        self.resend_window
    }

    /// Commands held now.
    pub fn held(&self) -> usize {
        self.held.len()
    }

    /// Whether a reader listens (as last told).
    pub fn has_reader(&self) -> bool {
        self.present
    }

    /// Offers `msg`: stamped now unless it has a stamp, then to be sent, or held.
    pub fn offer(&mut self, mut msg: T) -> Offered<T> {
        if msg.header().stamp_ns == 0 {
            msg.header_mut().stamp_ns = self.clock.now_ns();
        }
        let now = self.clock.now();
        if self.present {
            self.sent(msg.clone(), now);
            return Offered::Send(msg);
        }
        let first = self.held.iter().all(|h| h.again);
        let evicted = (self.held.len() >= self.max_len)
            .then(|| self.held.pop_front().map(|h| h.released(now)))
            .flatten();
        self.held.push_back(Held {
            msg,
            since: now,
            again: false,
        });
        Offered::Held { first, evicted }
    }

    /// Whether a reader listens now. When the readers go away, the commands sent in the resend
    /// window are held again (ahead of the others, in order); when one is back, everything held
    /// is handed back to be published, in order.
    pub fn readers(&mut self, present: bool) -> Vec<Released<T>> {
        let now = self.clock.now();
        let was = std::mem::replace(&mut self.present, present);
        self.forget_old(now);
        if was && !present {
            let again: Vec<Held<T>> = self
                .recent
                .drain(..)
                .map(|(msg, _)| Held {
                    msg,
                    since: now,
                    again: true,
                })
                .collect();
            for h in again.into_iter().rev() {
                self.held.push_front(h);
            }
            while self.held.len() > self.max_len {
                self.held.pop_back();
            }
            return Vec::new();
        }
        if !present {
            return Vec::new();
        }
        let out: Vec<Released<T>> = self.held.drain(..).map(|h| h.released(now)).collect();
        for r in &out {
            self.recent.push_back((r.msg.clone(), now));
        }
        out
    }

    /// The held commands that waited longer than the limit, removed. One held `again` was sent
    /// once already (and most likely carried out): drop it without a word.
    pub fn expire(&mut self) -> Vec<Released<T>> {
        let now = self.clock.now();
        self.forget_old(now);
        let mut out = Vec::new();
        while self
            .held
            .front()
            .is_some_and(|h| now.duration_since(h.since) > self.max_hold)
        {
            if let Some(h) = self.held.pop_front() {
                out.push(h.released(now));
            }
        }
        out
    }

    fn sent(&mut self, msg: T, now: Moment) {
        self.forget_old(now);
        self.recent.push_back((msg, now));
        while self.recent.len() > self.max_len {
            self.recent.pop_front();
        }
    }

    fn forget_old(&mut self, now: Moment) {
        while self
            .recent
            .front()
            .is_some_and(|(_, t)| now.duration_since(*t) > self.resend_window)
        {
            self.recent.pop_front();
        }
    }
}

/// The stamps of the commands a reader acted on, newest last, so that one sent again after the
/// reader restarted is recognised (see the module). Keeps the last [`Handled::KEEP`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Handled {
    stamps: VecDeque<i64>,
}

impl Handled {
    /// How many stamps are kept: far more than anyone gives in a resend window.
    pub const KEEP: usize = 32;

    /// Stamps kept earlier (oldest first).
    pub fn from_stamps(stamps: &[i64]) -> Handled {
        let skip = stamps.len().saturating_sub(Self::KEEP);
        Handled {
            stamps: stamps[skip..].iter().copied().collect(),
        }
    }

    /// The stamps, oldest first (to keep them).
    pub fn stamps(&self) -> Vec<i64> {
        self.stamps.iter().copied().collect()
    }

    /// True the first time a command of this stamp comes (and keeps it); false for one already
    /// handled. A command without a stamp (0) is always new.
    pub fn first_time(&mut self, stamp_ns: i64) -> bool {
        if stamp_ns == 0 {
            return true;
        }
        if self.stamps.contains(&stamp_ns) {
            return false;
        }
        if self.stamps.len() == Self::KEEP {
            self.stamps.pop_front();
        }
        self.stamps.push_back(stamp_ns);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::std_msgs::Text;

    fn text(s: &str) -> Text {
        Text {
            text: s.into(),
            ..Text::default()
        }
    }

    fn clock() -> Clock {
        Clock::virtual_at(1_000_000_000)
    }

    fn texts(r: &[Released<Text>]) -> Vec<(&str, bool)> {
        r.iter().map(|r| (r.msg.text.as_str(), r.again)).collect()
    }

    #[test]
    fn held_without_a_reader_and_sent_in_order_when_one_is_back() {
        let c = clock();
        let mut o = Outbox::new(c.clone(), Duration::from_secs(15));
        assert!(matches!(
            o.offer(text("a")),
            Offered::Held {
                first: true,
                evicted: None
            }
        ));
        c.advance(Duration::from_secs(1));
        assert!(matches!(
            o.offer(text("b")),
            Offered::Held { first: false, .. }
        ));
        c.advance(Duration::from_secs(2));
        let out = o.readers(true);
        assert_eq!(texts(&out), [("a", false), ("b", false)]);
        assert_eq!(out[0].waited, Duration::from_secs(3));
        // Stamped when offered, not when sent.
        assert_eq!(out[0].msg.header.stamp_ns, 1_000_000_000);
        assert_eq!(o.held(), 0);
        match o.offer(text("c")) {
            Offered::Send(m) => assert_eq!(m.header.stamp_ns, 4_000_000_000),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_held_command_too_old_is_dropped_and_the_oldest_goes_when_full() {
        let c = clock();
        let mut o = Outbox::new(c.clone(), Duration::from_secs(15)).with_max_len(2);
        o.offer(text("a"));
        c.advance(Duration::from_secs(1));
        o.offer(text("b"));
        match o.offer(text("c")) {
            Offered::Held {
                first: false,
                evicted: Some(m),
            } => assert_eq!(m.msg.text, "a"),
            other => panic!("{other:?}"),
        }
        c.advance(Duration::from_secs(15));
        assert!(o.expire().is_empty(), "15 s is within the limit");
        c.advance(Duration::from_millis(1));
        let gone: Vec<String> = o.expire().into_iter().map(|m| m.msg.text).collect();
        assert_eq!(gone, ["b", "c"]);
        assert!(o.readers(true).is_empty());
    }

    #[test]
    fn commands_sent_just_before_the_reader_went_are_sent_again_with_their_stamps() {
        let c = clock();
        let mut o = Outbox::new(c.clone(), Duration::from_secs(15));
        o.readers(true);
        let Offered::Send(old) = o.offer(text("old")) else {
            panic!()
        };
        c.advance(Duration::from_secs(3));
        let Offered::Send(recent) = o.offer(text("recent")) else {
            panic!()
        };
        c.advance(Duration::from_millis(500));
        assert!(o.readers(false).is_empty());
        assert!(!o.has_reader());
        assert!(
            matches!(
                o.offer(text("while away")),
                Offered::Held { first: true, .. }
            ),
            "the first new command held (the person is told to wait)"
        );
        c.advance(Duration::from_secs(1));
        let out = o.readers(true);
        assert_eq!(texts(&out), [("recent", true), ("while away", false)]);
        assert_eq!(out[0].msg.header.stamp_ns, recent.header.stamp_ns);
        assert_ne!(old.header.stamp_ns, recent.header.stamp_ns);
        // Sent again, they are recent again: the reader going twice sends them twice.
        c.advance(Duration::from_millis(100));
        o.readers(false);
        assert_eq!(o.readers(true).len(), 2);
        // Past the window nothing is sent again.
        c.advance(Duration::from_secs(3));
        o.readers(false);
        assert!(o.readers(true).is_empty());
        // Held again and never read: dropped, marked as sent before (no "sorry" for it).
        o.offer(text("last"));
        o.readers(false);
        c.advance(Duration::from_secs(16));
        assert_eq!(texts(&o.expire()), [("last", true)]);
    }

    #[test]
    fn a_reader_recognises_a_command_it_handled() {
        let mut h = Handled::default();
        assert!(h.first_time(5));
        assert!(!h.first_time(5));
        assert!(h.first_time(0) && h.first_time(0), "no stamp: always new");
        for s in 6..6 + Handled::KEEP as i64 {
            assert!(h.first_time(s));
        }
        assert!(h.first_time(5), "forgotten after KEEP more");
        let kept = Handled::from_stamps(&h.stamps());
        assert_eq!(kept, h);
        assert_eq!(Handled::from_stamps(&[1; 40]).stamps().len(), Handled::KEEP);
    }
}
