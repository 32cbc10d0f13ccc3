//! Prints the PDDL problem of a ready-made scene (see `world_model::scenes`).
//!
//! `cargo run -p world_model --example export_pddl -- touch|coach`
//! The files in `deep_representation/pddl/examples/` are this program's output; a test checks
//! that they stay in sync with the code.

use robot_model::RobotModel;
use world_model::field::FieldModel;
use world_model::graph::At;
use world_model::pddl::{Atom, export_problem};
use world_model::predicates::PredicateConfig;
use world_model::scenes;
use world_model::types::Stamp;

fn main() -> anyhow::Result<()> {
    let which = std::env::args().nth(1).unwrap_or_else(|| "touch".into());
    let models = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models");
    let (g, name, goal) = match which.as_str() {
        "touch" => {
            let loki = RobotModel::from_urdf_file(format!("{models}/loki.urdf"))?;
            (
                scenes::touch_the_ball(&loki, Stamp(0))?,
                "touch-the-ball",
                Atom::new("touched", &["ball"]),
            )
        }
        "coach" => {
            let field = FieldModel::from_file(format!("{models}/spl_field.toml"))?;
            (
                scenes::coach_game(&field, Stamp(0))?,
                "coach-game",
                Atom::new("touched", &["ball"]),
            )
        }
        other => anyhow::bail!("unknown scene `{other}` (touch | coach)"),
    };
    let p = export_problem(&g, &PredicateConfig::default(), At::Latest, name, &[goal])?;
    print!("{}", p.to_pddl());
    Ok(())
}
