//! A hierarchical, concurrent state machine engine (a statechart), with no bus and no clock.
//!
//! # Concepts
//!
//! - **States** form a tree under an unnamed root. A state is *atomic* (no children), *compound*
//!   (exactly one active child; entering it enters its *initial* child), *parallel* (every child,
//!   called a *region*, is active at once), *final* (entering it completes its parent), or a
//!   *history* pseudo-state (entering it re-enters what its parent last had active: its active
//!   child for *shallow* history, its active leaves for *deep* history; the parent's initial child
//!   the first time, or the history's own default).
//! - **Names** are paths from the root joined by `/` (`game/playing/gaze/following`). A state is
//!   declared with its full path, after its parent.
//! - The **configuration** is the set of active states: the active leaves and all their
//!   ancestors. With parallel regions several leaves are active at once.
//! - **Transitions** leave a source state, triggered by a named [`Event`] (with a payload the
//!   guards and actions can read), by a *timer* (`after(d)`: `d` after the source was entered,
//!   cancelled when it is left), or by nothing at all (*eventless*: taken as soon as the source is
//!   active and the guard holds). An optional **guard** (a named predicate on the context and the
//!   event) must hold. A transition with no target only runs its actions (nothing is exited).
//!   An *external* transition (the default) leaves and re-enters its source when the target is
//!   the source or inside it; an *internal* one to a descendant does not leave the source.
//! - **Order** (SCXML semantics): the states that are left are those active under the transition
//!   domain (the least common compound ancestor of source and target), exited innermost first with
//!   their exit actions; then the transition's actions run; then the states on the way to the
//!   target are entered outermost first with their entry actions (a compound's initial child and
//!   every region of a parallel state included). When one event enables transitions in several
//!   parallel regions, all of them are taken in one step, in document order; a transition in a
//!   deeper state takes precedence over a conflicting one in its ancestor.
//! - **Completion**: entering a final state raises the internal event `done.state.<parent path>`
//!   (and `done.state.<parallel path>` once every region of a parallel state is final); entering a
//!   final child of the root finishes the machine. Internal events and eventless transitions are
//!   processed in the same step, before the next external event (run to completion).
//! - **Time** is passed in: every call takes `now` (a [`Duration`] since the caller's clock
//!   epoch); the engine never reads a clock. [`Machine::advance`] fires the timers due at `now`,
//!   each at its own deadline (a state entered by a timer step starts its own timers at that
//!   deadline, so chains of timers are exact on a virtual clock).
//! - **Actions** are data (`A`, often an enum) that the engine hands, in order, to the caller's
//!   [`Context::run`]; guards read the context. The game code stays a readable table of states and
//!   transitions, and is tested by looking at the actions a step produced ([`Step::actions`]).
//!
//! A definition ([`Definition`]) is built with [`Builder`] and checked once: an unknown target
//! or parent, a compound state without an initial child, a duplicate name, a malformed name are
//! [`DefinitionError`]s. [`Definition::mermaid`] and [`Definition::dot`] draw it.

mod diagram;
mod machine;
#[cfg(test)]
mod tests;

pub use machine::{Context, Machine, Step};

use std::collections::HashMap;
use std::fmt;
use std::sync::Arc;
use std::time::Duration;

/// An event: a name (`command:touch_ball`, `ball:lost`) and a payload the guards and actions can
/// read.
#[derive(Debug, Clone, PartialEq)]
pub struct Event<E> {
    pub name: String,
    pub payload: E,
}

impl<E: Default> Event<E> {
    /// An event with the default payload.
    pub fn named(name: impl Into<String>) -> Self {
        Event {
            name: name.into(),
            payload: E::default(),
        }
    }
}

impl<E> Event<E> {
    /// An event with a payload.
    pub fn new(name: impl Into<String>, payload: E) -> Self {
        Event {
            name: name.into(),
            payload,
        }
    }
}

