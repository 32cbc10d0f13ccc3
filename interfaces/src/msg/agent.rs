//! The launcher and the agents of a graph over several machines (`robocog agent`): what the
//! launcher asks an agent to do with the components placed on its machine, and what the agent
//! reports back (their output, their exits).

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// What the launcher asks of an agent.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AgentAction {
    /// Which of this launch's components run on the machine (nothing is changed).
    #[default]
    Status,
    /// Start a component (a generation the launcher numbers).
    Start,
    /// Stop a component: SIGTERM to its process group, SIGKILL after `stop_timeout_ms`. The reply
    /// comes once it has exited.
    Stop,
}

/// One environment variable of a component.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct EnvVar {
    pub name: String,
    pub value: String,
}

/// A request to the agent of one machine (`agent/<machine>/control`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AgentRequest {
    pub header: Header,
    /// The launch asking (its id, new at every `robocog launch`). An agent runs one launch's
    /// components at a time; a new launch replaces what an earlier one left.
    pub launch_id: String,
    /// The graph's name (the agent keeps component state in `<root>/<graph>/<namespace>/`).
    pub graph: String,
    pub action: AgentAction,
    /// The component (Start, Stop).
    pub component: String,
    /// The launcher's count of this component's starts; events carry it back.
    pub generation: u64,
    /// The binary, arguments and environment as the launcher's manifest has them. The agent
    /// starts the component as its own copy of the manifest has it, and refuses a request that
    /// differs (or names a component its manifest does not place on its machine).
    pub binary: String,
    /// The folder of the launcher's manifest (for the messages).
    pub dir: String,
    pub args: Vec<String>,
    pub env: Vec<EnvVar>,
    /// Stop: how long SIGTERM has before SIGKILL.
    pub stop_timeout_ms: u64,
}

/// One component an agent runs.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AgentChild {
    pub component: String,
    pub generation: u64,
    pub pid: u32,
}

/// An agent's answer.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AgentReply {
    pub header: Header,
    pub machine: String,
    /// Start: the new process's pid.
    pub pid: u32,
    /// Stop: the exit, as `wait(2)` gives it (raw wait status); -1 when nothing ran.
    pub wait_status: i32,
    /// Status: this launch's components that run now.
    pub running: Vec<AgentChild>,
}

/// What an event is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AgentEventKind {
    /// A line the component wrote on its standard output.
    #[default]
    Stdout,
    /// A line on its standard error.
    Stderr,
    /// It exited (`wait_status`).
    Exited,
}

/// Something a component placed on an agent's machine did (`agent/events`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AgentEvent {
    pub header: Header,
    pub launch_id: String,
    pub machine: String,
    pub component: String,
    pub generation: u64,
    pub kind: AgentEventKind,
    /// Stdout, Stderr: the line, without its end.
    pub line: String,
    /// Exited: the raw wait status (`WIFEXITED`/`WTERMSIG` decode it).
    pub wait_status: i32,
}
