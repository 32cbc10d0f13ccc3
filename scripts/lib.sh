# Shared by the scripts: where builds go, and how to say what we are doing.
# shellcheck shell=bash

# One persistent build folder outside the clone, shared by runs, tests, benchmarks and CI, in one
# profile (release): a clean build of the dependencies takes minutes on a small machine.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/robocog/target}"
export CARGO_TERM_COLOR="${CARGO_TERM_COLOR:-never}"
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export ROOT
BIN="$CARGO_TARGET_DIR/release"
export BIN

# What the script is doing, and, when a step fails, which one and what might help (STEP_HINT).
CURRENT_STEP="starting"
STEP_HINT=""
step() {
  CURRENT_STEP="$*"
  STEP_HINT=""
  printf '\n==> %s\n' "$*" >&2
}
on_step_error() {
  local rc=$?
  printf '\nerror: this step failed (exit %s): %s\n' "$rc" "$CURRENT_STEP" >&2
  if [ -n "$STEP_HINT" ]; then printf '%s\n' "$STEP_HINT" >&2; fi
}
set -E
trap on_step_error ERR

# Install Debian packages that are missing, once (idempotent, quiet when all are there).
need_debs() {
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    step "installing Debian packages: ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    STEP_HINT="Could not install them through apt-get (no network to the Debian mirrors, or no rights?).
Install them by hand and run this again: $sudo apt-get install ${missing[*]}"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
  fi
}

# The voice components' system packages: PocketSphinx (library, headers, US English model, CLI
# for the benchmark's comparison), espeak-ng (the speech generator and the test voices), sox.
need_voice_debs() {
  need_debs libpocketsphinx-dev pocketsphinx-en-us pocketsphinx espeak-ng libespeak-ng-dev sox \
    sphinxtrain sphinxbase-utils
  # Voices of two other synthesizer families, for evaluation only (never adapted or tuned on).
  need_debs flite festival festvox-kallpc16k festvox-kdlpc16k festvox-us-slt-hts
  # The microphone and speaker (audio_io, through libpulse) and the sound server the tests
  # start as the room (pulseaudio, with pactl and parec).
  need_debs libpulse-dev pulseaudio pulseaudio-utils
}

# The head camera's driver library and its test stand-in: libfreenect (the Kinect v1) and the
# fakenect library that replays a dump in its place (both in Debian's libfreenect-dev).
need_camera_debs() {
  need_debs libfreenect0.5 libfreenect-dev
}

# The acoustic model adapted on the synthesized voices (components/speech_recognition,
# `speech_model`), which the speech recognizer's tests use (the recognizer's default is the stock
# model, which hears people better): built into ~/.cache/robocog/speech/ when missing or when its
# recipe changed (about 9 minutes on two cores), otherwise left alone.
need_speech_model() {
  STEP_HINT="$CARGO_HINT"
  (cd "$ROOT" && cargo build --release --workspace --quiet --bin speech_model)
  if ! "$BIN/speech_model" --check >/dev/null 2>&1; then
    step "adapting the speech recognizer's acoustic model to noisy speech (speech_model, ~9 min)"
    "$BIN/speech_model"
  fi
}

# Everything the workspace's build scripts and links need (pkg-config, the voice and camera
# libraries).
need_build_debs() {
  need_debs pkg-config
  need_voice_debs
  need_camera_debs
}

# Make sure cargo-nextest is there (the machine image ships it; install it otherwise).
need_nextest() {
  if ! cargo nextest --version >/dev/null 2>&1; then
    step "installing cargo-nextest"
    cargo install --locked cargo-nextest
  fi
}

# The release profile builds incrementally (quick rebuilds of the workspace crates), and cargo
# never trims the incremental caches: each checkout path adds its own. Past this size they are
# removed before a build (the next build of the workspace crates is then a full one).
INCREMENTAL_MAX_GB="${ROBOCOG_INCREMENTAL_MAX_GB:-8}"

prune_incremental() {
  local dir="$CARGO_TARGET_DIR/release/incremental" gb
  [ -d "$dir" ] || return 0
  gb=$(( $(du -sk "$dir" | cut -f1) / 1024 / 1024 ))
  if [ "$gb" -gt "$INCREMENTAL_MAX_GB" ]; then
    step "removing $gb GB of incremental build caches (over ${INCREMENTAL_MAX_GB} GB) in $dir"
    # Another build writing there meanwhile leaves some behind: not worth failing for.
    rm -rf "$dir" 2>/dev/null || echo "(some of it is in use by another build: left there)" >&2
  fi
}

# Two checkouts sharing the cache (a CI clone beside a working copy): the workspace crates'
# binaries of one checkout carry its paths (where models, grammars and test data are), and cargo
# takes them for up to date in the other when that one's sources are older. When the last build
# came from another checkout, the workspace's sources are touched so its crates are rebuilt
# (the dependencies are shared as they are).
claim_cache() {
  local mark="$CARGO_TARGET_DIR/.last-checkout"
  mkdir -p "$CARGO_TARGET_DIR"
  if [ -f "$mark" ] && [ "$(cat "$mark")" != "$ROOT" ]; then
    step "the build cache was last used by $(cat "$mark"): rebuilding this checkout's crates"
    find "$ROOT" -path "$ROOT/tests/browser/node_modules" -prune -o -path "$ROOT/.git" -prune \
      -o \( -name '*.rs' -o -name 'Cargo.toml' \) -print0 | xargs -0 touch
  fi
  echo "$ROOT" > "$mark"
}

