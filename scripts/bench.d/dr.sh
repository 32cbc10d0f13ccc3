#!/usr/bin/env bash
# The deep representation: in-process transform lookups (13 joints), fork and what-if, and the
# dr/transform and dr/update services over a local zenoh router (p50/p99 per call).
# Extra arguments go to bench_dr (e.g. --calls 20000 --lookups 1000000).
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
step "building bench_dr (release)"
(cd "$ROOT" && cargo build --release -p deep_representation --bin bench_dr)
step "running bench_dr"
exec "$BIN/bench_dr" "$@"
