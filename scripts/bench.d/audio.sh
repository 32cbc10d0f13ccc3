#!/usr/bin/env bash
# The audio path: a click on audio/out back on audio/in through audio_io and a sound server
# (speaker to microphone), against the same click through libpulse alone (the floor), the
# capture-to-bus delay of the microphone's chunks, and the robot's own voice in its microphone
# without and with the sound server's WebRTC echo canceller. The sound server is a PulseAudio of
# this run's own (system mode as root, an anonymous unix socket in the bench's folder): a null
# sink `room` with a virtual source `mic` on its monitor, and null sinks `speaker` (the robot's
# loudspeaker) and `person` (a player talking over the robot) heard in the room through
# loop-backs. Extra arguments go to bench_audio
# (--clicks N, --sentences N).
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
need_voice_debs
# The workspace's build (what scripts/test builds, so its cache serves): a build of audio_io
# alone would resolve its dependencies' features apart and build them all again.
step "building bench_audio (release, with the workspace's binaries)"
(cd "$ROOT" && cargo build --release --workspace --bins)
# The server drops to its own user: its folder is a temporary one it can reach (not under a
# home folder), removed at the end.
work=$(mktemp -d "${TMPDIR:-/tmp}/robocog-bench-audio.XXXXXX")
chmod 0777 "$work"
cat >"$work/room.pa" <<PA
load-module module-native-protocol-unix socket=$work/native auth-anonymous=1
load-module module-null-sink sink_name=room rate=48000 channels=2
load-module module-virtual-source source_name=mic master=room.monitor
load-module module-null-sink sink_name=speaker rate=48000 channels=2
load-module module-loopback source=speaker.monitor sink=room latency_msec=20
load-module module-null-sink sink_name=person rate=48000 channels=2
load-module module-loopback source=person.monitor sink=room latency_msec=20
PA
mode=()
[ "$(id -u)" -eq 0 ] && mode=(--system)
step "starting a sound server ($work/native)"
PULSE_RUNTIME_PATH="$work/runtime" pulseaudio "${mode[@]}" --daemonize=no --use-pid-file=no \
  --disallow-exit --exit-idle-time=-1 --log-target=stderr -n -F "$work/room.pa" \
  2>"$work/server.log" &
server=$!
trap 'kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true; rm -rf "$work"' EXIT
for _ in $(seq 1 100); do
  pactl --server "unix:$work/native" info >/dev/null 2>&1 && break
  sleep 0.1
done
pactl --server "unix:$work/native" info >/dev/null || { cat "$work/server.log" >&2; exit 1; }
step "running bench_audio"
"$BIN/bench_audio" --server "unix:$work/native" "$@"
