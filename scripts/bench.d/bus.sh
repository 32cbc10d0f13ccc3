#!/usr/bin/env bash
# Typed bus vs raw zenoh: latency p50/p99 (64 B, 4 KiB, 1 MiB, RGB-D frame), 8-byte throughput.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
step "building the bus benchmark (release)"
cargo build --release -p interfaces --example bench_bus
step "running: typed bus vs raw zenoh, same run, same sessions"
exec "$BIN/examples/bench_bus" "$@"
