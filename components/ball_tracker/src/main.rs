//! The `ball_tracker` component binary: see [`ball_tracker::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<ball_tracker::component::BallTrackerComponent>()
}
