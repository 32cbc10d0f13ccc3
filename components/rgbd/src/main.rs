//! The `rgbd` component binary: see [`rgbd::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<rgbd::component::Rgbd>()
}
