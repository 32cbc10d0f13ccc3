//! `robocog launch`: host the router, start the graph in dependency order, watch it, restart what
//! crashes, and stop everything cleanly.
//!
//! The launcher is the parent of every component. Each child runs in its own process group (so a
//! terminal's Ctrl-C reaches the launcher only, and stopping a child also stops what it started),
//! and dies with the launcher even if the launcher is killed with SIGKILL (`PR_SET_PDEATHSIG`).
//! A component is *up* when its liveliness token appears on the bus.
//!
//! Each component gets a state folder, `<state_dir>/<component>` in ROBOCOG_STATE_DIR (created
//! by the component if it keeps state): it outlives the component's restarts, so a restarted
//! component takes up where it was (the deep representation recovers its world model there). A
//! launch starts afresh (an earlier launch's folder is moved aside to `<namespace>.previous`)
//! unless `--resume`; a launch that ends cleanly removes its folder, one that fails keeps it for
//! a look and for `--resume`.
//!
//! A component that exits with [`EX_CONFIG`] (it cannot start for a reason a restart cannot fix:
//! a missing file, no such device) or [`EX_USAGE`] (flags it cannot parse) is not restarted,
//! whatever its policy: if it is required, the graph stops at once with its message and the
//! launcher exits with [`EX_CONFIG`].

use crate::manifest::{Component, Manifest, RestartPolicy};
use interfaces::liveliness::{self, Token};
use interfaces::node::{EX_CONFIG, EX_USAGE};
use nix::sys::signal::Signal;
use std::collections::{HashMap, VecDeque};
use std::process::ExitStatus;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{mpsc, watch};

use crate::agent::{AGENT_PREFIX, LAUNCHER_NAME};
use crate::router_process::RouterProcess;
use anyhow::Context;
use interfaces::bus::Bus;
use interfaces::msg::agent::{AgentChild, AgentEvent};

mod process;
mod remote;
mod stop;
use process::spawn;
pub(crate) use process::{BoxFuture, spawn_process};
use remote::{Machines, spawn_remote};
use stop::stop_all;

/// How `launch` runs.
#[derive(Debug, Clone)]
pub struct LaunchOptions {
    pub namespace: String,
    /// The endpoint the launcher's router listens on (`tcp/127.0.0.1:0` for any free port).
    pub router: String,
    pub color: bool,
    /// The graph's state folder for this namespace: each component keeps its state in
    /// `<state_dir>/<component>` (ROBOCOG_STATE_DIR), across its restarts.
    pub state_dir: std::path::PathBuf,
    /// Keep what an earlier launch left in `state_dir` (else it is moved aside).
    pub resume: bool,
    /// The machine the launcher runs on, for a graph over several machines.
    pub machine: Option<String>,
    /// How long a launch waits for the agents of the other machines.
    pub machine_timeout: Duration,
}

const PALETTE: [u8; 12] = [36, 32, 33, 35, 34, 31, 96, 92, 93, 95, 94, 91];
const TAIL_LINES: usize = 20;
const MAX_BACKOFF: Duration = Duration::from_secs(30);

