//! The Nao link of the coach game as a robocog component: the UDP sockets to the robots and the
//! GameController, the receive path ([`Inbound`]: source filter, the `spl` library's decoders,
//! drop counters, link monitors per robot), link-loss detection ([`link`]), the bus side
//! ([`component`]: the codecs read and write the `nao/*` messages themselves) and the mirror of the robots' obstacles into the deep representation
//! ([`dr`]). The packets, their validation and the team world model are the `spl` library.
//! Time is passed in as seconds (`f64`) of the caller's clock.

pub mod component;
pub mod dr;
pub mod inbound;
pub mod link;

pub use inbound::{ExpectedRobot, Inbound, InboundConfig};
pub use link::{LinkEvent, LinkMonitor, LinkState};
