//! The Executive: a hierarchical concurrent state machine engine and the games' machines.