#[derive(Debug)]
enum Event {
    Up {
        name: String,
        pid: u32,
    },
    Exited {
        name: String,
        generation: u64,
        status: Option<ExitStatus>,
    },
    RestartDue {
        name: String,
    },
    Stop {
        reason: String,
    },
    /// An agent answered a start (the pid) or refused it.
    RemoteStarted {
        name: String,
        generation: u64,
        result: Result<u32, String>,
    },
    /// Output or an exit from a component on another machine.
    Remote(AgentEvent),
    /// A machine's agent appeared on the bus.
    MachineUp {
        machine: String,
    },
    /// A machine's agent vanished from the bus (the machine dropped off, or its agent died).
    MachineLost {
        machine: String,
    },
    /// What a machine that came back still runs (the answer to status call `attempt`).
    Reconciled {
        machine: String,
        attempt: u32,
        running: Result<Vec<AgentChild>, String>,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Pending,
    Starting {
        deadline: Instant,
    },
    Up,
    Backoff,
    Exited,
    Failed,
    /// On a machine that dropped off: running there, as far as we know, and out of reach.
    Unreachable,
}

struct Child {
    spec: Component,
    binary: std::path::PathBuf,
    state: State,
    pid: Option<u32>,
    generation: u64,
    restarts: u32,
    started: Instant,
    exit: Option<watch::Receiver<Option<Option<ExitStatus>>>>,
    tail: Arc<Mutex<VecDeque<String>>>,
    prefix: String,
    /// The other machine it runs on; `None`: this one.
    remote: Option<String>,
}

fn prefix(name: &str, width: usize, index: usize, color: bool) -> String {
    if color {
        format!(
            "\x1b[{}m{name:>width$}\x1b[0m |",
            PALETTE[index % PALETTE.len()]
        )
    } else {
        format!("{name:>width$} |")
    }
}

/// Say something as the launcher.
fn say(msg: impl std::fmt::Display) {
    eprintln!("robocog | {msg}");
}

pub(crate) fn describe_status(status: Option<ExitStatus>) -> String {
    use std::os::unix::process::ExitStatusExt;
    match status {
        None => "exit status unknown".into(),
        Some(s) => match (s.code(), s.signal()) {
            (Some(c), _) => format!("exit code {c}"),
            (None, Some(sig)) => {
                let name = Signal::try_from(sig).map(|s| s.as_str()).unwrap_or("?");
                format!("killed by signal {sig} ({name})")
            }
            _ => "exited".into(),
        },
    }
}

fn failed(status: Option<ExitStatus>) -> bool {
    status.is_none_or(|s| !s.success())
}

/// Whether the component said it cannot start for a reason a restart cannot fix.
fn misconfigured(status: Option<ExitStatus>) -> bool {
    status
        .and_then(|s| s.code())
        .is_some_and(|c| c == i32::from(EX_CONFIG) || c == i32::from(EX_USAGE))
}

/// Run the graph until it completes, fails for good, or is asked to stop. Returns the process
/// exit code: 0 on a clean stop or completion, 1 when a required component failed,
/// [`EX_CONFIG`] when a required component cannot start for a reason a restart cannot fix.
pub async fn launch(manifest: Manifest, opts: LaunchOptions) -> anyhow::Result<i32> {
    let order: Vec<String> = manifest
        .start_order()
        .map_err(|p| anyhow::anyhow!("{p}"))?
        .into_iter()
        .map(|c| c.name.clone())
        .collect();

    // The router every component of this machine joins (and, over several machines, the other
    // machines' routers too).
    let me = match (&opts.machine, manifest.machines.is_empty()) {
        (_, true) => None,
        (Some(name), false) => Some(crate::machines::machine(&manifest, name)?.clone()),
        (None, false) => {
            let known: Vec<&str> = manifest.machines.iter().map(|m| m.name.as_str()).collect();
            anyhow::bail!(
                "the graph {:?} runs on several machines ({}): say which one this is with --machine (or ROBOCOG_MACHINE)",
                manifest.name,
                known.join(", ")
            );
        }
    };
    let config = match &me {
        None => interfaces::router::router_config(&opts.router)?,
        Some(me) => crate::machines::router_config(&manifest, me, &opts.router, &opts.namespace)?,
    };
    prepare_state_dir(&opts.state_dir, opts.resume)?;
    // The router is a process of its own, restarted when it dies (a link's fault takes it down,
    // not the launcher); the launcher joins it as a client, as the components do.
    let router = RouterProcess::start(config, &opts.router)
        .await
        .with_context(|| match &me {
            None => format!("the router on {}", opts.router),
            Some(me) => format!(
                "machine {:?}'s router on {} and {}",
                me.name, opts.router, me.router
            ),
        })?;
    let endpoint = router.endpoint.clone();
    let connect = interfaces::ConnectArgs::to_router(&endpoint, &opts.namespace);
    say(format!(
        "graph {:?}: router {endpoint}, namespace {}, {} components",
        manifest.name,
        opts.namespace,
        manifest.components.len()
    ));
    say(format!(
        "component state in {}{}",
        opts.state_dir.display(),
        if opts.resume { " (resumed)" } else { "" }
    ));
    // The launcher's own session: it watches the components' tokens (and, over several
    // machines, calls the agents). Over several machines it announces itself to the agents.
    let session_bus = match &me {
        None => {
            let options = interfaces::bus::BusOptions {
                announce: false,
                ..Default::default()
            };
            Bus::open_with(&connect, LAUNCHER_NAME, options).await?
        }
        Some(_) => Bus::open(&connect, LAUNCHER_NAME).await?,
    };

    let (tx, mut rx) = mpsc::channel::<Event>(1024);

    // Over several machines: the launcher's own session, to call the agents and hear them.
    let mut machines = match &me {
        None => None,
        Some(me) => {
            let bus = session_bus.clone();
            let events = bus.subscriber(&interfaces::topics::AGENT_EVENTS).await?;
            let launch_id = format!(
                "{}-{}-{}",
                bus.host(),
                std::process::id(),
                interfaces::header::system_now_ns() / 1_000_000
            );
            let tx = tx.clone();
            tokio::spawn(async move {
                while let Ok(e) = events.recv().await {
                    if tx.send(Event::Remote(e)).await.is_err() {
                        return;
                    }
                }
            });
            let others: Vec<String> = manifest
                .machines
                .iter()
                .filter(|m| m.name != me.name)
                .map(|m| format!("{} ({})", m.name, m.router))
                .collect();
            say(format!(
                "this is machine {:?} ({}); the other machines: {}; waiting for their agents",
                me.name,
                me.router,
                others.join(", ")
            ));
            Some(Machines::new(
                bus,
                launch_id,
                manifest.name.clone(),
                opts.machine_timeout,
            ))
        }
    };

    // Components are up when their liveliness token appears.
    let tokens = component_tokens(session_bus.session(), &opts.namespace).await?;
    {
        let tx = tx.clone();
        let ns = opts.namespace.clone();
        tokio::spawn(async move {
            while let Ok(sample) = tokens.recv_async().await {
                let put = sample.kind() == zenoh::sample::SampleKind::Put;
                let Some(Token::Component { name, pid, .. }) =
                    liveliness::parse(&ns, sample.key_expr().as_str())
                else {
                    continue;
                };
                let event = match name.strip_prefix(AGENT_PREFIX) {
                    Some(machine) if put => Event::MachineUp {
                        machine: machine.to_string(),
                    },
                    Some(machine) => Event::MachineLost {
                        machine: machine.to_string(),
                    },
                    None if put => Event::Up { name, pid },
                    None => continue,
                };
                if tx.send(event).await.is_err() {
                    return;
                }
            }
        });
    }
    // Ctrl-C and SIGTERM stop the graph.
    {
        let tx = tx.clone();
        tokio::spawn(async move {
            use tokio::signal::unix::{SignalKind, signal};
            let (Ok(mut term), Ok(mut int)) = (
                signal(SignalKind::terminate()),
                signal(SignalKind::interrupt()),
            ) else {
                return;
            };
            let reason = tokio::select! {
                _ = term.recv() => "SIGTERM",
                _ = int.recv() => "interrupted",
            };
            let _ = tx
                .send(Event::Stop {
                    reason: reason.into(),
                })
                .await;
        });
    }

    // Over several machines, every line says where it comes from: `machine/component`.
    let label = |c: &Component| match (&me, &c.machine) {
        (None, _) => c.name.clone(),
        (Some(me), None) => format!("{}/{}", me.name, c.name),
        (Some(_), Some(m)) => format!("{m}/{}", c.name),
    };
    let width = manifest
        .components
        .iter()
        .map(|c| label(c).len())
        .max()
        .unwrap_or(8)
        .max(7);
    let mut children: HashMap<String, Child> = HashMap::new();
    for (i, c) in manifest.components.iter().enumerate() {
        let elsewhere = c
            .machine
            .as_ref()
            .is_some_and(|m| me.as_ref().is_some_and(|me| &me.name != m));
        // A component of another machine is found there, by its agent.
        let binary = if elsewhere {
            std::path::PathBuf::from(&c.binary)
        } else {
            c.resolve_binary()
                .ok_or_else(|| anyhow::anyhow!("{}: unknown binary {:?}", c.origin, c.binary))?
        };
        #[expect(
            clippy::disallowed_methods,
            reason = "the launcher supervises real processes: their start times are on the wall"
        )]
        children.insert(
            c.name.clone(),
            Child {
                spec: c.clone(),
                binary,
                state: State::Pending,
                pid: None,
                generation: 0,
                restarts: 0,
                started: Instant::now(),
                exit: None,
                tail: Arc::new(Mutex::new(VecDeque::new())),
                prefix: prefix(&label(c), width, i, opts.color),
                remote: c
                    .machine
                    .clone()
                    .filter(|m| me.as_ref().is_some_and(|me| &me.name != m)),
            },
        );
    }

    let mut exit_code: Option<i32> = None;
    let mut pending: VecDeque<Event> = VecDeque::new();
    // The launcher's status poll: start deadlines of real processes, on the wall.
    #[expect(
        clippy::disallowed_methods,
        reason = "the launcher polls real processes' start deadlines on the wall"
    )]
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    loop {
        // Start whatever has all its dependencies up.
        for name in &order {
            let ready = {
                let c = &children[name];
                c.state == State::Pending
                    && c.spec
                        .depends_on
                        .iter()
                        .all(|d| children.get(d).is_some_and(|d| d.state == State::Up))
                    && c.remote
                        .as_ref()
                        .is_none_or(|m| machines.as_ref().is_some_and(|ms| ms.up.contains(m)))
            };
            if !ready {
                continue;
            }
            let Some(c) = children.get_mut(name) else {
                continue;
            };
            if c.remote.is_some() {
                if let Some(ms) = &machines {
                    spawn_remote(c, ms, &tx);
                }
            } else if let Err(e) = spawn(c, &connect, &opts.state_dir, &tx) {
                say(format!("cannot start {name}: {e:#}"));
                exit_code = Some(1);
            }
        }
        if exit_code.is_some() {
            break;
        }
        // Events the loop made itself first (never sent into its own channel, which could be
        // full), then the channel.
        let event = match pending.pop_front() {
            Some(e) => Some(e),
            None => tokio::select! {
                e = rx.recv() => e,
                _ = tick.tick() => None,
            },
        };
        match event {
            Some(Event::Up { name, pid }) => {
                if let Some(c) = children.get_mut(&name)
                    && (c.pid == Some(pid) || (c.remote.is_some() && c.pid.is_none()))
                    && matches!(c.state, State::Starting { .. })
                {
                    c.pid = Some(pid);
                    c.state = State::Up;
                    say(format!(
                        "{name} is up (pid {pid}, {} ms)",
                        c.started.elapsed().as_millis()
                    ));
                }
            }
            Some(Event::Exited {
                name,
                generation,
                status,
            }) => {
                let Some(c) = children.get_mut(&name) else {
                    continue;
                };
                if c.generation != generation {
                    continue;
                }
                // A remote exit can be heard twice (its event, and the status of a machine that
                // came back): once handled, it is done.
                if c.remote.is_some()
                    && matches!(c.state, State::Backoff | State::Failed | State::Exited)
                {
                    continue;
                }
                let what = describe_status(status);
                if c.spec.completes_graph && !failed(status) {
                    say(format!("{name} completed ({what}): the graph is done"));
                    exit_code = Some(0);
                    c.state = State::Exited;
                    c.pid = None;
                    continue;
                }
                let restart = match c.spec.restart {
                    RestartPolicy::Never => false,
                    RestartPolicy::OnFailure => failed(status),
                    RestartPolicy::Always => true,
                };
                c.pid = None;
                if misconfigured(status) {
                    c.state = State::Failed;
                    let tail = last_lines(c);
                    if c.spec.required {
                        say(format!(
                            "{name} cannot start ({what}: its configuration, a file or a device it needs; a restart would not fix it): stopping the graph{tail}"
                        ));
                        exit_code = Some(i32::from(EX_CONFIG));
                    } else {
                        say(format!(
                            "{name} cannot start ({what}: its configuration, a file or a device it needs); it is not required, the graph goes on without it{tail}"
                        ));
                    }
                } else if restart && c.restarts < c.spec.max_restarts {
                    c.restarts += 1;
                    let delay =
                        (c.spec.backoff * 2u32.saturating_pow(c.restarts - 1)).min(MAX_BACKOFF);
                    say(format!(
                        "{name} stopped ({what}); restart {}/{} in {} ms",
                        c.restarts,
                        c.spec.max_restarts,
                        delay.as_millis()
                    ));
                    c.state = State::Backoff;
                    let tx = tx.clone();
                    tokio::spawn(async move {
                        #[expect(
                            clippy::disallowed_methods,
                            reason = "a real process' restart back-off, on the wall"
                        )]
                        tokio::time::sleep(delay).await;
                        let _ = tx.send(Event::RestartDue { name }).await;
                    });
                } else if restart || failed(status) {
                    c.state = State::Failed;
                    let tail = last_lines(c);
                    if c.spec.required {
                        say(format!(
                            "{name} failed for good ({what}, after {} restarts); stopping the graph{tail}",
                            c.restarts
                        ));
                        exit_code = Some(1);
                    } else {
                        say(format!(
                            "{name} failed for good ({what}); it is not required, the graph goes on{tail}"
                        ));
                    }
                } else {
                    c.state = State::Exited;
                    say(format!("{name} exited ({what})"));
                }
            }
            Some(Event::RestartDue { name }) => {
                if let Some(c) = children.get_mut(&name)
                    && c.state == State::Backoff
                    && c.remote.is_some()
                {
                    if let Some(ms) = &machines {
                        spawn_remote(c, ms, &tx);
                    }
                } else if let Some(c) = children.get_mut(&name)
                    && c.state == State::Backoff
                    && let Err(e) = spawn(c, &connect, &opts.state_dir, &tx)
                {
                    say(format!("cannot restart {name}: {e:#}"));
                    c.state = State::Failed;
                    if c.spec.required {
                        exit_code = Some(1);
                    }
                }
            }
            Some(Event::Stop { reason }) => {
                say(format!("{reason}: stopping the graph"));
                exit_code = Some(0);
            }
            Some(Event::RemoteStarted {
                name,
                generation,
                result,
            }) => {
                if let Some(c) = children.get_mut(&name)
                    && c.generation == generation
                    && remote::started(c, result)
                {
                    exit_code = Some(1);
                }
            }
            Some(Event::Remote(e)) => {
                if let Some(ms) = &machines {
                    ms.on_event(e, &mut children, &mut pending);
                }
            }
            Some(Event::MachineUp { machine }) => {
                if let Some(ms) = machines.as_mut() {
                    ms.machine_up(machine, &tx);
                }
            }
            Some(Event::MachineLost { machine }) => {
                if let Some(ms) = machines.as_mut() {
                    ms.machine_lost(&machine, &mut children);
                }
            }
            Some(Event::Reconciled {
                machine,
                attempt,
                running,
            }) => {
                if let Some(ms) = &machines {
                    ms.status_answered(machine, attempt, running, &mut children, &mut pending, &tx);
                }
            }
            None => {
                #[expect(
                    clippy::disallowed_methods,
                    reason = "real processes' start deadlines are on the wall"
                )]
                let now = Instant::now();
                if let Some(ms) = &machines
                    && ms.agents_missing(&children)
                {
                    exit_code = Some(1);
                }
                for c in children.values_mut() {
                    if let State::Starting { deadline } = c.state
                        && now > deadline
                    {
                        say(format!(
                            "{} never came up: no liveliness token within {:.1} s (is it a robocog component, and can it reach the router?){}",
                            c.spec.name,
                            c.spec.ready_timeout.as_secs_f64(),
                            last_lines(c)
                        ));
                        c.state = State::Failed;
                        exit_code = Some(1);
                    }
                }
            }
        }
        if exit_code.is_some() {
            break;
        }
    }

    // Said on the bus first, so that no component takes its neighbours' leaving for a failure
    // (the dialog would tell the person it cannot hear her).
    let session = session_bus.session();
    let stopping_key = liveliness::stopping_key(&opts.namespace, &session.zid().to_string());
    let stopping = session
        .liveliness()
        .declare_token(stopping_key.clone())
        .await;
    match &stopping {
        Err(e) => say(format!(
            "cannot tell the graph it is stopping ({e}): its components may report each other gone"
        )),
        Ok(_) => router_has(session, &stopping_key).await,
    }
    stop_all(&manifest, &mut children, machines.as_ref()).await;
    drop(stopping);
    drop(machines);
    drop(session_bus);
    router.stop().await;
    let code = exit_code.unwrap_or(0);
    if code == 0 {
        if let Err(e) = std::fs::remove_dir_all(&opts.state_dir)
            && e.kind() != std::io::ErrorKind::NotFound
        {
            say(format!(
                "cannot remove the state folder {}: {e}",
                opts.state_dir.display()
            ));
        }
        // The graph's folder too, when no other namespace has state in it.
        if let Some(graph) = opts.state_dir.parent() {
            let _ = std::fs::remove_dir(graph);
        }
    } else {
        say(format!(
            "the components' state stays in {} (robocog launch --resume takes it up)",
            opts.state_dir.display()
        ));
    }
    Ok(code)
}

