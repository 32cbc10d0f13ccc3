//! The process loop's tests on a real bus (a router of their own) and a virtual clock.

use super::*;
use interfaces::msg::vision::CameraStatus;

fn status(streaming: bool) -> CameraStatus {
    CameraStatus {
        driver: "freenect".into(),
        streaming,
        detail: "camera lost: unplugged".into(),
        ..Default::default()
    }
}

/// The touch game's process loop on a virtual clock: its timers and the tracker watchdog
/// fire when the clock is moved to their deadline, never before, and never from the wall.
/// Every input first fires the timers due, so an input sent just before a deadline is
/// stepped alone and the timer's step follows when the clock reaches it: no sleeps.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_touch_loop_runs_its_timers_and_watchdog_on_a_virtual_clock() {
    use interfaces::bus::BusOptions;
    use interfaces::msg::command::{Command, CommandSource, Game, GameCommand};
    use interfaces::msg::tracking::BallTrack;

    let (_router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0")
        .await
        .unwrap();
    let args = interfaces::ConnectArgs::to_router(
        &endpoint,
        &format!("unit-exec-clock-{}", std::process::id()),
    );
    let clock = Clock::virtual_unset();
    let options = BusOptions {
        announce: true,
        clock: clock.clone(),
        ..Default::default()
    };
    let exec_bus = Bus::open_with(&args, "executive", options).await.unwrap();
    let bus = Bus::open(&args, "unit-test").await.unwrap();
    let steps = bus
        .subscriber(&topics::EXECUTIVE_TRANSITIONS)
        .await
        .unwrap();
    let commands = bus.publisher(&topics::GAME_COMMAND).await.unwrap();
    let events = bus.publisher(&topics::VISION_BALL_EVENTS).await.unwrap();
    let tracks = bus.publisher(&topics::VISION_BALL).await.unwrap();
    let config = Config {
        game: GameKind::Touch,
        settings: None,
        print_diagram: false,
        print_dot: false,
        exit_when_finished: false,
        state_dir: None,
        hearing_from: vec![],
        hearing_grace_s: 5.0,
        base: true,
    };
    let (stop, shutdown) = Shutdown::new();
    let exec = tokio::spawn(run_touch(exec_bus, config, Settings::default(), shutdown));
    let next = || async {
        let t = tokio::time::timeout(Duration::from_secs(20), steps.recv())
            .await
            .expect("a step within 20 s")
            .unwrap();
        (t.event, t.active)
    };
    let command = |c: Command| {
        let commands = &commands;
        async move {
            let mut m = GameCommand {
                game: Game::Touch,
                command: c,
                source: CommandSource::Panel,
                text: c.phrase().into(),
                confidence: 1.0,
                ..Default::default()
            };
            commands.publish(&mut m).await.unwrap();
        }
    };
    let event = |kind: BallEventKind| {
        let events = &events;
        async move {
            let mut e = BallEvent {
                kind,
                ..Default::default()
            };
            events.publish(&mut e).await.unwrap();
        }
    };
    // The subscriptions meet before the game starts: it starts once the clock has a time.
    interfaces::Clock::system()
        .sleep(Duration::from_millis(500))
        .await;
    clock.set_ns(1_700_000_000_000_000_000);
    let s = next().await;
    assert_eq!(s.1, [touch::state::WAITING]);
    command(Command::Play).await;
    assert_eq!(next().await.0, "command:play");
    command(Command::ScanBall).await;
    let (e, active) = next().await;
    assert_eq!(e, "command:scan_ball");
    assert!(
        active.iter().any(|a| a == touch::state::LOOKING),
        "{active:?}"
    );

    // The scan's move time-out (3 s): not at 2.999 s, at 3 s.
    clock.advance(Duration::from_millis(2_999));
    command(Command::Greet).await;
    assert_eq!(
        next().await.0,
        "command:greet",
        "no timer before its deadline"
    );
    clock.advance(Duration::from_millis(1));
    assert_eq!(next().await.0, "timer:scan");

    // The tracker watchdog (1.5 s without a track while tracking): the clock's, too.
    event(BallEventKind::Detected).await;
    assert_eq!(next().await.0, "ball:detected");
    event(BallEventKind::OutOfView).await;
    assert_eq!(next().await.0, "ball:out_of_view");
    let mut t = BallTrack {
        found: true,
        state: BallTrackState::Tracking,
        has_centre_m: true,
        centre_m: [0.0, 0.0, 0.8],
        ..Default::default()
    };
    tracks.publish(&mut t).await.unwrap();
    let (e, active) = next().await;
    assert_eq!(e, "ball:in_view", "the track was heard at this time");
    assert!(
        active.iter().any(|a| a == touch::state::TRACKING),
        "{active:?}"
    );
    clock.advance(Duration::from_millis(1_499));
    command(Command::Greet).await;
    assert_eq!(
        next().await.0,
        "command:greet",
        "the tracker is not silent yet"
    );
    clock.advance(Duration::from_millis(1));
    let (e, active) = next().await;
    assert_eq!(e, "ball:lost", "silent for 1.5 s on the clock");
    assert!(
        active.iter().any(|a| a == touch::state::LOOKING),
        "{active:?}"
    );

    // A jump of a minute: every move time-out of the scan, each at its own deadline.
    clock.advance(Duration::from_secs(60));
    for i in 0..20 {
        assert_eq!(next().await.0, "timer:scan", "time-out #{i} of 20");
    }
    stop.send(true).unwrap();
    exec.await.unwrap().unwrap();
}

