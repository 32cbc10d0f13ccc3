//! # deep_representation: the world model served on the bus
//!
//! The *deep representation* (DR) of RoboCog (seed 001 §IV) is the one place where the robot, its
//! surroundings and the agents in them are represented. Its data structures (the scene graph,
//! transforms in time, predicates, forks, PDDL export, the state folder) are the `world_model`
//! library; this crate is the process that serves them: [`service`] (binary
//! `deep_representation`: node, transform, update, propose, predicate, fork, PDDL, snapshot and
//! restore services; every change on `dr/changes`), keeping its state in a state folder when given
//! one so that a restart loses nothing. The binary `bench_dr` measures the lookup in process and
//! over the bus.

pub mod service;
