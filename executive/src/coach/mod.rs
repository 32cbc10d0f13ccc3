//! The Nao coach game (seed 000 §1.2, §3.1.3-3.1.5) in the Executive: every coach command is
//! answered before it is executed, checked against the world model and the game's rules, and
//! remembered so it resumes after a fall, a penalty or a lost link.
//!
//! - [`rules`]: the decisions as a pure library (no bus, no clock).
//! - [`machine`]: the `coach` machine on the Executive's engine (waiting_for_game, playing,
//!   robot_down, penalised, link_lost), driven by bus messages, time passed in.
//! - [`run`]: the process side.
//!
//! # On the bus
//!
//! In: `game/command` (coach commands by voice through `speech_recognition --game coach` and
//! `dialogs`, or panel buttons), `coach/request` (panel commands with targets and aims),
//! `nao/world_model`, `nao/game_state`, `nao/link`. Out: `nao/command` (source `executive`, to
//! `nao_bridge`), `speech/say` (every answer, before the command is sent), `executive/transitions`
//! (machine `coach`), `executive/log`, `coach/status` (memory and last-seen times, on every
//! change and once a second).
//!
//! # Restarts
//!
//! With a state folder (`ROBOCOG_STATE_DIR`, from the launcher) the game's record
//! ([`machine::resume::Resume`]) is kept in `<state dir>/coach.json` after every input that
//! changes it, and before a command goes out (so one the process dies sending is sent again); a
//! restarted Executive takes the game up from it ([`CoachGame::resume`]). Commands go out only
//! while a bridge ([`CoachSettings`]' `bridges`) subscribes to `nao/command`; meanwhile they are
//! held, and sent when one does.

pub mod machine;
pub mod rules;

pub use machine::{CoachGame, CoachSettings, MACHINE, Outcome, Output};

use std::time::Duration;

use std::path::Path;

use interfaces::liveliness::Readers;
use interfaces::msg::executive::{GameLog, StateTransition};
use interfaces::msg::speech::SayRequest;
use interfaces::node::Interface;
use interfaces::{Bus, Moment, Shutdown, topics};

use crate::component::sleep_until;
use crate::state_file::StateFile;

/// Adds the coach's topics to the Executive's interface.
pub fn interface(i: Interface) -> Interface {
    i.subscribes(&topics::GAME_COMMAND)
        .subscribes(&topics::COACH_REQUEST)
        .subscribes(&topics::NAO_WORLD_MODEL)
        .subscribes(&topics::NAO_GAME_STATE)
        .subscribes(&topics::NAO_LINK)
        .publishes(&topics::NAO_COMMAND)
        .publishes(&topics::SPEECH_SAY)
        .publishes(&topics::EXECUTIVE_TRANSITIONS)
        .publishes(&topics::EXECUTIVE_LOG)
        .publishes(&topics::COACH_STATUS)
}

/// Runs the coach machine on the bus until shutdown, its record kept in `state_dir` (none: not
/// kept). Time is the bus clock (system or virtual).
pub async fn run(
    bus: Bus,
    settings: CoachSettings,
    state_dir: Option<&Path>,
    shutdown: Shutdown,
) -> anyhow::Result<()> {
    run_observed(bus, settings, state_dir, shutdown, |_| {}).await
}

/// How long a starting Executive waits for a bridge's subscription to show before it holds its
/// commands (the bridge starts first; its token comes within milliseconds).
const BRIDGE_WAIT: Duration = Duration::from_secs(2);

