//! The touch game's watch over the ball tracker: a tracker that falls silent with its writer
//! still on the bus (its camera stalled, it hangs) has lost the ball; a tracker or a camera that
//! left the bus, or a tracker that came back as a new process (killed, crashed, restarted by the
//! launcher), is an anomaly the game rides out for a grace, the ball taken to be where it was,
//! until the tracker holds it again. All on the component's clock.

use std::collections::BTreeSet;
use std::time::Duration;

use interfaces::Moment;
use interfaces::msg::tracking::{BallTrack, BallTrackState};

/// How long without `vision/ball` before a tracking game calls the ball lost.
pub(super) const TRACKER_SILENCE: Duration = Duration::from_millis(1500);

/// The feeds whose writers the watch follows: the tracks (`vision/ball`) and the frames they
/// are made from (`vision/rgbd`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Feed {
    Tracker = 0,
    Camera = 1,
}

/// What a track told the watch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TrackNews {
    Nothing,
    /// A new tracker process while the eyes follow the ball (its sequence numbers start again,
    /// or it has no target): riding out its restart from now.
    Restarted,
    /// The tracker holds the ball again: the ride-out is over.
    Back,
}

/// What fell due on the clock: both are a lost ball.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TrackerDue {
    /// No track for [`TRACKER_SILENCE`], the tracker still on the bus (a stalled camera, a
    /// frozen tracker).
    Silent,
    /// A restarted tracker did not hold the ball within the grace.
    GraceOver,
}

/// Watches the tracker's heartbeat (`vision/ball` comes once per frame, found or not), its
/// writers on the bus and its sequence numbers.
#[derive(Debug)]
pub(super) struct TrackerWatch {
    grace: Duration,
    last: Option<Moment>,
    reported: bool,
    last_resend: Option<Moment>,
    /// `header.seq` of the last track (per publisher, from 0: lower or equal is a new one).
    last_seq: Option<u64>,
    /// The components publishing each [`Feed`].
    writers: [BTreeSet<String>; 2],
    /// Riding out a restart since then.
    riding_out_since: Option<Moment>,
}

impl TrackerWatch {
    pub(super) fn new(grace: Duration) -> Self {
        Self {
            grace,
            last: None,
            reported: false,
            last_resend: None,
            last_seq: None,
            writers: [BTreeSet::new(), BTreeSet::new()],
            riding_out_since: None,
        }
    }

    pub(super) fn grace(&self) -> Duration {
        self.grace
    }

    /// The components publishing `feed` now. True when one left while the eyes follow the ball
    /// (`tracking`) and no ride-out was on: one starts at `now`, and ends when the tracker holds
    /// the ball again.
    pub(super) fn writers(
        &mut self,
        feed: Feed,
        now_set: BTreeSet<String>,
        tracking: bool,
        now: Moment,
    ) -> bool {
        let mine = &mut self.writers[feed as usize];
        let left = mine.difference(&now_set).next().is_some();
        *mine = now_set;
        if left && tracking && self.riding_out_since.is_none() {
            self.riding_out_since = Some(now);
            return true;
        }
        false
    }

    /// A track at `now` (`held`: the tracker holds the ball in it).
    pub(super) fn heard(
        &mut self,
        t: &BallTrack,
        held: bool,
        tracking: bool,
        now: Moment,
    ) -> TrackNews {
        let new_process = self.last_seq.is_some_and(|s| t.header.seq <= s);
        self.last_seq = Some(t.header.seq);
        self.last = Some(now);
        self.reported = false;
        if !tracking {
            self.riding_out_since = None;
            return TrackNews::Nothing;
        }
        if (new_process || t.state == BallTrackState::Waiting)
            && !held
            && self.riding_out_since.is_none()
        {
            self.riding_out_since = Some(now);
            return TrackNews::Restarted;
        }
        if held && self.riding_out_since.take().is_some() {
            return TrackNews::Back;
        }
        TrackNews::Nothing
    }

    /// Whether a restart is being ridden out.
    #[cfg(test)]
    pub(super) fn riding_out(&self) -> bool {
        self.riding_out_since.is_some()
    }

