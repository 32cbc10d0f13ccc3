//! The `loki_world` binary, the simulated person of the touch-the-ball game: see
//! [`loki_world::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<loki_world::component::LokiWorld>()
}
