//! The viewer component: a namespace's topics into rerun. See the library doc for the mapping.

fn main() -> std::process::ExitCode {
    interfaces::node::main::<viewer::component::Viewer>()
}
