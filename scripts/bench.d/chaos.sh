#!/usr/bin/env bash
# The chaos matrix: every component of the touch game killed with SIGKILL as each phase of the
# game begins (greeting, scan, tracking, reaching, touching, homing, goodbye), one game per cell,
# the simulated person playing the `still` scenario. A cell passes when the game completes, the
# killed component was restarted, the person never had to repeat a command, and the robot said
# nothing untrue (no "I lost the ball" with the ball held still in front of it). Target: every
# cell passes. About 40 s a cell: the whole matrix (9 components x 7 phases) takes about 45 min.
# The cells run from a copy of the graph's programs, so a build meanwhile does not mix versions.
# Usage: scripts/bench chaos [--components a,b] [--phases p,q]
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_debs pkg-config python3
need_voice_debs
build_graph launch/touch_the_ball.toml
stamp="$(date -u +%Y%m%dT%H%M%SZ)"
work="$CARGO_TARGET_DIR/bench/chaos/$stamp"
mkdir -p "$work/bin"
for p in robocog $GRAPH_PROGRAMS; do
  case "$p" in */*) continue ;; esac
  cp -l "$BIN/$p" "$work/bin/" 2>/dev/null || cp "$BIN/$p" "$work/bin/"
done
trap 'rm -rf "$work/bin"' EXIT
step "chaos matrix: each component killed as each phase of the touch game begins (cells' output in $work)"
python3 "$ROOT/scripts/bench.d/chaos.py" "$work/bin" "$work" "$@"
