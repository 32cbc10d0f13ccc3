#!/usr/bin/env bash
# The touch-the-ball game end to end, every component a process. The simulated person plays the
# `bench` scenario (five 8 cm jumps of the ball, then "touch it" twice) RUNS times, then every
# other shipped scenario that starts a search by itself once (still, moving, out_of_view,
# unreachable, and confirm_yes with dialog_high=0.9; tracker_restart needs a test to kill the
# tracker, so it is left out). Figures:
#   - touch (bench runs): end of the person's "touch it" sentence to the robot's hand within 3 cm
#     of the ball (speech recognition + dialog + Executive + IK + trajectory + joint dynamics);
#   - gaze (bench runs): ball jump to the head camera's axis within 3 degrees of the ball (render +
#     tracking + DR + gaze IK + neck motion);
#   - scan (every run): end of the person's "scan the ball" (or its synonym "track the ball", or
#     the "yes" that confirms it when the robot asked) to the tracker's "detected" event (speech
#     recognition + dialog + Executive + the head's search + tracking).
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
# name, scenario, extra --set; one line per game.
plan=()
for i in $(seq 1 "$runs"); do
  plan+=("bench$i bench")
done
plan+=("still still" "moving moving" "out_of_view out_of_view" "unreachable unreachable"
  "confirm_yes confirm_yes dialog_high=0.9")
n=0
for line in "${plan[@]}"; do
  read -r name scenario extra <<<"$line"
  n=$((n + 1))
  # The panel runs too, on a free port.
  sets=(--set "scenario=$scenario" --set "panel_http=127.0.0.1:0")
  if [[ -n "${extra:-}" ]]; then
    sets+=(--set "$extra")
  fi
  step "game $n of ${#plan[@]}: robocog launch launch/touch_the_ball.toml ${sets[*]}"
  if ! "$BIN/robocog" launch launch/touch_the_ball.toml "${sets[@]}" \
      --namespace "bench-touch-$$-$n" --router tcp/127.0.0.1:0 --color never >"$out/$name.log" 2>&1; then
    echo "game $n ($scenario) failed; its last lines:" >&2
    tail -30 "$out/$name.log" >&2
    exit 1
  fi
  grep -h "person: timings" "$out/$name.log" | sed 's/.*person: timings //' >"$out/$name.timings.json"
done
python3 - "$out" "$runs" <<'EOF'
import json, sys, glob, os
out, runs = sys.argv[1], int(sys.argv[2])
touch, gaze, scan = [], [], []
scan_by = {}
SCAN = ('says "scan the ball"', 'says "track the ball"')
for f in sorted(glob.glob(os.path.join(out, "*.timings.json"))):
    name = os.path.basename(f)[: -len(".timings.json")]
    ts = json.load(open(f))
    for k, t in enumerate(ts):
        if name.startswith("bench"):
            if "hand within" in t["what"]:
                touch.append(t["after_s"])
            elif "gaze within 3.0" in t["what"] and t["step"] > 5:
                gaze.append(t["after_s"])
        # A detection right after the scan command (or after the "yes" that confirmed it).
        if t["what"] != "ball detected" or t["step"] > t["action_step"] + 1:
            continue
        confirmed = (
            t["action"] == 'says "yes"'
            and k > 0
            and any(w in ts[k - 1]["what"] for w in ("did you say scan", "did you say track"))
        )
        if t["action"] in SCAN or confirmed:
            scan.append(t["after_s"])
            scan_by.setdefault(name.rstrip("0123456789"), []).append(t["after_s"])
def pct(v, p):
    v = sorted(v)
    if not v:
        return float("nan")
    k = min(len(v) - 1, max(0, round(p / 100 * (len(v) - 1))))
    return v[k]
print()
print(f"touch-the-ball game: bench scenario x {runs}, 5 other scenarios x 1, {os.cpu_count()} cores")
print(f"{'figure':44} {'n':>4} {'p50 s':>8} {'p90 s':>8} {'max s':>8}")
for name, v in [
    ("end of 'touch it' -> hand within 3 cm", touch),
    ("ball jump 8 cm -> gaze within 3 deg", gaze),
    ("end of 'scan the ball' -> ball detected", scan),
]:
    print(f"{name:44} {len(v):4d} {pct(v,50):8.2f} {pct(v,90):8.2f} {max(v) if v else float('nan'):8.2f}")
print("scan, per scenario: " + ", ".join(f"{k} {' '.join(f'{x:.2f}' for x in v)} s" for k, v in sorted(scan_by.items())))
print(json.dumps({
    "runs": runs,
    "touch_n": len(touch), "touch_p50_s": round(pct(touch, 50), 3), "touch_p90_s": round(pct(touch, 90), 3),
    "gaze_n": len(gaze), "gaze_settle_p50_s": round(pct(gaze, 50), 3), "gaze_settle_p90_s": round(pct(gaze, 90), 3),
    "scan_n": len(scan), "scan_p50_s": round(pct(scan, 50), 3), "scan_p90_s": round(pct(scan, 90), 3),
    "scan_max_s": round(max(scan), 3) if scan else float("nan"),
}))
EOF
