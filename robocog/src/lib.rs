//! # robocog: the command line of the component network
//!
//! - `robocog launch <manifest>` runs a graph of components ([`supervisor`]);
//! - `robocog check <manifest>` validates one ([`manifest`], [`check`]);
//! - `robocog topic list|echo|hz|info|pub` and `robocog component list` look at a running graph;
//! - `robocog record` / `robocog replay` write a graph's topics to an MCAP file and publish them
//!   back ([`mcap_io`]).
//!
//! - `robocog agent` runs one machine's share of a graph over several machines ([`agent`],
//!   [`machines`]); `robocog certs` makes the certificates of its links.
//!
//! One file per verb lives in [`command`].

pub mod agent;
pub mod check;
pub mod command;
pub mod machines;
pub mod manifest;
pub mod mcap_io;
pub mod router_process;
pub mod supervisor;
