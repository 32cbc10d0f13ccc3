#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: times the solver's CPU work on the wall clock"
)]
//! IK benchmark on Loki: random reachable targets (FK of seeded random in-limit configurations),
//! solved from a fixed start; success rate (1 mm, 0.01 rad, within limits, checked here by FK of
//! the returned configuration) and solve-time percentiles.
//!
//! ```text
//! cargo run --release -p body_inverse_kinematics --example bench_ik -- \
//!     [--n 10000] [--seed 7] [--targets-out targets.json] [--results-out ours.json]
//! ```
//!
//! The targets file (JSON) lets `bench/peers.py` solve exactly the same problems with ikpy and
//! roboticstoolbox-python. Cases: `arm7_pose` (`left_arm_7`, position + orientation),
//! `arm11_pos` (`left_arm_11`, position), `arm13_pos` (`left_arm_13`, position), and
//! `arm7_pose_collision` (the same arm-7 targets with the self-collision check on: only the
//! collision-free solutions count, and some targets have none).

use std::time::Instant;

use body_inverse_kinematics::{
    BodyIk, Goal, IkRequest, IkSolver, IkTarget, MonotonicDeadline, SolverOptions, Tolerance,
};
use nalgebra::{Isometry3, UnitQuaternion};
use rand::SeedableRng;
use rand::rngs::SmallRng;
use robot_model::RobotModel;

struct Case {
    name: &'static str,
    body_part: &'static str,
    pose: bool,
}