#[test]
fn the_robot_says_once_when_its_camera_stops_and_once_when_it_is_back() {
    let t0 = Moment::from_duration(Duration::from_secs(1_000));
    let at = |s: u64| t0 + Duration::from_secs(s);
    let mut w = CameraWatch::default();
    assert_eq!(
        w.update(&status(true), at(0)),
        None,
        "streaming from the start"
    );
    assert_eq!(w.update(&status(true), at(1)), None);
    let (said, log) = w.update(&status(false), at(2)).expect("stopped");
    assert_eq!(said, Some(CANNOT_SEE));
    assert!(log.contains("unplugged"), "{log}");
    assert_eq!(w.update(&status(false), at(3)), None, "said once");
    assert_eq!(w.update(&status(true), at(4)).unwrap().0, Some(SEE_AGAIN));
    assert_eq!(w.update(&status(true), at(5)), None);
    // A flapping camera: logged every time, said again only after CAMERA_REPEAT.
    let (said, _) = w.update(&status(false), at(6)).unwrap();
    assert_eq!(said, None);
    assert_eq!(w.update(&status(true), at(7)).unwrap().0, None);
    let (said, _) = w.update(&status(false), at(2 + 20)).unwrap();
    assert_eq!(said, Some(CANNOT_SEE));
    assert_eq!(w.update(&status(true), at(23)).unwrap().0, Some(SEE_AGAIN));
}

/// A bus of the touch game's own, on a router of its own, with the Executive's loop running on a
/// virtual clock, and a ball tracker that can be killed and restarted (a bus of its own, named as
/// the real one: its writer token on `vision/ball` goes with it).
mod tracker_restart {
    use super::*;
    use interfaces::Publisher;
    use interfaces::msg::body::{ReachGoal, ReachState, ReachStatus};
    use interfaces::msg::command::{Command, CommandSource, Game, GameCommand};
    use interfaces::msg::tracking::BallTrack;

    /// The longest any wait of these tests takes (wall): each ends on an event.
    const WAIT: Duration = Duration::from_secs(20);
    /// The ball, in `world` (m).
    const P: [f64; 3] = [0.45, 0.30, 1.20];

    async fn within<T>(what: &str, f: impl std::future::Future<Output = T>) -> T {
        tokio::time::timeout(WAIT, f)
            .await
            .unwrap_or_else(|_| panic!("{what} within {WAIT:?}"))
    }

    struct Tracker {
        tracks: Publisher<BallTrack>,
        events: Publisher<BallEvent>,
        _bus: Bus,
    }

