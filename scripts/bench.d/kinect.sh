#!/usr/bin/env bash
# The freenect driver's cost per frame through Debian's fakenect libfreenect: a dump of 300
# rendered frames is written, then replayed through the real library as fast as it delivers;
# libfreenect's share (delivery and copy) against robocog's (disparity to mm, registration).
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_camera_debs
step "building the Kinect driver benchmark (release)"
cargo build --release --workspace --example bench_kinect
dump="$(mktemp -d)"
trap 'rm -rf "$dump"' EXIT
step "writing a fakenect dump of rendered frames"
"$BIN/examples/bench_kinect" write "$dump"
step "replaying it through fakenect"
FAKENECT_PATH="$dump" "$BIN/examples/bench_kinect" replay
