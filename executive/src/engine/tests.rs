use super::*;
use std::time::Duration;

/// Records every action; `allow` is what the guards read.
#[derive(Debug, Default)]
struct Ctx {
    log: Vec<String>,
    allow: bool,
    payloads: Vec<i32>,
}

impl Context<String, i32> for Ctx {
    fn run(&mut self, a: &String, e: &Event<i32>) {
        self.log.push(a.clone());
        self.payloads.push(e.payload);
    }
}

type B = Builder<Ctx, i32, String>;
type M = Machine<Ctx, i32, String>;

fn s(x: &str) -> String {
    x.to_string()
}

fn secs(x: f64) -> Duration {
    Duration::from_secs_f64(x)
}

/// Adds entry/exit actions `+path` / `-path` to a state.
fn traced(d: &mut StateDecl<String>, path: &str) {
    d.entry(format!("+{path}")).exit(format!("-{path}"));
}

fn machine(b: B) -> (M, Ctx) {
    let def = b.build().expect("valid definition");
    let mut m = Machine::new(Arc::new(def));
    let mut c = Ctx::default();
    m.start(&mut c, Duration::ZERO);
    (m, c)
}

fn ev(name: &str) -> Event<i32> {
    Event::named(name)
}

/// a { a1 { a11, a12 }, a2 }, b { b1 }
fn nested() -> B {
    let mut b = B::new("nested");
    b.root_initial("a");
    for (p, init) in [("a", Some("a1")), ("a/a1", Some("a11"))] {
        let d = b.compound(p, init.unwrap_or_default());
        traced(d, p);
    }
    for p in ["a/a1/a11", "a/a1/a12", "a/a2"] {
        traced(b.atomic(p), p);
    }
    traced(b.compound("b", "b1"), "b");
    traced(b.atomic("b/b1"), "b/b1");
    b.on("a/a1/a11", "go").to("b/b1").action(s("t:go"));
    b.on("a/a1", "side").to("a/a2");
    b.on("a", "self").to("a").action(s("t:self"));
    b.on("a", "inner").to("a/a2").internal();
    b.on("a", "noop").action(s("t:noop"));
    b
}

#[test]
fn start_enters_outermost_first_with_initial_children() {
    let (m, c) = machine(nested());
    assert_eq!(c.log, ["+a", "+a/a1", "+a/a1/a11"]);
    assert_eq!(m.active_leaves(), ["a/a1/a11"]);
    assert_eq!(m.configuration(), ["a", "a/a1", "a/a1/a11"]);
    assert_eq!(m.steps(), 1);
}

#[test]
fn exits_innermost_first_then_transition_actions_then_entries_outermost_first() {
    let (mut m, mut c) = machine(nested());
    c.log.clear();
    let step = m.send(&mut c, ev("go"), secs(1.0));
    assert_eq!(step.exited, ["a/a1/a11", "a/a1", "a"]);
    assert_eq!(step.entered, ["b", "b/b1"]);
    assert_eq!(c.log, ["-a/a1/a11", "-a/a1", "-a", "t:go", "+b", "+b/b1"]);
    assert_eq!(step.actions, c.log);
    assert_eq!(step.active, ["b/b1"]);
    assert_eq!(step.configuration, ["b", "b/b1"]);
    assert_eq!(step.step, 2);
    assert!(!step.ignored);
}

#[test]
fn the_lca_bounds_what_is_left() {
    let (mut m, mut c) = machine(nested());
    c.log.clear();
    // a/a1 -> a/a2: the domain is `a`, which stays.
    let step = m.send(&mut c, ev("side"), secs(1.0));
    assert_eq!(step.exited, ["a/a1/a11", "a/a1"]);
    assert_eq!(step.entered, ["a/a2"]);
    assert_eq!(c.log, ["-a/a1/a11", "-a/a1", "+a/a2"]);
}

