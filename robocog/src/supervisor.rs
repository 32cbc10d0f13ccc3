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
use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use std::collections::{HashMap, VecDeque};
use std::process::{ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::process::Command;
use tokio::sync::{mpsc, watch};

use crate::agent::{AGENT_PREFIX, LAUNCHER_NAME};
use interfaces::bus::{Bus, CallError};
use interfaces::msg::agent::{
    AgentAction, AgentChild, AgentEvent, AgentEventKind, AgentRequest, EnvVar,
};
use std::os::unix::process::ExitStatusExt;

/// The machines of a graph over several, as the launcher sees them.
struct Machines {
    bus: Bus,
    launch_id: String,
    graph: String,
    /// Agents on the bus now.
    up: std::collections::BTreeSet<String>,
    /// Agents that have been up at least once (a lost one is then "back" when it returns).
    seen: std::collections::BTreeSet<String>,
    since: Instant,
    timeout: Duration,
}

/// The request every call to an agent starts from.
fn agent_request(m: &Machines, action: AgentAction, c: &Child) -> AgentRequest {
    AgentRequest {
        launch_id: m.launch_id.clone(),
        graph: m.graph.clone(),
        action,
        component: c.spec.name.clone(),
        generation: c.generation,
        ..Default::default()
    }
}

/// Call machine `machine`'s agent, waiting at most `timeout` in all. An agent whose token has
/// just reached the launcher may not be reachable by queries yet: when a link between routers
/// comes back, the routers hear of each other's tokens before they have routes for queries, so a
/// call finds nobody for a moment (seen after a pulled cable). Such calls are sent again until
/// the time-out; any other failure is final.
async fn call_agent(
    bus: &Bus,
    machine: &str,
    request: &AgentRequest,
    timeout: Duration,
) -> Result<interfaces::msg::agent::AgentReply, String> {
    let control = interfaces::topics::agent_control(machine)
        .ok_or_else(|| format!("invalid machine name {machine:?}"))?;
    let deadline = Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match bus.call(&control, request, left).await {
            Err(CallError::NoServer(_)) if Instant::now() + AGENT_CALL_RETRY < deadline => {
                tokio::time::sleep(AGENT_CALL_RETRY).await
            }
            other => return other.map_err(|e| format!("machine {machine}'s agent: {e}")),
        }
    }
}

