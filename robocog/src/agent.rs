//! `robocog agent --machine <name> <manifest>`: one machine's share of a graph over several.
//!
//! The agent hosts its machine's router ([`crate::machines`]: loopback for the machine's own
//! components, the manifest's endpoint for the other machines, TLS and access control between
//! machines) and starts, stops and reports the components that `robocog launch`, run on any
//! machine of the graph, asks it to, over the bus itself (the service `agent/<machine>/control`
//! and the topic `agent/events`): no SSH, no transport of its own. The launcher keeps every
//! decision (start order across machines, restart policies, stopping dependents first); the
//! agent runs processes and says what became of them.
//!
//! - It starts only what its own copy of the manifest places on its machine, exactly as the
//!   manifest has it (binary, arguments, environment): a request that differs is refused with
//!   both versions named, so a launcher with other `--set` values, or anything else on the bus,
//!   cannot make it run something else.
//! - A component's lines go to the launcher as `agent/events` (and to the agent's own log, so
//!   the machine's journal has them too).
//! - Its exit is reported with its wait status; the launcher decides whether to restart it.
//! - Components are the agent's children, in their own process groups, and die with it.
//! - While the launcher is away (its machine dropped off, or it was killed), the components run
//!   on; once it has been gone `--orphan-after-s`, the agent stops them. A new launch (another
//!   launch id) first stops what an earlier one left.
//!
//! The agent is meant to run as a service (`robocog/systemd/robocog-agent@.service`), started
//! before any launch: a launch waits for every machine's agent.

use crate::manifest::{Component, Manifest};
use crate::supervisor::{BoxFuture, describe_status, spawn_process};
use anyhow::Context;
use interfaces::bus::{Bus, BusOptions, ServiceError};
use interfaces::liveliness::{self, Token};
use interfaces::msg::agent::{
    AgentAction, AgentChild, AgentEvent, AgentEventKind, AgentReply, AgentRequest,
};
use interfaces::topics;
use nix::sys::signal::{Signal, killpg};
use nix::unistd::Pid;
use std::collections::HashMap;
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::ExitStatus;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{mpsc, watch};

/// The component name the launcher's bus session announces; agents watch for it.
pub const LAUNCHER_NAME: &str = "robocog.launch";

/// What the component names of the agents start with on the bus.
pub const AGENT_PREFIX: &str = "robocog.agent.";

/// The component name of machine `machine`'s agent on the bus.
pub fn agent_name(machine: &str) -> String {
    format!("{AGENT_PREFIX}{machine}")
}

/// How an agent runs.
#[derive(Debug, Clone)]
pub struct AgentOptions {
    pub machine: String,
    pub namespace: String,
    /// The loopback endpoint the machine's components join (`tcp/127.0.0.1:0`: any free port).
    pub local_router: String,
    /// The root of the components' state folders (`<root>/<graph>/<namespace>/<component>`).
    pub state_root: PathBuf,
    /// How long the launcher may be gone before the agent stops its components.
    pub orphan_after: Duration,
}

struct Running {
    generation: u64,
    pid: u32,
    launch_id: String,
    exit: watch::Receiver<Option<Option<ExitStatus>>>,
}

struct Shared {
    machine: String,
    namespace: String,
    local_endpoint: String,
    state_root: PathBuf,
    running: Mutex<HashMap<String, Running>>,
    events: mpsc::Sender<AgentEvent>,
    /// The launch whose components run here ("" before the first).
    launch_id: Mutex<String>,
    /// The components this agent's own manifest places on its machine: the only ones it
    /// starts, and only as its manifest says (binary, arguments, environment).
    placed: HashMap<String, Component>,
}

fn say(machine: &str, msg: impl std::fmt::Display) {
    eprintln!("agent {machine} | {msg}");
}

fn components(n: usize) -> String {
    if n == 1 {
        "1 component".into()
    } else {
        format!("{n} components")
    }
}

fn raw_status(status: Option<ExitStatus>) -> i32 {
    status.map_or(-1, |s| s.into_raw())
}

