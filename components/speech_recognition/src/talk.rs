//! Push-to-talk: in a hall where everyone talks (a RoboCup field), the operator holds a key (the
//! command panel's "Hold to talk" button, or V on its page) while speaking, and only what the microphone
//! hears while the key is held is speech to the recognizer (`--push-to-talk`).
//!
//! The key comes as [`TalkKey`] messages on `speech/talk`, stamped with when the key was in that
//! state; the audio as blocks stamped with when they were heard. [`TalkGate`] keeps the key's
//! recent history and answers, for a block, whether the key was held when it was heard. What
//! was heard outside the key is handed to the end-pointer as sound from elsewhere
//! ([`crate::vad::Vad::set_elsewhere`]): it neither opens nor stretches an utterance, however
//! loud, so another talker is never decoded; and an utterance that was open when the key came up
//! ends after the end-pointer's hangover, as after a pause.
//!
//! - The key's last [`RELEASE_TAIL_S`] still counts as held: people let go as they say the last
//!   syllable. What she said just before pressing is in the end-pointer's pre-roll.
//! - A held key that is not sent again within [`TALK_KEY_EXPIRY_S`] is taken as released (the
//!   panel or its page is gone), counted, and logged: a key never stays down for lack of news.
//! - A key message stamped far from the audio's time (a machine's clock off, a replayed
//!   message) is dropped and counted rather than opening the microphone for minutes.

use interfaces::msg::speech::{TALK_KEY_EXPIRY_S, TalkKey};
use std::collections::VecDeque;

/// How long after the key comes up what is heard still counts as said with it (s).
pub const RELEASE_TAIL_S: f64 = 0.3;
/// How much of the key's history is kept (s of stamps behind the newest).
const HISTORY_S: f64 = 30.0;
/// A key message further than this from the newest audio heard is not believed (s).
const BELIEVABLE_S: f64 = 60.0;

fn ns(s: f64) -> i64 {
    (s * 1e9) as i64
}

/// What became of one key message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeyNews {
    /// The key went down (it was up).
    Pressed,
    /// The key came up (it was down).
    Released,
    /// Nothing changed: a held key sent again, or a second release.
    Same,
    /// Dropped: stamped before the key's last message, or too far from the audio's time.
    Dropped,
}

/// The talk key's recent history, and for each block of audio whether the key was held.
#[derive(Debug, Default)]
pub struct TalkGate {
    /// (stamp ns, held), in stamp order.
    history: VecDeque<(i64, bool)>,
    /// The newest audio heard (ns), to judge a key message's stamp by.
    audio_ns: Option<i64>,
    /// Holds that ended for want of news ([`TALK_KEY_EXPIRY_S`]).
    pub expired: u64,
    /// The hold whose expiry was counted (its last held stamp), so it is counted once.
    expired_at: Option<i64>,
}

impl TalkGate {
    pub fn new() -> Self {
        Self::default()
    }

    /// A key message: added to the history, unless it is older than the last one or its stamp is
    /// not believable next to the audio's time.
    pub fn key(&mut self, key: &TalkKey) -> KeyNews {
        let at = key.header.stamp_ns;
        if at <= 0 {
            return KeyNews::Dropped;
        }
        if let Some(audio) = self.audio_ns
            && (at - audio).abs() > ns(BELIEVABLE_S)
        {
            return KeyNews::Dropped;
        }
        let before = self.history.back().copied();
        if let Some((last, _)) = before
            && at < last
        {
            return KeyNews::Dropped;
        }
        self.history.push_back((at, key.held));
        while let Some(&(first, _)) = self.history.front()
            && at - first > ns(HISTORY_S)
            && self.history.len() > 1
        {
            self.history.pop_front();
        }
        // Whether it was held just before this message, expiry included.
        let was = before.is_some_and(|(last, held)| held && at - last <= ns(TALK_KEY_EXPIRY_S));
        match (was, key.held) {
            (false, true) => KeyNews::Pressed,
            (true, false) => KeyNews::Released,
            _ => KeyNews::Same,
        }
    }

