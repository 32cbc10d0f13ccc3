//! PDDL export of the two games' states, parsed back (objects and predicates round-trip), and
//! checked against the domain file.

#![allow(clippy::unwrap_used)] // tests may unwrap (STYLE: no unwrap outside tests)

use robot_model::RobotModel;
use world_model::field::FieldModel;
use world_model::graph::{At, SceneGraph, translation};
use world_model::pddl::{Atom, DOMAIN, PddlProblem, domain_signature, export_problem};
use world_model::predicates::{PredicateConfig, evaluate};
use world_model::scenes;
use world_model::types::Stamp;

const S: Stamp = Stamp(0);

fn loki() -> RobotModel {
    RobotModel::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap()
}
fn field() -> FieldModel {
    FieldModel::from_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/spl_field.toml"
    ))
    .unwrap()
}

/// Exports, writes, parses back and checks the round trip and the domain; returns the problem.
fn round_trip(g: &SceneGraph, name: &str, goal: &[Atom]) -> PddlProblem {
    let cfg = PredicateConfig::default();
    let p = export_problem(g, &cfg, At::Latest, name, goal).unwrap();
    let text = p.to_pddl();
    let back = PddlProblem::parse(&text).unwrap();
    assert_eq!(back, p, "round trip of\n{text}");
    // Every true fact of the graph is in :init, and :init has nothing else but has-part/has-camera.
    let facts = evaluate(g, &cfg, At::Latest).unwrap();
    for f in &facts {
        let a = Atom {
            predicate: f.kind.pddl_name().into(),
            args: f.args.clone(),
        };
        assert!(back.init.contains(&a), "{a:?} missing");
    }
    let structural = back
        .init
        .iter()
        .filter(|a| a.predicate.starts_with("has-"))
        .count();
    assert_eq!(back.init.len(), facts.len() + structural);
    // Domain consistency: predicates with the right arity, types declared, args declared.
    let (preds, types) = domain_signature(DOMAIN).unwrap();
    for a in back.init.iter().chain(&back.goal) {
        assert_eq!(
            preds.get(&a.predicate),
            Some(&a.args.len()),
            "{a:?} vs domain"
        );
        for o in &a.args {
            assert!(back.objects.contains_key(o), "{o} used but not declared");
        }
    }
    for t in back.objects.values() {
        assert!(types.contains(t), "type {t} not in the domain");
    }
    p
}

#[test]
fn touch_the_ball_start_state_round_trips() {
    let g = scenes::touch_the_ball(&loki(), S).unwrap();
    let p = round_trip(&g, "touch-the-ball", &[Atom::new("touched", &["ball"])]);
    assert_eq!(p.objects.get("ball").map(String::as_str), Some("ball"));
    assert_eq!(p.objects.get("loki").map(String::as_str), Some("robot"));
    assert_eq!(p.objects.get("player").map(String::as_str), Some("human"));
    assert_eq!(
        p.objects.get("head_rgbd").map(String::as_str),
        Some("camera")
    );
    assert_eq!(
        p.objects.get("left_arm").map(String::as_str),
        Some("bodypart")
    );
    assert!(
        p.init
            .contains(&Atom::new("has-part", &["loki", "left_arm"]))
    );
    assert!(
        p.init
            .contains(&Atom::new("has-camera", &["loki", "head_rgbd"]))
    );
    assert!(
        !p.init.iter().any(|a| a.predicate == "reachable"),
        "start: ball out of reach"
    );
    assert_eq!(p.goal, vec![Atom::new("touched", &["ball"])]);

    // After the ball comes close and the head looks down, the state has reachable and visible.
    let mut near = g.fork();
    near.set_joint("neck_pitch", 0.6, S).unwrap();
    near.set_pose("ball", &translation(0.42, 0.2, 1.0), S)
        .unwrap();
    let p = round_trip(
        &near,
        "touch-the-ball-2",
        &[Atom::new("touched", &["ball"])],
    );
    assert!(
        p.init
            .contains(&Atom::new("reachable", &["ball", "left_arm"]))
    );
    assert!(
        p.init
            .contains(&Atom::new("visible", &["ball", "head_rgbd"]))
    );
}

#[test]
fn coach_game_state_round_trips() {
    let g = scenes::coach_game(&field(), S).unwrap();
    let p = round_trip(&g, "coach-game", &[Atom::new("near", &["nao_2", "ball"])]);
    for r in ["nao_1", "nao_2", "opponent_1", "opponent_2"] {
        assert_eq!(p.objects.get(r).map(String::as_str), Some("robot"));
        assert!(p.init.contains(&Atom::new("in-field", &[r])));
    }
    assert_eq!(
        p.objects.get("opponent_goalpost_left").map(String::as_str),
        Some("goalpost")
    );
    assert_eq!(p.objects.get("field").map(String::as_str), Some("field"));
    assert_eq!(p.objects.get("coach").map(String::as_str), Some("human"));
    assert!(p.init.contains(&Atom::new("in-field", &["ball"])));
    assert!(p.init.contains(&Atom::new("closest-to-ball", &["nao_2"])));
    assert!(p.init.contains(&Atom::new("fallen", &["opponent_2"])));
    assert!(!p.init.contains(&Atom::new("in-field", &["coach"])));
}

#[test]
fn parser_rejects_bad_problems_with_reasons() {
    for (text, want) in [
        (
            "(define (problem p) (:domain d) (:init (at a b))",
            "unbalanced `(`",
        ),
        (")(define (problem p))", "unbalanced `)`"),
        ("(problem p)", "define"),
        ("(define (problem p) (:objects a - ) )", "without a type"),
        (
            "(define (problem p) (:metric minimize (cost)))",
            "unsupported section",
        ),
        ("(define (problem p)) trailing", "after the end"),
        ("", "empty"),
    ] {
        let e = PddlProblem::parse(text).unwrap_err().to_string();
        assert!(e.contains(want), "{text:?}: {e}");
    }
    // Comments, case and a single-atom goal are fine.
    let p = PddlProblem::parse("; c\n(DEFINE (problem P) (:domain robocog) (:objects B - ball)\n (:init (In-Field b)) (:goal (touched b)))").unwrap();
    assert_eq!(p.objects.get("b").map(String::as_str), Some("ball"));
    assert!(p.init.contains(&Atom::new("in-field", &["b"])));
    assert_eq!(p.goal, vec![Atom::new("touched", &["b"])]);
}

#[test]
fn example_problem_files_are_in_sync_with_the_code() {
    let cfg = PredicateConfig::default();
    let goal = [Atom::new("touched", &["ball"])];
    let touch = scenes::touch_the_ball(&loki(), S).unwrap();
    let coach = scenes::coach_game(&field(), S).unwrap();
    for (g, name, file) in [
        (&touch, "touch-the-ball", "touch-the-ball.pddl"),
        (&coach, "coach-game", "coach-game.pddl"),
    ] {
        let text = export_problem(g, &cfg, At::Latest, name, &goal)
            .unwrap()
            .to_pddl();
        let path = format!("{}/pddl/examples/{file}", env!("CARGO_MANIFEST_DIR"));
        let on_disk = std::fs::read_to_string(&path).unwrap();
        assert_eq!(
            text, on_disk,
            "{path} is stale: regenerate with `cargo run -p world_model --example export_pddl`"
        );
    }
}