/// Make `dir` ready for this launch: kept with `resume`, else an earlier launch's moved aside.
fn prepare_state_dir(dir: &std::path::Path, resume: bool) -> anyhow::Result<()> {
    use anyhow::Context;
    if !resume && dir.exists() {
        let mut aside = dir.as_os_str().to_owned();
        aside.push(".previous");
        let aside = std::path::PathBuf::from(aside);
        if aside.exists() {
            std::fs::remove_dir_all(&aside)
                .with_context(|| format!("cannot remove {}", aside.display()))?;
        }
        std::fs::rename(dir, &aside).with_context(|| {
            format!(
                "cannot move an earlier launch's state aside to {}",
                aside.display()
            )
        })?;
        say(format!(
            "an earlier launch left state in {}: moved aside to {} (--resume takes it up)",
            dir.display(),
            aside.display()
        ));
    }
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the state folder {}", dir.display()))?;
    Ok(())
}

fn last_lines(c: &Child) -> String {
    let tail = c.tail.lock().unwrap_or_else(|p| p.into_inner());
    if tail.is_empty() {
        return String::new();
    }
    let mut s = format!("\n  last lines of {}:", c.spec.name);
    for l in tail.iter() {
        s.push_str("\n    ");
        s.push_str(l);
    }
    s
}

