#!/usr/bin/env bash
# The deep representation: in-process transform lookups (13 joints), fork and what-if, and the
# dr/transform and dr/update services over the bus, p50/p99 per call, in both ways components can
# join the bus: as clients of the launcher's router (the default) and as peers (`--mode peer`,
# direct links after discovery through the router); and the game's dr/transform calls while a
# foreign zenoh client and a robocog component flood the service (target: p99 under 20 ms, none
# failed; the flood refused and counted per caller). Extra arguments go to bench_dr.
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
# The same flood beside a touch game (every component a process): the game must pass.
need_voice_debs
build_all
port="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
ns="bench-dr-game-$$"
step "a touch game (scenario still) with the flood beside it, router tcp/127.0.0.1:$port"
"$BIN/robocog" launch "$ROOT/launch/touch_the_ball.toml" --set scenario=still \
  --namespace "$ns" --router "tcp/127.0.0.1:$port" --color never >"$work/game.log" 2>&1 &
game=$!
trap 'kill "$game" 2>/dev/null || true' EXIT
"$BIN/bench_dr" --beside "tcp/127.0.0.1:$port" --namespace "$ns" --flood-s 15 | tee "$work/beside.txt"
if wait "$game"; then game_passed=true; else game_passed=false; fi
trap - EXIT
if [[ "$game_passed" != true ]]; then
  echo "the touch game beside the flood failed; its last lines:" >&2
  tail -30 "$work/game.log" >&2
fi
python3 - "$work/client.txt" "$work/peer.txt" "$work/beside.txt" "$game_passed" <<'PY'
import json, sys
client = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
peer = json.loads(open(sys.argv[2]).read().strip().splitlines()[-1])
beside = json.loads(open(sys.argv[3]).read().strip().splitlines()[-1])
out = dict(client)
for k, v in beside.items():
    out["game_" + k] = v
out["game_beside_flood_passed"] = sys.argv[4] == "true"
for k, v in peer.items():
    if (k.startswith("bus_") and k != "bus_calls") or k.startswith("flood_game_transform"):
        out["peer_" + k] = v
print()
print("| over the bus | client via router (µs) | peer (µs) |")
print("|---|---:|---:|")
for k in ("bus_transform_query_p50_us", "bus_update_p50_us", "bus_echo_baseline_p50_us",
          "flood_game_transform_p50_us", "flood_game_transform_p99_us"):
    print(f"| {k} | {client.get(k, '-')} | {peer.get(k, '-')} |")
print()
print("| beside a touch game (every component a process) | value |")
print("|---|---:|")
for k in ("flood_game_transform_p50_us", "flood_game_transform_p99_us", "flood_game_failed",
          "flood_busy_refused", "flood_expired_dropped"):
    print(f"| {k} | {beside.get(k, '-')} |")
print(f"| the game passed | {out['game_beside_flood_passed']} |")
print(json.dumps(out))
PY
