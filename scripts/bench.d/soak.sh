#!/usr/bin/env bash
# A day at the exhibition in miniature: one `robocog launch` plays a game again and again (every
# component a process), and after every game each process is sampled: resident memory, open file
# descriptors, threads, and the router's sessions. Target: every game passes, and no resource
# grows more than 5 % between game 20 and the last games (means over 5 games, so one game's
# allocator noise is not a leak); no component restarts.
#
#   scripts/bench soak [GAMES] [SCENARIO]   the touch game, the simulated person playing SCENARIO
#                                           GAMES times, each time as a new visitor (default 200
#                                           `still`; a game takes about 30 s: 100 minutes)
#   scripts/bench soak coach [ATTACKS]      the coach game: the simulated field plays ATTACKS
#                                           attacks of 90 s (default 36, about an hour of the
#                                           field's time, at 3x: about 20 minutes), a coach
#                                           outside the graph giving a panel command every few
#                                           seconds; the teammate does not score (an attack
#                                           lasts), the opponents play, robots fall at random
#
# Figures: a table per process, the CSV (game, process, ...) kept in the build folder's
# bench/soak/, and the JSON line.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
usage="usage: scripts/bench soak [GAMES] [SCENARIO] | scripts/bench soak coach [ATTACKS]"
if [ "${1:-}" = coach ]; then
  game=coach
  games="${2:-36}"
else
  game=touch
  games="${1:-200}"
  scenario="${2:-still}"
fi
if ! [[ "$games" =~ ^[0-9]+$ ]] || [ "$games" -lt 1 ]; then
  echo "$usage: the count is a whole number (at least 1), got '$games'" >&2
  exit 2
fi
need_debs pkg-config python3
need_voice_debs
work="$CARGO_TARGET_DIR/bench/soak"
mkdir -p "$work"
stamp="$(date -u +%Y%m%dT%H%M%SZ)"
args="$work/launch-$stamp.args"
ns="bench-soak-$$"
warm=20
[ "$games" -lt 40 ] && warm=$(( games / 4 > 1 ? games / 4 : 1 ))
# One argument per line: the launch the sampler runs (its own namespace, a free router port, the
# panel off: nothing else on the machine is disturbed).
if [ "$game" = touch ]; then
  build_graph launch/touch_the_ball.toml
  printf '%s\n' "$BIN/robocog" launch launch/touch_the_ball.toml \
    --set "scenario=$scenario" --set "games=$games" --set panel=false \
    --namespace "$ns" --router tcp/127.0.0.1:0 --color never >"$args"
  step "soak: the $scenario scenario $games times in one launch (about $(( games / 2 )) minutes); samples after each game"
  python3 "$ROOT/scripts/bench.d/soak.py" "$args" "$work/soak-$stamp.csv" "$games" "$warm"
else
  build_graph launch/nao_coach.toml
  scale=3
  # The field's UDP ports: free ones, so that another field on this machine is not disturbed.
  read -r debug_port gc_port command_port < <(python3 -c '
import socket
s = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(3)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
  printf '%s\n' "$BIN/robocog" launch launch/nao_coach.toml \
    --set "attacks=$games" --set "time_scale=$scale" --set panel=false --set passive_teammate=true \
    --set "debug_port=$debug_port" --set "gc_port=$gc_port" --set "command_port=$command_port" \
    --namespace "$ns" --router tcp/127.0.0.1:0 --color never >"$args"
  step "soak: the coach game, $games attacks in one launch at ${scale}x (about $(( games * 105 / scale / 60 )) minutes); samples after each attack"
  python3 "$ROOT/scripts/bench.d/soak.py" "$args" "$work/soak-coach-$stamp.csv" "$games" "$warm" \
    --coach "$BIN/robocog" "$ns" "$scale"
fi