    impl Tracker {
        async fn start(args: &interfaces::ConnectArgs) -> Tracker {
            let bus = Bus::open(args, "ball_tracker").await.unwrap();
            Tracker {
                tracks: bus.publisher(&topics::VISION_BALL).await.unwrap(),
                events: bus.publisher(&topics::VISION_BALL_EVENTS).await.unwrap(),
                _bus: bus,
            }
        }
        async fn track(&self, mut t: BallTrack) {
            self.tracks.publish(&mut t).await.unwrap();
        }
        async fn event(&self, kind: BallEventKind) {
            let mut e = BallEvent {
                kind,
                ..Default::default()
            };
            self.events.publish(&mut e).await.unwrap();
        }
    }

    /// A track that holds the ball at `p` in `world`.
    fn held_at(p: [f64; 3]) -> BallTrack {
        BallTrack {
            found: true,
            state: BallTrackState::Tracking,
            has_centre_m: true,
            centre_m: [0.0, 0.0, 0.8],
            has_centre_world: true,
            centre_world_m: p,
            confidence: 0.9,
            ..Default::default()
        }
    }

    /// A freshly started tracker's track: no target, nothing found.
    fn waiting() -> BallTrack {
        BallTrack {
            state: BallTrackState::Waiting,
            ..Default::default()
        }
    }

    struct TouchRun {
        /// The router's session (kept open).
        _router: Box<dyn std::any::Any + Send + Sync>,
        args: interfaces::ConnectArgs,
        clock: Clock,
        settings: Settings,
        _bus: Bus,
        steps: interfaces::Subscriber<StateTransition>,
        says: interfaces::Subscriber<SayRequest>,
        logs: interfaces::Subscriber<GameLog>,
        reaches: interfaces::Subscriber<ReachGoal>,
        targets: interfaces::Subscriber<BallTarget>,
        commands: Publisher<GameCommand>,
        statuses: Publisher<ReachStatus>,
        tracker: Option<Tracker>,
        /// Every step seen.
        seen: Vec<StateTransition>,
        stop: tokio::sync::watch::Sender<bool>,
        exec: tokio::task::JoinHandle<anyhow::Result<()>>,
    }