#[test]
fn external_self_transition_leaves_and_reenters_internal_does_not() {
    let (mut m, mut c) = machine(nested());
    let step = m.send(&mut c, ev("self"), secs(1.0));
    assert_eq!(step.exited, ["a/a1/a11", "a/a1", "a"]);
    assert_eq!(step.entered, ["a", "a/a1", "a/a1/a11"]);
    let step = m.send(&mut c, ev("inner"), secs(2.0));
    assert_eq!(step.exited, ["a/a1/a11", "a/a1"]);
    assert_eq!(step.entered, ["a/a2"]);
    assert!(!step.exited.contains(&s("a")));
    // A targetless transition runs its actions only.
    c.log.clear();
    let step = m.send(&mut c, ev("noop"), secs(3.0));
    assert!(step.exited.is_empty() && step.entered.is_empty() && !step.ignored);
    assert_eq!(c.log, ["t:noop"]);
}

#[test]
fn unmatched_events_are_ignored_and_counted() {
    let (mut m, mut c) = machine(nested());
    let before = m.configuration();
    let step = m.send(&mut c, ev("nobody_listens"), secs(1.0));
    assert!(step.ignored);
    assert!(step.exited.is_empty() && step.entered.is_empty() && step.actions.is_empty());
    assert_eq!(m.ignored(), 1);
    assert_eq!(m.configuration(), before);
    assert_eq!(step.step, 1, "an ignored event is not a step");
    m.send(&mut c, ev("also_nothing"), secs(1.0));
    assert_eq!(m.ignored(), 2);
}

/// p (parallel) { left { l1, l2 }, right { r1, r2 } }, out
fn parallel() -> B {
    let mut b = B::new("par");
    b.root_initial("p");
    traced(b.parallel("p"), "p");
    traced(b.compound("p/left", "l1"), "p/left");
    traced(b.atomic("p/left/l1"), "p/left/l1");
    traced(b.atomic("p/left/l2"), "p/left/l2");
    traced(b.compound("p/right", "r1"), "p/right");
    traced(b.atomic("p/right/r1"), "p/right/r1");
    traced(b.atomic("p/right/r2"), "p/right/r2");
    b.atomic("out");
    b.on("p/left/l1", "tick")
        .to("p/left/l2")
        .action(s("t:left"));
    b.on("p/right/r1", "tick")
        .to("p/right/r2")
        .action(s("t:right"));
    b.on("p/right/r2", "leave").to("out");
    b.on("p/left/l2", "leave_left").to("p/left/l1");
    b
}

#[test]
fn parallel_regions_are_entered_together_and_both_step_on_one_event() {
    let (mut m, mut c) = machine(parallel());
    assert_eq!(
        c.log,
        ["+p", "+p/left", "+p/left/l1", "+p/right", "+p/right/r1"]
    );
    assert_eq!(m.active_leaves(), ["p/left/l1", "p/right/r1"]);
    c.log.clear();
    let step = m.send(&mut c, ev("tick"), secs(1.0));
    assert_eq!(step.active, ["p/left/l2", "p/right/r2"]);
    assert_eq!(step.exited, ["p/right/r1", "p/left/l1"]);
    assert_eq!(step.entered, ["p/left/l2", "p/right/r2"]);
    // Exits of both, then both transitions' actions in document order, then entries.
    assert_eq!(
        c.log,
        [
            "-p/right/r1",
            "-p/left/l1",
            "t:left",
            "t:right",
            "+p/left/l2",
            "+p/right/r2"
        ]
    );
    assert_eq!(m.steps(), 2, "one event, one step");
    // Leaving from one region leaves the whole parallel state, innermost and last region first.
    c.log.clear();
    let step = m.send(&mut c, ev("leave"), secs(2.0));
    assert_eq!(
        step.exited,
        ["p/right/r2", "p/right", "p/left/l2", "p/left", "p"]
    );
    assert_eq!(step.active, ["out"]);
}

#[test]
fn a_transition_in_one_region_leaves_the_other_alone() {
    let (mut m, mut c) = machine(parallel());
    m.send(&mut c, ev("tick"), secs(1.0));
    let step = m.send(&mut c, ev("leave_left"), secs(2.0));
    assert_eq!(step.exited, ["p/left/l2"]);
    assert_eq!(step.entered, ["p/left/l1"]);
    assert_eq!(step.active, ["p/left/l1", "p/right/r2"]);
}

