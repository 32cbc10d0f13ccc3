//! The `executive` binary: see [`executive::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<executive::component::Executive>()
}
