#!/usr/bin/env bash
# The deep representation: in-process transform lookups (13 joints), fork and what-if, and the
# dr/transform and dr/update services over the bus, p50/p99 per call, in both ways components can
# join the bus: as clients of the launcher's router (the default) and as peers (`--mode peer`,
# direct links after discovery through the router). Extra arguments go to bench_dr.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
step "building bench_dr (release)"
(cd "$ROOT" && cargo build --release --workspace --bin bench_dr)
work="$CARGO_TARGET_DIR/bench/dr"
mkdir -p "$work"
step "running bench_dr, components as clients of the router (the default)"
ROBOCOG_MODE=client "$BIN/bench_dr" "$@" | tee "$work/client.txt"
step "running bench_dr, components as peers (--mode peer)"
ROBOCOG_MODE=peer "$BIN/bench_dr" "$@" | tee "$work/peer.txt"
python3 - "$work/client.txt" "$work/peer.txt" <<'PY'
import json, sys
client = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
peer = json.loads(open(sys.argv[2]).read().strip().splitlines()[-1])
out = dict(client)
for k, v in peer.items():
    if k.startswith("bus_") and k != "bus_calls":
        out["peer_" + k] = v
print()
print("| over the bus | client via router p50 µs | peer p50 µs |")
print("|---|---:|---:|")
for k in ("bus_transform_query_p50_us", "bus_update_p50_us", "bus_echo_baseline_p50_us"):
    print(f"| {k} | {client[k]} | {peer[k]} |")
print(json.dumps(out))
PY
