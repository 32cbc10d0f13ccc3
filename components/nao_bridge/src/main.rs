//! The `nao_bridge` component binary: see [`nao_bridge::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<nao_bridge::component::NaoBridge>()
}