/// How long a call to an agent that nobody served waits before it is sent again.
const AGENT_CALL_RETRY: Duration = Duration::from_millis(100);

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
    /// What a machine that came back still runs.
    Reconciled {
        machine: String,
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
    let (router, endpoint) = match &me {
        None => interfaces::router::open_router(&opts.router).await?,
        Some(me) => {
            crate::machines::open_router(&manifest, me, &opts.router, &opts.namespace).await?
        }
    };
    let connect = interfaces::ConnectArgs::to_router(&endpoint, &opts.namespace);
    say(format!(
        "graph {:?}: router {endpoint}, namespace {}, {} components",
        manifest.name,
        opts.namespace,
        manifest.components.len()
    ));

    prepare_state_dir(&opts.state_dir, opts.resume)?;
    say(format!(
        "component state in {}{}",
        opts.state_dir.display(),
        if opts.resume { " (resumed)" } else { "" }
    ));

    let (tx, mut rx) = mpsc::channel::<Event>(1024);

    // Over several machines: the launcher's own session, to call the agents and hear them.
    let mut machines = match &me {
        None => None,
        Some(me) => {
            let bus = Bus::open(&connect, LAUNCHER_NAME).await?;
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
            Some(Machines {
                bus,
                launch_id,
                graph: manifest.name.clone(),
                up: Default::default(),
                seen: Default::default(),
                since: Instant::now(),
                timeout: opts.machine_timeout,
            })
        }
    };

    // Components are up when their liveliness token appears.
    let tokens = component_tokens(&router, &opts.namespace).await?;
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
                let Some(c) = children.get_mut(&name) else {
                    continue;
                };
                if c.generation != generation {
                    continue;
                }
                match result {
                    Ok(pid) => {
                        say(format!(
                            "started {} on machine {} (pid {pid}): {} {}",
                            c.spec.name,
                            c.remote.as_deref().unwrap_or("?"),
                            c.spec.binary,
                            c.spec.args.join(" ")
                        ));
                        if c.pid.is_none() {
                            c.pid = Some(pid);
                        }
                    }
                    Err(why) => {
                        say(format!("cannot start {name}: {why}"));
                        c.state = State::Failed;
                        if c.spec.required {
                            exit_code = Some(1);
                        }
                    }
                }
            }
            Some(Event::Remote(e)) => {
                let Some(ms) = &machines else { continue };
                if e.launch_id != ms.launch_id {
                    continue;
                }
                let Some(c) = children.get_mut(&e.component) else {
                    continue;
                };
                match e.kind {
                    AgentEventKind::Stdout => {
                        println!("{} {}", c.prefix, e.line);
                        push_tail(&c.tail, e.line);
                    }
                    AgentEventKind::Stderr => {
                        eprintln!("{} {}", c.prefix, e.line);
                        push_tail(&c.tail, e.line);
                    }
                    AgentEventKind::Exited => {
                        let status =
                            (e.wait_status >= 0).then(|| ExitStatus::from_raw(e.wait_status));
                        pending.push_back(Event::Exited {
                            name: e.component,
                            generation: e.generation,
                            status,
                        });
                    }
                }
            }
            Some(Event::MachineUp { machine }) => {
                let Some(ms) = machines.as_mut() else {
                    continue;
                };
                if !ms.up.insert(machine.clone()) {
                    continue;
                }
                if ms.seen.insert(machine.clone()) {
                    say(format!(
                        "machine {machine}'s agent is up ({} ms)",
                        ms.since.elapsed().as_millis()
                    ));
                } else {
                    say(format!(
                        "machine {machine} is back: asking its agent what still runs there"
                    ));
                    let bus = ms.bus.clone();
                    let request = AgentRequest {
                        launch_id: ms.launch_id.clone(),
                        graph: ms.graph.clone(),
                        action: AgentAction::Status,
                        ..Default::default()
                    };
                    let tx = tx.clone();
                    tokio::spawn(async move {
                        let running = call_agent(&bus, &machine, &request, Duration::from_secs(10))
                            .await
                            .map(|r| r.running);
                        let _ = tx.send(Event::Reconciled { machine, running }).await;
                    });
                }
            }
            Some(Event::MachineLost { machine }) => {
                let Some(ms) = machines.as_mut() else {
                    continue;
                };
                if !ms.up.remove(&machine) {
                    continue;
                }
                let mut lost: Vec<&str> = Vec::new();
                for c in children.values_mut() {
                    if c.remote.as_deref() == Some(machine.as_str())
                        && matches!(c.state, State::Up | State::Starting { .. } | State::Backoff)
                    {
                        c.state = State::Unreachable;
                        lost.push(&c.spec.name);
                    }
                }
                lost.sort();
                say(format!(
                    "machine {machine} is out of reach (its agent left the bus: the machine or its link is down); its components {} are out of reach too: they run on there if the machine does, and are taken up again when it is back",
                    if lost.is_empty() {
                        "(none running)".to_string()
                    } else {
                        lost.join(", ")
                    }
                ));
            }
            Some(Event::Reconciled { machine, running }) => {
                let running = match running {
                    Ok(r) => r,
                    Err(why) => {
                        say(format!(
                            "{why}: it did not say what runs on machine {machine}; its components there count as stopped"
                        ));
                        Vec::new()
                    }
                };
                let mut names: Vec<String> = Vec::new();
                for c in children.values_mut() {
                    if c.remote.as_deref() != Some(machine.as_str())
                        || c.state != State::Unreachable
                    {
                        continue;
                    }
                    match running
                        .iter()
                        .find(|r| r.component == c.spec.name && r.generation == c.generation)
                    {
                        Some(r) => {
                            c.state = State::Up;
                            c.pid = Some(r.pid);
                            names.push(c.spec.name.clone());
                        }
                        None => {
                            // It stopped while the machine was away: its policy decides.
                            c.state = State::Starting {
                                deadline: Instant::now() + c.spec.ready_timeout,
                            };
                            pending.push_back(Event::Exited {
                                name: c.spec.name.clone(),
                                generation: c.generation,
                                status: None,
                            });
                        }
                    }
                }
                names.sort();
                say(format!(
                    "machine {machine}: {} ran on while it was away",
                    if names.is_empty() {
                        "nothing".to_string()
                    } else {
                        names.join(", ")
                    }
                ));
            }
            None => {
                let now = Instant::now();
                if let Some(ms) = &machines
                    && ms.since.elapsed() > ms.timeout
                {
                    let mut missing: Vec<&str> = children
                        .values()
                        .filter(|c| c.state == State::Pending)
                        .filter_map(|c| c.remote.as_deref())
                        .filter(|m| !ms.seen.contains(*m))
                        .collect();
                    missing.sort();
                    missing.dedup();
                    if !missing.is_empty() {
                        say(format!(
                            "no agent on machine {} within {:.0} s: is `robocog agent --machine <name> <manifest>` running there, and can its router reach this one (the [machines] endpoints, certificates, firewall)?",
                            missing.join(", "),
                            ms.timeout.as_secs_f64()
                        ));
                        exit_code = Some(1);
                    }
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
    let stopping = router
        .liveliness()
        .declare_token(liveliness::stopping_key(
            &opts.namespace,
            &router.zid().to_string(),
        ))
        .await;
    if let Err(e) = &stopping {
        say(format!(
            "cannot tell the graph it is stopping ({e}): its components may report each other gone"
        ));
    }
    stop_all(&manifest, &mut children, machines.as_ref()).await;
    drop(stopping);
    drop(machines);
    drop(router);
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

/// Ask the kernel to SIGKILL the child when the launcher dies, whatever the reason.
#[allow(unsafe_code)]
pub(crate) fn die_with_parent(cmd: &mut Command) {
    // SAFETY: the closure runs in the forked child before exec and only calls prctl(2), which is
    // async-signal-safe, and getppid(2).
    unsafe {
        cmd.pre_exec(|| {
            nix::sys::prctl::set_pdeathsig(Signal::SIGKILL).map_err(std::io::Error::from)?;
            // The launcher may already be gone (it died between fork and prctl).
            if nix::unistd::getppid() == Pid::from_raw(1) {
                return Err(std::io::Error::other("the launcher is gone"));
            }
            Ok(())
        });
    }
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

/// What a process's exit runs.
pub(crate) type BoxFuture = std::pin::Pin<Box<dyn std::future::Future<Output = ()> + Send>>;

/// A process started by [`spawn_process`].
pub(crate) struct Spawned {
    pub pid: u32,
    /// Becomes `Some(status)` when it has exited (`None` inside: its status is unknown).
    pub exit: watch::Receiver<Option<Option<ExitStatus>>>,
}

/// Start `binary` as a component process: its own process group, killed with its parent, stdin
/// closed, every line it writes handed to `on_line` (with whether it came on stderr), and
/// `on_exit` called with its status once it has exited.
pub(crate) fn spawn_process(
    binary: &std::path::Path,
    args: &[String],
    env: Vec<(String, String)>,
    on_line: impl Fn(String, bool) + Send + Sync + 'static,
    on_exit: impl FnOnce(Option<ExitStatus>) -> BoxFuture + Send + 'static,
) -> anyhow::Result<Spawned> {
    let mut cmd = Command::new(binary);
    cmd.args(args)
        .envs(env)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .kill_on_drop(false);
    die_with_parent(&mut cmd);
    let mut child = cmd
        .spawn()
        .map_err(|e| anyhow::anyhow!("cannot run {}: {e}", binary.display()))?;
    let pid = child.id().unwrap_or(0);
    let on_line = Arc::new(on_line);
    for (stream, to_stderr) in [
        (
            child
                .stdout
                .take()
                .map(|s| Box::new(s) as Box<dyn tokio::io::AsyncRead + Unpin + Send>),
            false,
        ),
        (
            child
                .stderr
                .take()
                .map(|s| Box::new(s) as Box<dyn tokio::io::AsyncRead + Unpin + Send>),
            true,
        ),
    ] {
        let Some(stream) = stream else { continue };
        let on_line = on_line.clone();
        tokio::spawn(async move {
            let mut lines = BufReader::new(stream).split(b'\n');
            while let Ok(Some(line)) = lines.next_segment().await {
                on_line(
                    String::from_utf8_lossy(&line).trim_end().to_string(),
                    to_stderr,
                );
            }
        });
    }
    let (exit_tx, exit_rx) = watch::channel(None);
    tokio::spawn(async move {
        let status = child.wait().await.ok();
        let _ = exit_tx.send(Some(status));
        on_exit(status).await;
    });
    Ok(Spawned { pid, exit: exit_rx })
}

fn spawn(
    c: &mut Child,
    connect: &interfaces::ConnectArgs,
    state_dir: &std::path::Path,
    tx: &mpsc::Sender<Event>,
) -> anyhow::Result<()> {
    let mut env = connect.to_env();
    env.push(("ROBOCOG_COMPONENT".into(), c.spec.name.clone()));
    env.push((
        "ROBOCOG_STATE_DIR".into(),
        state_dir.join(&c.spec.name).display().to_string(),
    ));
    env.extend(c.spec.env.iter().map(|(k, v)| (k.clone(), v.clone())));
    let prefix = c.prefix.clone();
    let tail = c.tail.clone();
    let on_line = move |line: String, to_stderr: bool| {
        if to_stderr {
            eprintln!("{prefix} {line}");
        } else {
            println!("{prefix} {line}");
        }
        push_tail(&tail, line);
    };
    let tx = tx.clone();
    let name = c.spec.name.clone();
    let generation = c.generation + 1;
    let on_exit = move |status: Option<ExitStatus>| -> BoxFuture {
        Box::pin(async move {
            let _ = tx
                .send(Event::Exited {
                    name,
                    generation,
                    status,
                })
                .await;
        })
    };
    let spawned = spawn_process(&c.binary, &c.spec.args, env, on_line, on_exit)?;
    let pid = spawned.pid;
    c.generation = generation;
    c.pid = Some(pid);
    c.started = Instant::now();
    c.state = State::Starting {
        deadline: Instant::now() + c.spec.ready_timeout,
    };
    c.exit = Some(spawned.exit);
    say(format!(
        "started {} (pid {pid}): {} {}",
        c.spec.name,
        c.binary.display(),
        c.spec.args.join(" ")
    ));
    Ok(())
}

/// Ask `c`'s machine's agent to start it; the answer comes back as [`Event::RemoteStarted`].
fn spawn_remote(c: &mut Child, ms: &Machines, tx: &mpsc::Sender<Event>) {
    c.generation += 1;
    c.pid = None;
    c.started = Instant::now();
    c.state = State::Starting {
        deadline: Instant::now() + c.spec.ready_timeout,
    };
    let machine = c.remote.clone().unwrap_or_default();
    let mut request = agent_request(ms, AgentAction::Start, c);
    request.binary = c.spec.binary.clone();
    request.dir = c.spec.dir.display().to_string();
    request.args = c.spec.args.clone();
    request.env = c
        .spec
        .env
        .iter()
        .map(|(k, v)| EnvVar {
            name: k.clone(),
            value: v.clone(),
        })
        .collect();
    let bus = ms.bus.clone();
    let tx = tx.clone();
    let name = c.spec.name.clone();
    let generation = c.generation;
    tokio::spawn(async move {
        let result = call_agent(&bus, &machine, &request, Duration::from_secs(10))
            .await
            .map(|r| r.pid);
        let _ = tx
            .send(Event::RemoteStarted {
                name,
                generation,
                result,
            })
            .await;
    });
}

/// Keep `line` among the last lines of a component (shown when it fails).
pub(crate) fn push_tail(tail: &Mutex<VecDeque<String>>, line: String) {
    let mut t = tail.lock().unwrap_or_else(|p| p.into_inner());
    if t.len() == TAIL_LINES {
        t.pop_front();
    }
    t.push_back(line);
}

/// Stop every running child, dependents before their dependencies: SIGTERM to its process group,
/// then SIGKILL after its stop time-out. Finally SIGKILL every group, so nothing is left behind.
async fn stop_all(
    manifest: &Manifest,
    children: &mut HashMap<String, Child>,
    machines: Option<&Machines>,
) {
    // Depth in the dependency graph: leaves (no dependents) stop first.
    let mut depth: HashMap<String, usize> = HashMap::new();
    if let Ok(order) = manifest.start_order() {
        for c in order {
            let d = c
                .depends_on
                .iter()
                .filter_map(|d| depth.get(d))
                .max()
                .map_or(0, |d| d + 1);
            depth.insert(c.name.clone(), d);
        }
    }
    let max_depth = depth.values().copied().max().unwrap_or(0);
    let mut groups = Vec::new();
    for level in (0..=max_depth).rev() {
        let mut waiting = Vec::new();
        let mut remote: Vec<BoxFuture> = Vec::new();
        for c in children.values_mut() {
            if depth.get(&c.spec.name).copied().unwrap_or(0) != level {
                continue;
            }
            if let Some(machine) = c.remote.clone() {
                // On another machine: its agent stops it (and says so when it has exited).
                let running = c.pid.take().is_some()
                    || matches!(c.state, State::Starting { .. } | State::Unreachable);
                if let (true, Some(ms)) = (running, machines) {
                    let mut request = agent_request(ms, AgentAction::Stop, c);
                    request.stop_timeout_ms = c.spec.stop_timeout.as_millis() as u64;
                    let wait = c.spec.stop_timeout + Duration::from_secs(6);
                    let bus = ms.bus.clone();
                    let name = c.spec.name.clone();
                    let reachable = ms.up.contains(&machine);
                    remote.push(Box::pin(async move {
                        if !reachable {
                            say(format!(
                                "cannot stop {name}: machine {machine} is out of reach (its agent stops it once the launcher has been gone a while)"
                            ));
                            return;
                        }
                        if let Err(e) = call_agent(&bus, &machine, &request, wait).await {
                            say(format!("cannot stop {name}: {e}"));
                        }
                    }));
                }
                continue;
            }
            if let Some(pid) = c.pid.take() {
                groups.push(pid);
                let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGTERM);
                waiting.push((
                    c.spec.name.clone(),
                    pid,
                    c.spec.stop_timeout,
                    c.exit.clone(),
                ));
            }
        }
        let waits = waiting
            .into_iter()
            .map(|(name, pid, grace, exit)| async move {
                let Some(mut exit) = exit else { return };
                let done = tokio::time::timeout(grace, async {
                    let _ = exit.wait_for(|s| s.is_some()).await.map(|_| ());
                })
                .await;
                if done.is_err() {
                    say(format!(
                        "{name} ignored SIGTERM for {:.1} s: SIGKILL",
                        grace.as_secs_f64()
                    ));
                    let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGKILL);
                    let _ = tokio::time::timeout(Duration::from_secs(5), async {
                        let _ = exit.wait_for(|s| s.is_some()).await.map(|_| ());
                    })
                    .await;
                }
            });
        let remote = remote.into_iter().map(tokio::spawn).collect::<Vec<_>>();
        futures_join_all(waits).await;
        for r in remote {
            let _ = r.await;
        }
    }
    // Anything a component left in its group goes too.
    for pid in groups {
        let _ = killpg(Pid::from_raw(pid as i32), Signal::SIGKILL);
    }
    say("all components stopped");
}

async fn futures_join_all<F: std::future::Future<Output = ()> + Send + 'static>(
    futures: impl IntoIterator<Item = F>,
) {
    let handles: Vec<_> = futures.into_iter().map(tokio::spawn).collect();
    for h in handles {
        let _ = h.await;
    }
}
