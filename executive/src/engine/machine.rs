//! A running machine: the configuration, the history, the timers, and the step algorithm.

use std::collections::{BTreeSet, HashMap, VecDeque};
use std::sync::Arc;
use std::time::Duration;

use super::{ANY_EVENT, Definition, Event, StateId, StateKind, Trigger};

/// Runs the actions of a machine and holds what its guards read.
pub trait Context<A, E> {
    /// Runs one action, caused by `event`.
    fn run(&mut self, action: &A, event: &Event<E>);
}

/// Microsteps allowed in one step before the engine stops (an eventless loop in the
/// definition); see [`Machine::livelocks`].
const MAX_MICROSTEPS: usize = 1000;

/// What one step did: the triggering event, the states left and entered, the actions run, and
/// the configuration after it.
#[derive(Debug, Clone, PartialEq)]
pub struct Step<A> {
    /// The external event (`start`, `timer:<label>`, or the event's name).
    pub event: String,
    /// States left, innermost first (over every microstep of the step).
    pub exited: Vec<String>,
    /// States entered, outermost first.
    pub entered: Vec<String>,
    /// Actions run, in order (exit actions, transition actions, entry actions, per microstep).
    pub actions: Vec<A>,
    /// Active leaves after the step, sorted.
    pub active: Vec<String>,
    /// Every active state after the step (leaves and ancestors), sorted.
    pub configuration: Vec<String>,
    /// No transition matched: nothing happened (counted in [`Machine::ignored`]).
    pub ignored: bool,
    /// The machine's step number (unchanged by an ignored event).
    pub step: u64,
}

#[derive(Debug, Clone, Copy)]
struct Timer {
    deadline: Duration,
    seq: u64,
    transition: usize,
}

/// A running instance of a [`Definition`].
#[derive(Debug)]
pub struct Machine<C, E, A> {
    def: Arc<Definition<C, E, A>>,
    config: BTreeSet<StateId>,
    history: HashMap<StateId, Vec<StateId>>,
    timers: Vec<Timer>,
    timer_seq: u64,
    now: Duration,
    steps: u64,
    ignored: u64,
    livelocks: u64,
    started: bool,
    finished: bool,
}

/// What a microstep collects.
struct Collect<A> {
    exited: Vec<String>,
    entered: Vec<String>,
    actions: Vec<A>,
    internal: VecDeque<String>,
}