/// The event that matches every event name in a transition trigger.
pub const ANY_EVENT: &str = "*";

/// What is wrong with a machine definition.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefinitionError {
    #[error("state `{0}` is declared twice")]
    Duplicate(String),
    #[error("state name `{0}` is empty, or has an empty segment or `*`")]
    BadName(String),
    #[error("state `{state}`: its parent `{parent}` is not declared before it")]
    UnknownParent { state: String, parent: String },
    #[error("state `{0}`: the parent is atomic, final or history and cannot have children")]
    ParentCannotHaveChildren(String),
    #[error("compound state `{0}` has no initial child")]
    NoInitial(String),
    #[error("compound state `{state}`: initial `{initial}` is not one of its children")]
    BadInitial { state: String, initial: String },
    #[error("parallel state `{0}` has no regions")]
    EmptyParallel(String),
    #[error("the machine has no states")]
    Empty,
    #[error("the root has no initial state")]
    NoRootInitial,
    #[error("transition from `{from}` ({trigger}): unknown target `{target}`")]
    UnknownTarget {
        from: String,
        trigger: String,
        target: String,
    },
    #[error("transition from unknown state `{0}`")]
    UnknownSource(String),
    #[error("history state `{state}`: default `{default}` is not a descendant of its parent")]
    BadHistoryDefault { state: String, default: String },
    #[error("history state `{0}` is not inside a compound or parallel state")]
    HistoryOutsideCompound(String),
    #[error("transition from `{0}`: an internal transition needs a target inside its source")]
    BadInternal(String),
    #[error("transition from `{0}`: a zero-length `after` timer would be an eventless transition")]
    ZeroTimer(String),
}

/// The kind of a state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StateKind {
    Atomic,
    Compound,
    Parallel,
    Final,
    /// `deep`: remembers the active leaves, else the active child.
    History {
        deep: bool,
    },
}

/// What triggers a transition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Trigger {
    /// A named event ([`ANY_EVENT`] matches every one).
    Event(String),
    /// A timer: this long after the source state was entered; `label` names its event
    /// (`timer:<label>`).
    After { delay: Duration, label: String },
    /// Nothing: taken as soon as the source is active and the guard holds.
    Eventless,
}

impl fmt::Display for Trigger {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Trigger::Event(e) => write!(f, "{e}"),
            Trigger::After { delay, label } => {
                write!(f, "after {} ({label})", fmt_duration(*delay))
            }
            Trigger::Eventless => write!(f, "eventless"),
        }
    }
}

pub(crate) fn fmt_duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s >= 1.0 && d.subsec_millis() == 0 {
        format!("{}s", d.as_secs())
    } else {
        format!("{}ms", d.as_millis())
    }
}

/// A named guard: a predicate on the context and the event.
pub struct Guard<C, E> {
    pub name: String,
    #[allow(clippy::type_complexity)]
    pub test: Arc<dyn Fn(&C, &Event<E>) -> bool + Send + Sync>,
}

impl<C, E> Clone for Guard<C, E> {
    fn clone(&self) -> Self {
        Guard {
            name: self.name.clone(),
            test: self.test.clone(),
        }
    }
}

impl<C, E> fmt::Debug for Guard<C, E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Guard({})", self.name)
    }
}

pub(crate) type StateId = usize;

/// A checked state.
#[derive(Debug, Clone)]
pub(crate) struct StateNode<A> {
    pub name: String,
    pub path: String,
    pub parent: Option<StateId>,
    pub children: Vec<StateId>,
    pub kind: StateKind,
    pub initial: Option<StateId>,
    /// For history states: where to go the first time (None = the parent's initial).
    pub history_default: Option<StateId>,
    pub entry: Vec<A>,
    pub exit: Vec<A>,
    /// Transitions whose source is this state, in declaration order.
    pub transitions: Vec<usize>,
    /// Preorder position (document order).
    pub order: usize,
}