const CASES: &[Case] = &[
    Case {
        name: "arm7_pose",
        body_part: "left_arm_7",
        pose: true,
    },
    Case {
        name: "arm11_pos",
        body_part: "left_arm_11",
        pose: false,
    },
    Case {
        name: "arm13_pos",
        body_part: "left_arm_13",
        pose: false,
    },
];

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((p / 100.0) * (sorted.len() - 1) as f64).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = arg(&args, "--n").map_or(Ok(10_000), |s| s.parse())?;
    let seed: u64 = arg(&args, "--seed").map_or(Ok(7), |s| s.parse())?;
    let urdf = arg(&args, "--urdf").unwrap_or_else(|| {
        concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/loki.urdf").to_string()
    });
    let model = RobotModel::from_urdf_file(&urdf)?;
    let tol = Tolerance::default();
    let budget_s = 0.02;
    let mut body = BodyIk::new(model.clone());

    let mut cases_json = Vec::new();
    let mut results = serde_json::Map::new();
    println!(
        "ours: {n} targets per case, start = mid-range, budget {budget_s} s, tol {} m / {} rad",
        tol.m, tol.rad
    );
    println!(
        "{:<22} {:>5} {:>10} {:>10} {:>10} {:>8}",
        "case", "dof", "success%", "p50_us", "p99_us", "iters"
    );
    for case in CASES {
        let chain = model.body_part(case.body_part)?;
        let mut solver = IkSolver::new(chain.clone(), SolverOptions::default());
        let mut rng = SmallRng::seed_from_u64(seed ^ case.name.len() as u64);
        let q0 = solver.mid_range();
        let mut q = vec![0.0; chain.dof()];
        let mut targets = Vec::with_capacity(n);
        let mut colliding = 0usize;
        for _ in 0..n {
            solver.random_configuration(&mut rng, &mut q);
            let t = chain.fk(&q)?;
            targets.push(t);
            if case.pose && body.self_collision(case.body_part, &q)?.is_some() {
                colliding += 1;
            }
        }
        let goal_of = |t: &Isometry3<f64>| {
            if case.pose {
                Goal::pose(*t)
            } else {
                Goal::position(t.translation.vector)
            }
        };
        let check = |q: &[f64], t: &Isometry3<f64>| -> bool {
            let Ok(f) = chain.fk(q) else { return false };
            let dp = (f.translation.vector - t.translation.vector).norm();
            let dr = (f.rotation * t.rotation.inverse()).angle();
            chain.within_limits(q) && dp <= tol.m && (!case.pose || dr <= tol.rad)
        };
        let mut times = Vec::with_capacity(n);
        let mut ok = 0usize;
        let mut iters = 0u64;
        for (k, t) in targets.iter().enumerate() {
            let goal = goal_of(t);
            let start = Instant::now();
            let mut deadline = MonotonicDeadline::after_s(budget_s);
            let r = solver.solve(
                &goal,
                &tol,
                &q0,
                k as u64,
                &mut deadline,
                &mut |_: &[f64]| true,
            );
            times.push(start.elapsed().as_secs_f64() * 1e6);
            iters += u64::from(r.iterations);
            if r.reached && check(solver.solution(), t) {
                ok += 1;
            }
        }
        times.sort_by(f64::total_cmp);
        let (p50, p99) = (percentile(&times, 50.0), percentile(&times, 99.0));
        let pct = 100.0 * ok as f64 / n as f64;
        println!(
            "{:<22} {:>5} {:>10.2} {:>10.1} {:>10.1} {:>8.1}",
            case.name,
            chain.dof(),
            pct,
            p50,
            p99,
            iters as f64 / n as f64
        );
        results.insert(
            case.name.into(),
            serde_json::json!({"success_pct": pct, "p50_us": p50, "p99_us": p99, "n": n,
                               "dof": chain.dof(), "mean_iterations": iters as f64 / n as f64}),
        );

        if case.pose {
            // The same targets through BodyIk with the self-collision check (the rest of the body
            // at the zero posture).
            let mut times = Vec::with_capacity(n);
            let mut ok = 0usize;
            for (k, t) in targets.iter().enumerate() {
                let rot: UnitQuaternion<f64> = t.rotation;
                let c = rot.coords;
                let mut req = IkRequest::new(
                    case.body_part,
                    IkTarget::Pose {
                        position_m: t.translation.vector.into(),
                        orientation_xyzw: [c.x, c.y, c.z, c.w],
                    },
                );
                req.seed = k as u64;
                req.q_start = Some(q0.clone());
                req.max_time_s = budget_s;
                let start = Instant::now();
                let r = body.solve(&req)?;
                times.push(start.elapsed().as_secs_f64() * 1e6);
                if r.is_reached() && check(r.q(), t) {
                    ok += 1;
                }
            }
            times.sort_by(f64::total_cmp);
            let (p50, p99) = (percentile(&times, 50.0), percentile(&times, 99.0));
            let pct = 100.0 * ok as f64 / n as f64;
            let name = format!("{}_collision", case.name);
            println!(
                "  ({:.2} % of the arm-7 targets come from a self-colliding configuration)",
                100.0 * colliding as f64 / n as f64
            );
            println!(
                "{:<22} {:>5} {:>10.2} {:>10.1} {:>10.1} {:>8}",
                name,
                chain.dof(),
                pct,
                p50,
                p99,
                "-"
            );
            results.insert(
                name,
                serde_json::json!({"success_pct": pct, "p50_us": p50, "p99_us": p99, "n": n}),
            );
        }

        let rows: Vec<[f64; 7]> = targets
            .iter()
            .map(|t| {
                let p = t.translation.vector;
                let c = t.rotation.coords;
                [p.x, p.y, p.z, c.x, c.y, c.z, c.w]
            })
            .collect();
        cases_json.push(serde_json::json!({
            "name": case.name,
            "body_part": case.body_part,
            "root": chain.root,
            "tip": chain.tip,
            "joints": chain.joint_names(),
            "pose": case.pose,
            "q_start": q0,
            "targets_xyz_qxyzw": rows,
        }));
    }
    if let Some(path) = arg(&args, "--targets-out") {
        let doc = serde_json::json!({
            "urdf": urdf,
            "seed": seed,
            "tolerance_m": tol.m,
            "tolerance_rad": tol.rad,
            "budget_s": budget_s,
            "cases": cases_json,
        });
        std::fs::write(&path, serde_json::to_string(&doc)?)?;
    }
    if let Some(path) = arg(&args, "--results-out") {
        std::fs::write(&path, serde_json::to_string_pretty(&results)?)?;
    }
    Ok(())
}
