//! The clock a component takes its time from: the system's, or a virtual one a replay or a test
//! drives.
//!
//! A component never reads the wall clock for its stamps, timers, time-outs or watchdogs: it asks
//! its bus' [`Clock`] ([`crate::Bus::clock`]), which the component runtime sets from the node
//! flags (`--clock system|bus`, see [`crate::node::NodeArgs`]).
//!
//! - [`Clock::now_ns`]: nanoseconds since the Unix epoch, for message stamps.
//! - [`Clock::now`]: a [`Moment`] on the clock's monotonic time line, for durations
//!   ([`Moment::duration_since`], [`Clock::elapsed`]); on the system clock it is
//!   `std::time::Instant`'s, so a change of the system time moves no timer.
//! - [`Clock::sleep_until`], [`Clock::sleep`], [`Clock::interval`]: waits on the clock. On a
//!   virtual clock they wake when the clock is moved to or past their time (however fast it is
//!   moved), never from the wall.
//!
//! A virtual clock only moves forward: it is set ([`Clock::set_ns`]) or advanced
//! ([`Clock::advance`]) from outside: by a test, or, with `--clock bus`, by the `clock` topic
//! that `robocog replay` publishes (the recording's time, as ROS' `/clock` with `use_sim_time`).
//! Until it is first set it reads 0 and [`Clock::is_started`] is false; [`Clock::started`] waits
//! for that.

#![expect(
    clippy::disallowed_methods,
    reason = "the clock module is where the system clock is read; everything else asks it"
)]

use std::future::Future;
use std::sync::{Arc, OnceLock};
use std::time::Duration;
use tokio::sync::watch;

/// Where a component takes its time from (cheap to clone; clones share the time).
#[derive(Debug, Clone, Default)]
pub struct Clock {
    kind: Kind,
}

#[derive(Debug, Clone, Default)]
enum Kind {
    /// The system's clocks: real time for stamps, `Instant` for durations.
    #[default]
    System,
    /// Set from outside; nanoseconds since the epoch, `None` until first set.
    Virtual(Arc<watch::Sender<Option<i64>>>),
}

/// A reading of a [`Clock`] for durations: a point on the clock's monotonic time line (for the
/// system clock, since an arbitrary point of this process; for a virtual clock, since the epoch).
/// Moments of different clocks do not compare.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Moment(Duration);

impl Moment {
    /// The moment `d` after the clock's origin.
    pub const fn from_duration(d: Duration) -> Moment {
        Moment(d)
    }
    /// The time since the clock's origin (what a state machine takes as `now`).
    pub const fn as_duration(self) -> Duration {
        self.0
    }
    /// The time from `earlier` to this moment; zero if `earlier` is later.
    pub fn duration_since(self, earlier: Moment) -> Duration {
        self.0.saturating_sub(earlier.0)
    }
    /// The time from this moment to `later`; zero if `later` is earlier.
    pub fn until(self, later: Moment) -> Duration {
        later.duration_since(self)
    }
}

impl std::ops::Add<Duration> for Moment {
    type Output = Moment;
    fn add(self, d: Duration) -> Moment {
        Moment(self.0.saturating_add(d))
    }
}

impl std::ops::AddAssign<Duration> for Moment {
    fn add_assign(&mut self, d: Duration) {
        *self = *self + d;
    }
}

impl std::ops::Sub<Duration> for Moment {
    type Output = Moment;
    fn sub(self, d: Duration) -> Moment {
        Moment(self.0.saturating_sub(d))
    }
}

/// The origin of the system clock's [`Moment`]s: the first reading in this process.
fn system_origin() -> std::time::Instant {
    static ORIGIN: OnceLock<std::time::Instant> = OnceLock::new();
    *ORIGIN.get_or_init(std::time::Instant::now)
}

