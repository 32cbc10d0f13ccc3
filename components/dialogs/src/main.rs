//! The `dialogs` component binary: see [`dialogs::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<dialogs::component::Dialogs>()
}
