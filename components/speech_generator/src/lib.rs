//! # speech_generator: text to speech for robocog
//!
//! The robot speaks with espeak-ng (the `audio` library's `synth`); requests wait in a priority queue ([`queue`]) and
//! an urgent one interrupts. The component ([`component`]) takes [`SayRequest`]s on `speech/say`,
//! publishes [`SpeakingEvent`]s on `speech/speaking` and the synthesized audio, paced in real
//! time, on `audio/out` (16 kHz mono s16le chunks of 100 ms). An urgent request with no text
//! only silences the robot (a barge-in): it cuts the sentence under way and is reported
//! finished at once.
//!
//! [`SayRequest`]: interfaces::msg::speech::SayRequest
//! [`SpeakingEvent`]: interfaces::msg::speech::SpeakingEvent

pub mod component;
pub mod queue;
