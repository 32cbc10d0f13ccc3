#!/usr/bin/env bash
# The robocog Python package on the bus: publish-to-callback latency (p50, p99; one way = round
# trip / 2) and one-way throughput, for a 64 B message and a 640x480 RGB-D frame (1.5 MB, shared
# memory), in the same run, every end its own process, all clients of one zenoh router on
# loopback (`robocog router`, multicast scouting off):
#   1. Python <-> Python: the `robocog` package at both ends (scripts/bench.d/python/robocog_end.py);
#   2. Python -> Rust and Rust -> Python: one end the Rust `bench_bus_machines` echo or probe
#      (64 B Pings and Counter64; it has no frames and keeps shared memory off);
#   3. Rust <-> Rust, the reference: bench_bus_machines probe and echo (64 B), and `bench_bus`
#      for the frame (three sessions in one process through a router of its own);
#   4. a plain eclipse-zenoh Python client (scripts/bench.d/python/zenoh_end.py, no robocog: the
#      same CDR bytes on the same keys) at both ends (the baseline), and as the peer of a robocog
#      Python end, both ways.
# Prints the tables and, as its last line, one JSON object with the figures and their ratios to
# the Rust reference and to the plain zenoh-python client. `--quick`: fewer samples, 1 s runs.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"

quick=()
for a in "$@"; do [ "$a" = "--quick" ] && quick=(--quick); done

need_python
step "building the Rust ends (robocog router, bench_bus, bench_bus_machines; release)"
STEP_HINT="$CARGO_HINT"
cargo build --release --workspace --bin robocog --example bench_bus --example bench_bus_machines
STEP_HINT=""

