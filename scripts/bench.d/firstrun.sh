#!/usr/bin/env bash
# From a fresh clone to the end of the first game, as a new user gets it: `scripts/run` in a new
# clone of this checkout's HEAD, with an empty build folder and an empty model cache, each phase
# timed from the script's own steps (Debian packages, build, speech model, game). Compared with
# the last run of another commit kept in the cache (the previous release, when one was measured).
# Not emptied: the Debian packages already installed and cargo's download cache (~/.cargo), so
# the packages phase and the crates' downloads are a fresh machine's lower bound.
# About 10 minutes on two cores with the crates already downloaded. Usage: scripts/bench firstrun
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
rev="$(git rev-parse --short HEAD)"
keep="${XDG_CACHE_HOME:-$HOME/.cache}/robocog/bench"
mkdir -p "$keep"
work="$(mktemp -d "${TMPDIR:-/tmp}/robocog-firstrun.XXXXXX")"
# The game's background build of the speech model runs on after the game: stopped with the run.
cleanup() {
  pkill -f "$work/target/release/speech_model" 2>/dev/null || true
  sleep 1
  rm -rf "$work" 2>/dev/null || true
}
trap cleanup EXIT
step "cloning $rev into $work (a fresh clone, an empty build folder and model cache)"
git clone -q "$ROOT" "$work/robocog"
free_gb=$(($(df -Pk "$work" | awk 'NR==2 {print $4}') / 1024 / 1024))
step "scripts/run in the clone ($(nproc) cores, $free_gb GB free; its output in $work/run.log while it runs)"
started=$(date +%s.%N)
set +e
(
  cd "$work/robocog" &&
    env CARGO_TARGET_DIR="$work/target" XDG_CACHE_HOME="$work/cache" scripts/run 2>&1
) | while IFS= read -r line; do
  printf '%s %s\n' "$(date +%s.%N)" "$line"
done >"$work/run.log"
rc=${PIPESTATUS[0]}
set -e
ended=$(date +%s.%N)
tail -n 5 "$work/run.log" | cut -d' ' -f2- >&2

python3 - "$work/run.log" "$started" "$ended" "$rc" "$rev" "$keep" "$(nproc)" <<'EOF'
import json, os, sys, glob
log, started, ended, rc, rev, keep, cores = sys.argv[1:]
started, ended, rc = float(started), float(ended), int(rc)
steps = []
for line in open(log, errors="replace"):
    t, _, text = line.rstrip("\n").partition(" ")
    if text.startswith("==> "):
        steps.append((float(t), text[4:]))

def phase(text):
    if text.startswith("installing Debian packages"):
        return "packages"
    if text.startswith("building") or text.startswith("reading the programs"):
        return "build"
    if "speech model" in text:
        return "model"
    if text.startswith("checking") or text.startswith("launching"):
        return "game"
    return "other"

spans = {"packages": 0.0, "build": 0.0, "model": 0.0, "game": 0.0, "other": 0.0}
bounds = [s[0] for s in steps[1:]] + [ended]
for (t, text), end in zip(steps, bounds):
    spans[phase(text)] += end - t
if steps:
    spans["other"] += steps[0][0] - started
first_game = next((t for t, text in steps if text.startswith("launching")), None)
to_game = (first_game - started) if first_game else float("nan")
total = ended - started
figures = {
    "rev": rev,
    "cores": int(cores),
    "game_passed": rc == 0,
    "packages_s": round(spans["packages"], 1),
    "build_s": round(spans["build"], 1),
    "model_s": round(spans["model"], 1),
    "game_s": round(spans["game"], 1),
    "other_s": round(spans["other"], 1),
    "to_first_game_s": round(to_game, 1),
    "total_s": round(total, 1),
}
previous = None
for f in sorted(glob.glob(os.path.join(keep, "firstrun-*.json")), key=os.path.getmtime, reverse=True):
    try:
        p = json.load(open(f))
    except (OSError, ValueError):
        continue
    if p.get("rev") != rev:
        previous = p
        break
json.dump(figures, open(os.path.join(keep, f"firstrun-{rev}.json"), "w"))

print(f"\nfirst run of {rev} on {cores} cores (game {'passed' if rc == 0 else 'FAILED, exit %d' % rc})")
print(f"{'phase':<24}{'this run (s)':>14}{'previous (s)':>14}{'ratio':>8}")
rows = [("Debian packages", "packages_s"), ("build", "build_s"), ("speech model", "model_s"),
        ("game", "game_s"), ("other steps", "other_s"), ("to the first game", "to_first_game_s"),
        ("total", "total_s")]
for name, key in rows:
    prev = previous.get(key) if previous else None
    ratio = (figures[key] / prev) if prev else None
    if prev:
        figures[f"{key.removesuffix('_s')}_ratio_vs_{previous['rev']}"] = round(ratio, 3)
    print(f"{name:<24}{figures[key]:>14.1f}{(f'{prev:.1f}' if prev else '-'):>14}{(f'{ratio:.2f}' if ratio else '-'):>8}")
if previous:
    figures["previous_rev"] = previous["rev"]
else:
    print("(no earlier run of another commit in the cache to compare with)")
print(json.dumps(figures))
sys.exit(0 if rc == 0 else 1)
EOF
