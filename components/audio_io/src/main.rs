//! The `audio_io` component binary: see [`audio_io::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<audio_io::component::AudioIo>()
}
