//! # interfaces: the typed bus of robocog
//!
//! Every message a robocog component sends is a Rust type defined here ([`msg`]); every topic and
//! service is a typed constant ([`topics`]), so a misspelt topic or a wrong message type is a
//! compile error. Underneath, [`bus::Bus`] is a zenoh session bound to a namespace:
//!
//! - **Topics** carry CDR-encoded messages ([`codec`], little-endian with the 4-byte
//!   encapsulation header, as ROS 2 does) under `robocog/<namespace>/t/<topic>`.
//! - **Services** are zenoh queryables under `robocog/<namespace>/s/<service>`; calls carry a
//!   time-out and errors come back typed.
//! - **Raw samples**: tools that carry messages they only know by type name (record, replay,
//!   the topic tools, the viewer) subscribe and publish bytes through [`raw`], the one place
//!   that writes and reads the `application/cdr;<type name>` encoding.
//! - **Liveliness tokens** announce every component, publisher, subscriber and service with its
//!   type name ([`liveliness`]), so tools see a running graph with no opt-in.
//! - **Headers**: every message starts with a [`Header`] (stamp, sequence number, frame), stamped
//!   from the component's [`Clock`] ([`clock`]): the system's, or a virtual one that a test or,
//!   with `--clock bus`, a replay drives; timers and time-outs wait on it too. On the wire it is
//!   a ROS 2 `std_msgs/Header`; the sequence number travels in every sample's attachment
//!   ([`attachment`], rmw_zenoh's format), and ROS 2's standard types stand for geometry
//!   ([`msg::ros`]).
//! - **Connection flags**: [`args::ConnectArgs`] is the one set of flags of every binary
//!   (`--namespace`, `--connect`, `--listen`, `--config`); multicast scouting is off.
//! - **Components** run through [`node::run`], which wires logging, signals, liveliness and
//!   diagnostics the same way for all.

pub mod args;
pub mod attachment;
pub mod bus;
pub mod clock;
pub mod codec;
pub mod header;
pub mod liveliness;
pub mod msg;
pub mod node;
pub mod outbox;
pub mod ratelimit;
pub mod raw;
pub mod router;
pub mod state;
pub mod topic;
pub mod topics;

pub use args::ConnectArgs;
pub use bus::{
    Bus, BusError, CallError, ErrorCode, Publisher, Received, RecentPublisher, ServiceError,
    Subscriber,
};
pub use clock::{Clock, Moment};
pub use header::Header;
pub use msg::{Borrowable, Message};
pub use node::{Interface, NodeArgs, Shutdown};
pub use raw::{RawListener, RawPublisher, RawReply, RawSample, RawSubscriber};
pub use topic::{Service, Topic};