/// [`run`], calling `observe` with the game after every input it handled (for the
/// `executive/configuration` service: `game.machine()` has the active states and the step count).
pub async fn run_observed(
    bus: Bus,
    settings: CoachSettings,
    state_dir: Option<&Path>,
    mut shutdown: Shutdown,
    mut observe: impl FnMut(&CoachGame) + Send,
) -> anyhow::Result<()> {
    let bridges = settings.bridges.clone();
    let mut game = CoachGame::new(settings)?;
    let mut readers = Readers::watch(&bus, &topics::NAO_COMMAND).await?;
    let listening = |r: &Readers| bridges.is_empty() || r.any_of(&bridges);
    let commands = bus.subscriber(&topics::GAME_COMMAND).await?;
    let requests = bus.subscriber(&topics::COACH_REQUEST).await?;
    let worlds = bus.subscriber(&topics::NAO_WORLD_MODEL).await?;
    let states = bus.subscriber(&topics::NAO_GAME_STATE).await?;
    let links = bus.subscriber(&topics::NAO_LINK).await?;
    let mut out = Publishers {
        nao: bus.publisher(&topics::NAO_COMMAND).await?,
        say: bus.publisher(&topics::SPEECH_SAY).await?,
        transitions: bus.publisher(&topics::EXECUTIVE_TRANSITIONS).await?,
        log: bus.publisher(&topics::EXECUTIVE_LOG).await?,
        status: bus.publisher(&topics::COACH_STATUS).await?,
        counters: bus.counters().clone(),
        say_id: 0,
    };
    // The bus clock (system or virtual), monotonic: timers follow a replayed or virtual clock.
    let clock = bus.clock().clone();
    let now = {
        let clock = clock.clone();
        move || clock.now().as_duration()
    };
    tokio::select! {
        _ = shutdown.wait() => return Ok(()),
        _ = clock.started() => {}
    }
    tracing::info!(
        "coach: machine `{MACHINE}` with states {:?}",
        game.machine().definition().state_paths()
    );
    let _ = clock
        .timeout(BRIDGE_WAIT, async {
            while !listening(&readers) {
                readers.changed().await;
            }
        })
        .await;
    let mut kept = StateFile::new(state_dir, "coach.json");
    let mut o = match kept.load() {
        Some(record) => game.resume(&record, now()),
        None => game.start(now()),
    };
    o.extend(game.bridge(listening(&readers), now()));
    observe(&game);
    kept.save(Some(game.resume_record()), &out.counters);
    if out.emit(o).await? {
        game.delivered();
    }
    kept.save(Some(game.resume_record()), &out.counters);
    let mut status_tick = clock.interval(Duration::from_secs(1));
    let mut last_status = None;
    loop {
        // Wake for the machine's next timer, on the clock.
        let deadline = game.next_deadline().map(Moment::from_duration);
        let (outcome, changed) = tokio::select! {
            _ = shutdown.wait() => return Ok(()),
            c = commands.recv() => (game.command(&c?, now()), true),
            r = requests.recv() => (game.request(&r?, now()), true),
            w = worlds.recv() => (game.world_model(&w?, now()), false),
            g = states.recv() => (game.game_state(&g?, now()), false),
            l = links.recv() => (game.link(&l?, now()), true),
            _ = readers.changed() => (game.bridge(listening(&readers), now()), true),
            _ = sleep_until(&clock, deadline) => (game.advance(now()), false),
            _ = status_tick.tick() => (Outcome::default(), true),
        };
        let stepped = outcome.steps.iter().any(|s| !s.ignored) || !outcome.outputs.is_empty();
        // The configuration is current before anyone hears of the step.
        if stepped {
            observe(&game);
        }
        // Kept before the commands go out (with them as undelivered), and again once they did.
        kept.save(Some(game.resume_record()), &out.counters);
        if out.emit(outcome).await? {
            game.delivered();
            kept.save(Some(game.resume_record()), &out.counters);
        }
        let mut st = game.status(now());
        // Publish on change (ages aside) and on the tick.
        let key = {
            let mut k = st.clone();
            k.ball_last_seen_s = 0.0;
            k.obstacle_last_seen_s = 0.0;
            k
        };
        if changed || stepped || last_status.as_ref() != Some(&key) {
            out.status.publish(&mut st).await?;
            last_status = Some(key);
        }
    }
}

struct Publishers {
    nao: interfaces::Publisher<interfaces::msg::nao::NaoCommand>,
    say: interfaces::Publisher<SayRequest>,
    transitions: interfaces::Publisher<StateTransition>,
    log: interfaces::Publisher<GameLog>,
    status: interfaces::Publisher<interfaces::msg::nao::CoachStatus>,
    counters: std::sync::Arc<interfaces::bus::Counters>,
    say_id: u64,
}

impl Publishers {
    /// Publishes an outcome: the steps first, then the outputs in order (so an answer is on
    /// `speech/say` before its command is on `nao/command`). True when a command went out.
    async fn emit(&mut self, o: Outcome) -> anyhow::Result<bool> {
        let mut commanded = false;
        for s in o.steps.iter().filter(|s| !s.ignored) {
            self.transitions
                .publish(&mut crate::component::transition_msg(MACHINE, s))
                .await?;
        }
        for output in o.outputs {
            match output {
                Output::Say { text, priority } => {
                    self.say_id += 1;
                    tracing::info!("says: {text}");
                    let mut r = SayRequest {
                        id: self.say_id,
                        text,
                        priority,
                        ..Default::default()
                    };
                    self.say.publish(&mut r).await?;
                }
                Output::Command(mut c) => {
                    tracing::info!(
                        "command to the robot: {:?} head {:?} target ({:.0}, {:.0})",
                        c.body,
                        c.head,
                        c.target.x_mm,
                        c.target.y_mm
                    );
                    self.counters.incr("commands_sent");
                    self.nao.publish(&mut c).await?;
                    commanded = true;
                }
                Output::Log(l) => {
                    if l.kind == "refused" || l.kind == "anomaly" {
                        self.counters.incr(&format!("coach/{}", l.kind));
                    }
                    tracing::info!("[{}] {}", l.kind, l.text);
                    let mut g = GameLog {
                        machine: MACHINE.into(),
                        kind: l.kind.into(),
                        text: l.text,
                        distance_m: l.distance_m,
                        ..Default::default()
                    };
                    self.log.publish(&mut g).await?;
                }
            }
        }
        Ok(commanded)
    }
}
