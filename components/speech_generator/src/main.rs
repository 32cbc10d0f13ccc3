//! The `speech_generator` component binary: see [`speech_generator::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<speech_generator::component::SpeechGenerator>()
}
