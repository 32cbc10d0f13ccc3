#!/usr/bin/env bash
# The touch-the-ball game end to end, every component a process: the simulated person plays the
# `bench` scenario (five 8 cm jumps of the ball, then "touch it" twice) RUNS times. Figures:
#   - touch: end of the person's "touch it" sentence to the robot's hand within 3 cm of the ball
#     (speech recognition + dialog + Executive + IK + trajectory + joint dynamics);
#   - gaze: ball jump to the head camera's axis within 3 degrees of the ball (render + tracking +
#     DR + gaze IK + neck motion).
# Usage: scripts/bench touch [RUNS]   (default 3)
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
runs="${1:-3}"
need_debs pkg-config
need_voice_debs
build_all
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
for i in $(seq 1 "$runs"); do
  step "run $i of $runs: robocog launch launch/touch_the_ball.toml --set scenario=bench"
  if ! "$BIN/robocog" launch launch/touch_the_ball.toml --set scenario=bench \
      --namespace "bench-touch-$$-$i" --router tcp/127.0.0.1:0 --color never >"$out/run$i.log" 2>&1; then
    echo "run $i failed; its last lines:" >&2
    tail -30 "$out/run$i.log" >&2
    exit 1
  fi
  grep -h "person: timings" "$out/run$i.log" | sed 's/.*person: timings //' >"$out/timings$i.json"
done
python3 - "$out" "$runs" <<'EOF'
import json, sys, glob, statistics, platform, os
out, runs = sys.argv[1], int(sys.argv[2])
touch, gaze = [], []
for f in sorted(glob.glob(os.path.join(out, "timings*.json"))):
    for t in json.load(open(f)):
        if "hand within" in t["what"]:
            touch.append(t["after_s"])
        elif "gaze within 3.0" in t["what"] and t["step"] > 5:
            gaze.append(t["after_s"])
def pct(v, p):
    v = sorted(v)
    if not v:
        return float("nan")
    k = min(len(v) - 1, max(0, round(p / 100 * (len(v) - 1))))
    return v[k]
print()
print(f"touch-the-ball game, {runs} runs, {os.cpu_count()} cores")
print(f"{'figure':44} {'n':>4} {'p50 s':>8} {'p90 s':>8} {'max s':>8}")
for name, v in [("end of 'touch it' -> hand within 3 cm", touch), ("ball jump 8 cm -> gaze within 3 deg", gaze)]:
    print(f"{name:44} {len(v):4d} {pct(v,50):8.2f} {pct(v,90):8.2f} {max(v) if v else float('nan'):8.2f}")
print(json.dumps({
    "runs": runs,
    "touch_n": len(touch), "touch_p50_s": round(pct(touch, 50), 3), "touch_p90_s": round(pct(touch, 90), 3),
    "gaze_n": len(gaze), "gaze_settle_p50_s": round(pct(gaze, 50), 3), "gaze_settle_p90_s": round(pct(gaze, 90), 3),
}))
EOF