/// A checked transition.
#[derive(Debug, Clone)]
pub(crate) struct TransitionNode<C, E, A> {
    pub source: StateId,
    pub trigger: Trigger,
    pub guard: Option<Guard<C, E>>,
    pub target: Option<StateId>,
    pub internal: bool,
    pub actions: Vec<A>,
}

/// A checked machine definition: shared, immutable, drawn by [`Definition::mermaid`].
#[derive(Debug)]
pub struct Definition<C, E, A> {
    pub(crate) name: String,
    /// Index 0 is the root (path "").
    pub(crate) states: Vec<StateNode<A>>,
    pub(crate) transitions: Vec<TransitionNode<C, E, A>>,
    pub(crate) by_path: HashMap<String, StateId>,
}

impl<C, E, A> Definition<C, E, A> {
    /// The machine's name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Every state path, in document order (parents before children).
    pub fn state_paths(&self) -> Vec<String> {
        let mut v: Vec<&StateNode<A>> = self.states.iter().skip(1).collect();
        v.sort_by_key(|s| s.order);
        v.into_iter().map(|s| s.path.clone()).collect()
    }
    /// The kind of the state at `path`.
    pub fn kind(&self, path: &str) -> Option<StateKind> {
        self.by_path.get(path).map(|&i| self.states[i].kind)
    }
    /// Every event name some transition is triggered by (timers as `timer:<label>`), sorted.
    pub fn events(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .transitions
            .iter()
            .filter_map(|t| match &t.trigger {
                Trigger::Event(e) => Some(e.clone()),
                Trigger::After { label, .. } => Some(format!("timer:{label}")),
                Trigger::Eventless => None,
            })
            .collect();
        v.sort();
        v.dedup();
        v
    }
    pub(crate) fn id(&self, path: &str) -> Option<StateId> {
        self.by_path.get(path).copied()
    }
    pub(crate) fn is_descendant(&self, s: StateId, ancestor: StateId) -> bool {
        let mut p = self.states[s].parent;
        while let Some(x) = p {
            if x == ancestor {
                return true;
            }
            p = self.states[x].parent;
        }
        false
    }
    /// Ancestors of `s` up to (excluding) `stop`, innermost first; all the way to the root
    /// (included) when `stop` is None.
    pub(crate) fn proper_ancestors(&self, s: StateId, stop: Option<StateId>) -> Vec<StateId> {
        let mut v = Vec::new();
        let mut p = self.states[s].parent;
        while let Some(x) = p {
            if Some(x) == stop {
                break;
            }
            v.push(x);
            p = self.states[x].parent;
        }
        v
    }
}

/// A state being declared (see [`Builder`]).
#[derive(Debug)]
pub struct StateDecl<A> {
    path: String,
    kind: StateKind,
    initial: Option<String>,
    history_default: Option<String>,
    entry: Vec<A>,
    exit: Vec<A>,
}

impl<A> StateDecl<A> {
    /// Adds an entry action (run in order when the state is entered).
    pub fn entry(&mut self, action: A) -> &mut Self {
        self.entry.push(action);
        self
    }
    /// Adds an exit action (run in order when the state is left).
    pub fn exit(&mut self, action: A) -> &mut Self {
        self.exit.push(action);
        self
    }
    /// For a history state: where to go when there is no history yet (a full path; default: the
    /// parent's initial child).
    pub fn default_target(&mut self, path: &str) -> &mut Self {
        self.history_default = Some(path.to_string());
        self
    }
}

/// A transition being declared (see [`Builder`]).
pub struct TransitionDecl<C, E, A> {
    source: String,
    trigger: Trigger,
    guard: Option<Guard<C, E>>,
    target: Option<String>,
    internal: bool,
    actions: Vec<A>,
}

impl<C, E, A> fmt::Debug for TransitionDecl<C, E, A> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} --{}--> {:?}", self.source, self.trigger, self.target)
    }
}

