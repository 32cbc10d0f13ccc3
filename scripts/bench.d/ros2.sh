#!/usr/bin/env bash
# What the rmw_zenoh-compatible mode costs: robocog's bus latency p50/p99 (64 B, 4 KiB, 64 KiB)
# and 8-byte throughput with the ROS 2 bridge off (the peer) and on, and the latency of the same
# probes as a ROS 2 subscriber on the rmw_zenoh key receives them; then the bytes of the ROS 2
# schemas a recording carries. The last line is one JSON object with the figures. `--quick`: fewer samples.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
step "building the ROS 2 bridge benchmark and robocog (release)"
cargo build --release --workspace --example bench_ros2 --bin robocog
quick=()
for a in "$@"; do [ "$a" = "--quick" ] && quick=(--quick); done
# The table goes to this script's stderr as it is (tee to /dev/stderr would reopen a log file at
# its start and write over it).
bus_json="$("$BIN/examples/bench_ros2" "${quick[@]}" | tee >(cat >&2) | tail -n 1)"
# The schema bytes of a recording: one schema per type, as `robocog record` writes them.
schema_json="$("$BIN/robocog" interface list --json | python3 -c '
import json, subprocess, sys
types = json.load(sys.stdin)
ros = 0
for t in types:
    if t["ros2"]:
        ros += len(subprocess.run([sys.argv[1], "interface", "show", t["type"]],
                                  capture_output=True, check=True).stdout)
print(json.dumps({"types": len(types), "ros2_types": sum(1 for t in types if t["ros2"]),
                  "ros2msg_schema_bytes_all_types": ros}))
' "$BIN/robocog")"
echo "schemas: $schema_json" >&2
python3 -c 'import json,sys; a=json.loads(sys.argv[1]); a.update(json.loads(sys.argv[2])); print(json.dumps(a))' \
  "$bus_json" "$schema_json"
