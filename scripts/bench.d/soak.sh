#!/usr/bin/env bash
# A day at the exhibition in miniature: one `robocog launch` of the touch game (every component a
# process, the simulated person) plays the `still` scenario GAMES times, each time as a new
# visitor. After every game each process is sampled: resident memory, open file descriptors,
# threads, and the router's sessions. Target: every game passes, and no resource grows more than
# 5 % between game 20 and the last games (means over 5 games, so one game's allocator noise is not
# a leak); no component restarts.
# Figures: a table per process, the CSV (game, process, ...) kept in the build folder's
# bench/soak/, and the JSON line. A game takes about 30 s: 200 games are about 100 minutes.
# Usage: scripts/bench soak [GAMES] [SCENARIO]   (default 200 still)
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
games="${1:-200}"
scenario="${2:-still}"
if ! [[ "$games" =~ ^[0-9]+$ ]] || [ "$games" -lt 1 ]; then
  echo "usage: scripts/bench soak [GAMES] [SCENARIO]: GAMES is a whole number of games (at least 1)" >&2
  exit 2
fi
need_debs pkg-config python3
need_voice_debs
build_graph launch/touch_the_ball.toml
work="$CARGO_TARGET_DIR/bench/soak"
mkdir -p "$work"
stamp="$(date -u +%Y%m%dT%H%M%SZ)"
args="$work/launch-$stamp.args"
# One argument per line: the launch the sampler runs (its own namespace, a free router port, the
# panel off: nothing else on the machine is disturbed).
printf '%s\n' "$BIN/robocog" launch launch/touch_the_ball.toml \
  --set "scenario=$scenario" --set "games=$games" --set panel=false \
  --namespace "bench-soak-$$" --router tcp/127.0.0.1:0 --color never >"$args"
warm=20
[ "$games" -lt 40 ] && warm=$(( games / 4 > 1 ? games / 4 : 1 ))
step "soak: the $scenario scenario $games times in one launch (about $(( games / 2 )) minutes); samples after each game"
python3 "$ROOT/scripts/bench.d/soak.py" "$args" "$work/soak-$stamp.csv" "$games" "$warm"