#[test]
fn guards_choose_and_a_deeper_transition_wins_over_its_ancestor() {
    let mut b = B::new("guards");
    b.root_initial("a");
    b.compound("a", "a1");
    b.atomic("a/a1");
    b.atomic("a/yes");
    b.atomic("a/no");
    b.atomic("a/outer");
    b.on("a/a1", "ask")
        .guard("allowed", |c, _| c.allow)
        .to("a/yes");
    b.on("a/a1", "ask").to("a/no");
    b.on("a", "ask").to("a/outer");
    b.on("a/yes", "big")
        .guard("payload>10", |_, e| e.payload > 10)
        .to("a/a1");
    let def = Arc::new(b.build().unwrap());

    let mut c = Ctx::default();
    let mut m = Machine::new(def.clone());
    m.start(&mut c, Duration::ZERO);
    assert_eq!(m.send(&mut c, ev("ask"), secs(1.0)).active, ["a/no"]);

    let mut c = Ctx {
        allow: true,
        ..Ctx::default()
    };
    let mut m = Machine::new(def);
    m.start(&mut c, Duration::ZERO);
    assert_eq!(m.send(&mut c, ev("ask"), secs(1.0)).active, ["a/yes"]);
    // From a/yes only the ancestor's transition matches `ask`.
    assert!(m.send(&mut c, Event::new("big", 3), secs(2.0)).ignored);
    assert_eq!(
        m.send(&mut c, Event::new("big", 11), secs(3.0)).active,
        ["a/a1"]
    );
}

/// g { h (history), x { x1, x2 }, y }, other
fn history(deep: bool) -> B {
    let mut b = B::new("history");
    b.root_initial("g");
    b.compound("g", "x");
    if deep {
        b.deep_history("g/h");
    } else {
        b.shallow_history("g/h");
    }
    b.compound("g/x", "x1");
    b.atomic("g/x/x1");
    b.atomic("g/x/x2");
    b.atomic("g/y");
    b.atomic("other");
    b.on("g/x/x1", "next").to("g/x/x2");
    b.on("g", "pause").to("other");
    b.on("other", "resume").to("g/h");
    b.on("g/x", "to_y").to("g/y");
    b
}

#[test]
fn shallow_history_restores_the_child_and_deep_history_the_leaves() {
    let (mut m, mut c) = machine(history(false));
    m.send(&mut c, ev("next"), secs(1.0));
    m.send(&mut c, ev("pause"), secs(2.0));
    let step = m.send(&mut c, ev("resume"), secs(3.0));
    assert_eq!(
        step.entered,
        ["g", "g/x", "g/x/x1"],
        "shallow: x, then its initial"
    );

    let (mut m, mut c) = machine(history(true));
    m.send(&mut c, ev("next"), secs(1.0));
    m.send(&mut c, ev("pause"), secs(2.0));
    let step = m.send(&mut c, ev("resume"), secs(3.0));
    assert_eq!(
        step.entered,
        ["g", "g/x", "g/x/x2"],
        "deep: the leaf itself"
    );
    // The history is updated on every exit.
    m.send(&mut c, ev("to_y"), secs(4.0));
    m.send(&mut c, ev("pause"), secs(5.0));
    assert_eq!(m.send(&mut c, ev("resume"), secs(6.0)).active, ["g/y"]);
}

#[test]
fn history_without_a_record_enters_the_default() {
    let mut b = history(false);
    b.root_initial("other");
    let (mut m, mut c) = machine(b);
    assert_eq!(m.send(&mut c, ev("resume"), secs(1.0)).active, ["g/x/x1"]);
}

#[test]
fn deep_history_restores_every_parallel_region() {
    let mut b = parallel();
    b.deep_history("p/h");
    b.on("out", "back").to("p/h");
    let (mut m, mut c) = machine(b);
    m.send(&mut c, ev("tick"), secs(1.0));
    m.send(&mut c, ev("leave_left"), secs(2.0));
    m.send(&mut c, ev("leave"), secs(3.0));
    let step = m.send(&mut c, ev("back"), secs(4.0));
    assert_eq!(step.active, ["p/left/l1", "p/right/r2"]);
}