impl<C, E: Clone + Default, A: Clone> Machine<C, E, A>
where
    C: Context<A, E>,
{
    /// A machine, not started yet.
    pub fn new(def: Arc<Definition<C, E, A>>) -> Self {
        Machine {
            def,
            config: BTreeSet::new(),
            history: HashMap::new(),
            timers: Vec::new(),
            timer_seq: 0,
            now: Duration::ZERO,
            steps: 0,
            ignored: 0,
            livelocks: 0,
            started: false,
            finished: false,
        }
    }

    /// The definition.
    pub fn definition(&self) -> &Arc<Definition<C, E, A>> {
        &self.def
    }

    /// Enters the initial configuration at `now` (event `start`). Calling it again does
    /// nothing (an ignored step).
    pub fn start(&mut self, ctx: &mut C, now: Duration) -> Step<A> {
        let event = Event::named("start");
        self.now = self.now.max(now);
        if self.started {
            self.ignored += 1;
            return self.report(&event.name, None);
        }
        self.started = true;
        let mut col = self.new_collect();
        let mut to_enter = BTreeSet::new();
        let mut default_entry = BTreeSet::new();
        self.add_descendants(0, &mut to_enter, &mut default_entry);
        to_enter.remove(&0);
        self.enter_set(ctx, &event, to_enter, &mut col);
        self.run_to_completion(ctx, &event, &mut col);
        self.steps += 1;
        self.report(&event.name, Some(col))
    }

    /// Processes one external event at `now` (which should be at or after the last `now`; an
    /// earlier one is taken as the last). Timers due before `now` are NOT fired: call
    /// [`Machine::advance`] first. Before [`Machine::start`] or after the machine finished, every
    /// event is ignored.
    pub fn send(&mut self, ctx: &mut C, event: Event<E>, now: Duration) -> Step<A> {
        self.now = self.now.max(now);
        if !self.started || self.finished {
            self.ignored += 1;
            return self.report(&event.name, None);
        }
        let enabled = self.select(ctx, &event, |t| match t {
            Trigger::Event(n) => n == &event.name || n == ANY_EVENT,
            _ => false,
        });
        self.macrostep(ctx, &event, enabled)
    }

    /// Fires every timer due at `now` (deadline `<= now`), earliest first, each as its own step
    /// taken at its deadline; moves the machine's time to `now`.
    pub fn advance(&mut self, ctx: &mut C, now: Duration) -> Vec<Step<A>> {
        let mut steps = Vec::new();
        loop {
            let due = self
                .timers
                .iter()
                .enumerate()
                .filter(|(_, t)| t.deadline <= now)
                .min_by_key(|(_, t)| (t.deadline, t.seq))
                .map(|(i, t)| (i, *t));
            let Some((i, timer)) = due else { break };
            self.timers.swap_remove(i);
            self.now = self.now.max(timer.deadline);
            let label = match &self.def.transitions[timer.transition].trigger {
                Trigger::After { label, .. } => label.clone(),
                _ => String::new(),
            };
            let event = Event::named(format!("timer:{label}"));
            if self.finished {
                continue;
            }
            let t = &self.def.transitions[timer.transition];
            let enabled = match &t.guard {
                Some(g) if !(g.test)(ctx, &event) => Vec::new(),
                _ => vec![timer.transition],
            };
            steps.push(self.macrostep(ctx, &event, enabled));
        }
        self.now = self.now.max(now);
        steps
    }

    /// The earliest pending timer deadline, if any.
    pub fn next_deadline(&self) -> Option<Duration> {
        self.timers.iter().map(|t| t.deadline).min()
    }

    /// Pending timers as `(state path, label, deadline)`, earliest first.
    pub fn pending_timers(&self) -> Vec<(String, String, Duration)> {
        let mut v: Vec<_> = self
            .timers
            .iter()
            .map(|t| {
                let tr = &self.def.transitions[t.transition];
                let label = match &tr.trigger {
                    Trigger::After { label, .. } => label.clone(),
                    _ => String::new(),
                };
                (self.def.states[tr.source].path.clone(), label, t.deadline)
            })
            .collect();
        v.sort_by_key(|x| x.2);
        v
    }

    /// Whether the state at `path` is active.
    pub fn is_active(&self, path: &str) -> bool {
        self.def.id(path).is_some_and(|i| self.config.contains(&i))
    }
    /// Every active state, sorted.
    pub fn configuration(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .config
            .iter()
            .map(|&s| self.def.states[s].path.clone())
            .collect();
        v.sort();
        v
    }
    /// The active leaves, sorted.
    pub fn active_leaves(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .config
            .iter()
            .filter(|&&s| {
                !self.def.states[s]
                    .children
                    .iter()
                    .any(|c| self.config.contains(c))
            })
            .map(|&s| self.def.states[s].path.clone())
            .collect();
        v.sort();
        v
    }
    /// Steps taken (the start included; ignored events not).
    pub fn steps(&self) -> u64 {
        self.steps
    }
    /// Events that matched no transition.
    pub fn ignored(&self) -> u64 {
        self.ignored
    }
    /// Steps cut short because eventless transitions kept firing (a definition bug).
    pub fn livelocks(&self) -> u64 {
        self.livelocks
    }
    /// Whether a final child of the root was entered.
    pub fn is_finished(&self) -> bool {
        self.finished
    }
    /// The machine's time: the latest `now` it was given.
    pub fn now(&self) -> Duration {
        self.now
    }

    // --- the algorithm (SCXML's, single target per transition) ---

    fn new_collect(&self) -> Collect<A> {
        Collect {
            exited: Vec::new(),
            entered: Vec::new(),
            actions: Vec::new(),
            internal: VecDeque::new(),
        }
    }

    fn report(&self, event: &str, col: Option<Collect<A>>) -> Step<A> {
        let ignored = col.is_none();
        let col = col.unwrap_or_else(|| self.new_collect());
        Step {
            event: event.to_string(),
            exited: col.exited,
            entered: col.entered,
            actions: col.actions,
            active: self.active_leaves(),
            configuration: self.configuration(),
            ignored,
            step: self.steps,
        }
    }

    fn macrostep(&mut self, ctx: &mut C, event: &Event<E>, enabled: Vec<usize>) -> Step<A> {
        if enabled.is_empty() {
            self.ignored += 1;
            return self.report(&event.name, None);
        }
        let mut col = self.new_collect();
        self.microstep(ctx, event, &enabled, &mut col);
        self.run_to_completion(ctx, event, &mut col);
        self.steps += 1;
        self.report(&event.name, Some(col))
    }

    /// Eventless transitions and internal events until none is enabled.
    fn run_to_completion(&mut self, ctx: &mut C, cause: &Event<E>, col: &mut Collect<A>) {
        for _ in 0..MAX_MICROSTEPS {
            if self.finished {
                return;
            }
            let enabled = self.select(ctx, cause, |t| matches!(t, Trigger::Eventless));
            if !enabled.is_empty() {
                self.microstep(ctx, cause, &enabled, col);
                continue;
            }
            let Some(name) = col.internal.pop_front() else {
                return;
            };
            let internal = Event::new(name, cause.payload.clone());
            let enabled = self.select(ctx, &internal, |t| match t {
                Trigger::Event(n) => n == &internal.name,
                _ => false,
            });
            if !enabled.is_empty() {
                self.microstep(ctx, &internal, &enabled, col);
            }
        }
        self.livelocks += 1;
    }

    /// Active atomic states in document order.
    fn atomic_config(&self) -> Vec<StateId> {
        let mut v: Vec<StateId> = self
            .config
            .iter()
            .copied()
            .filter(|&s| {
                !self.def.states[s]
                    .children
                    .iter()
                    .any(|c| self.config.contains(c))
            })
            .collect();
        v.sort_by_key(|&s| self.def.states[s].order);
        v
    }

    /// The enabled transitions for `event`, conflicts removed (SCXML selectTransitions).
    fn select(&self, ctx: &C, event: &Event<E>, matches: impl Fn(&Trigger) -> bool) -> Vec<usize> {
        let mut enabled: Vec<usize> = Vec::new();
        for atomic in self.atomic_config() {
            let mut chain = vec![atomic];
            chain.extend(self.def.proper_ancestors(atomic, Some(0)));
            'chain: for s in chain {
                for &ti in &self.def.states[s].transitions {
                    let t = &self.def.transitions[ti];
                    if !matches(&t.trigger) {
                        continue;
                    }
                    if let Some(g) = &t.guard
                        && !(g.test)(ctx, event)
                    {
                        continue;
                    }
                    if !enabled.contains(&ti) {
                        enabled.push(ti);
                    }
                    break 'chain;
                }
            }
        }
        self.remove_conflicts(enabled)
    }

    fn remove_conflicts(&self, enabled: Vec<usize>) -> Vec<usize> {
        let mut filtered: Vec<usize> = Vec::new();
        for t1 in enabled {
            let x1 = self.exit_set(t1);
            let mut preempted = false;
            let mut to_remove = Vec::new();
            for &t2 in &filtered {
                let x2 = self.exit_set(t2);
                if x1.intersection(&x2).next().is_some() {
                    let s1 = self.def.transitions[t1].source;
                    let s2 = self.def.transitions[t2].source;
                    if self.def.is_descendant(s1, s2) {
                        to_remove.push(t2);
                    } else {
                        preempted = true;
                        break;
                    }
                }
            }
            if !preempted {
                filtered.retain(|t| !to_remove.contains(t));
                filtered.push(t1);
            }
        }
        filtered
    }

    /// The states a transition targets, history resolved.
    fn effective_targets(&self, ti: usize) -> Vec<StateId> {
        let Some(target) = self.def.transitions[ti].target else {
            return Vec::new();
        };
        let mut out = Vec::new();
        let mut todo = vec![target];
        while let Some(s) = todo.pop() {
            if let StateKind::History { .. } = self.def.states[s].kind {
                match self.history.get(&s) {
                    Some(h) => out.extend(h.iter().copied()),
                    None => todo.extend(self.history_default(s)),
                }
            } else {
                out.push(s);
            }
        }
        out
    }

    fn history_default(&self, h: StateId) -> Vec<StateId> {
        let st = &self.def.states[h];
        if let Some(d) = st.history_default {
            return vec![d];
        }
        let parent = st.parent.unwrap_or(0);
        let p = &self.def.states[parent];
        match p.kind {
            StateKind::Parallel => p
                .children
                .iter()
                .copied()
                .filter(|&c| !matches!(self.def.states[c].kind, StateKind::History { .. }))
                .collect(),
            _ => p.initial.into_iter().collect(),
        }
    }

    /// The transition domain: the state whose active descendants the transition exits.
    fn domain(&self, ti: usize) -> Option<StateId> {
        let t = &self.def.transitions[ti];
        let targets = self.effective_targets(ti);
        if targets.is_empty() {
            return None;
        }
        let src = t.source;
        if t.internal
            && self.def.states[src].kind == StateKind::Compound
            && targets.iter().all(|&s| self.def.is_descendant(s, src))
        {
            return Some(src);
        }
        // Least common compound ancestor of the source and the targets.
        for anc in self.def.proper_ancestors(src, None) {
            if anc != 0 && self.def.states[anc].kind != StateKind::Compound {
                continue;
            }
            if targets.iter().all(|&s| self.def.is_descendant(s, anc)) {
                return Some(anc);
            }
        }
        Some(0)
    }

    fn exit_set(&self, ti: usize) -> BTreeSet<StateId> {
        match self.domain(ti) {
            None => BTreeSet::new(),
            Some(d) => self
                .config
                .iter()
                .copied()
                .filter(|&s| self.def.is_descendant(s, d))
                .collect(),
        }
    }

    fn microstep(
        &mut self,
        ctx: &mut C,
        event: &Event<E>,
        enabled: &[usize],
        col: &mut Collect<A>,
    ) {
        // Exit.
        let mut exit: BTreeSet<StateId> = BTreeSet::new();
        for &t in enabled {
            exit.extend(self.exit_set(t));
        }
        let mut exit: Vec<StateId> = exit.into_iter().collect();
        exit.sort_by_key(|&s| std::cmp::Reverse(self.def.states[s].order));
        // History is recorded before anything is left.
        for &s in &exit {
            for &h in &self.def.states[s].children {
                if let StateKind::History { deep } = self.def.states[h].kind {
                    let value: Vec<StateId> = if deep {
                        self.config
                            .iter()
                            .copied()
                            .filter(|&x| {
                                self.def.is_descendant(x, s)
                                    && !self.def.states[x]
                                        .children
                                        .iter()
                                        .any(|c| self.config.contains(c))
                            })
                            .collect()
                    } else {
                        self.config
                            .iter()
                            .copied()
                            .filter(|&x| self.def.states[x].parent == Some(s))
                            .collect()
                    };
                    self.history.insert(h, value);
                }
            }
        }
        let def = self.def.clone();
        for &s in &exit {
            let st = &def.states[s];
            for a in &st.exit {
                ctx.run(a, event);
                col.actions.push(a.clone());
            }
            self.timers
                .retain(|t| def.transitions[t.transition].source != s);
            self.config.remove(&s);
            col.exited.push(st.path.clone());
        }
        // Transition actions.
        let mut ordered = enabled.to_vec();
        ordered.sort_by_key(|&t| def.states[def.transitions[t].source].order);
        for &t in &ordered {
            for a in &def.transitions[t].actions {
                ctx.run(a, event);
                col.actions.push(a.clone());
            }
        }
        // Enter.
        let mut to_enter = BTreeSet::new();
        let mut default_entry = BTreeSet::new();
        for &t in &ordered {
            if let Some(target) = def.transitions[t].target {
                self.add_descendants(target, &mut to_enter, &mut default_entry);
            }
            let domain = self.domain(t);
            for s in self.effective_targets(t) {
                self.add_ancestors(s, domain, &mut to_enter, &mut default_entry);
            }
        }
        self.enter_set(ctx, event, to_enter, col);
    }

    fn enter_set(
        &mut self,
        ctx: &mut C,
        event: &Event<E>,
        to_enter: BTreeSet<StateId>,
        col: &mut Collect<A>,
    ) {
        let def = self.def.clone();
        let mut enter: Vec<StateId> = to_enter.into_iter().collect();
        enter.sort_by_key(|&s| def.states[s].order);
        for s in enter {
            let st = &def.states[s];
            if matches!(st.kind, StateKind::History { .. }) || self.config.contains(&s) {
                continue;
            }
            self.config.insert(s);
            col.entered.push(st.path.clone());
            for &ti in &st.transitions {
                if let Trigger::After { delay, .. } = def.transitions[ti].trigger {
                    self.timer_seq += 1;
                    self.timers.push(Timer {
                        deadline: self.now + delay,
                        seq: self.timer_seq,
                        transition: ti,
                    });
                }
            }
            for a in &st.entry {
                ctx.run(a, event);
                col.actions.push(a.clone());
            }
            if st.kind == StateKind::Final {
                let parent = st.parent.unwrap_or(0);
                if parent == 0 {
                    self.finished = true;
                    self.timers.clear();
                } else {
                    col.internal
                        .push_back(format!("done.state.{}", def.states[parent].path));
                    if let Some(gp) = def.states[parent].parent
                        && gp != 0
                        && def.states[gp].kind == StateKind::Parallel
                        && self.in_final(gp)
                    {
                        col.internal
                            .push_back(format!("done.state.{}", def.states[gp].path));
                    }
                }
            }
        }
    }

    fn in_final(&self, s: StateId) -> bool {
        let st = &self.def.states[s];
        match st.kind {
            StateKind::Compound => st
                .children
                .iter()
                .any(|&c| self.def.states[c].kind == StateKind::Final && self.config.contains(&c)),
            StateKind::Parallel => st
                .children
                .iter()
                .filter(|&&c| !matches!(self.def.states[c].kind, StateKind::History { .. }))
                .all(|&c| self.in_final(c)),
            _ => false,
        }
    }

    fn add_descendants(
        &self,
        s: StateId,
        to_enter: &mut BTreeSet<StateId>,
        default_entry: &mut BTreeSet<StateId>,
    ) {
        let st = &self.def.states[s];
        if let StateKind::History { .. } = st.kind {
            let parent = st.parent.unwrap_or(0);
            let targets = match self.history.get(&s) {
                Some(h) => h.clone(),
                None => self.history_default(s),
            };
            for &t in &targets {
                self.add_descendants(t, to_enter, default_entry);
            }
            for &t in &targets {
                self.add_ancestors(t, Some(parent), to_enter, default_entry);
            }
            return;
        }
        to_enter.insert(s);
        match st.kind {
            StateKind::Compound => {
                default_entry.insert(s);
                if let Some(init) = st.initial {
                    self.add_descendants(init, to_enter, default_entry);
                    self.add_ancestors(init, Some(s), to_enter, default_entry);
                }
            }
            StateKind::Parallel => {
                for &c in &st.children {
                    if matches!(self.def.states[c].kind, StateKind::History { .. }) {
                        continue;
                    }
                    if !to_enter
                        .iter()
                        .any(|&x| x == c || self.def.is_descendant(x, c))
                    {
                        self.add_descendants(c, to_enter, default_entry);
                    }
                }
            }
            _ => {}
        }
    }

    fn add_ancestors(
        &self,
        s: StateId,
        stop: Option<StateId>,
        to_enter: &mut BTreeSet<StateId>,
        default_entry: &mut BTreeSet<StateId>,
    ) {
        for anc in self.def.proper_ancestors(s, stop) {
            if anc == 0 {
                break;
            }
            to_enter.insert(anc);
            if self.def.states[anc].kind == StateKind::Parallel {
                for &c in &self.def.states[anc].children {
                    if matches!(self.def.states[c].kind, StateKind::History { .. }) {
                        continue;
                    }
                    if !to_enter
                        .iter()
                        .any(|&x| x == c || self.def.is_descendant(x, c))
                    {
                        self.add_descendants(c, to_enter, default_entry);
                    }
                }
            }
        }
    }
}