impl<C, E, A> TransitionDecl<C, E, A> {
    /// The target state (full path). Without one the transition only runs its actions.
    pub fn to(&mut self, target: &str) -> &mut Self {
        self.target = Some(target.to_string());
        self
    }
    /// A guard, named for the diagram and the logs.
    pub fn guard(
        &mut self,
        name: &str,
        test: impl Fn(&C, &Event<E>) -> bool + Send + Sync + 'static,
    ) -> &mut Self {
        self.guard = Some(Guard {
            name: name.to_string(),
            test: Arc::new(test),
        });
        self
    }
    /// Adds an action, run between the exits and the entries.
    pub fn action(&mut self, action: A) -> &mut Self {
        self.actions.push(action);
        self
    }
    /// Makes it internal: a target inside the source does not leave the source.
    pub fn internal(&mut self) -> &mut Self {
        self.internal = true;
        self
    }
}

/// Builds a [`Definition`]: states declared by full path (parents first), then transitions;
/// every mistake is reported by [`Builder::build`].
///
/// ```
/// use executive::engine::{Builder, Event, Machine, Context};
/// use std::time::Duration;
///
/// #[derive(Default)]
/// struct Log(Vec<&'static str>);
/// impl Context<&'static str, ()> for Log {
///     fn run(&mut self, a: &&'static str, _e: &Event<()>) { self.0.push(*a) }
/// }
/// let mut b = Builder::<Log, (), &'static str>::new("door");
/// b.root_initial("closed");
/// b.atomic("closed").entry("lock");
/// b.atomic("open").exit("close");
/// b.on("closed", "push").to("open");
/// b.after("open", Duration::from_secs(3), "auto_close").to("closed");
/// let def = b.build().unwrap();
/// let mut m = Machine::new(def.into());
/// let mut log = Log::default();
/// m.start(&mut log, Duration::ZERO);
/// let step = m.send(&mut log, Event::named("push"), Duration::from_secs(1));
/// assert_eq!(step.entered, ["open"]);
/// assert_eq!(m.advance(&mut log, Duration::from_secs(4))[0].event, "timer:auto_close");
/// assert_eq!(log.0, ["lock", "close", "lock"]);
/// ```
pub struct Builder<C, E, A> {
    name: String,
    root_initial: Option<String>,
    states: Vec<StateDecl<A>>,
    transitions: Vec<TransitionDecl<C, E, A>>,
}

impl<C, E, A> fmt::Debug for Builder<C, E, A> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Builder")
            .field("name", &self.name)
            .field("states", &self.states.len())
            .field("transitions", &self.transitions.len())
            .finish()
    }
}

impl<C, E, A: Clone> Builder<C, E, A> {
    /// A machine called `name` (the topic's `machine` field).
    pub fn new(name: &str) -> Self {
        Builder {
            name: name.to_string(),
            root_initial: None,
            states: Vec::new(),
            transitions: Vec::new(),
        }
    }

    /// The top-level state entered at start (a name without `/`).
    pub fn root_initial(&mut self, name: &str) -> &mut Self {
        self.root_initial = Some(name.to_string());
        self
    }

    fn decl(&mut self, path: &str, kind: StateKind, initial: Option<&str>) -> &mut StateDecl<A> {
        self.states.push(StateDecl {
            path: path.to_string(),
            kind,
            initial: initial.map(str::to_string),
            history_default: None,
            entry: Vec::new(),
            exit: Vec::new(),
        });
        let last = self.states.len() - 1;
        &mut self.states[last]
    }