# A build needs room: stop before it, and say so, when the build folder's disk has less than
# 4 GB free (a full build of the workspace takes about 10 GB).
need_disk_space() {
  mkdir -p "$CARGO_TARGET_DIR"
  local free_kb
  free_kb=$(df -Pk "$CARGO_TARGET_DIR" | awk 'NR==2 {print $4}')
  if [ "${free_kb:-0}" -lt $((4 * 1024 * 1024)) ]; then
    printf 'error: only %s MB free on the disk of %s; a build needs at least 4 GB (a full one about 10 GB).\n' \
      "$((${free_kb:-0} / 1024))" "$CARGO_TARGET_DIR" >&2
    printf 'Free some space, or build elsewhere: CARGO_TARGET_DIR=/a/roomier/folder %s\n' "$0" >&2
    exit 1
  fi
}

CARGO_HINT="If the error names a missing library or pkg-config package, install its Debian -dev package
(apt-get install pkg-config libpocketsphinx-dev libespeak-ng-dev libpulse-dev libfreenect-dev);
if cargo could not download a crate, the machine cannot reach crates.io."

# The launcher and the programs one graph starts, and nothing else (no benchmark, example or
# viewer the graph does not run). Built through the workspace (`--workspace --bin ...`), so the
# dependencies' features are unified as for every other build and their artifacts are shared
# with `scripts/test` and `scripts/bench`. Usage: build_graph MANIFEST [--set k=v|--profile p]...
build_graph() {
  local manifest="$1"
  shift
  need_disk_space
  prune_incremental
  claim_cache
  step "building the launcher (robocog, release, into $CARGO_TARGET_DIR)"
  STEP_HINT="$CARGO_HINT"
  (cd "$ROOT" && cargo build --release --workspace --bin robocog)
  step "reading the programs $manifest starts"
  local programs
  programs="$("$BIN/robocog" check --binaries "$manifest" "$@")"
  GRAPH_PROGRAMS="$programs"
  local bins=() p
  for p in $programs; do
    case "$p" in
      "$ROBOCOG_PYTHON") need_python ;; # the graph has Python components
      */*) ;; # a program of the user's own, by path
      *) bins+=(--bin "$p") ;;
    esac
  done
  step "building the graph's programs: $(echo $programs)"
  STEP_HINT="$CARGO_HINT"
  (cd "$ROOT" && cargo build --release --workspace "${bins[@]}")
}

build_all() {
  prune_incremental
  claim_cache
  need_disk_space
  step "building every robocog binary (release, into $CARGO_TARGET_DIR)"
  STEP_HINT="$CARGO_HINT"
  (cd "$ROOT" && cargo build --release --workspace --bins --examples)
}

# The command panel's browser tests: Debian's Chromium and node/npm (apt), and playwright-core
# pinned by tests/browser/package-lock.json (npm ci, only when node_modules is missing or older
# than the lock file). Idempotent.
need_browser() {
  need_debs chromium
  # node and npm may come from elsewhere than Debian (the machine image ships them).
  if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
    need_debs nodejs npm
  fi
  local dir="$ROOT/tests/browser"
  if [ ! -f "$dir/node_modules/playwright-core/package.json" ] ||
     [ "$dir/package-lock.json" -nt "$dir/node_modules/.package-lock.json" ]; then
    step "installing playwright-core for the browser tests (npm ci in tests/browser)"
    (cd "$dir" && npm ci --no-audit --no-fund --silent)
  fi
}

# The Python of robocog's Python components: a venv outside the clone with NumPy, OpenCV and the
# eclipse-zenoh client (the benchmark's peer), pinned; the `robocog` package (libs/python) with its
# extension built through the workspace, so with the same artifacts as every other build (a
# `pip install libs/python` builds it with maturin, the package alone, and compiles zenoh again
# with other features); and the Python ball tracker (components/ball_tracker_py). ROBOCOG_PYTHON
# is the interpreter the launcher runs `python = "..."` components with, PYO3_PYTHON the one
# every build of the extension targets (the same, so builds never invalidate each other).
PY_VENV="${XDG_CACHE_HOME:-$HOME/.cache}/robocog/python"
export ROBOCOG_PYTHON="${ROBOCOG_PYTHON:-$PY_VENV/bin/python}"
export PYO3_PYTHON="${PYO3_PYTHON:-$PY_VENV/bin/python}"
need_python_venv() {
  local pins="numpy==2.4.6 opencv-python-headless==5.0.0.93 eclipse-zenoh==1.10.2 setuptools==80.9.0"
  local stamp
  stamp="$PY_VENV/.pins-$(echo "$pins" | cksum | cut -d' ' -f1)"
  if [ ! -x "$PY_VENV/bin/python" ] || [ ! -f "$stamp" ]; then
    need_debs python3-venv
    step "making the Python venv of robocog's Python components ($pins) in $PY_VENV"
    python3 -m venv "$PY_VENV"
    # shellcheck disable=SC2086
    "$PY_VENV/bin/pip" install --quiet --disable-pip-version-check $pins
    touch "$stamp"
  fi
}
need_python() {
  need_python_venv
  step "building the robocog Python package's extension (libs/python, through the workspace)"
  STEP_HINT="$CARGO_HINT"
  (cd "$ROOT" && cargo build --release --workspace --lib --quiet)
  STEP_HINT=""
  step "installing the robocog Python package and the Python ball tracker into $PY_VENV"
  local site
  site="$("$PY_VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
  local suffix
  suffix="$("$PY_VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_config_var("EXT_SUFFIX"))')"
  rm -rf "$site/robocog"
  cp -r "$ROOT/libs/python/robocog" "$site/robocog"
  cp "$BIN/lib_robocog.so" "$site/robocog/_robocog$suffix"
  "$PY_VENV/bin/pip" install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
    --force-reinstall "$ROOT/components/ball_tracker_py"
}

# The ROS 2 tools the tests read robocog with, as programs outside the project would: mcap,
# mcap-ros2-support and rosbags (recordings, CDR, type hashes) and the eclipse-zenoh client at
# the zenoh version of the workspace (an rmw_zenoh peer), from PyPI, pinned, in a Python venv
# outside the clone. Exports ROBOCOG_ROS2_PYTHON, that venv's python. Idempotent.
need_ros2_decoders() {
  local pins="mcap==1.6.0 mcap-ros2-support==0.6.0 rosbags==0.11.9 eclipse-zenoh==1.10.2"
  local venv="${XDG_CACHE_HOME:-$HOME/.cache}/robocog/ros2-decoders-$(echo "$pins" | cksum | cut -d' ' -f1)"
  if [ ! -x "$venv/bin/python" ] || [ ! -f "$venv/.installed" ]; then
    need_debs python3-venv
    step "installing the ROS 2 tools for the tests ($pins) into $venv"
    python3 -m venv "$venv"
    # shellcheck disable=SC2086
    "$venv/bin/pip" install --quiet --disable-pip-version-check $pins
    touch "$venv/.installed"
  fi
  export ROBOCOG_ROS2_PYTHON="$venv/bin/python"
}

# The room acoustics simulator the audio library's image-source rooms are checked against
# (libs/audio/tests/room_reference.rs): pyroomacoustics from PyPI with the NumPy, SciPy and Cython
# it needs at run time, pinned, in a Python venv outside the clone (pyroomacoustics ships
# manylinux wheels: nothing is compiled). Exports ROBOCOG_PYROOM_PYTHON, that venv's python.
# Idempotent.
need_pyroom() {
  local pins="pyroomacoustics==0.10.1 numpy==2.4.6 scipy==1.17.1 Cython==3.3.1"
  local venv="${XDG_CACHE_HOME:-$HOME/.cache}/robocog/pyroom-$(echo "$pins" | cksum | cut -d' ' -f1)"
  if [ ! -x "$venv/bin/python" ] || [ ! -f "$venv/.installed" ]; then
    need_debs python3-venv
    step "installing the room acoustics reference for the tests ($pins) into $venv"
    python3 -m venv "$venv"
    # shellcheck disable=SC2086
    "$venv/bin/pip" install --quiet --disable-pip-version-check $pins
    touch "$venv/.installed"
  fi
  export ROBOCOG_PYROOM_PYTHON="$venv/bin/python"
}

# The `rerun` command line of the rerun-sdk Python package, at the exact version of the `rerun`
# crate the viewer component links (components/viewer/Cargo.toml), for the viewer's tests
# (`rerun rrd verify`, `rerun rrd print`) and for watching a game (`rerun` is the viewer
# `robocog view` spawns). Installed once into a Python venv outside the clone; exports
# ROBOCOG_RERUN_CLI, the path of its `rerun` executable. Idempotent.
need_rerun_cli() {
  local version
  version="$(sed -n 's/^rerun = { version = "=\([0-9.]*\)".*/\1/p' "$ROOT/components/viewer/Cargo.toml")"
  if [ -z "$version" ]; then
    echo "need_rerun_cli: cannot read the rerun version from components/viewer/Cargo.toml" >&2
    return 1
  fi
  local venv="${XDG_CACHE_HOME:-$HOME/.cache}/robocog/rerun-sdk-$version"
  if [ ! -x "$venv/bin/rerun" ]; then
    need_debs python3-venv
    step "installing the rerun viewer and CLI (pip rerun-sdk==$version) into $venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check "rerun-sdk==$version"
    # The viewer and CLI send anonymous usage data by default; robots and CI do not.
    "$venv/bin/rerun" analytics disable >/dev/null
  fi
  export ROBOCOG_RERUN_CLI="$venv/bin/rerun"
}