/// Run the agent until SIGTERM or Ctrl-C; its components are stopped first.
pub async fn run(manifest: Manifest, opts: AgentOptions) -> anyhow::Result<i32> {
    let me = crate::machines::machine(&manifest, &opts.machine)?.clone();
    // The machine's router is a process of its own, restarted when it dies: a link's fault
    // takes it down, not the agent and the components it supervises.
    let config =
        crate::machines::router_config(&manifest, &me, &opts.local_router, &opts.namespace)?;
    let router = crate::router_process::RouterProcess::start(config, &opts.local_router)
        .await
        .with_context(|| {
            format!(
                "machine {:?}'s router on {} and {}",
                me.name, opts.local_router, me.router
            )
        })?;
    let endpoint = router.endpoint.clone();
    let others: Vec<String> = manifest
        .machines
        .iter()
        .filter(|m| m.name != me.name)
        .map(|m| format!("{} at {}", m.name, m.router))
        .collect();
    say(
        &me.name,
        format!(
            "graph {:?}, namespace {}: router on {endpoint} (this machine's components) and {} (the other machines; {}), joining {}",
            manifest.name,
            opts.namespace,
            me.router,
            if me.is_tls() {
                "mutual TLS, access control"
            } else {
                "plain TCP"
            },
            if others.is_empty() {
                "no other machine".to_string()
            } else {
                others.join(", ")
            }
        ),
    );
    let connect = interfaces::ConnectArgs::to_router(&endpoint, &opts.namespace);
    let control = topics::agent_control(&me.name)
        .ok_or_else(|| anyhow::anyhow!("invalid machine name {:?}", me.name))?;
    let bus = Bus::open_with(
        &connect,
        &agent_name(&me.name),
        BusOptions {
            announce: true,
            ready_after_services: vec![control.name().to_string()],
            ..Default::default()
        },
    )
    .await?;
    let (events_tx, mut events_rx) = mpsc::channel::<AgentEvent>(4096);
    let shared = Arc::new(Shared {
        machine: me.name.clone(),
        namespace: opts.namespace.clone(),
        local_endpoint: endpoint.clone(),
        state_root: opts.state_root.clone(),
        running: Mutex::new(HashMap::new()),
        events: events_tx,
        launch_id: Mutex::new(String::new()),
        placed: manifest
            .components
            .iter()
            .filter(|c| c.machine.as_deref() == Some(me.name.as_str()))
            .map(|c| (c.name.clone(), c.clone()))
            .collect(),
    });

    // Events out, in order, from one task.
    let publisher = bus.publisher(&topics::AGENT_EVENTS).await?;
    tokio::spawn(async move {
        while let Some(mut e) = events_rx.recv().await {
            if let Err(err) = publisher.publish(&mut e).await {
                tracing::warn!("cannot publish an agent event: {err}");
            }
        }
    });

    let handler_shared = shared.clone();
    let _service = bus
        .serve(&control, move |req: AgentRequest| {
            let shared = handler_shared.clone();
            async move { handle(&shared, req).await }
        })
        .await?;
    say(&me.name, "ready: waiting for a launch");

    // The launcher's presence, for orphaned components.
    let launcher_tokens =
        crate::supervisor::component_tokens(bus.session(), &opts.namespace).await?;
    let (present_tx, mut present_rx) = watch::channel(false);
    {
        let ns = opts.namespace.clone();
        tokio::spawn(async move {
            let mut launchers = 0usize;
            while let Ok(sample) = launcher_tokens.recv_async().await {
                if let Some(Token::Component { name, .. }) =
                    liveliness::parse(&ns, sample.key_expr().as_str())
                    && name == LAUNCHER_NAME
                {
                    match sample.kind() {
                        zenoh::sample::SampleKind::Put => launchers += 1,
                        zenoh::sample::SampleKind::Delete => {
                            launchers = launchers.saturating_sub(1)
                        }
                    }
                    let _ = present_tx.send(launchers > 0);
                }
            }
        });
    }

    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate())?;
    let mut int = signal(SignalKind::interrupt())?;
    let mut gone_since: Option<tokio::time::Instant> = None;
    #[expect(
        clippy::disallowed_methods,
        reason = "the agent polls how long the launcher has been away on the wall: it supervises real processes"
    )]
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    let reason = loop {
        tokio::select! {
            _ = term.recv() => break "SIGTERM",
            _ = int.recv() => break "interrupted",
            _ = present_rx.changed() => {
                let present = *present_rx.borrow();
                if present {
                    if gone_since.take().is_some() {
                        say(&me.name, "the launcher is back");
                    }
                } else if gone_since.is_none() {
                    #[expect(
                        clippy::disallowed_methods,
                        reason = "the launcher's absence is timed on the wall: the agent supervises real processes"
                    )]
                    let now = tokio::time::Instant::now();
                    gone_since = Some(now);
                    let n = shared.running.lock().unwrap_or_else(|p| p.into_inner()).len();
                    if n > 0 {
                        say(&me.name, format!(
                            "the launcher is out of reach: its {} here run on, and are stopped if it is not back within {:.0} s",
                            components(n),
                            opts.orphan_after.as_secs_f64()
                        ));
                    }
                }
            }
            _ = tick.tick() => {
                if let Some(since) = gone_since
                    && since.elapsed() >= opts.orphan_after
                {
                    let n = shared.running.lock().unwrap_or_else(|p| p.into_inner()).len();
                    if n > 0 {
                        say(&me.name, format!(
                            "the launcher has been gone {:.0} s: stopping its {}",
                            opts.orphan_after.as_secs_f64(),
                            components(n)
                        ));
                        stop_all(&shared).await;
                    }
                    gone_since = None;
                }
            }
        }
    };
    say(&me.name, format!("{reason}: stopping"));
    stop_all(&shared).await;
    drop(bus);
    router.stop().await;
    Ok(0)
}