impl Clock {
    /// The system's clock (the default).
    pub fn system() -> Clock {
        Clock::default()
    }
    /// A virtual clock starting at `start_ns` (nanoseconds since the epoch).
    pub fn virtual_at(start_ns: i64) -> Clock {
        let (tx, _) = watch::channel(Some(start_ns));
        Clock {
            kind: Kind::Virtual(Arc::new(tx)),
        }
    }
    /// A virtual clock not set yet (it reads 0 until [`Clock::set_ns`]); what a component
    /// following the bus' `clock` topic starts with.
    pub fn virtual_unset() -> Clock {
        let (tx, _) = watch::channel(None);
        Clock {
            kind: Kind::Virtual(Arc::new(tx)),
        }
    }
    /// Whether this clock is virtual (moved from outside).
    pub fn is_virtual(&self) -> bool {
        matches!(self.kind, Kind::Virtual(_))
    }
    /// Whether the clock has a time: always for the system clock, once set for a virtual one.
    pub fn is_started(&self) -> bool {
        match &self.kind {
            Kind::System => true,
            Kind::Virtual(t) => t.borrow().is_some(),
        }
    }
    /// Waits until the clock has a time (at once on the system clock).
    pub async fn started(&self) {
        if let Kind::Virtual(t) = &self.kind {
            let mut rx = t.subscribe();
            // The sender lives in `self`: `wait_for` cannot fail while we hold it.
            let _ = rx.wait_for(Option::is_some).await;
        }
    }
    /// Now, in nanoseconds since the epoch: what message stamps are.
    pub fn now_ns(&self) -> i64 {
        match &self.kind {
            Kind::System => system_now_ns(),
            Kind::Virtual(t) => t.borrow().unwrap_or(0),
        }
    }
    /// Now, on the clock's monotonic time line: what durations, timers and watchdogs use.
    pub fn now(&self) -> Moment {
        match &self.kind {
            Kind::System => Moment(system_origin().elapsed()),
            Kind::Virtual(t) => Moment(virtual_duration(*t.borrow())),
        }
    }
    /// The time since `since` on this clock.
    pub fn elapsed(&self, since: Moment) -> Duration {
        self.now().duration_since(since)
    }
    /// Moves a virtual clock to `t_ns`, waking whoever waits for a time up to it. A virtual clock
    /// never goes back: an earlier time is ignored. Ignored on the system clock.
    pub fn set_ns(&self, t_ns: i64) {
        if let Kind::Virtual(t) = &self.kind {
            t.send_if_modified(|now| {
                if now.is_none_or(|n| t_ns > n) {
                    *now = Some(t_ns);
                    true
                } else {
                    false
                }
            });
        }
    }
    /// Advances a virtual clock by `dt` (from 0 if it was not set). Ignored on the system clock.
    pub fn advance(&self, dt: Duration) {
        if let Kind::Virtual(t) = &self.kind {
            let dt = i64::try_from(dt.as_nanos()).unwrap_or(i64::MAX);
            t.send_modify(|now| *now = Some(now.unwrap_or(0).saturating_add(dt)));
        }
    }
    /// Advances a virtual clock by `dt_ns` nanoseconds (ignored on the system clock).
    pub fn advance_ns(&self, dt_ns: i64) {
        self.advance(Duration::from_nanos(u64::try_from(dt_ns).unwrap_or(0)));
    }
    /// Waits until the clock reads `at` or later. On a virtual clock, until it is moved there.
    pub async fn sleep_until(&self, at: Moment) {
        match &self.kind {
            Kind::System => {
                let deadline = system_origin() + at.0;
                tokio::time::sleep_until(tokio::time::Instant::from_std(deadline)).await;
            }
            Kind::Virtual(t) => {
                let mut rx = t.subscribe();
                let _ = rx.wait_for(|now| virtual_duration(*now) >= at.0).await;
            }
        }
    }
    /// Waits for `d` on this clock.
    pub async fn sleep(&self, d: Duration) {
        self.sleep_until(self.now() + d).await;
    }
    /// `fut`, or `None` once `d` has passed on this clock.
    pub async fn timeout<F: Future>(&self, d: Duration, fut: F) -> Option<F::Output> {
        tokio::select! {
            biased;
            out = fut => Some(out),
            _ = self.sleep(d) => None,
        }
    }
    /// Ticks every `period` on this clock, the first at once; missed ticks are skipped (a
    /// virtual clock moved by several periods ticks once).
    pub fn interval(&self, period: Duration) -> Interval {
        Interval {
            clock: self.clone(),
            next: None,
            period: period.max(Duration::from_nanos(1)),
        }
    }
}

/// A virtual reading as a duration since the epoch (0 before it is set, or before 1970).
fn virtual_duration(t: Option<i64>) -> Duration {
    Duration::from_nanos(u64::try_from(t.unwrap_or(0)).unwrap_or(0))
}

