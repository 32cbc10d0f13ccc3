//! Components on other machines: the launcher's view of the machines, the calls to their agents
//! (start, stop, status), and what it makes of the agents' events.

use super::process::push_tail;
use super::{Child, Event, State, say};
use interfaces::bus::{Bus, CallError};
use interfaces::msg::agent::{
    AgentAction, AgentChild, AgentEvent, AgentEventKind, AgentRequest, EnvVar,
};
use std::collections::{BTreeSet, HashMap, VecDeque};
use std::os::unix::process::ExitStatusExt;
use std::process::ExitStatus;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// The machines of a graph over several, as the launcher sees them.
pub(super) struct Machines {
    pub(super) bus: Bus,
    pub(super) launch_id: String,
    graph: String,
    /// Agents on the bus now.
    pub(super) up: BTreeSet<String>,
    /// Agents that have been up at least once (a lost one is then "back" when it returns).
    seen: BTreeSet<String>,
    since: Instant,
    timeout: Duration,
}

impl Machines {
    /// The launcher's view of the other machines, their agents not heard of yet; they have
    /// `timeout` to show.
    #[expect(
        clippy::disallowed_methods,
        reason = "the launcher waits for the agents of real machines on the wall"
    )]
    pub(super) fn new(bus: Bus, launch_id: String, graph: String, timeout: Duration) -> Machines {
        Machines {
            bus,
            launch_id,
            graph,
            up: BTreeSet::new(),
            seen: BTreeSet::new(),
            since: Instant::now(),
            timeout,
        }
    }

    /// Output or an exit from a component on another machine (an exit goes to `pending`, for the
    /// launcher's loop).
    pub(super) fn on_event(
        &self,
        e: AgentEvent,
        children: &mut HashMap<String, Child>,
        pending: &mut VecDeque<Event>,
    ) {
        if e.launch_id != self.launch_id {
            return;
        }
        let Some(c) = children.get_mut(&e.component) else {
            return;
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
                let status = (e.wait_status >= 0).then(|| ExitStatus::from_raw(e.wait_status));
                pending.push_back(Event::Exited {
                    name: e.component,
                    generation: e.generation,
                    status,
                });
            }
        }
    }

    /// A machine's agent appeared on the bus: the first time it is said; a machine that comes
    /// back is asked what still runs there (the answer comes as [`Event::Reconciled`]).
    pub(super) fn machine_up(&mut self, machine: String, tx: &mpsc::Sender<Event>) {
        if !self.up.insert(machine.clone()) {
            return;
        }
        if self.seen.insert(machine.clone()) {
            say(format!(
                "machine {machine}'s agent is up ({} ms)",
                self.since.elapsed().as_millis()
            ));
        } else {
            say(format!(
                "machine {machine} is back: asking its agent what still runs there"
            ));
            let bus = self.bus.clone();
            let request = AgentRequest {
                launch_id: self.launch_id.clone(),
                graph: self.graph.clone(),
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

    /// A machine's agent vanished from the bus: its components are out of reach.
    pub(super) fn machine_lost(&mut self, machine: &str, children: &mut HashMap<String, Child>) {
        if !self.up.remove(machine) {
            return;
        }
        let mut lost: Vec<&str> = Vec::new();
        for c in children.values_mut() {
            if c.remote.as_deref() == Some(machine)
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

    /// Whether, the machines' time-out passed, a component still waits for a machine whose
    /// agent never came (said).
    pub(super) fn agents_missing(&self, children: &HashMap<String, Child>) -> bool {
        if self.since.elapsed() <= self.timeout {
            return false;
        }
        let mut missing: Vec<&str> = children
            .values()
            .filter(|c| c.state == State::Pending)
            .filter_map(|c| c.remote.as_deref())
            .filter(|m| !self.seen.contains(*m))
            .collect();
        missing.sort();
        missing.dedup();
        if missing.is_empty() {
            return false;
        }
        say(format!(
            "no agent on machine {} within {:.0} s: is `robocog agent --machine <name> <manifest>` running there, and can its router reach this one (the [machines] endpoints, certificates, firewall)?",
            missing.join(", "),
            self.timeout.as_secs_f64()
        ));
        true
    }
}

/// An agent's answer to the start of `c`: its pid, or why it refused. Whether a required
/// component could not start (the graph stops).
pub(super) fn started(c: &mut Child, result: Result<u32, String>) -> bool {
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
            false
        }
        Err(why) => {
            say(format!("cannot start {}: {why}", c.spec.name));
            c.state = State::Failed;
            c.spec.required
        }
    }
}

/// What `machine`, back on the bus, still runs: its components that ran on while it was away are
/// up again; those that stopped meanwhile go to `pending` as exits, for their restart policies.
#[expect(
    clippy::disallowed_methods,
    reason = "the launcher supervises real processes: their start deadlines are on the wall"
)]
pub(super) fn reconciled(
    machine: &str,
    running: Result<Vec<AgentChild>, String>,
    children: &mut HashMap<String, Child>,
    pending: &mut VecDeque<Event>,
) {
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
        if c.remote.as_deref() != Some(machine) || c.state != State::Unreachable {
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

/// The request every call to an agent starts from.
pub(super) fn agent_request(m: &Machines, action: AgentAction, c: &Child) -> AgentRequest {
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
#[expect(
    clippy::disallowed_methods,
    reason = "a call over the network to a real machine's agent: its retries and time-out are the transport's, on the wall"
)]
pub(super) async fn call_agent(
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

/// Ask `c`'s machine's agent to start it; the answer comes back as [`Event::RemoteStarted`].
#[expect(
    clippy::disallowed_methods,
    reason = "the launcher supervises real processes: their start time and deadline are on the wall"
)]
pub(super) fn spawn_remote(c: &mut Child, ms: &Machines, tx: &mpsc::Sender<Event>) {
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