    impl TouchRun {
        /// The game up to the hand touching the ball at [`P`], the tracker holding it.
        async fn touching(tag: &str) -> TouchRun {
            let (router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0")
                .await
                .unwrap();
            let args = interfaces::ConnectArgs::to_router(
                &endpoint,
                &format!("unit-exec-{tag}-{}", std::process::id()),
            );
            let clock = Clock::virtual_unset();
            let options = interfaces::bus::BusOptions {
                announce: true,
                clock: clock.clone(),
                ..Default::default()
            };
            let exec_bus = Bus::open_with(&args, "executive", options).await.unwrap();
            let bus = Bus::open(&args, "unit-test").await.unwrap();
            let mut settings = Settings::default();
            // No courtesy time-out while the tracker restarts.
            settings.touch.courtesy_delay_s = 30.0;
            let config = Config {
                game: GameKind::Touch,
                settings: None,
                print_diagram: false,
                print_dot: false,
                exit_when_finished: false,
                state_dir: None,
                hearing_from: vec![],
                hearing_grace_s: 5.0,
                base: true,
            };
            let (stop, shutdown) = Shutdown::new();
            let mut g = TouchRun {
                steps: bus
                    .subscriber(&topics::EXECUTIVE_TRANSITIONS)
                    .await
                    .unwrap(),
                says: bus.subscriber(&topics::SPEECH_SAY).await.unwrap(),
                logs: bus.subscriber(&topics::EXECUTIVE_LOG).await.unwrap(),
                reaches: bus.subscriber(&topics::BODY_REACH).await.unwrap(),
                targets: bus.subscriber(&topics::VISION_BALL_TARGET).await.unwrap(),
                commands: bus.publisher(&topics::GAME_COMMAND).await.unwrap(),
                statuses: bus.publisher(&topics::BODY_REACH_STATUS).await.unwrap(),
                tracker: Some(Tracker::start(&args).await),
                exec: tokio::spawn(run_touch(exec_bus, config, settings.clone(), shutdown)),
                _router: Box::new(router),
                args,
                clock,
                settings,
                _bus: bus,
                seen: vec![],
                stop,
            };
            // The subscriptions meet before the game starts: it starts once the clock has a time.
            Clock::system().sleep(Duration::from_millis(500)).await;
            g.clock.set_ns(1_700_000_000_000_000_000);
            assert_eq!(g.next().await.active, [touch::state::WAITING]);
            g.command(Command::Play).await;
            g.until("command:play").await;
            g.command(Command::ScanBall).await;
            g.until("command:scan_ball").await;
            let tracker = g.tracker.as_ref().unwrap();
            tracker.track(held_at(P)).await;
            tracker.event(BallEventKind::Detected).await;
            let active = g.until("ball:detected").await;
            assert!(
                active.iter().any(|a| a == touch::state::TRACKING),
                "{active:?}"
            );
            g.command(Command::TouchBall).await;
            g.until("command:touch_ball").await;
            let arm = g.settings.touch.arm.clone();
            let goal = within("the arm's reach goal", async {
                loop {
                    let r = g.reaches.recv().await.unwrap();
                    if r.body_part == arm && r.active {
                        return r;
                    }
                }
            })
            .await;
            let mut reached = ReachStatus {
                id: goal.id,
                body_part: arm,
                state: ReachState::Reached,
                distance_m: 0.01,
                ..Default::default()
            };
            g.statuses.publish(&mut reached).await.unwrap();
            let active = g.until("reach:reached").await;
            assert!(
                active.iter().any(|a| a == touch::state::TOUCHING),
                "{active:?}"
            );
            assert!(
                active.iter().any(|a| a == touch::state::TRACKING),
                "{active:?}"
            );
            g
        }

        async fn command(&self, c: Command) {
            let mut m = GameCommand {
                game: Game::Touch,
                command: c,
                source: CommandSource::Panel,
                text: c.phrase().into(),
                confidence: 1.0,
                ..Default::default()
            };
            self.commands.publish(&mut m).await.unwrap();
        }

        /// The next step of the machine.
        async fn next(&mut self) -> StateTransition {
            let t = within("a step", self.steps.recv()).await.unwrap();
            self.seen.push(t.clone());
            t
        }

        /// The steps up to one made by `event`: its active states.
        async fn until(&mut self, event: &str) -> Vec<String> {
            loop {
                let t = self.next().await;
                if t.event == event {
                    return t.active;
                }
            }
        }

        /// The next step is `event` (nothing came before it): its active states.
        async fn next_is(&mut self, event: &str) -> Vec<String> {
            let t = self.next().await;
            assert_eq!(t.event, event, "{:?}", self.events());
            t.active
        }

        fn events(&self) -> Vec<&str> {
            self.seen.iter().map(|t| t.event.as_str()).collect()
        }

        /// Waits for a game log line containing `text`.
        async fn log(&self, text: &str) -> String {
            within(&format!("a log line with {text:?}"), async {
                loop {
                    let l = self.logs.recv().await.unwrap();
                    if l.text.contains(text) {
                        return l.text;
                    }
                }
            })
            .await
        }

        /// Everything said so far.
        fn said(&self) -> Vec<String> {
            std::iter::from_fn(|| self.says.try_recv())
                .map(|s| s.text)
                .collect()
        }

        /// Kills the tracker (its writer token goes): the Executive starts riding out its
        /// restart at the clock's time, which it returns.
        async fn kill_tracker(&mut self) -> Moment {
            self.tracker = None;
            let line = self.log("the ball tracker left vision/ball").await;
            assert!(line.contains("riding out"), "{line}");
            self.clock.now()
        }

        /// A new tracker process: its first track has no target (its numbers start at 0 again),
        /// and the game sends the target again. Should the first track go before the new
        /// publisher's route is up, another goes a second later (the game sends the target at
        /// most once a second, on its clock).
        async fn restart_tracker(&mut self) {
            let tracker = Tracker::start(&self.args).await;
            while self.targets.try_recv().is_some() {}
            for _ in 0..10 {
                tracker.track(waiting()).await;
                let target = tokio::time::timeout(Duration::from_secs(2), async {
                    loop {
                        let t = self.targets.recv().await.unwrap();
                        if t.active {
                            return t;
                        }
                    }
                })
                .await;
                if let Ok(t) = target {
                    assert_eq!(t.hue_deg, self.settings.touch.ball_hue_deg);
                    self.tracker = Some(tracker);
                    return;
                }
                self.clock.advance(Duration::from_secs(1));
            }
            panic!("the target was not sent again to the restarted tracker");
        }

        async fn stop(self) {
            self.stop.send(true).unwrap();
            self.exec.await.unwrap().unwrap();
        }
    }