/// wait --after 5s--> late; wait --poke--> busy --after 2s--> wait
fn timers() -> B {
    let mut b = B::new("timers");
    b.root_initial("wait");
    b.atomic("wait");
    b.atomic("late");
    b.atomic("busy");
    b.after("wait", secs(5.0), "patience")
        .to("late")
        .action(s("t:late"));
    b.on("wait", "poke").to("busy");
    b.after("busy", secs(2.0), "rest").to("wait");
    b
}

#[test]
fn a_timer_fires_exactly_at_its_deadline_on_the_virtual_clock() {
    let (mut m, mut c) = machine(timers());
    assert_eq!(m.next_deadline(), Some(secs(5.0)));
    assert!(m.advance(&mut c, secs(4.999_999)).is_empty());
    assert_eq!(m.active_leaves(), ["wait"]);
    let steps = m.advance(&mut c, secs(5.0));
    assert_eq!(steps.len(), 1);
    assert_eq!(steps[0].event, "timer:patience");
    assert_eq!(steps[0].active, ["late"]);
    assert_eq!(c.log, ["t:late"]);
    assert_eq!(m.next_deadline(), None);
}

#[test]
fn a_timer_is_cancelled_when_its_state_is_left_and_restarted_on_reentry() {
    let (mut m, mut c) = machine(timers());
    m.send(&mut c, ev("poke"), secs(3.0));
    assert_eq!(m.pending_timers(), [(s("busy"), s("rest"), secs(5.0))]);
    // At 5 s only `busy`'s timer is due; it re-enters `wait`, whose timer restarts at 5 s.
    let steps = m.advance(&mut c, secs(9.0));
    assert_eq!(steps.len(), 1, "{steps:?}");
    assert_eq!(steps[0].event, "timer:rest");
    assert_eq!(m.active_leaves(), ["wait"]);
    assert_eq!(m.next_deadline(), Some(secs(10.0)));
    // Chained timers in one advance are each taken at their own deadline.
    let (mut m, mut c) = machine(timers());
    m.send(&mut c, ev("poke"), secs(1.0));
    let steps = m.advance(&mut c, secs(100.0));
    let events: Vec<&str> = steps.iter().map(|s| s.event.as_str()).collect();
    assert_eq!(events, ["timer:rest", "timer:patience"]);
    assert_eq!(m.active_leaves(), ["late"]);
}

#[test]
fn eventless_transitions_and_done_events_complete_in_the_same_step() {
    let mut b = B::new("done");
    b.root_initial("work");
    b.parallel("work");
    b.compound("work/a", "a1");
    b.atomic("work/a/a1");
    b.final_state("work/a/fin");
    b.compound("work/b", "b1");
    b.atomic("work/b/b1");
    b.final_state("work/b/fin");
    b.atomic("after");
    b.final_state("end");
    b.on("work/a/a1", "a_done").to("work/a/fin");
    b.on("work/b/b1", "b_done").to("work/b/fin");
    b.on("work", "done.state.work")
        .to("after")
        .action(s("t:both_done"));
    b.always("after").guard("allowed", |c, _| c.allow).to("end");
    b.on("after", "allow").action(s("t:allow"));
    let (mut m, mut c) = machine(b);
    assert!(!m.send(&mut c, ev("a_done"), secs(1.0)).entered.is_empty());
    assert!(m.is_active("work"));
    let step = m.send(&mut c, ev("b_done"), secs(2.0));
    assert_eq!(step.active, ["after"]);
    assert!(c.log.contains(&s("t:both_done")));
    assert!(!m.is_finished());
    c.allow = true;
    // The eventless transition is checked after every step.
    let step = m.send(&mut c, ev("allow"), secs(3.0));
    assert_eq!(step.active, ["end"]);
    assert!(m.is_finished());
    assert!(m.send(&mut c, ev("allow"), secs(4.0)).ignored);
}

