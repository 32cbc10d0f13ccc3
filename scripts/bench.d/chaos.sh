#!/usr/bin/env bash
# The chaos matrix: every component of a game killed with SIGKILL as each phase of the game
# begins, one game per cell.
#
#   scripts/bench chaos [--components a,b] [--phases p,q]         the touch game
#   scripts/bench chaos coach [--components a,b] [--phases p,q]   the coach game
#
# Touch: the simulated person plays the `still` scenario; phases greeting, scan, tracking,
# reaching, touching, homing, goodbye. A cell passes when the game completes, the killed
# component was restarted, the person never had to repeat a command, and the robot said nothing
# untrue (no "I lost the ball" with the ball held still in front of it). About 40 s a cell: the
# whole matrix (9 components x 7 phases) takes about 45 min.
# Coach: one attack on the simulated field at 3x, a coach outside the graph giving four panel
# commands; phases go_to, turn, search, dribble (each command in flight), penalty and fall. A
# cell passes when the attack is played out, the component was restarted, every command reached
# the robot and no other did, and the robot said nothing untrue (no "not responding", no fall or
# penalty it did not have). About 35 s a cell: 6 components x 6 phases, about 20 min.
# Target: every cell passes. The cells run from a copy of the graph's programs, so a build
# meanwhile does not mix versions.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
game=touch
if [ "${1:-}" = coach ]; then
  game=coach
  shift
fi
manifest=launch/touch_the_ball.toml
[ "$game" = coach ] && manifest=launch/nao_coach.toml
need_debs pkg-config python3
need_voice_debs
build_graph "$manifest"
stamp="$(date -u +%Y%m%dT%H%M%SZ)"
work="$CARGO_TARGET_DIR/bench/chaos/$game-$stamp"
mkdir -p "$work/bin"
for p in robocog $GRAPH_PROGRAMS; do
  case "$p" in */*) continue ;; esac
  cp -l "$BIN/$p" "$work/bin/" 2>/dev/null || cp "$BIN/$p" "$work/bin/"
done
trap 'rm -rf "$work/bin"' EXIT
step "chaos matrix: each component killed as each phase of the $game game begins (cells' output in $work)"
python3 "$ROOT/scripts/bench.d/chaos.py" "$work/bin" "$work" --game "$game" "$@"