    /// The tracker is killed while the hand touches the ball and restarted by the launcher: the
    /// game rides it out (no `ball:lost`, nothing said, the arm stays), the new tracker gets the
    /// target again and finds the ball where it was, and "you touched it" is thanked.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_tracker_restarted_while_touching_is_ridden_out_and_thanked() {
        let mut g = TouchRun::touching("ride-out").await;
        let _before = g.said();
        g.kill_tracker().await;
        // Longer than the silence that loses the ball of a stalled camera: still touching.
        g.clock.advance(Duration::from_secs(3));
        g.command(Command::Greet).await;
        let active = g.next_is("command:greet").await;
        assert!(
            active.iter().any(|a| a == touch::state::TOUCHING),
            "{active:?}"
        );
        assert!(
            active.iter().any(|a| a == touch::state::TRACKING),
            "{active:?}"
        );
        g.restart_tracker().await;
        let tracker = g.tracker.as_ref().unwrap();
        tracker.event(BallEventKind::Detected).await;
        // A centimetre off: the ball did not move.
        tracker.track(held_at([P[0] + 0.01, P[1], P[2]])).await;
        let line = g.log("the ball tracker holds the ball again").await;
        assert!(line.contains("holds the ball"), "{line}");
        g.command(Command::YouTouchedIt).await;
        let active = g.until("command:you_touched_it").await;
        assert!(
            active.iter().any(|a| a == touch::state::HOMING),
            "{active:?}"
        );
        assert!(
            active.iter().any(|a| a == touch::state::TRACKING),
            "{active:?}"
        );
        let thanks = within("the thanks", async {
            loop {
                let s = g.says.recv().await.unwrap();
                if s.text == touch::say::THANKS {
                    return s;
                }
                assert!(
                    ![
                        touch::say::LOST,
                        touch::say::LOOKING,
                        touch::say::NOT_TOUCHING
                    ]
                    .contains(&s.text.as_str()),
                    "said {:?} while the tracker restarted",
                    s.text
                );
            }
        })
        .await;
        assert_eq!(thanks.text, touch::say::THANKS);
        let events = g.events();
        assert!(!events.contains(&"ball:lost"), "{events:?}");
        assert!(!events.contains(&"ball:moved"), "{events:?}");
        g.stop().await;
    }

    /// A restarted tracker that does not find the ball again: the ball is lost at the end of the
    /// grace (from the tracker's leave, on the clock), not a millisecond before.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_restarted_tracker_that_does_not_find_the_ball_loses_it_at_the_grace() {
        let mut g = TouchRun::touching("grace").await;
        let grace = Duration::from_secs_f64(g.settings.touch.tracker_restart_grace_s);
        let left = g.kill_tracker().await;
        g.restart_tracker().await;
        let _before = g.said();
        let end = left + grace;
        g.clock
            .advance(g.clock.now().until(end) - Duration::from_millis(1));
        g.command(Command::Greet).await;
        let active = g.next_is("command:greet").await;
        assert!(
            active.iter().any(|a| a == touch::state::TOUCHING),
            "{active:?}"
        );
        g.clock.advance(Duration::from_millis(1));
        let active = g.next_is("ball:lost").await;
        assert!(
            active.iter().any(|a| a == touch::state::LOOKING),
            "{active:?}"
        );
        assert!(
            active.iter().any(|a| a == touch::state::HOMING),
            "{active:?}"
        );
        g.log("did not hold the ball again within 6.0 s").await;
        let lost = within("the robot says it lost the ball", async {
            loop {
                let s = g.says.recv().await.unwrap();
                if s.text == touch::say::LOST {
                    return s;
                }
            }
        })
        .await;
        assert_eq!(lost.text, touch::say::LOST);
        g.stop().await;
    }
}
