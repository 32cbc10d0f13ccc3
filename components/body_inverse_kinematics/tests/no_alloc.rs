//! The solver's hot path allocates nothing: solving (restarts included) after construction makes
//! no heap allocation. Counted with `allocation-counter`, which replaces the global allocator of
//! this test binary only.

#![allow(clippy::unwrap_used)] // tests may unwrap (STYLE: no unwrap outside tests)

use body_inverse_kinematics::{Goal, IkSolver, MonotonicDeadline, SolverOptions, Tolerance};
use nalgebra::Point3;
use robot_model::RobotModel;

#[test]
fn solve_makes_no_heap_allocation() {
    let model = RobotModel::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))
    .unwrap();
    for (part, pose) in [
        ("left_arm_7", true),
        ("left_arm_13", false),
        ("neck", false),
    ] {
        let chain = model.body_part(part).unwrap();
        let mut solver = IkSolver::new(chain.clone(), SolverOptions::default());
        let q_true: Vec<f64> = (0..chain.dof())
            .map(|i| {
                let l = chain.joints[i].limits;
                l.lower + (l.upper - l.lower) * (0.3 + 0.05 * i as f64)
            })
            .collect();
        let t = chain.fk(&q_true).unwrap();
        let goal = if part == "neck" {
            Goal::Gaze {
                point: (t * Point3::new(0.0, 0.0, 1.5)).coords,
            }
        } else if pose {
            Goal::pose(t)
        } else {
            Goal::position(t.translation.vector)
        };
        let start = solver.mid_range();
        let tol = Tolerance::default();
        let mut deadline = MonotonicDeadline::after_s(1.0);
        let mut reached = false;
        let info = allocation_counter::measure(|| {
            // Several solves, and an unreachable one that restarts 50 times.
            for seed in 0..20 {
                let r = solver.solve(
                    &goal,
                    &tol,
                    &start,
                    seed,
                    &mut deadline,
                    &mut |_: &[f64]| true,
                );
                reached = r.reached;
            }
            let mut attempts = 0;
            let far = Goal::position(nalgebra::Vector3::new(3.0, 0.0, 0.0));
            let r = solver.solve(
                &far,
                &tol,
                &start,
                1,
                &mut || {
                    attempts += 1;
                    attempts > 50
                },
                &mut |_: &[f64]| true,
            );
            assert!(!r.reached && r.attempts == 51);
        });
        assert!(reached, "{part}");
        assert_eq!(info.count_total, 0, "{part}: {info:?}");
    }
    // The counter does count: one Vec is one allocation.
    let control = allocation_counter::measure(|| {
        std::hint::black_box(vec![1u8; 8]);
    });
    assert_eq!(control.count_total, 1);
}
