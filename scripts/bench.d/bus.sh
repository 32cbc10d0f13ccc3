#!/usr/bin/env bash
# Typed bus vs raw zenoh: latency p50/p99 (64 B, 4 KiB, 1 MiB, RGB-D frame), 8-byte throughput.
# Then the bus between two machines: two network namespaces joined by a veth pair (root needed),
# a router in each, the probe a client of A's router and the echo a client of B's: latency
# (64 B, 4 KiB, 64 KiB) and 8-byte throughput one way, routers joined over tcp and over mutual
# TLS, against the raw veth floor (plain TCP between the two addresses) measured in the same run.
# The last line is one JSON object with the figures of both parts. `--quick`: fewer samples.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
step "building the bus benchmarks (release)"
cargo build --release --workspace --example bench_bus --example bench_bus_machines

quick=()
for a in "$@"; do [ "$a" = "--quick" ] && quick=(--quick); done

SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"
work="$(mktemp -d "${TMPDIR:-/tmp}/robocog-bench-bus.XXXXXX")"
ns_a="rcbench-$$-a"
ns_b="rcbench-$$-b"
ip_a="10.77.0.1"
ip_b="10.77.0.2"
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
  for ns in "$ns_a" "$ns_b"; do
    if $SUDO ip netns list | grep -qw "$ns"; then
      # Anything still running in our namespaces was started by this script.
      for pid in $($SUDO ip netns pids "$ns" 2>/dev/null); do $SUDO kill -9 "$pid" 2>/dev/null || true; done
      $SUDO ip netns del "$ns" 2>/dev/null || true
    fi
  done
  if [ "$rc" -ne 0 ]; then
    echo "error: the bus benchmark failed (exit $rc); the last lines of each process:" >&2
    for log in "$work"/*.log; do
      [ -s "$log" ] && { echo "--- $(basename "$log"):" >&2; tail -n 20 "$log" >&2; }
    done
  fi
  rm -rf "$work"
  exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

machines() { # machines <ns> <args>...: one run of the machines bench in a namespace, waited for
  local ns="$1" rc=0
  shift
  # In the background and waited for, so that a signal to this script is handled at once.
  timeout 600 $SUDO ip netns exec "$ns" "$BIN/examples/bench_bus_machines" "$@" &
  pid_of[run]=$!
  wait "${pid_of[run]}" || rc=$?
  unset "pid_of[run]"
  return "$rc"
}

start() { # start <name> <ns> <args>...: a server in a namespace, in the background
  local name="$1" ns="$2"
  shift 2
  $SUDO ip netns exec "$ns" "$BIN/examples/bench_bus_machines" "$@" \
    >"$work/$name.out" 2>"$work/$name.log" &
  pid_of[$name]=$!
}

wait_ready() { # wait_ready <name>...: each prints `ready` within 15 s
  local name deadline
  for name in "$@"; do
    deadline=$((SECONDS + 15))
    until grep -q '^ready' "$work/$name.out" 2>/dev/null; do
      if ! kill -0 "${pid_of[$name]}" 2>/dev/null; then
        echo "error: $name exited before it was ready" >&2
        return 1
      fi
      if [ "$SECONDS" -ge "$deadline" ]; then
        echo "error: $name not ready after 15 s" >&2
        return 1
      fi
      sleep 0.1
    done
  done
}

step "running: typed bus vs raw zenoh, same run, same sessions"
# Its output as it comes, but its last line (its JSON object) kept aside: the last line of this
# script is the merged object.
"$BIN/examples/bench_bus" "$@" |
  awk -v last="$work/same_host.json" 'NR > 1 { print prev; fflush() } { prev = $0 } END { if (NR) print prev > last }'

step "two machines: namespaces $ns_a ($ip_a) and $ns_b ($ip_b), joined by a veth pair"
veth_a="rcb$(($$ % 1000000))a"
veth_b="rcb$(($$ % 1000000))b"
$SUDO ip netns add "$ns_a"
$SUDO ip netns add "$ns_b"
$SUDO ip link add "$veth_a" type veth peer name "$veth_b"
$SUDO ip link set "$veth_a" netns "$ns_a"
$SUDO ip link set "$veth_b" netns "$ns_b"
for side in "a $ns_a $veth_a $ip_a" "b $ns_b $veth_b $ip_b"; do
  read -r _ ns dev addr <<<"$side"
  $SUDO ip -n "$ns" link set "$dev" name eth0
  $SUDO ip -n "$ns" addr add "$addr/24" dev eth0
  $SUDO ip -n "$ns" link set eth0 up
  $SUDO ip -n "$ns" link set lo up
done

step "two machines: the veth floor (plain TCP ping-pong and one-way 8-byte messages)"
start tcp-echo "$ns_b" --role tcp-echo --listen "$ip_b:7600"
wait_ready tcp-echo
machines "$ns_a" --role tcp-probe --connect "$ip_b:7600" "${quick[@]}" >"$work/floor.json"
stop tcp-echo

bus_run() { # bus_run <tcp|tls> <port> <out> [router flags]...: routers, echo, probe
  # Each router at <proto>/<its ip>:<port> for the other, at tcp/127.0.0.1:<port + 1> for its
  # machine's components (fresh ports per run: none left in TIME_WAIT by the previous one).
  local proto="$1" port="$2" out="$3" local_ep
  local_ep="tcp/127.0.0.1:$(($2 + 1))"
  shift 3
  start "router-a" "$ns_a" --role router --machine a \
    --listen "$local_ep,$proto/$ip_a:$port" --connect "$proto/$ip_b:$port" "$@"
  start "router-b" "$ns_b" --role router --machine b \
    --listen "$local_ep,$proto/$ip_b:$port" --connect "$proto/$ip_a:$port" "$@"
  wait_ready router-a router-b
  start echo "$ns_b" --role echo --connect "$local_ep" "${quick[@]}"
  wait_ready echo
  machines "$ns_a" --role probe --connect "$local_ep" "${quick[@]}" >"$out"
  stop echo router-a router-b
}

step "two machines: the bus through both routers, routers joined over tcp"
bus_run tcp 7447 "$work/bus.json"

step "two machines: the bus through both routers, routers joined over mutual TLS"
certs="$work/certs"
mkdir -p "$certs"
(
  cd "$certs"
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 2 \
    -subj /CN=robocog-bench-ca -keyout ca.key -out ca.pem 2>/dev/null
  for m in "a $ip_a" "b $ip_b"; do
    read -r name addr <<<"$m"
    openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/CN=$name" \
      -keyout "$name.key" -out "$name.csr" 2>/dev/null
    openssl x509 -req -in "$name.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -days 2 \
      -extfile <(printf "subjectAltName=IP:%s\n" "$addr") -out "$name.pem" 2>/dev/null
  done
)
bus_run tls 7457 "$work/bus_tls.json" --tls-dir "$certs" --machines a,b

"$BIN/examples/bench_bus_machines" --role report --same-host "$work/same_host.json" \
  --floor "$work/floor.json" --bus "$work/bus.json" --bus-tls "$work/bus_tls.json"
