#!/usr/bin/env bash
# The Nao bridge's hot paths on loopback: bus command -> UDP packet at the robot, and debug
# packet at the bridge -> world model on the bus; p50/p99, beside a bare UDP hop.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
step "building the coach benchmark (release)"
cargo build --release --workspace --example bench_coach
step "running: bridge paths on loopback"
exec "$BIN/examples/bench_coach" "$@"