    /// Whether the key was held when audio stamped `at_ns` was heard (the tail after a release
    /// included). A hold that runs out of news is counted once in [`Self::expired`].
    pub fn held_at(&mut self, at_ns: i64) -> bool {
        self.audio_ns = Some(self.audio_ns.map_or(at_ns, |a| a.max(at_ns)));
        // The last message at or before the audio, and the one before it.
        let i = self.history.partition_point(|&(t, _)| t <= at_ns);
        let Some(&(last, held)) = i.checked_sub(1).and_then(|i| self.history.get(i)) else {
            return false;
        };
        if held {
            if at_ns - last <= ns(TALK_KEY_EXPIRY_S) {
                return true;
            }
            if self.expired_at != Some(last) {
                self.expired_at = Some(last);
                self.expired += 1;
            }
            return false;
        }
        // Released at `last`: the tail, when the key was held until then.
        let held_before = i
            .checked_sub(2)
            .and_then(|j| self.history.get(j))
            .is_some_and(|&(t, h)| h && last - t <= ns(TALK_KEY_EXPIRY_S));
        held_before && at_ns - last <= ns(RELEASE_TAIL_S)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::Header;

    const S: i64 = 1_000_000_000;
    /// The tests' time origin (ns): any wall time.
    const T0: i64 = 1_800_000_000 * S;

    fn key(at_s: f64, held: bool) -> TalkKey {
        TalkKey {
            header: Header {
                stamp_ns: T0 + ns(at_s),
                ..Header::default()
            },
            held,
            source: "test".into(),
        }
    }

    fn at(s: f64) -> i64 {
        T0 + ns(s)
    }

    #[test]
    fn nothing_is_held_before_the_key_is_pressed() {
        let mut g = TalkGate::new();
        assert!(!g.held_at(at(0.0)));
        assert!(!g.held_at(at(5.0)));
    }

    #[test]
    fn audio_is_hers_from_the_press_to_the_release_and_its_tail() {
        let mut g = TalkGate::new();
        assert_eq!(g.key(&key(1.0, true)), KeyNews::Pressed);
        assert_eq!(g.key(&key(1.5, true)), KeyNews::Same);
        assert_eq!(g.key(&key(2.0, true)), KeyNews::Same);
        assert_eq!(g.key(&key(2.2, false)), KeyNews::Released);
        assert!(!g.held_at(at(0.9)));
        assert!(g.held_at(at(1.0)));
        assert!(g.held_at(at(2.1)));
        // The last syllable as she lets go.
        assert!(g.held_at(at(2.2 + RELEASE_TAIL_S - 0.01)));
        assert!(!g.held_at(at(2.2 + RELEASE_TAIL_S + 0.01)));
        assert!(!g.held_at(at(4.0)));
        assert_eq!(g.expired, 0);
    }

    #[test]
    fn a_held_key_without_news_is_released_and_counted_once() {
        let mut g = TalkGate::new();
        g.key(&key(1.0, true));
        assert!(g.held_at(at(1.0 + TALK_KEY_EXPIRY_S - 0.01)));
        assert!(!g.held_at(at(1.0 + TALK_KEY_EXPIRY_S + 0.01)));
        assert!(!g.held_at(at(10.0)));
        assert_eq!(g.expired, 1);
        // A release long after is no release: no tail.
        assert_eq!(g.key(&key(20.0, false)), KeyNews::Same);
        assert!(!g.held_at(at(20.1)));
        // Pressed again: held again, and a new hold may expire again.
        assert_eq!(g.key(&key(21.0, true)), KeyNews::Pressed);
        assert!(g.held_at(at(21.5)));
        assert!(!g.held_at(at(25.0)));
        assert_eq!(g.expired, 2);
    }

    #[test]
    fn a_late_audio_block_is_judged_by_the_key_at_its_own_time() {
        // The release arrives before the audio it ends: the audio heard while the key was down
        // is still hers, and what was heard after is not.
        let mut g = TalkGate::new();
        g.key(&key(1.0, true));
        g.key(&key(1.4, false));
        g.key(&key(3.0, true));
        g.key(&key(3.3, false));
        let verdicts: Vec<bool> = [0.5, 1.2, 2.0, 3.1, 4.0]
            .iter()
            .map(|&s| g.held_at(at(s)))
            .collect();
        assert_eq!(verdicts, [false, true, false, true, false]);
    }

    #[test]
    fn messages_out_of_order_or_far_off_the_audio_clock_are_dropped() {
        let mut g = TalkGate::new();
        assert!(!g.held_at(at(100.0)));
        // An hour off: a machine whose clock is wrong.
        assert_eq!(g.key(&key(3700.0, true)), KeyNews::Dropped);
        assert_eq!(g.key(&key(-3500.0, true)), KeyNews::Dropped);
        assert!(!g.held_at(at(100.1)));
        // Unstamped.
        let mut unstamped = key(100.0, true);
        unstamped.header.stamp_ns = 0;
        assert_eq!(g.key(&unstamped), KeyNews::Dropped);
        assert_eq!(g.key(&key(100.2, true)), KeyNews::Pressed);
        // Older than the last one.
        assert_eq!(g.key(&key(100.1, false)), KeyNews::Dropped);
        assert!(g.held_at(at(100.3)));
    }

    #[test]
    fn the_history_is_bounded() {
        let mut g = TalkGate::new();
        for i in 0..10_000 {
            g.key(&key(f64::from(i) * 0.5, i % 2 == 0));
        }
        assert!(
            g.history.len() <= (HISTORY_S / 0.5) as usize + 2,
            "{}",
            g.history.len()
        );
    }
}
