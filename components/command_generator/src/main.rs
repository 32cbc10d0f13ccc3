//! The `command_generator` component binary, the command panel: see [`command_generator::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<command_generator::component::CommandGenerator>()
}
