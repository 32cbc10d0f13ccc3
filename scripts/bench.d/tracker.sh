#!/usr/bin/env bash
# Ball tracker vs OpenCV's CamShift pipeline on the same generated 640x480 sequence, same run.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
work="$CARGO_TARGET_DIR/bench/tracker"
mkdir -p "$work"
step "building the tracker benchmark (release)"
cargo build --release --workspace --example bench_tracker
venv="$CARGO_TARGET_DIR/bench/venv"
if [ ! -x "$venv/bin/python" ]; then
  step "creating a Python venv for the OpenCV peer ($venv)"
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c "import cv2, numpy" 2>/dev/null; then
  step "installing opencv-python-headless and numpy from PyPI"
  "$venv/bin/pip" install -q opencv-python-headless numpy
fi
step "robocog ball_tracker on a generated sequence (written as TUM RGB-D for the peer)"
"$BIN/examples/bench_tracker" --write-tum "$work/seq" | tee "$work/ours.txt"
step "OpenCV CamShift pipeline on the same frames"
"$venv/bin/python" components/ball_tracker/bench/opencv_camshift.py "$work/seq" | tee "$work/peer.txt"
"$venv/bin/python" - "$work/ours.txt" "$work/peer.txt" <<'PY'
import json, sys
ours = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
peer = json.loads(open(sys.argv[2]).read().strip().splitlines()[-1])
out = {f"ours_{k}": v for k, v in ours.items()}
out.update({f"opencv_{k}": v for k, v in peer.items()})
for k in ("p50_us", "p99_us"):
    a = next((v for kk, v in ours.items() if kk.endswith(k)), None)
    b = next((v for kk, v in peer.items() if kk.endswith(k)), None)
    if a and b:
        out[f"speedup_{k}_vs_opencv"] = b / a
print()
print("| | robocog ball_tracker | OpenCV CamShift |")
print("|---|---:|---:|")
for key in sorted(set(ours) | set(peer)):
    print(f"| {key} | {ours.get(key, '')} | {peer.get(key, '')} |")
print(json.dumps(out))
PY