#[test]
fn an_eventless_loop_is_cut_and_counted() {
    let mut b = B::new("loop");
    b.root_initial("a");
    b.atomic("a");
    b.atomic("b");
    b.on("a", "go").to("b");
    b.always("b").to("a");
    b.always("a").guard("allowed", |c, _| c.allow).to("b");
    let (mut m, mut c) = machine(b);
    c.allow = true;
    m.send(&mut c, ev("go"), secs(1.0));
    assert_eq!(m.livelocks(), 1);
}

#[test]
fn payloads_reach_the_actions() {
    let mut b = B::new("payload");
    b.root_initial("a");
    b.atomic("a");
    b.on("a", "n").action(s("t:n"));
    let (mut m, mut c) = machine(b);
    m.send(&mut c, Event::new("n", 42), secs(1.0));
    assert_eq!(c.payloads, [42]);
}

#[test]
fn invalid_definitions_are_errors() {
    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.on("a", "e").to("nowhere");
    assert!(
        matches!(b.build(), Err(DefinitionError::UnknownTarget { target, .. }) if target == "nowhere")
    );

    let mut b = B::new("x");
    b.root_initial("a");
    b.compound("a", "missing");
    b.atomic("a/b");
    assert!(matches!(b.build(), Err(DefinitionError::BadInitial { .. })));

    let mut b = B::new("x");
    b.root_initial("a");
    b.compound("a", "b");
    assert_eq!(b.build().err(), Some(DefinitionError::NoInitial(s("a"))));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.atomic("a");
    assert_eq!(b.build().err(), Some(DefinitionError::Duplicate(s("a"))));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.atomic("q/b");
    assert!(matches!(
        b.build(),
        Err(DefinitionError::UnknownParent { .. })
    ));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.atomic("a/b");
    assert!(matches!(
        b.build(),
        Err(DefinitionError::ParentCannotHaveChildren(_))
    ));

    let mut b = B::new("x");
    b.atomic("a");
    assert_eq!(b.build().err(), Some(DefinitionError::NoRootInitial));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.atomic("a//b");
    assert!(matches!(b.build(), Err(DefinitionError::BadName(_))));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.on("ghost", "e").to("a");
    assert!(matches!(b.build(), Err(DefinitionError::UnknownSource(_))));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.atomic("b");
    b.on("a", "e").to("b").internal();
    assert!(matches!(b.build(), Err(DefinitionError::BadInternal(_))));

    let mut b = B::new("x");
    b.root_initial("a");
    b.atomic("a");
    b.after("a", Duration::ZERO, "now").to("a");
    assert!(matches!(b.build(), Err(DefinitionError::ZeroTimer(_))));
}

#[test]
fn events_before_start_are_ignored() {
    let def = Arc::new(timers().build().unwrap());
    let mut m = Machine::new(def);
    let mut c = Ctx::default();
    assert!(m.send(&mut c, ev("poke"), secs(1.0)).ignored);
    assert!(m.configuration().is_empty());
}

#[test]
fn mermaid_draws_states_regions_and_labelled_transitions() {
    let mut b = parallel();
    b.after("out", secs(2.0), "again")
        .to("p")
        .guard("allowed", |c, _| c.allow);
    b.final_state("fin");
    b.on("out", "quit").to("fin");
    let d = b.build().unwrap();
    let m = d.mermaid();
    assert!(m.starts_with("stateDiagram-v2\n"), "{m}");
    assert!(m.contains("[*] --> p\n"), "{m}");
    assert!(m.contains("state p {"), "{m}");
    assert!(m.contains("\n        --\n"), "regions separated: {m}");
    assert!(m.contains("l1 --> l2 : tick"), "{m}");
    assert!(m.contains("out --> p : after 2s (again) [allowed]"), "{m}");
    assert!(m.contains("fin --> [*]"), "{m}");
    let dot = d.dot();
    assert!(dot.starts_with("digraph \"par\""), "{dot}");
    assert!(dot.contains("subgraph cluster_p {"), "{dot}");
    assert!(dot.contains("style=dashed"), "{dot}");
}
