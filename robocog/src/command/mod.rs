//! One file per verb of the `robocog` command line.

pub mod check;
pub mod component;
pub mod launch;
pub mod topic;