PY="$ROBOCOG_PYTHON"
HERE="$ROOT/scripts/bench.d/python"
MACHINES="$BIN/examples/bench_bus_machines"
# The Rust probe's one-way messages (bench_bus_machines: 500 000, a tenth with --quick); the
# Python ends send as many at most, so the Rust echo's count ends on them.
if [ ${#quick[@]} -gt 0 ]; then rust_count=50000; else rust_count=500000; fi

work="$(mktemp -d "${TMPDIR:-/tmp}/robocog-bench-python.XXXXXX")"
declare -A pid_of=()

stop() { # stop <name>...: the processes started under these names
  local name pid
  for name in "$@"; do
    pid="${pid_of[$name]:-}"
    [ -n "$pid" ] || continue
    kill "$pid" 2>/dev/null || true
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
    unset "pid_of[$name]"
  done
}

cleanup() {
  local rc=$?
  stop "${!pid_of[@]}"
  if [ "$rc" -ne 0 ]; then
    echo "error: the Python benchmark failed (exit $rc); the last lines of each process:" >&2
    for log in "$work"/*.log; do
      [ -s "$log" ] && { echo "--- $(basename "$log"):" >&2; tail -n 20 "$log" >&2; }
    done
  fi
  rm -rf "$work"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

start() { # start <name> <program> <args>...: a server in the background
  local name="$1"
  shift
  "$@" >"$work/$name.out" 2>"$work/$name.log" &
  pid_of[$name]=$!
}

wait_ready() { # wait_ready <name> <pattern>: its output has a line starting with <pattern> in 20 s
  local name="$1" pattern="$2" deadline=$((SECONDS + 20))
  until grep -q "^$pattern" "$work/$name.out" 2>/dev/null; do
    if ! kill -0 "${pid_of[$name]}" 2>/dev/null; then
      echo "error: $name exited before it was ready" >&2
      return 1
    fi
    if [ "$SECONDS" -ge "$deadline" ]; then
      echo "error: $name not ready after 20 s" >&2
      return 1
    fi
    sleep 0.1
  done
}

run() { # run <name> <program> <args>...: a probe, waited for; its output into <name>.json
  local name="$1" rc=0
  shift
  # In the background and waited for, so that a signal to this script is handled at once.
  timeout 300 "$@" >"$work/$name.json" 2>"$work/$name.log" &
  pid_of[$name]=$!
  wait "${pid_of[$name]}" || rc=$?
  unset "pid_of[$name]"
  if [ "$rc" -ne 0 ]; then
    echo "error: $name failed (exit $rc)" >&2
    return "$rc"
  fi
}

step "starting a zenoh router on loopback (robocog router, multicast scouting off)"
cat >"$work/router.json5" <<'EOF'
{
  mode: "router",
  scouting: { multicast: { enabled: false } },
  listen: { endpoints: ["tcp/127.0.0.1:0"] },
}
EOF
start router "$BIN/robocog" router --config "$work/router.json5"
wait_ready router "listening on"
endpoint="$(sed -n 's/^listening on //p' "$work/router.out" | head -n1)"
echo "router: $endpoint" >&2

step "writing the CDR bytes the plain zenoh client sends (robocog.encode)"
"$PY" "$HERE/robocog_end.py" --role templates --out "$work/cdr"

ns() { echo "bench-python-$$-$1"; }
robocog_echo() { # robocog_echo <pair> [args]...
  local pair="$1"
  shift
  start echo "$PY" "$HERE/robocog_end.py" --role echo --connect "$endpoint" --namespace "$(ns "$pair")" "$@"
  wait_ready echo ready
}
rust_echo() {
  start echo "$MACHINES" --role echo --connect "$endpoint" --namespace "$(ns "$1")" "${quick[@]}"
  wait_ready echo ready
}
zenoh_echo() {
  start echo "$PY" "$HERE/zenoh_end.py" --role echo --connect "$endpoint" --namespace "$(ns "$1")" \
    --templates "$work/cdr"
  wait_ready echo ready
}

step "1. Python -> Python (robocog at both ends): 64 B and frames"
robocog_echo py_py
run py_py "$PY" "$HERE/robocog_end.py" --role probe --connect "$endpoint" --namespace "$(ns py_py)" "${quick[@]}"
stop echo

step "2a. Python probe -> Rust echo (bench_bus_machines): 64 B"
rust_echo py_rust
run py_rust "$PY" "$HERE/robocog_end.py" --role probe --connect "$endpoint" --namespace "$(ns py_rust)" \
  --no-frames --max-count "$rust_count" "${quick[@]}"
stop echo

step "2b. Rust probe (bench_bus_machines) -> Python echo: 64 B"
robocog_echo rust_py --expected "$rust_count"
run rust_py "$MACHINES" --role probe --connect "$endpoint" --namespace "$(ns rust_py)" "${quick[@]}"
stop echo

step "3a. Rust <-> Rust (bench_bus_machines probe and echo): 64 B"
rust_echo rust_rust
run rust_rust "$MACHINES" --role probe --connect "$endpoint" --namespace "$(ns rust_rust)" "${quick[@]}"
stop echo

step "3b. Rust <-> Rust frames (bench_bus: the typed bus, shared memory, one process)"
run rust_bus "$BIN/examples/bench_bus" "${quick[@]}"

step "4a. plain zenoh-python <-> plain zenoh-python (the baseline): 64 B and frames"
zenoh_echo zenoh_py
run zenoh_py "$PY" "$HERE/zenoh_end.py" --role probe --connect "$endpoint" --namespace "$(ns zenoh_py)" \
  --templates "$work/cdr" "${quick[@]}"

step "4b. Python probe -> plain zenoh-python echo: 64 B and frames"
stop echo
zenoh_echo py_zenoh_py
run py_zenoh_py "$PY" "$HERE/robocog_end.py" --role probe --connect "$endpoint" \
  --namespace "$(ns py_zenoh_py)" "${quick[@]}"
stop echo

step "4c. plain zenoh-python probe -> Python echo: 64 B and frames"
robocog_echo zenoh_py_py
run zenoh_py_py "$PY" "$HERE/zenoh_end.py" --role probe --connect "$endpoint" \
  --namespace "$(ns zenoh_py_py)" --templates "$work/cdr" "${quick[@]}"
stop echo router

"$PY" "$HERE/report.py" "$work" "${quick[@]}"