    /// An atomic state.
    pub fn atomic(&mut self, path: &str) -> &mut StateDecl<A> {
        self.decl(path, StateKind::Atomic, None)
    }
    /// A compound state whose initial child is `initial` (a child's name, not a path).
    pub fn compound(&mut self, path: &str, initial: &str) -> &mut StateDecl<A> {
        self.decl(path, StateKind::Compound, Some(initial))
    }
    /// A parallel state: each child is a region, all active together.
    pub fn parallel(&mut self, path: &str) -> &mut StateDecl<A> {
        self.decl(path, StateKind::Parallel, None)
    }
    /// A final state.
    pub fn final_state(&mut self, path: &str) -> &mut StateDecl<A> {
        self.decl(path, StateKind::Final, None)
    }
    /// A shallow history pseudo-state (remembers the parent's active child).
    pub fn shallow_history(&mut self, path: &str) -> &mut StateDecl<A> {
        self.decl(path, StateKind::History { deep: false }, None)
    }
    /// A deep history pseudo-state (remembers the parent's active leaves).
    pub fn deep_history(&mut self, path: &str) -> &mut StateDecl<A> {
        self.decl(path, StateKind::History { deep: true }, None)
    }

    fn transition(&mut self, source: &str, trigger: Trigger) -> &mut TransitionDecl<C, E, A> {
        self.transitions.push(TransitionDecl {
            source: source.to_string(),
            trigger,
            guard: None,
            target: None,
            internal: false,
            actions: Vec::new(),
        });
        let last = self.transitions.len() - 1;
        &mut self.transitions[last]
    }

    /// A transition from `source` on the event `event` ([`ANY_EVENT`] for every event).
    pub fn on(&mut self, source: &str, event: &str) -> &mut TransitionDecl<C, E, A> {
        self.transition(source, Trigger::Event(event.to_string()))
    }
    /// A timer transition: `delay` after `source` was entered (event `timer:<label>`); cancelled
    /// when `source` is left first.
    pub fn after(
        &mut self,
        source: &str,
        delay: Duration,
        label: &str,
    ) -> &mut TransitionDecl<C, E, A> {
        self.transition(
            source,
            Trigger::After {
                delay,
                label: label.to_string(),
            },
        )
    }
    /// An eventless transition (give it a guard, or it is taken at once).
    pub fn always(&mut self, source: &str) -> &mut TransitionDecl<C, E, A> {
        self.transition(source, Trigger::Eventless)
    }

