//! The `spl_field` binary, the simulated SPL field: see [`spl_field::process`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<spl_field::process::SplFieldComponent>()
}
