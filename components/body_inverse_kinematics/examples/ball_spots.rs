//! Which ball positions suit "touch the ball": prints, for a grid of world positions in front of
//! Loki (touch scene: Loki at the origin, z up), whether `left_arm_7` reaches the position and
//! the neck can put it on the head camera's optical axis, both solved from the rest posture
//! (`joint_motor::home`), with the 1 cm tolerance of the component.
//!
//! `cargo run --release -p body_inverse_kinematics --example ball_spots`

use body_inverse_kinematics::{BodyIk, IkRequest, IkTarget};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut ik = BodyIk::from_urdf_file(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/loki.urdf"
    ))?;
    // The rest posture (joint_motor::home::REST).
    for (j, q) in [
        ("left_shoulder_roll", 0.10),
        ("right_shoulder_roll", -0.10),
        ("left_elbow", -0.15),
        ("right_elbow", -0.15),
        ("neck_pitch", 0.30),
    ] {
        ik.set_joint(j, q)?;
    }
    // The chains' root `torso` in the world (= base_footprint, base joints at 0).
    let base = ik.model().chain("base_footprint", "torso")?;
    let torso = base.fk(&vec![0.0; base.dof()])?.translation.vector;
    let start = |ik: &mut BodyIk, part: &str| -> Result<Vec<f64>, Box<dyn std::error::Error>> {
        let names: Vec<String> = ik
            .solver(part)?
            .chain()
            .joint_names()
            .iter()
            .map(|s| s.to_string())
            .collect();
        let model = ik.model().clone();
        Ok(names
            .iter()
            .map(|n| {
                let i = model.joints.iter().position(|j| &j.name == n).unwrap_or(0);
                ik.posture()[i]
            })
            .collect())
    };
    println!("world x, y, z (m) | left_arm_7 residual (mm) | neck gaze residual (mm)");
    for x in [0.35, 0.45, 0.55] {
        for y in [0.1, 0.2, 0.3, 0.4] {
            for z in [0.95, 1.05, 1.15, 1.25] {
                let p = [x - torso.x, y - torso.y, z - torso.z];
                let mut arm = IkRequest::new("left_arm_7", IkTarget::Position { position_m: p });
                arm.tolerance_m = 1e-3;
                arm.q_start = Some(start(&mut ik, "left_arm_7")?);
                let a = ik.solve(&arm)?;
                let mut gaze = IkRequest::new("neck", IkTarget::Gaze { point_m: p });
                gaze.q_start = Some(start(&mut ik, "neck")?);
                let g = ik.solve(&gaze)?;
                let (ar, gr) = (a.residual().0, g.residual().0);
                let ok = ar <= 0.01 && gr <= 0.01;
                println!(
                    "{x:.2}, {y:.2}, {z:.2} | {:7.1} | {:7.1} {}",
                    ar * 1e3,
                    gr * 1e3,
                    if ok { "<- both" } else { "" }
                );
            }
        }
    }
    Ok(())
}
