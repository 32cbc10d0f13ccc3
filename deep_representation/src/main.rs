//! `deep_representation`: the world model component (see `deep_representation::service`).

fn main() -> std::process::ExitCode {
    interfaces::node::main::<deep_representation::service::DeepRepresentation>()
}
