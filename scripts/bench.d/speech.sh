#!/usr/bin/env bash
# Speech recognition: robocog speech_recognition (end-pointer + PocketSphinx JSGF + garbage-model
# confidence, decoding while the person speaks, on the adapted acoustic model) vs the
# pocketsphinx_continuous program (stock model) with the same grammar on the same audio files, for
# both games, in every condition of the corpus (clean, white noise, reverberant rooms, other people
# talking, a fan). Extra flags go to the benchmark: `--acoustic-model stock` measures ours on the
# stock model, `--denoise` adds the enhancement, `--conditions clean,babble_10` some conditions.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_voice_debs
work="$CARGO_TARGET_DIR/bench/speech"
rm -rf "$work" && mkdir -p "$work/wav"
step "building the speech benchmark (release)"
cargo build --release --workspace --example bench_speech --bin speech_model
need_speech_model
step "robocog speech_recognition: both games' commands x 6 voices x 3 speeds in 7 conditions (clean; white noise at 20/10/5 dB SNR; reverberant rooms; babble of 3 talkers at 10 dB; a fan at 10 dB), plus out-of-grammar sentences and talk alone"
"$BIN/examples/bench_speech" --write-wav "$work/wav" "$@" | tee "$work/ours.txt"
step "pocketsphinx_continuous on the same files, same grammar (two at a time)"
# The peer per game and condition, then the last line: our figures, the peer's, and our
# accuracy over the peer's in each condition (the lowest of them too).
python3 - "$work/wav" "$work/ours.txt" "$ROOT/components/speech_recognition/grammars" <<'PY_END'
import collections, concurrent.futures, json, re, subprocess, sys, time
wav, ours_file, grammars = sys.argv[1], sys.argv[2], sys.argv[3]
rows = [l.rstrip("\n").split("\t") for l in open(f"{wav}/truth.tsv") if l.strip()]
# Every phrase of the grammars and its command: a synonym ("follow the ball" for "track the
# ball") is the same command, for the peer as for ours.
command_of = {(g, ph): c for g, ph, c in
              (l.rstrip("\n").split("\t") for l in open(f"{wav}/phrases.tsv") if l.strip())}

def decode(row):
    n, game, cond, phrase = row
    out = subprocess.run(
        ["pocketsphinx_continuous", "-infile", f"{wav}/{n}.wav", "-jsgf",
         f"{grammars}/{game}.gram", "-logfn", "/dev/null"],
        capture_output=True, text=True).stdout
    hyp = " ".join(out.split())
    # The grammar allows "robot"/"please" before the command; the command is what counts.
    norm = " ".join(w for w in hyp.split() if w not in ("robot", "please"))
    return game, cond, command_of.get((game, norm)) == command_of[game, phrase]

start = time.time()
ok, n = collections.Counter(), collections.Counter()
with concurrent.futures.ThreadPoolExecutor(2) as pool:
    for game, cond, right in pool.map(decode, rows):
        n[game, cond] += 1
        ok[game, cond] += right
ours = json.loads(open(ours_file).read().strip().splitlines()[-1])
ratios = {}
for (game, cond) in sorted(n):
    acc = ok[game, cond] / n[game, cond]
    print(f"pocketsphinx_continuous {game:5} {cond:>9}: {ok[game, cond]}/{n[game, cond]} = {acc:.3}"
          f"   (ours {ours.get(f'{game}_accuracy_{cond}', float('nan')):.3})")
    ours[f"peer_{game}_accuracy_{cond}"] = round(acc, 4)
    if acc > 0 and f"{game}_accuracy_{cond}" in ours:
        ratios[f"ratio_{game}_accuracy_{cond}_vs_peer"] = round(ours[f"{game}_accuracy_{cond}"] / acc, 3)
print(f"pocketsphinx_continuous: {sum(ok.values())}/{sum(n.values())} correct, "
      f"{time.time() - start:.0f} s wall for all files (two at a time, model loaded per file)")
ours.update(ratios)
below = [f"{game} {cond}" for (game, cond) in sorted(n)
         if f"{game}_accuracy_{cond}" in ours
         and ours[f"{game}_accuracy_{cond}"] < ours[f"peer_{game}_accuracy_{cond}"]]
print("below the peer in: " + (", ".join(below) if below else "no condition"))
if ratios:
    ours["ratio_min_accuracy_vs_peer"] = min(ratios.values())
print(json.dumps(ours))
PY_END
