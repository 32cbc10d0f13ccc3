//! Ready-made start states of the two games, used by tests, the benchmark and the simulators.
//!
//! - [`touch_the_ball`]: Loki at the world origin (its `base_footprint` = `world` at start), the
//!   human player 1.5 m in front of it facing it, and a yellow ball of radius 35 mm held at
//!   (0.8, 0.2, 1.1) m in `world`: not yet seen (the head looks ahead) and out of reach.
//! - [`coach_game`]: the SPL field at the world origin, two robots of team 1 (`nao_1`, the
//!   autonomous teammate; `nao_2`, the robot the coach controls), two opponents of team 2
//!   (`opponent_2` fallen), the ball (radius 50 mm) and the coach standing behind the touch line.

use nalgebra::Isometry3;

use crate::error::{DrError, Result};
use crate::field::FieldModel;
use crate::graph::SceneGraph;
use crate::types::{AttrValue, NodeSpec, NodeType, Stamp, StructuralChange, Transform, attr};
use robot_model::RobotModel;

fn add(g: &mut SceneGraph, spec: NodeSpec, stamp: Stamp) -> Result<()> {
    g.propose(StructuralChange::AddNode(Box::new(spec)), stamp)
        .map_err(|r| DrError::Rejected(Box::new(r)))
}

/// The touch-the-ball start state (see the module docs).
pub fn touch_the_ball(loki: &RobotModel, stamp: Stamp) -> Result<SceneGraph> {
    let mut g = SceneGraph::new();
    g.add_robot(loki, "loki", "world", &Isometry3::identity(), stamp)?;
    add(
        &mut g,
        NodeSpec::free(
            "player",
            NodeType::Human,
            "world",
            Transform::planar(1.5, 0.0, std::f64::consts::PI),
        ),
        stamp,
    )?;
    add(
        &mut g,
        NodeSpec::free(
            "ball",
            NodeType::Ball,
            "world",
            Transform::from_translation(0.8, 0.2, 1.1),
        )
        .with_attr(attr::RADIUS_M, AttrValue::Float(0.035))
        .with_attr(attr::COLOR, AttrValue::Text("yellow".into())),
        stamp,
    )?;
    Ok(g)
}

/// The coach-game state (see the module docs). Positions in metres in the field frame.
pub fn coach_game(field: &FieldModel, stamp: Stamp) -> Result<SceneGraph> {
    let mut g = SceneGraph::new();
    field.add_to_graph(&mut g, "world", Transform::default(), stamp)?;
    let robots = [
        ("nao_1", 1, -2.0, 1.0, 0.0),
        ("nao_2", 1, -1.0, -0.5, 0.3),
        ("opponent_1", 2, 1.5, 0.5, 3.0),
        ("opponent_2", 2, 3.5, 0.0, 3.1),
    ];
    for (name, team, x, y, th) in robots {
        add(
            &mut g,
            NodeSpec::free(name, NodeType::Robot, "field", Transform::planar(x, y, th))
                .with_attr(attr::TEAM, AttrValue::Int(team))
                .with_attr(attr::FALLEN, AttrValue::Bool(name == "opponent_2")),
            stamp,
        )?;
    }
    add(
        &mut g,
        NodeSpec::free(
            "ball",
            NodeType::Ball,
            "field",
            Transform::from_translation(0.5, -0.3, 0.05),
        )
        .with_attr(
            attr::RADIUS_M,
            AttrValue::Float(field.ball_diameter_mm / 2000.0),
        ),
        stamp,
    )?;
    add(
        &mut g,
        NodeSpec::free(
            "coach",
            NodeType::Human,
            "field",
            Transform::planar(0.0, -3.6, -1.57),
        ),
        stamp,
    )?;
    Ok(g)
}