/// The component tokens of namespace `ns` as they come and go (those already there first).
pub(crate) async fn component_tokens(
    session: &zenoh::Session,
    ns: &str,
) -> anyhow::Result<
    zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
> {
    session
        .liveliness()
        .declare_subscriber(liveliness::components(ns))
        .history(true)
        .with(zenoh::handlers::FifoChannel::new(1024))
        .await
        .map_err(|e| anyhow::anyhow!("cannot watch liveliness: {e}"))
}

/// Waits (at most 2 s) until the router has the launcher's liveliness token `key`. The launcher
/// is a client of its router: a declared token is on its way there, not there yet, and a
/// component stopped at once could leave before it. A query for the token over the same link
/// ends after the router took the declaration. (Components may still see a neighbour leave just
/// before the token: see `interfaces::liveliness::Stopping`.)
#[expect(
    clippy::disallowed_methods,
    reason = "a transport time-out, on the wall as zenoh's own query time-out is"
)]
async fn router_has(session: &zenoh::Session, key: &str) {
    const WAIT: std::time::Duration = std::time::Duration::from_secs(2);
    let seen = async {
        let replies = session.liveliness().get(key).timeout(WAIT).await.ok()?;
        // Every reply, to the query's end: the launcher's own session answers at once, the
        // router once it has the token, and the query ends when the router is done. (Stopping
        // at the first reply did not wait for the router, and its reply then fell on a dropped
        // channel: an ERROR in the launcher's log at every stop.)
        let mut seen = false;
        while let Ok(reply) = replies.recv_async().await {
            seen |= reply.result().is_ok();
        }
        seen.then_some(())
    };
    if tokio::time::timeout(WAIT, seen)
        .await
        .ok()
        .flatten()
        .is_none()
    {
        say(
            "the router did not confirm that the graph is stopping within 2 s: its components may report each other gone",
        );
    }
}
