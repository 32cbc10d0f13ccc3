//! The `speech_recognition` component binary: see [`speech_recognition::component`].

fn main() -> std::process::ExitCode {
    interfaces::node::main::<speech_recognition::component::SpeechRecognition>()
}
