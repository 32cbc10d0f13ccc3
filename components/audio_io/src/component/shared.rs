//! What the device threads share: the flags, the devices and the counters ([`Loops`]), and the
//! time line of the microphone and the speaker ([`VoiceClock`]) the double-talk detector aligns
//! them on.

use super::Config;
use super::devices::{Echo, Presence};
use interfaces::clock::Clock;
use std::sync::Arc;
use std::time::Instant;

/// What the capture and the playback threads share.
pub(super) struct Loops<'a> {
    pub(super) config: &'a Config,
    /// The component's clock: the threads' back-offs (reopening a lost device) run on it.
    pub(super) clock: &'a Clock,
    pub(super) echo: &'a Echo,
    pub(super) presence: &'a Presence,
    pub(super) counters: &'a interfaces::bus::Counters,
    pub(super) voice: &'a VoiceClock,
}

/// What the capture and the playback threads are started with (owned, for [`Loops`]).
#[derive(Clone)]
pub(super) struct Shared {
    pub(super) config: Config,
    pub(super) clock: Clock,
    pub(super) echo: Arc<Echo>,
    pub(super) presence: Arc<Presence>,
    pub(super) counters: Arc<interfaces::bus::Counters>,
    pub(super) voice: Arc<VoiceClock>,
}

impl Shared {
    /// Run `f` on a thread named `name`, over a [`Loops`] of its own copy of these.
    pub(super) fn spawn(
        &self,
        name: &str,
        f: impl FnOnce(&Loops) + Send + 'static,
    ) -> std::io::Result<std::thread::JoinHandle<()>> {
        let shared = self.clone();
        std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                f(&Loops {
                    config: &shared.config,
                    clock: &shared.clock,
                    echo: &shared.echo,
                    presence: &shared.presence,
                    counters: &shared.counters,
                    voice: &shared.voice,
                })
            })
    }
}

/// The clock the capture threads and the playback thread share (ns since `origin`), and what
/// the playback thread tells the double-talk detector: what the robot played, and when.
///
/// It is the devices' time, the wall's: the microphone hears and the speaker plays in real
/// time whatever the component's clock says, and the detector lines the two streams up on it.
#[derive(Debug)]
pub(super) struct VoiceClock {
    origin: Instant,
    /// To the capture thread's detector; `None` without one.
    played: Option<std::sync::mpsc::SyncSender<Played>>,
}

/// What the speaker played, for the double-talk detector.
#[derive(Debug)]
pub(super) enum Played {
    /// Mono samples at a rate, the first playing at a time (ns).
    Voice(i64, u32, Vec<i16>),
    /// What was queued from this time (ns) on was thrown away.
    DroppedFrom(i64),
}

impl VoiceClock {
    /// A clock starting now; `played` to the detector, if there is one.
    #[expect(
        clippy::disallowed_methods,
        reason = "the time line of the real microphone and speaker, which play in real time"
    )]
    pub(super) fn new(played: Option<std::sync::mpsc::SyncSender<Played>>) -> Self {
        Self {
            origin: Instant::now(),
            played,
        }
    }

    /// Now on the devices' time line (the wall's).
    #[expect(
        clippy::disallowed_methods,
        reason = "the real microphone and speaker run in real time: what they heard and played is lined up on the wall"
    )]
    pub(super) fn now(&self) -> Instant {
        Instant::now()
    }

    pub(super) fn ns(&self, t: Instant) -> i64 {
        i64::try_from(t.saturating_duration_since(self.origin).as_nanos()).unwrap_or(i64::MAX)
    }

    /// When the first sample of a chunk of `frames` at `rate_hz` just read was heard, the stream
    /// saying its last one waited `latency_us`.
    pub(super) fn heard_ns(&self, frames: usize, rate_hz: u32, latency_us: u64) -> i64 {
        let chunk = frames as i64 * 1_000_000_000 / i64::from(rate_hz.max(1));
        self.ns(self.now()) - chunk - latency_us as i64 * 1000
    }

    /// `samples` (interleaved, `channels`) play from `at` on.
    pub(super) fn played(
        &self,
        at: Instant,
        (rate_hz, channels): (u32, usize),
        samples: &[i16],
        counters: &interfaces::bus::Counters,
    ) {
        let Some(tx) = &self.played else {
            return;
        };
        let mono: Vec<i16> = samples
            .chunks(channels.max(1))
            .map(|f| (f.iter().map(|&x| i32::from(x)).sum::<i32>() / f.len() as i32) as i16)
            .collect();
        if tx
            .try_send(Played::Voice(self.ns(at), rate_hz, mono))
            .is_err()
        {
            counters.incr("double_talk_reference_dropped");
        }
    }

    /// What the server held was thrown away.
    pub(super) fn stopped(&self, counters: &interfaces::bus::Counters) {
        if let Some(tx) = &self.played
            && tx
                .try_send(Played::DroppedFrom(self.ns(self.now())))
                .is_err()
        {
            counters.incr("double_talk_reference_dropped");
        }
    }
}