/// Periodic ticks on a [`Clock`] (see [`Clock::interval`]).
#[derive(Debug)]
pub struct Interval {
    clock: Clock,
    next: Option<Moment>,
    period: Duration,
}

impl Interval {
    /// Waits for the next tick and returns its moment (the clock's reading when it woke).
    pub async fn tick(&mut self) -> Moment {
        if let Some(next) = self.next {
            self.clock.sleep_until(next).await;
        }
        let now = self.clock.now();
        let mut next = self.next.unwrap_or(now) + self.period;
        if next <= now {
            next = now + self.period;
        }
        self.next = Some(next);
        now
    }
    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }
}

/// The system clock in nanoseconds since the epoch (0 if the clock is before 1970).
pub fn system_now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as i64)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_virtual_clock_moves_only_when_told_and_never_back() {
        let c = Clock::virtual_at(1_000);
        assert!(c.is_virtual() && c.is_started());
        assert_eq!(c.now_ns(), 1_000);
        c.advance_ns(500);
        assert_eq!(c.now_ns(), 1_500);
        assert_eq!(c.now(), Moment::from_duration(Duration::from_nanos(1_500)));
        c.set_ns(10);
        assert_eq!(c.now_ns(), 1_500, "a virtual clock never goes back");
        c.set_ns(2_000);
        let t0 = Moment::from_duration(Duration::from_nanos(1_000));
        assert_eq!(c.elapsed(t0), Duration::from_nanos(1_000));
        let clone = c.clone();
        clone.advance(Duration::from_nanos(1));
        assert_eq!(c.now_ns(), 2_001, "clones share the time");

        let unset = Clock::virtual_unset();
        assert!(!unset.is_started());
        assert_eq!((unset.now_ns(), unset.now()), (0, Moment::default()));
        unset.set_ns(5);
        assert!(unset.is_started());

        let s = Clock::system();
        assert!(s.now_ns() > 1_600_000_000_000_000_000);
        assert!(s.is_started() && !s.is_virtual());
        let a = s.now();
        assert!(s.now() >= a);
    }

    #[tokio::test(flavor = "current_thread")]
    async fn sleeps_on_a_virtual_clock_wake_when_it_is_moved_past_them() {
        let c = Clock::virtual_unset();
        let started = tokio::spawn({
            let c = c.clone();
            async move { c.started().await }
        });
        tokio::task::yield_now().await;
        assert!(!started.is_finished());
        c.set_ns(1_000_000_000);
        started.await.unwrap();

        let t0 = c.now();
        let sleeper = tokio::spawn({
            let c = c.clone();
            async move {
                c.sleep(Duration::from_secs(5)).await;
                c.now()
            }
        });
        let mut interval = c.interval(Duration::from_secs(1));
        assert_eq!(interval.tick().await, t0, "the first tick is at once");
        for _ in 0..10 {
            tokio::task::yield_now().await;
        }
        c.advance(Duration::from_millis(4_999));
        for _ in 0..10 {
            tokio::task::yield_now().await;
        }
        assert!(!sleeper.is_finished(), "4.999 s is not 5 s");
        // A jump far past the deadline wakes it; it reads the clock's time, not the deadline.
        c.advance(Duration::from_secs(60));
        let woke = sleeper.await.unwrap();
        assert_eq!(woke.duration_since(t0), Duration::from_millis(64_999));
        // The interval skips what it missed: one tick, the next a period later.
        assert_eq!(
            interval.tick().await.duration_since(t0),
            woke.duration_since(t0)
        );
        let next = tokio::spawn(async move { interval.tick().await });
        for _ in 0..10 {
            tokio::task::yield_now().await;
        }
        assert!(!next.is_finished());
        c.advance(Duration::from_secs(1));
        assert_eq!(
            next.await.unwrap().duration_since(t0),
            Duration::from_millis(65_999)
        );
        // A time-out on the virtual clock: the future wins while the clock stands still.
        let never = std::future::pending::<()>();
        let timed = tokio::spawn({
            let c = c.clone();
            async move { c.timeout(Duration::from_secs(2), never).await }
        });
        for _ in 0..10 {
            tokio::task::yield_now().await;
        }
        assert!(!timed.is_finished());
        c.advance(Duration::from_secs(2));
        assert_eq!(timed.await.unwrap(), None);
    }
}
