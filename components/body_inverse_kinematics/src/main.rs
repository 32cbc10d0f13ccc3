//! The `body_inverse_kinematics` component binary: see [`body_inverse_kinematics::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<body_inverse_kinematics::component::BodyInverseKinematics>()
}
