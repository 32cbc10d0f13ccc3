//! robocog's topics for ROS 2 nodes on rmw_zenoh (the ROS 2 middleware on zenoh, Tier 1 since
//! Kilted), and ROS 2 publishers for robocog: the rmw_zenoh-compatible mode of a graph
//! (`ros2 = true` in a game's manifest, or `--set ros2=true`). The formats are in [`wire`], the
//! loop in [`bridge`]; the message definitions and type hashes come from `ros_msgs`.
//!
//! Off by default: with it on, every bridged topic is sent twice (once on robocog's key, once on
//! rmw_zenoh's), which `scripts/bench bus` measures.

pub mod bridge;
pub mod wire;

use interfaces::node::{Component, Interface};
use interfaces::{Bus, Shutdown};

/// `--help`'s text after the flags.
const AFTER_HELP: &str = "\
Every topic a robocog component publishes, of a type with a ROS 2 definition (`robocog\n\
interface list`), appears to ROS 2 as published by a node of the component's name, on\n\
/<topic>, in the ROS 2 domain --domain (ROS_DOMAIN_ID): `ros2 topic list`, `ros2 topic echo`\n\
and `ros2 node list` of ROS 2 Jazzy (rmw_zenoh_cpp 0.2.4 or later) or Kilted, with\n\
RMW_IMPLEMENTATION=rmw_zenoh_cpp, connected to this graph's router, see them. A ROS 2\n\
publisher of a robocog_msgs type, with robocog's type hash, feeds the robocog topic of its\n\
name. Samples with a malformed attachment, another type hash or a payload that does not\n\
decode are counted on diagnostics (ros2_bad_attachment/<topic>, ...), logged, and dropped.\n\
\n\
Examples:\n\
\x20 robocog launch launch/touch_the_ball.toml --set ros2=true\n\
\x20 ros2_bridge --connect tcp/127.0.0.1:7447 --namespace touch --domain 0";

/// The bridge's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// The ROS 2 domain to appear in (ROS_DOMAIN_ID).
    #[arg(long, env = "ROS_DOMAIN_ID", default_value_t = 0, value_name = "N")]
    pub domain: u32,
    /// robocog topics never shown to ROS 2 (comma-separated), e.g. the camera's frames.
    #[arg(long, value_delimiter = ',', value_name = "TOPIC,...")]
    pub exclude: Vec<String>,
}

/// The `ros2_bridge` component.
#[derive(Debug)]
pub struct Ros2Bridge;

impl Component for Ros2Bridge {
    const NAME: &'static str = "ros2_bridge";
    const ABOUT: &'static str = "Shows a robocog graph's topics to ROS 2 nodes on rmw_zenoh, and feeds it from ROS 2 publishers.";
    const AFTER_HELP: &'static str = AFTER_HELP;
    type Config = Flags;
    type Prepared = bridge::Settings;

    fn interface(_: &Flags) -> Interface {
        Interface::new(Self::NAME)
    }

    fn prepare(config: Flags) -> anyhow::Result<bridge::Settings> {
        if config.domain > 232 {
            return Err(interfaces::node::config_error(format!(
                "--domain {}: ROS 2 domains go from 0 to 232",
                config.domain
            )));
        }
        Ok(bridge::Settings {
            domain: config.domain,
            exclude: config.exclude,
        })
    }

    async fn run(bus: Bus, prepared: bridge::Settings, shutdown: Shutdown) -> anyhow::Result<()> {
        bridge::run(bus, prepared, shutdown).await
    }
}