async fn handle(shared: &Arc<Shared>, req: AgentRequest) -> Result<AgentReply, ServiceError> {
    let mut reply = AgentReply {
        machine: shared.machine.clone(),
        wait_status: -1,
        ..Default::default()
    };
    // Nothing is touched for a start this agent would refuse.
    let start_as = if req.action == AgentAction::Start {
        Some(allowed(shared, &req)?)
    } else {
        None
    };
    // A new launch takes the machine over: what an earlier one left is stopped first.
    let earlier = {
        let mut current = shared.launch_id.lock().unwrap_or_else(|p| p.into_inner());
        if *current != req.launch_id && req.action == AgentAction::Start {
            let old = std::mem::replace(&mut *current, req.launch_id.clone());
            (!old.is_empty()).then_some(old)
        } else {
            None
        }
    };
    if let Some(old) = earlier {
        let left: Vec<String> = shared
            .running
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
            .filter(|(_, r)| r.launch_id == old)
            .map(|(n, _)| n.clone())
            .collect();
        if !left.is_empty() {
            say(
                &shared.machine,
                format!(
                    "a new launch: stopping what the earlier one left ({})",
                    left.join(", ")
                ),
            );
            for name in left {
                stop_one(shared, &name, Duration::from_secs(5)).await;
            }
        }
    }
    match req.action {
        AgentAction::Status => {
            let running = shared.running.lock().unwrap_or_else(|p| p.into_inner());
            reply.running = running
                .iter()
                .filter(|(_, r)| r.launch_id == req.launch_id)
                .map(|(name, r)| AgentChild {
                    component: name.clone(),
                    generation: r.generation,
                    pid: r.pid,
                })
                .collect();
            reply.running.sort_by(|a, b| a.component.cmp(&b.component));
        }
        AgentAction::Start => {
            if let Some((spec, binary)) = start_as {
                reply.pid = start(shared, &req, spec, binary)?;
            }
        }
        AgentAction::Stop => {
            let grace = Duration::from_millis(req.stop_timeout_ms.clamp(100, 600_000));
            reply.wait_status = stop_one(shared, &req.component, grace).await;
        }
    }
    Ok(reply)
}

/// Start `spec` (the component `req` asks for, as this agent's manifest has it) from `binary`.
fn start(
    shared: &Arc<Shared>,
    req: &AgentRequest,
    spec: &Component,
    binary: PathBuf,
) -> Result<u32, ServiceError> {
    if !interfaces::topic::is_valid_segment(&req.component)
        || !interfaces::topic::is_valid_segment(&req.graph)
    {
        return Err(ServiceError::bad_request(format!(
            "invalid component or graph name {:?} / {:?}",
            req.component, req.graph
        )));
    }
    if let Some(r) = shared
        .running
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .get(&req.component)
    {
        return Err(ServiceError::refused(format!(
            "{} already runs here (pid {}, start {})",
            req.component, r.pid, r.generation
        )));
    }
    let connect = interfaces::ConnectArgs::to_router(&shared.local_endpoint, &shared.namespace);
    let mut env = connect.to_env();
    env.push(("ROBOCOG_COMPONENT".into(), req.component.clone()));
    let state = shared
        .state_root
        .join(&req.graph)
        .join(&shared.namespace)
        .join(&req.component);
    env.push(("ROBOCOG_STATE_DIR".into(), state.display().to_string()));
    env.extend(spec.env.iter().map(|(k, v)| (k.clone(), v.clone())));

    let event = {
        let base = AgentEvent {
            launch_id: req.launch_id.clone(),
            machine: shared.machine.clone(),
            component: req.component.clone(),
            generation: req.generation,
            ..Default::default()
        };
        move |kind, line: String, wait_status| AgentEvent {
            kind,
            line,
            wait_status,
            ..base.clone()
        }
    };
    let lines = {
        let event = event.clone();
        let events = shared.events.clone();
        let prefix = format!("{} |", req.component);
        move |line: String, stderr: bool| {
            eprintln!("{prefix} {line}");
            let kind = if stderr {
                AgentEventKind::Stderr
            } else {
                AgentEventKind::Stdout
            };
            // A launcher that cannot keep up loses lines, never the agent its footing.
            let _ = events.try_send(event(kind, line, 0));
        }
    };
    let on_exit = {
        let shared = shared.clone();
        let name = req.component.clone();
        let generation = req.generation;
        move |status: Option<ExitStatus>| -> BoxFuture {
            Box::pin(async move {
                {
                    let mut running = shared.running.lock().unwrap_or_else(|p| p.into_inner());
                    if running
                        .get(&name)
                        .is_some_and(|r| r.generation == generation)
                    {
                        running.remove(&name);
                    }
                }
                say(
                    &shared.machine,
                    format!("{name} exited ({})", describe_status(status)),
                );
                let _ = shared
                    .events
                    .send(event(
                        AgentEventKind::Exited,
                        String::new(),
                        raw_status(status),
                    ))
                    .await;
            })
        }
    };
    let spawned = spawn_process(&binary, &spec.args, env, lines, on_exit)
        .map_err(|e| ServiceError::refused(format!("machine {}: {e:#}", shared.machine)))?;
    say(
        &shared.machine,
        format!(
            "started {} (pid {}): {} {}",
            req.component,
            spawned.pid,
            binary.display(),
            spec.args.join(" ")
        ),
    );
    shared
        .running
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .insert(
            req.component.clone(),
            Running {
                generation: req.generation,
                pid: spawned.pid,
                launch_id: req.launch_id.clone(),
                exit: spawned.exit,
            },
        );
    Ok(spawned.pid)
}

