#!/usr/bin/env bash
# Hearing through a microphone array: the recognizer's chain on a 4-microphone circular array
# (beamformed at the player, the end-pointer told what comes from elsewhere) against one
# microphone of the same array, on rooms where two other people talk 10 dB under the player,
# and on the same rooms with nobody else; each as plane waves in free field (`two_talkers_10db`,
# `clean`) and in a reverberant 6 x 5 x 3 m room of RT60 0.5 s, every talker 1.5 m from the
# array (`two_talkers_10db_rt60_0.5`, `clean_rt60_0.5`). The player speaks with flite's voices
# (evaluation only). `--voices slt,rms`, `--games touch` and `--conditions clean,clean_rt60_0.5`
# narrow it. About 20 minutes on two cores.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_voice_debs
step "building the array benchmark (release)"
cargo build --release --workspace --example bench_array --bin speech_model
need_speech_model
step "robocog speech_recognition through a 4-microphone array, against its first microphone alone"
"$BIN/examples/bench_array" "$@"
