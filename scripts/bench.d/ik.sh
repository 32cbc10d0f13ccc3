#!/usr/bin/env bash
# IK benchmark: robocog's body_inverse_kinematics against ikpy and roboticstoolbox-python (C++ ik_LM)
# on Loki's URDF, same targets (10,000 FK of seeded random in-limit configurations per case).
# Prints a table; the very last line is one JSON object with the figures and speed-up ratios.
# Env: IK_N (targets, default 10000), IK_N_IKPY (default 500: ikpy is slow), IK_N_RTB (default 10000).
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
N="${IK_N:-10000}"
OUT="$CARGO_TARGET_DIR/ik-bench"
mkdir -p "$OUT"

cd "$ROOT"
cargo build --release -q --workspace --example bench_ik >&2
"$CARGO_TARGET_DIR/release/examples/bench_ik" --n "$N" --seed 7 \
    --targets-out "$OUT/targets.json" --results-out "$OUT/ours.json" >&2

VENV="$CARGO_TARGET_DIR/ik-venv"
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV" >&2
fi
if ! "$VENV/bin/python" -c "import ikpy" 2>/dev/null; then
    "$VENV/bin/pip" install -q ikpy >&2 || echo "note: ikpy could not be installed" >&2
fi
if ! "$VENV/bin/python" -c "import roboticstoolbox" 2>/dev/null; then
    "$VENV/bin/pip" install -q roboticstoolbox-python >&2 \
        || echo "note: roboticstoolbox-python could not be installed on $("$VENV/bin/python" --version)" >&2
fi
exec "$VENV/bin/python" "$ROOT/components/body_inverse_kinematics/bench/peers.py" \
    "$OUT/targets.json" "$OUT/ours.json" \
    --n-ikpy "${IK_N_IKPY:-500}" --n-rtb "${IK_N_RTB:-10000}"