/// The component `req` asks to start as this agent's own manifest has it, and its binary; or
/// why not.
fn allowed<'s>(
    shared: &'s Shared,
    req: &AgentRequest,
) -> Result<(&'s Component, PathBuf), ServiceError> {
    // Only what this machine's own copy of the manifest places here, as it says: a launcher
    // (or anything else on the bus) cannot make the agent run something else.
    let Some(spec) = shared.placed.get(&req.component) else {
        let mut here: Vec<&str> = shared.placed.keys().map(String::as_str).collect();
        here.sort();
        return Err(ServiceError::refused(format!(
            "machine {}: this agent's manifest places no component {:?} here (it places: {})",
            shared.machine,
            req.component,
            here.join(", ")
        )));
    };
    let env: std::collections::BTreeMap<String, String> = req
        .env
        .iter()
        .map(|v| (v.name.clone(), v.value.clone()))
        .collect();
    if spec.binary != req.binary || spec.args != req.args || spec.env != env {
        return Err(ServiceError::refused(format!(
            "machine {}: the launcher's manifest and this agent's differ for {}: {} {:?} there, {} {:?} here (give every machine the same manifest and the same --set and --profile)",
            shared.machine, req.component, req.binary, req.args, spec.binary, spec.args
        )));
    }
    let binary = spec.resolve_binary().ok_or_else(|| {
        ServiceError::not_found(format!(
            "machine {}: no binary {:?} (next to robocog, on PATH, or relative to {})",
            shared.machine,
            spec.binary,
            spec.dir.display()
        ))
    })?;
    Ok((spec, binary))
}

/// SIGTERM to `name`'s process group, SIGKILL after `grace`; the raw wait status (-1: nothing
/// ran).
async fn stop_one(shared: &Arc<Shared>, name: &str, grace: Duration) -> i32 {
    let found = {
        let running = shared.running.lock().unwrap_or_else(|p| p.into_inner());
        running.get(name).map(|r| (r.pid, r.exit.clone()))
    };
    let Some((pid, mut exit)) = found else {
        return -1;
    };
    let group = Pid::from_raw(pid as i32);
    let _ = killpg(group, Signal::SIGTERM);
    #[expect(
        clippy::disallowed_methods,
        reason = "a real process' stop time-out (SIGTERM, then SIGKILL), on the wall"
    )]
    let ended = tokio::time::timeout(grace, async {
        let _ = exit.wait_for(|s| s.is_some()).await;
    })
    .await;
    if ended.is_err() {
        say(
            &shared.machine,
            format!(
                "{name} ignored SIGTERM for {:.1} s: SIGKILL",
                grace.as_secs_f64()
            ),
        );
        let _ = killpg(group, Signal::SIGKILL);
        #[expect(
            clippy::disallowed_methods,
            reason = "waits for a killed real process to be reaped, on the wall"
        )]
        let _ = tokio::time::timeout(Duration::from_secs(5), async {
            let _ = exit.wait_for(|s| s.is_some()).await;
        })
        .await;
    }
    // Whatever it left in its group goes too.
    let _ = killpg(group, Signal::SIGKILL);
    let status = (*exit.borrow()).flatten();
    raw_status(status)
}

async fn stop_all(shared: &Arc<Shared>) {
    let names: Vec<String> = shared
        .running
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .keys()
        .cloned()
        .collect();
    let stops = names.into_iter().map(|name| {
        let shared = shared.clone();
        tokio::spawn(async move { stop_one(&shared, &name, Duration::from_secs(5)).await })
    });
    for s in stops.collect::<Vec<_>>() {
        let _ = s.await;
    }
}
