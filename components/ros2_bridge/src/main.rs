//! The ROS 2 bridge component: see the library doc.

fn main() -> std::process::ExitCode {
    interfaces::node::main::<ros2_bridge::Ros2Bridge>()
}
