#!/usr/bin/env bash
# The touch-the-ball game end to end, every component a process. The simulated person plays the
# `bench` scenario (five 8 cm jumps of the ball, then "touch it" twice) RUNS times, then every
# other shipped scenario that starts a search by itself once (still, moving, out_of_view,
# unreachable, beside (reached with the base), and confirm_yes with dialog_high=0.9;
# tracker_restart needs a test to kill the tracker, so it is left out). Figures:
#   - touch (bench runs): end of the person's "touch it" sentence to the robot's hand within 3 cm
#     of the ball (speech recognition + dialog + Executive + IK + trajectory + joint dynamics);
#   - gaze (bench runs): ball jump to the head camera's axis within 3 degrees of the ball (render +
#     tracking + DR + gaze IK + neck motion);
#   - scan (every run): end of the person's "scan the ball" (or its synonym "track the ball", or
#     the "yes" that confirms it when the robot asked) to the tracker's "detected" event (speech
#     recognition + dialog + Executive + the head's search + tracking);
#   - the arm's motion, per scenario: the peak hand speed and jerk of the trajectories the IK
#     planned for the arm (its "moving" log lines).
# Every game is played twice: with the motion limits near the person (the manifest's hand_speed
# and joint_jerk) and, as the peer, without them (both 1000: the motion before the limits).
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
  "beside beside" "confirm_yes confirm_yes dialog_high=0.9")
games=()
for line in "${plan[@]}"; do
  games+=("limited-$line" "unlimited-$line hand_speed=1000 joint_jerk=1000")
done
n=0
for line in "${games[@]}"; do
  read -r name scenario extra <<<"$line"
  n=$((n + 1))
  # The panel runs too, on a free port.
  sets=(--set "scenario=$scenario" --set "panel_http=127.0.0.1:0")
  for e in ${extra:-}; do
    sets+=(--set "$e")
  done
  step "game $n of ${#games[@]} ($name): robocog launch launch/touch_the_ball.toml ${sets[*]}"
  if ! "$BIN/robocog" launch launch/touch_the_ball.toml "${sets[@]}" \
      --namespace "bench-touch-$$-$n" --router tcp/127.0.0.1:0 --color never >"$out/$name.log" 2>&1; then
    echo "game $n ($scenario) failed; its last lines:" >&2
    tail -30 "$out/$name.log" >&2
    exit 1
  fi
  grep -h "person: timings" "$out/$name.log" | sed 's/.*person: timings //' >"$out/$name.timings.json"
done
python3 - "$out" "$runs" <<'EOF'
import json, sys, glob, os, re
out, runs = sys.argv[1], int(sys.argv[2])
SCAN = ('says "scan the ball"', 'says "track the ball"')
MOVING = re.compile(r"moving: .*tip peak ([\d.]+) m/s, ([\d.]+) m/s.* part=(\S*arm\S*)")
def figures(variant):
    touch, gaze, scan, scan_by, motion = [], [], [], {}, {}
    for f in sorted(glob.glob(os.path.join(out, f"{variant}-*.timings.json"))):
        name = os.path.basename(f)[len(variant) + 1 : -len(".timings.json")]
        scenario = name.rstrip("0123456789")
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
                scan_by.setdefault(scenario, []).append(t["after_s"])
        for line in open(f[: -len(".timings.json")] + ".log", errors="replace"):
            m = MOVING.search(line)
            if m:
                speed, jerk = motion.get(scenario, (0.0, 0.0))
                motion[scenario] = (max(speed, float(m.group(1))), max(jerk, float(m.group(2))))
    return touch, gaze, scan, scan_by, motion
def pct(v, p):
    v = sorted(v)
    if not v:
        return float("nan")
    k = min(len(v) - 1, max(0, round(p / 100 * (len(v) - 1))))
    return v[k]
print()
print(f"touch-the-ball game: bench scenario x {runs}, 6 other scenarios x 1, each with and without the motion limits, {os.cpu_count()} cores")
result = {"runs": runs}
for variant in ("limited", "unlimited"):
    touch, gaze, scan, scan_by, motion = figures(variant)
    print(f"\n{variant}: {'with' if variant == 'limited' else 'without'} the motion limits near the person")
    print(f"{'figure':44} {'n':>4} {'p50 s':>8} {'p90 s':>8} {'max s':>8}")
    for name, v in [
        ("end of 'touch it' -> hand within 3 cm", touch),
        ("ball jump 8 cm -> gaze within 3 deg", gaze),
        ("end of 'scan the ball' -> ball detected", scan),
    ]:
        print(f"{name:44} {len(v):4d} {pct(v,50):8.2f} {pct(v,90):8.2f} {max(v) if v else float('nan'):8.2f}")
    print("scan, per scenario: " + ", ".join(f"{k} {' '.join(f'{x:.2f}' for x in v)} s" for k, v in sorted(scan_by.items())))
    print(f"{'arm trajectories, per scenario':32} {'peak hand m/s':>14} {'peak jerk m/s3':>15}")
    for k, (speed, jerk) in sorted(motion.items()):
        print(f"{k:32} {speed:14.2f} {jerk:15.1f}")
    p = "" if variant == "limited" else "peer_"
    result.update({
        f"{p}touch_n": len(touch), f"{p}touch_p50_s": round(pct(touch, 50), 3), f"{p}touch_p90_s": round(pct(touch, 90), 3),
        f"{p}gaze_n": len(gaze), f"{p}gaze_settle_p50_s": round(pct(gaze, 50), 3), f"{p}gaze_settle_p90_s": round(pct(gaze, 90), 3),
        f"{p}scan_n": len(scan), f"{p}scan_p50_s": round(pct(scan, 50), 3), f"{p}scan_p90_s": round(pct(scan, 90), 3),
        f"{p}scan_max_s": round(max(scan), 3) if scan else float("nan"),
        f"{p}hand_peak_speed_max_m_s": round(max((s for s, _ in motion.values()), default=float("nan")), 3),
        f"{p}hand_peak_jerk_max_m_s3": round(max((j for _, j in motion.values()), default=float("nan")), 1),
    })
for k in ("touch_p50_s", "hand_peak_speed_max_m_s", "hand_peak_jerk_max_m_s3"):
    if result.get(f"peer_{k}"):
        result[f"ratio_{k}_vs_peer"] = round(result[k] / result[f"peer_{k}"], 3)
print(json.dumps(result))
EOF
