//! # world_model: the deep representation's world model
//!
//! The *deep representation* (DR) of RoboCog (seed 001 §IV) is the one place where the robot, its
//! surroundings and the agents in them are represented. Perception components update it, the
//! executive and the IK read it, and anyone can take a private copy of it ([`graph::SceneGraph::fork`])
//! to simulate virtual actions before doing them for real. This crate is the pure library: no
//! bus connection, no clock, no threads. The `deep_representation` process serves it on the
//! bus; the viewer mirrors it.
//!
//! ## Frames
//!
//! Every node of the scene graph is a frame; every edge is a rigid transform `parent_T_child`.
//! - `world` is the root (a fixed frame of the room or the SPL field's surroundings).
//! - Robots: an agent node (type `robot`, e.g. `loki`) whose free pose under `world` is the
//!   odometry pose; the URDF root link (`base_footprint` for Loki) hangs from it with identity;
//!   every other link hangs from its parent link through its joint. Link names are the URDF names.
//! - Cameras: a `camera` node (e.g. `head_rgbd`) under its optical frame
//!   (`head_rgbd_optical_frame`: z forward, x right, y down), with pinhole intrinsics.
//! - The SPL field: a `field` node (origin at the centre spot, x towards the opponent goal, y left,
//!   z up) with goalposts and marks as landmark children; see [`field`].
//! - Units: metres and radians everywhere in the graph (the field *file* is in millimetres, as the
//!   SPL rules; it is converted on load).
//! - [`graph::SceneGraph::transform`]`(target, source, at)` returns `target_T_source`, so that
//!   `p_target = target_T_source * p_source` (REP 103 conventions, x forward, y left, z up).
//!
//! ## Node kinds and edges
//!
//! [`types::NodeType`]: `world`, `frame`, `link`, `camera`, `ball`, `object`, `human`, `robot`,
//! `field`, `goalpost`, `landmark`. Nodes carry typed attributes ([`types::AttrValue`]: bool, int,
//! float, text, 3-vector; well-known keys in [`types::attr`], with the unit in the key:
//! `radius_m`, `team`, `fallen`, `effector`...), intrinsics for cameras and collision shapes for
//! links. Edges are `fixed` (constant), `free` (a pose set by perception or odometry) or `joint`
//! (`origin * motion(value)`, with the joint's kind, axis and limits).
//!
//! ## Time
//!
//! Time is a [`types::Stamp`]: u64 nanoseconds on the caller's clock (wall, monotonic, or a
//! replay's virtual clock); `Stamp::from_secs_f64` converts from seconds. The library never reads a
//! clock. Each free or joint edge keeps its last [`graph::SceneGraph::history_len`] samples
//! (default 128). A query [`graph::At::Latest`] uses the newest values; [`graph::At::Time`]`(t)`
//! interpolates each edge between its samples around `t` (linear in joint values and translations,
//! slerp in rotations), holds the newest sample after it, and fails with
//! [`error::DrError::TimeOutOfHistory`] before the oldest kept. Late measurements (older stamps)
//! are slotted into the history without replacing newer values, so perception that arrives late
//! can ask where the camera was when the image was taken.
//!
//! ## Changes
//!
//! - Joint values, poses and attributes go straight in ([`graph::SceneGraph::set_joint`],
//!   [`graph::SceneGraph::set_pose`], [`graph::SceneGraph::set_attr`]).
//! - Structural changes are [`types::StructuralChange`]s, accepted or rejected with a
//!   [`graph::RejectReason`]: unique valid names, the parent exists, the type is known, no cycles,
//!   no removal of nodes with children, of `world` or of robot links, finite geometry.
//! - With the log enabled, every accepted change is a serde [`types::ChangeEvent`]; a service
//!   persists a [`types::Snapshot`] (JSON) plus the events and recovers with
//!   [`graph::SceneGraph::restore_json`] and [`graph::SceneGraph::apply`].
//!
//! ## Predicates, forks and PDDL
//!
//! [`predicates`] computes typed facts (`visible`, `reachable`, `near`, `in_field`, `fallen`,
//! `closest_to_ball`) from geometry and attributes; [`predicates::fork_report`] compares a fork
//! with the live graph; [`pddl::export_problem`] writes the state as a PDDL problem for the domain
//! in `libs/world_model/pddl/robocog-domain.pddl`.
//!
//! ## Kinematics
//!
//! The `robot_model` library's `RobotModel` loads URDF (urdf-rs) and extracts `Chain`s between two
//! links or by body-part name (`left_arm_4`, `left_arm_7`, `left_arm_11`, `left_arm_13`, `neck`,
//! ...), with allocation-free FK, the 6xN geometric Jacobian and joint limits.
//!
//! ## Naming
//!
//! Node names are unique in a graph, non-empty, without whitespace or parentheses; joint names are
//! unique too. Keep them in `[a-z0-9_]` so they map one to one to PDDL names. Models live in
//! `models/` at the repository root: `loki.urdf`, `spl_field.toml`.
//!
//! The data types (node descriptions, changes, events, snapshots) are the bus' own,
//! `interfaces::msg::dr`, re-exported in [`types`]: one definition for the library, the service,
//! the wire and the state folder. [`mod@bus`] checks what comes from outside (numbers the graph
//! needs finite, attributes given twice).
//!
//! ## The service
//!
//! The `deep_representation` process serves the graph over the bus (node, transform, update,
//! propose, predicate, fork, PDDL, snapshot and restore services; every change on `dr/changes`);
//! [`persist`] keeps it in a state folder (snapshot + append-only change log) so a restart loses
//! nothing; [`mod@bench`] holds the in-process lookup benchmark (its binary `bench_dr` adds the
//! bus round trip).
//!
//! ## Example
//!
//! ```
//! use world_model::{At, RobotModel, SceneGraph, Stamp, scenes};
//! use world_model::predicates::{PredicateConfig, PredicateKind, fork_report};
//!
//! let loki = RobotModel::from_urdf_file(concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/loki.urdf"))?;
//! // Kinematics for the IK: the 7-joint left arm, FK and Jacobian for a joint vector.
//! let arm = loki.body_part("left_arm_7")?;
//! let (hand, jacobian) = arm.jacobian(&[0.0, 0.3, 0.0, -1.2, 0.0, 0.0, 0.0])?;
//! assert_eq!(jacobian.shape(), (6, 7));
//!
//! // The world: Loki, the player and the ball; joints arrive from joint_motor with stamps.
//! let mut g: SceneGraph = scenes::touch_the_ball(&loki, Stamp(0))?;
//! g.set_joint("left_elbow", -1.2, Stamp::from_secs_f64(0.1))?;
//! let ball_in_hand_frame = g.transform("left_hand_center", "ball", At::Latest)?;
//!
//! // What if the ball came closer? Ask a fork, not the live graph.
//! let mut what_if = g.fork();
//! what_if.set_pose("ball", &world_model::graph::translation(0.42, 0.2, 1.0), Stamp(0))?;
//! let report = fork_report(&g, &what_if, &PredicateConfig::default())?;
//! assert!(report.facts.became_true.iter().any(|f| f.kind == PredicateKind::Reachable));
//! # let _ = (hand, ball_in_hand_frame);
//! # Ok::<(), world_model::DrError>(())
//! ```

pub mod bench;
pub mod bus;
pub mod error;
pub mod field;
pub mod graph;
pub mod pddl;
pub mod persist;
pub mod predicates;
pub mod scenes;
pub mod types;

pub use error::{DrError, Result};
pub use graph::{At, SceneGraph};
pub use robot_model::{Chain, RobotModel};
pub use types::Stamp;