    /// Checks the definition.
    pub fn build(self) -> Result<Definition<C, E, A>, DefinitionError> {
        if self.states.is_empty() {
            return Err(DefinitionError::Empty);
        }
        let mut states: Vec<StateNode<A>> = vec![StateNode {
            name: String::new(),
            path: String::new(),
            parent: None,
            children: Vec::new(),
            kind: StateKind::Compound,
            initial: None,
            history_default: None,
            entry: Vec::new(),
            exit: Vec::new(),
            transitions: Vec::new(),
            order: 0,
        }];
        let mut by_path: HashMap<String, StateId> = HashMap::new();
        for d in &self.states {
            let segs: Vec<&str> = d.path.split('/').collect();
            if segs.iter().any(|s| s.is_empty() || s.contains('*')) {
                return Err(DefinitionError::BadName(d.path.clone()));
            }
            if by_path.contains_key(&d.path) {
                return Err(DefinitionError::Duplicate(d.path.clone()));
            }
            let parent = if segs.len() == 1 {
                0
            } else {
                let pp = segs[..segs.len() - 1].join("/");
                *by_path
                    .get(&pp)
                    .ok_or_else(|| DefinitionError::UnknownParent {
                        state: d.path.clone(),
                        parent: pp.clone(),
                    })?
            };
            if !matches!(
                states[parent].kind,
                StateKind::Compound | StateKind::Parallel
            ) {
                return Err(DefinitionError::ParentCannotHaveChildren(d.path.clone()));
            }
            if matches!(d.kind, StateKind::History { .. }) && parent == 0 {
                return Err(DefinitionError::HistoryOutsideCompound(d.path.clone()));
            }
            let id = states.len();
            states.push(StateNode {
                name: segs[segs.len() - 1].to_string(),
                path: d.path.clone(),
                parent: Some(parent),
                children: Vec::new(),
                kind: d.kind,
                initial: None,
                history_default: None,
                entry: d.entry.clone(),
                exit: d.exit.clone(),
                transitions: Vec::new(),
                order: 0,
            });
            states[parent].children.push(id);
            by_path.insert(d.path.clone(), id);
        }
        // Initial children.
        let root_initial = self
            .root_initial
            .as_deref()
            .ok_or(DefinitionError::NoRootInitial)?;
        let ri = *by_path
            .get(root_initial)
            .ok_or(DefinitionError::NoRootInitial)?;
        if states[ri].parent != Some(0) || matches!(states[ri].kind, StateKind::History { .. }) {
            return Err(DefinitionError::NoRootInitial);
        }
        states[0].initial = Some(ri);
        for (k, d) in self.states.iter().enumerate() {
            let id = k + 1;
            match d.kind {
                StateKind::Compound => {
                    let Some(init) = &d.initial else {
                        return Err(DefinitionError::NoInitial(d.path.clone()));
                    };
                    let child = states[id].children.iter().copied().find(|&c| {
                        states[c].name == *init
                            && !matches!(states[c].kind, StateKind::History { .. })
                    });
                    match child {
                        Some(c) => states[id].initial = Some(c),
                        None if states[id].children.is_empty() => {
                            return Err(DefinitionError::NoInitial(d.path.clone()));
                        }
                        None => {
                            return Err(DefinitionError::BadInitial {
                                state: d.path.clone(),
                                initial: init.clone(),
                            });
                        }
                    }
                }
                StateKind::Parallel
                    if !states[id]
                        .children
                        .iter()
                        .any(|&c| !matches!(states[c].kind, StateKind::History { .. })) =>
                {
                    return Err(DefinitionError::EmptyParallel(d.path.clone()));
                }
                StateKind::History { .. } => {
                    if let Some(def) = &d.history_default {
                        let parent = states[id].parent.unwrap_or(0);
                        let ok = by_path.get(def).copied().filter(|&t| {
                            let mut p = states[t].parent;
                            while let Some(x) = p {
                                if x == parent {
                                    return !matches!(states[t].kind, StateKind::History { .. });
                                }
                                p = states[x].parent;
                            }
                            false
                        });
                        match ok {
                            Some(t) => states[id].history_default = Some(t),
                            None => {
                                return Err(DefinitionError::BadHistoryDefault {
                                    state: d.path.clone(),
                                    default: def.clone(),
                                });
                            }
                        }
                    }
                }
                _ => {}
            }
        }
        // Document order (preorder).
        let mut order = 0;
        let mut stack = vec![0];
        while let Some(s) = stack.pop() {
            states[s].order = order;
            order += 1;
            for &c in states[s].children.iter().rev() {
                stack.push(c);
            }
        }
        let mut def = Definition {
            name: self.name,
            states,
            transitions: Vec::new(),
            by_path,
        };
        for t in self.transitions {
            let source = def
                .id(&t.source)
                .ok_or_else(|| DefinitionError::UnknownSource(t.source.clone()))?;
            let target = match &t.target {
                None => None,
                Some(p) => Some(def.id(p).ok_or_else(|| DefinitionError::UnknownTarget {
                    from: t.source.clone(),
                    trigger: t.trigger.to_string(),
                    target: p.clone(),
                })?),
            };
            if t.internal {
                match target {
                    Some(tg) if def.is_descendant(tg, source) => {}
                    _ => return Err(DefinitionError::BadInternal(t.source.clone())),
                }
            }
            if let Trigger::After { delay, .. } = &t.trigger
                && delay.is_zero()
            {
                return Err(DefinitionError::ZeroTimer(t.source.clone()));
            }
            let idx = def.transitions.len();
            def.states[source].transitions.push(idx);
            def.transitions.push(TransitionNode {
                source,
                trigger: t.trigger,
                guard: t.guard,
                target,
                internal: t.internal,
                actions: t.actions,
            });
        }
        Ok(def)
    }
}