    /// When the watch is next due while the eyes follow the ball (`tracking`), for the loop's
    /// sleep: the end of the grace while riding out a restart, else a silence of
    /// [`TRACKER_SILENCE`] since the tracker was last heard (not reported yet).
    pub(super) fn deadline(&self, tracking: bool) -> Option<Moment> {
        if !tracking {
            return None;
        }
        match self.riding_out_since {
            Some(t) => Some(t + self.grace),
            None => self
                .last
                .filter(|_| !self.reported)
                .map(|t| t + TRACKER_SILENCE),
        }
    }

    /// What is due at `now`, once each. Eyes that no longer follow the ball end a ride-out.
    pub(super) fn due(&mut self, tracking: bool, now: Moment) -> Option<TrackerDue> {
        if !tracking {
            self.riding_out_since = None;
            return None;
        }
        match self.deadline(tracking) {
            Some(d) if now >= d => {
                self.reported = true;
                Some(if self.riding_out_since.take().is_some() {
                    TrackerDue::GraceOver
                } else {
                    TrackerDue::Silent
                })
            }
            _ => None,
        }
    }

    /// At most once a second.
    pub(super) fn may_resend(&mut self, now: Moment) -> bool {
        if self
            .last_resend
            .is_some_and(|t| now.duration_since(t) < Duration::from_secs(1))
        {
            return false;
        }
        self.last_resend = Some(now);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::Header;

    fn at(ms: u64) -> Moment {
        Moment::from_duration(Duration::from_secs(1_000) + Duration::from_millis(ms))
    }

    fn track(seq: u64, state: BallTrackState) -> BallTrack {
        BallTrack {
            header: Header {
                seq,
                ..Default::default()
            },
            state,
            found: state == BallTrackState::Tracking,
            has_centre_m: state == BallTrackState::Tracking,
            ..Default::default()
        }
    }

    fn writers(names: &[&str]) -> BTreeSet<String> {
        names.iter().map(|n| n.to_string()).collect()
    }

    const GRACE: Duration = Duration::from_secs(6);

    #[test]
    fn a_silent_tracker_whose_writer_stays_has_lost_the_ball_at_the_silence() {
        let mut w = TrackerWatch::new(GRACE);
        assert!(!w.writers(Feed::Tracker, writers(&["ball_tracker"]), true, at(0)));
        let t = track(0, BallTrackState::Tracking);
        assert_eq!(w.heard(&t, true, true, at(0)), TrackNews::Nothing);
        assert_eq!(w.deadline(true), Some(at(1_500)));
        assert_eq!(
            w.deadline(false),
            None,
            "only while the eyes follow the ball"
        );
        assert_eq!(w.due(true, at(1_499)), None);
        assert_eq!(w.due(true, at(1_500)), Some(TrackerDue::Silent));
        assert_eq!(w.due(true, at(9_000)), None, "once");
        assert!(!w.riding_out());
    }

    #[test]
    fn a_writer_that_leaves_while_tracking_is_ridden_out_until_the_ball_is_held_again() {
        let mut w = TrackerWatch::new(GRACE);
        w.writers(Feed::Tracker, writers(&["ball_tracker"]), true, at(0));
        w.heard(&track(7, BallTrackState::Tracking), true, true, at(0));
        // Killed: its token goes.
        assert!(w.writers(Feed::Tracker, writers(&[]), true, at(100)));
        assert!(w.riding_out());
        assert_eq!(
            w.deadline(true),
            Some(at(6_100)),
            "the grace, not the silence"
        );
        assert_eq!(w.due(true, at(1_500)), None, "no silence while riding out");
        // Restarted: back on the bus, then a track with no target, its numbers from 0 again.
        assert!(!w.writers(Feed::Tracker, writers(&["ball_tracker"]), true, at(900)));
        let waiting = track(0, BallTrackState::Waiting);
        assert_eq!(
            w.heard(&waiting, false, true, at(1_000)),
            TrackNews::Nothing
        );
        assert_eq!(w.deadline(true), Some(at(6_100)), "still from the leave");
        assert_eq!(
            w.heard(&track(3, BallTrackState::Detecting), false, true, at(2_000)),
            TrackNews::Nothing
        );
        let held = track(4, BallTrackState::Tracking);
        assert_eq!(w.heard(&held, true, true, at(2_100)), TrackNews::Back);
        assert!(!w.riding_out());
        assert_eq!(w.deadline(true), Some(at(3_600)), "the silence watch again");
        assert_eq!(
            w.heard(&track(5, BallTrackState::Tracking), true, true, at(2_200)),
            TrackNews::Nothing
        );
    }

    #[test]
    fn a_camera_that_leaves_while_tracking_is_ridden_out_until_the_tracker_holds_the_ball() {
        let mut w = TrackerWatch::new(GRACE);
        w.writers(Feed::Tracker, writers(&["ball_tracker"]), true, at(0));
        w.writers(Feed::Camera, writers(&["rgbd"]), true, at(0));
        w.heard(&track(7, BallTrackState::Tracking), true, true, at(0));
        // The camera is killed: the tracker stays, silent without frames.
        assert!(w.writers(Feed::Camera, writers(&[]), true, at(100)));
        assert!(w.riding_out());
        assert_eq!(w.due(true, at(1_500)), None, "no silence while riding out");
        // Back, and the tracker holds the ball in the new camera's frames.
        assert!(!w.writers(Feed::Camera, writers(&["rgbd"]), true, at(800)));
        assert_eq!(
            w.heard(&track(8, BallTrackState::Tracking), true, true, at(900)),
            TrackNews::Back
        );
        assert!(!w.riding_out());
        // The tracker's own set is its own: the camera's return is no tracker leaving.
        assert!(!w.writers(Feed::Tracker, writers(&["ball_tracker"]), true, at(1_000)));
        // A camera that never comes back: the ball is lost at the grace.
        assert!(w.writers(Feed::Camera, writers(&[]), true, at(2_000)));
        assert_eq!(w.due(true, at(7_999)), None);
        assert_eq!(w.due(true, at(8_000)), Some(TrackerDue::GraceOver));
    }

    #[test]
    fn a_leave_while_not_tracking_is_not_ridden_out() {
        let mut w = TrackerWatch::new(GRACE);
        w.writers(Feed::Tracker, writers(&["ball_tracker"]), false, at(0));
        assert!(!w.writers(Feed::Tracker, writers(&[]), false, at(100)));
        assert!(!w.riding_out());
    }

    #[test]
    fn numbers_that_start_again_or_a_track_without_target_are_a_restart() {
        let mut w = TrackerWatch::new(GRACE);
        w.heard(&track(40, BallTrackState::Tracking), true, true, at(0));
        // A new process (the leave unseen: its token went and came back between two looks).
        let t = track(0, BallTrackState::Detecting);
        assert_eq!(w.heard(&t, false, true, at(100)), TrackNews::Restarted);
        assert_eq!(w.deadline(true), Some(at(6_100)));
        assert_eq!(
            w.heard(&track(1, BallTrackState::Waiting), false, true, at(200)),
            TrackNews::Nothing,
            "already riding out"
        );
        // The grace passes, to the millisecond: lost.
        assert_eq!(w.due(true, at(6_099)), None);
        assert_eq!(w.due(true, at(6_100)), Some(TrackerDue::GraceOver));
        assert!(!w.riding_out());
        assert_eq!(w.due(true, at(6_200)), None, "once");

        // No target while tracking (the leave and the numbers unseen).
        let mut w = TrackerWatch::new(GRACE);
        w.heard(&track(0, BallTrackState::Tracking), true, true, at(0));
        let waiting = track(1, BallTrackState::Waiting);
        assert_eq!(w.heard(&waiting, false, true, at(50)), TrackNews::Restarted);
        // Eyes that stop following the ball end the ride-out.
        assert_eq!(w.due(false, at(60)), None);
        assert!(!w.riding_out());
        // Not tracking: numbers that start again are only noted.
        assert_eq!(
            w.heard(&track(0, BallTrackState::Waiting), false, false, at(70)),
            TrackNews::Nothing
        );
        assert!(!w.riding_out());
    }

    #[test]
    fn a_target_is_sent_again_at_most_once_a_second() {
        let mut w = TrackerWatch::new(GRACE);
        assert!(w.may_resend(at(0)));
        assert!(!w.may_resend(at(999)));
        assert!(w.may_resend(at(1_000)));
    }
}
