//! The `joint_motor` component binary: see [`joint_motor::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<joint_motor::component::JointMotorComponent>()
}
