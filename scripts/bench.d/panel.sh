#!/usr/bin/env bash
# The command panel: a click in headless Chromium (GoToPosition, then a point of the field) to the
# checked command on nao/command, through the panel's WebSocket, the bus and the Executive's coach
# machine (which answers and checks it against the game state first); p50/p99 over N clicks
# (default 100: scripts/bench panel --clicks 200), in one attack made long enough for them
# (attack_s=3600: the simulated game's default 90 s ended the clicks of a slow machine). The last hop, nao/command to the robot's UDP
# packet, is scripts/bench coach's. The graph is launch/panel_coach.toml with the simulated field
# (its GameController brings the game to PLAYING, when the coach lets the robot move).
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
clicks=100
if [ "${1:-}" = "--clicks" ] && [ -n "${2:-}" ]; then clicks="$2"; fi
need_browser
step "building the panel, the bridge and the launcher (release)"
cargo build --release --workspace --bin robocog --bin nao_bridge --bin spl_field --bin command_generator --bin executive --bin deep_representation
free_port() { python3 -c 'import socket,sys; s=socket.socket(socket.AF_INET, getattr(socket,"SOCK_"+sys.argv[1])); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])' "$1"; }
http_port=$(free_port STREAM)
router_port=$(free_port STREAM)
cmd_port=$(free_port DGRAM)
debug_port=$(free_port DGRAM)
gc_port=$(free_port DGRAM)
ns="bench-panel-$$"
work="$CARGO_TARGET_DIR/bench/panel"
mkdir -p "$work"
log="$work/launch.log"
step "starting the graph (simulated field, bridge, coach machine, panel on 127.0.0.1:$http_port)"
"$BIN/robocog" launch launch/panel_coach.toml --namespace "$ns" --router "tcp/127.0.0.1:$router_port" \
  --color never --set falls_per_min=0 --set attack_s=3600 --set command_port="$cmd_port" --set debug_port="$debug_port" --set gc_port="$gc_port" \
  --set panel_http="127.0.0.1:$http_port" >"$log" 2>&1 &
launcher=$!
trap 'kill -TERM "$launcher" 2>/dev/null || true; wait "$launcher" 2>/dev/null || true' EXIT
for _ in $(seq 1 100); do
  grep -q "command panel on http://" "$log" && break
  if ! kill -0 "$launcher" 2>/dev/null; then cat "$log" >&2; echo "the graph did not start" >&2; exit 1; fi
  sleep 0.2
done
grep -q "command panel on http://" "$log" || { cat "$log" >&2; echo "the panel did not come up in 20 s" >&2; exit 1; }
echo_cmd=$(printf '["%s","topic","echo","nao/command","--namespace","%s","--connect","tcp/127.0.0.1:%s"]' "$BIN/robocog" "$ns" "$router_port")
step "clicking $clicks times once the game is PLAYING (headless Chromium, playwright-core)"
(cd tests/browser && node bench_panel.mjs --url "http://127.0.0.1:$http_port/" --echo "$echo_cmd" \
  --clicks "$clicks")
