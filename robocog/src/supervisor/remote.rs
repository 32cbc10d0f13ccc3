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
    /// How long a status call to an agent back on the bus waits for its answer.
    pub(super) status_timeout: Duration,
}

/// How long a status call waits for an agent that came back ([`Machines::status_timeout`]).
const STATUS_TIMEOUT: Duration = Duration::from_secs(10);
/// The pause before a status call that failed is sent again (the agent is on the bus: slow, or
/// its routes not there yet).
const STATUS_RETRY: Duration = Duration::from_secs(1);

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
            status_timeout: STATUS_TIMEOUT,
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
            self.ask_status(machine, 1, tx);
        }
    }

    /// Ask `machine`'s agent what runs there (after a pause, from the second attempt on); the
    /// answer comes as [`Event::Reconciled`].
    pub(super) fn ask_status(&self, machine: String, attempt: u32, tx: &mpsc::Sender<Event>) {
        let bus = self.bus.clone();
        let request = AgentRequest {
            launch_id: self.launch_id.clone(),
            graph: self.graph.clone(),
            action: AgentAction::Status,
            ..Default::default()
        };
        let timeout = self.status_timeout;
        let tx = tx.clone();
        tokio::spawn(async move {
            if attempt > 1 {
                #[expect(
                    clippy::disallowed_methods,
                    reason = "a pause between calls over the network to a real machine's agent"
                )]
                tokio::time::sleep(STATUS_RETRY).await;
            }
            let running = call_agent(&bus, &machine, &request, timeout)
                .await
                .map(|r| r.running);
            let _ = tx
                .send(Event::Reconciled {
                    machine,
                    attempt,
                    running,
                })
                .await;
        });
    }

    /// The answer of status call number `attempt` to `machine`'s agent. An answer reconciles
    /// (see [`reconciled`]). A failed call says so and changes nothing: the components there
    /// stay out of reach, never counted as stopped on a call's failure; while the agent is on
    /// the bus (slow, or its routes not there yet) it is asked again, and an agent that left
    /// again is asked when it is back.
    pub(super) fn status_answered(
        &self,
        machine: String,
        attempt: u32,
        running: Result<Vec<AgentChild>, String>,
        children: &mut HashMap<String, Child>,
        pending: &mut VecDeque<Event>,
        tx: &mpsc::Sender<Event>,
    ) {
        match running {
            Ok(running) => reconciled(&machine, running, children, pending),
            Err(why) if self.up.contains(&machine) => {
                // Said at calls 1, 2, 4, 8, ...: an agent that never answers does not fill the log.
                if attempt.is_power_of_two() {
                    say(format!(
                        "{why}: machine {machine}'s agent is on the bus but did not say what runs there (status call {attempt}); its components stay out of reach, not stopped; asking again"
                    ));
                }
                self.ask_status(machine, attempt + 1, tx);
            }
            Err(why) => say(format!(
                "{why}: machine {machine} left the bus again before its agent said what runs there; it is asked again when it is back"
            )),
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
    running: Vec<AgentChild>,
    children: &mut HashMap<String, Child>,
    pending: &mut VecDeque<Event>,
) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::manifest::{Component, Origin, RestartPolicy};
    use interfaces::msg::agent::AgentReply;
    use std::sync::atomic::{AtomicU32, Ordering};
    use std::sync::{Arc, Mutex};

    #[expect(
        clippy::disallowed_methods,
        reason = "a child's start time, which this test does not read"
    )]
    fn child_on(machine: &str, name: &str, generation: u64) -> Child {
        Child {
            spec: Component {
                name: name.into(),
                binary: "fixture_node".into(),
                args: Vec::new(),
                env: Default::default(),
                depends_on: Vec::new(),
                restart: RestartPolicy::OnFailure,
                max_restarts: 3,
                backoff: Duration::from_millis(500),
                required: false,
                ready_timeout: Duration::from_secs(10),
                stop_timeout: Duration::from_secs(5),
                hardware: Vec::new(),
                completes_graph: false,
                external_inputs: Vec::new(),
                origin: Origin {
                    file: "graph.toml".into(),
                    line: 1,
                },
                dir: ".".into(),
                machine: Some(machine.into()),
            },
            binary: "fixture_node".into(),
            state: State::Up,
            pid: Some(42),
            generation,
            restarts: 0,
            started: Instant::now(),
            exit: None,
            tail: Arc::new(Mutex::new(VecDeque::new())),
            prefix: format!("{machine}/{name} |"),
            remote: Some(machine.into()),
        }
    }

    /// A router of its own, and the connection flags of a fresh namespace on it.
    async fn bus_of_its_own(test: &str) -> (zenoh::Session, interfaces::ConnectArgs) {
        let (router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0")
            .await
            .unwrap();
        let ns = format!("unit-{test}-{}", std::process::id());
        (router, interfaces::ConnectArgs::to_router(&endpoint, &ns))
    }

    /// An agent back on the bus that answers its first status call late: the launcher says so,
    /// asks again, and its components there are up again, never counted as stopped.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_slow_agent_is_asked_again_and_its_components_are_not_counted_stopped() {
        let (_router, args) = bus_of_its_own("slow-agent").await;
        let launcher = Bus::open(&args, "launcher").await.unwrap();
        let agent = Bus::open(&args, "agent").await.unwrap();
        let status_timeout = Duration::from_millis(300);
        let calls = Arc::new(AtomicU32::new(0));
        let served = calls.clone();
        let _serve = agent
            .serve(
                &interfaces::topics::agent_control("speech").unwrap(),
                move |req: AgentRequest| {
                    let call = served.fetch_add(1, Ordering::SeqCst);
                    async move {
                        assert_eq!(req.action, AgentAction::Status);
                        if call == 0 {
                            // Slow: busy for three times the launcher's patience.
                            #[expect(
                                clippy::disallowed_methods,
                                reason = "a slow agent, slow on the wall as a real one is"
                            )]
                            tokio::time::sleep(status_timeout * 3).await;
                        }
                        Ok(AgentReply {
                            machine: "speech".into(),
                            running: vec![AgentChild {
                                component: "talker".into(),
                                generation: 1,
                                pid: 42,
                            }],
                            ..Default::default()
                        })
                    }
                },
            )
            .await
            .unwrap();

        let mut ms = Machines::new(
            launcher,
            "launch-1".into(),
            "graph".into(),
            Duration::from_secs(30),
        );
        ms.status_timeout = status_timeout;
        let mut children = HashMap::from([("talker".to_string(), child_on("speech", "talker", 1))]);
        let mut pending = VecDeque::new();
        let (tx, mut rx) = mpsc::channel(8);
        // Up, lost (its link down), back: asked what runs there.
        ms.machine_up("speech".into(), &tx);
        ms.machine_lost("speech", &mut children);
        assert_eq!(children["talker"].state, State::Unreachable);
        ms.machine_up("speech".into(), &tx);

        let mut answers = Vec::new();
        while children["talker"].state == State::Unreachable {
            #[expect(
                clippy::disallowed_methods,
                reason = "a test's guard against a hang, on the wall"
            )]
            let event = tokio::time::timeout(Duration::from_secs(30), rx.recv())
                .await
                .expect("a status answer within 30 s")
                .expect("the channel open");
            let Event::Reconciled {
                machine,
                attempt,
                running,
            } = event
            else {
                continue;
            };
            answers.push((attempt, running.is_ok()));
            ms.status_answered(machine, attempt, running, &mut children, &mut pending, &tx);
            assert!(
                pending.is_empty(),
                "nothing counted as stopped after {answers:?}"
            );
            assert!(answers.len() < 5, "answers: {answers:?}");
        }
        assert_eq!(answers, [(1, false), (2, true)]);
        assert_eq!(children["talker"].state, State::Up);
        assert_eq!(children["talker"].pid, Some(42));
        assert_eq!(calls.load(Ordering::SeqCst), 2);
    }

    /// A failed status call for an agent that left the bus again asks nothing more: it is
    /// asked when it is back.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_failed_status_call_for_an_agent_that_left_again_changes_nothing() {
        let (_router, args) = bus_of_its_own("gone-agent").await;
        let launcher = Bus::open(&args, "launcher").await.unwrap();
        let ms = Machines::new(
            launcher,
            "launch-1".into(),
            "graph".into(),
            Duration::from_secs(30),
        );
        let mut child = child_on("speech", "talker", 1);
        child.state = State::Unreachable;
        let mut children = HashMap::from([("talker".to_string(), child)]);
        let mut pending = VecDeque::new();
        let (tx, mut rx) = mpsc::channel(8);
        ms.status_answered(
            "speech".into(),
            1,
            Err("machine speech's agent: no answer".into()),
            &mut children,
            &mut pending,
            &tx,
        );
        assert!(pending.is_empty());
        assert_eq!(children["talker"].state, State::Unreachable);
        assert!(rx.try_recv().is_err(), "not asked again while it is away");
    }
}
