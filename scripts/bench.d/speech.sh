#!/usr/bin/env bash
# Speech recognition: robocog speech_recognition (end-pointer + PocketSphinx JSGF + garbage-model
# confidence, decoding while the person speaks) on every command of both games, in every
# condition of the corpus (clean, white noise, reverberant rooms, other people talking, a fan),
# said by two families of voices: espeak-ng's evaluation voices (the synthesizer the simulated
# person speaks with) and flite's and festival's (built from recordings of real speakers; never
# used to adapt or tune anything). Each family is decoded by the component's default acoustic
# model and, side by side, by the other one (the stock model, or the model adapted on espeak-ng),
# and by the peer, the pocketsphinx_continuous program (stock model) with the same grammar on the
# same audio files. Extra flags go to every run: `--conditions clean,reverb,babble_10` some
# conditions, `--denoise` adds the enhancement. The two models of a family run at once (two
# cores); all seven conditions take about an hour.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_voice_debs
work="$CARGO_TARGET_DIR/bench/speech"
rm -rf "$work" && mkdir -p "$work"
step "building the speech benchmark (release)"
cargo build --release --workspace --example bench_speech --bin speech_model
# The model adapted on espeak-ng, for the side-by-side run.
need_speech_model
default_model=$("$BIN/speech_model" --which)
if [ "$default_model" = stock ]; then other_model=adapted; else other_model=stock; fi
for family in espeak other; do
  mkdir -p "$work/$family/wav"
  step "voices: $family; our default model ($default_model) and the $other_model model side by side"
  "$BIN/examples/bench_speech" --family "$family" --write-wav "$work/$family/wav" "$@" \
    >"$work/$family/default.txt" 2>"$work/$family/default.log" &
  first=$!
  "$BIN/examples/bench_speech" --family "$family" --acoustic-model "$other_model" "$@" \
    >"$work/$family/other.txt" 2>"$work/$family/other.log" &
  second=$!
  wait "$first" || { cat "$work/$family/default.log" >&2; exit 1; }
  wait "$second" || { cat "$work/$family/other.log" >&2; exit 1; }
  cat "$work/$family/default.log"
done
step "pocketsphinx_continuous on the same files, same grammar (two at a time), and the table"
python3 - "$work" "$ROOT/components/speech_recognition/grammars" "$default_model" "$other_model" <<'PY_END'
import collections, concurrent.futures, json, subprocess, sys, time
work, grammars, default_model, other_model = sys.argv[1:5]

def peer(wav):
    """pocketsphinx_continuous's accuracy per (game, condition) on one family's files."""
    rows = [l.rstrip("\n").split("\t") for l in open(f"{wav}/truth.tsv") if l.strip()]
    # Every phrase of the grammars and its command: a synonym ("follow the ball" for "track
    # the ball") is the same command, for the peer as for ours.
    command_of = {(g, ph): c for g, ph, c in
                  (l.rstrip("\n").split("\t") for l in open(f"{wav}/phrases.tsv") if l.strip())}

    def decode(row):
        n, game, cond, phrase = row
        out = subprocess.run(
            ["pocketsphinx_continuous", "-infile", f"{wav}/{n}.wav", "-jsgf",
             f"{grammars}/{game}.gram", "-logfn", "/dev/null"],
            capture_output=True, text=True).stdout
        # The grammar allows "robot"/"please" before the command; the command is what counts.
        norm = " ".join(w for w in " ".join(out.split()).split() if w not in ("robot", "please"))
        return game, cond, command_of.get((game, norm)) == command_of[game, phrase]

    ok, n = collections.Counter(), collections.Counter()
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        for game, cond, right in pool.map(decode, rows):
            n[game, cond] += 1
            ok[game, cond] += right
    return {k: ok[k] / n[k] for k in n}

def last_json(path):
    return json.loads(open(path).read().strip().splitlines()[-1])

out, below_peer, below_stock = {}, [], []
print(f"\n{'voices':7} {'game':5} {'condition':>9} | {'ours (' + default_model + ')':>22} | "
      f"{other_model + ' model':>22} | peer")
print("(accuracy, and in brackets the share right and carried out at once; false accepts after /)")
for family in ("espeak", "other"):
    start = time.time()
    ours, alt = last_json(f"{work}/{family}/default.txt"), last_json(f"{work}/{family}/other.txt")
    stock = ours if default_model == "stock" else alt
    theirs = peer(f"{work}/{family}/wav")
    for (game, cond), acc in sorted(theirs.items()):
        key = f"{game}_accuracy_{cond}"
        if key not in ours:
            continue
        cell = lambda j: (f"{100 * j[key]:5.1f} % ({100 * j[f'{game}_sure_right_{cond}']:5.1f})"
                          f" / {100 * j[f'{game}_false_accept_rate_{cond}']:3.1f}")
        print(f"{family:7} {game:5} {cond:>9} | {cell(ours):>22} | {cell(alt):>22} | {100 * acc:5.1f} %")
        for k in (key, f"{game}_sure_right_{cond}", f"{game}_false_accept_rate_{cond}"):
            out[f"{family}_{k}"] = ours[k]
            out[f"{family}_{other_model}_{k}"] = alt[k]
        out[f"{family}_peer_{key}"] = round(acc, 4)
        if acc > 0:
            out[f"ratio_{family}_{key}_vs_peer"] = round(ours[key] / acc, 3)
        if stock[key] > 0:
            out[f"ratio_{family}_{key}_vs_stock"] = round(ours[key] / stock[key], 3)
        if ours[key] < acc:
            below_peer.append(f"{family} {game} {cond}")
        if ours[key] < stock[key]:
            below_stock.append(f"{family} {game} {cond}")
    for k in ("rtf", "false_accept_rate_max", "end_of_speech_to_result_p50_s"):
        out[f"{family}_{k}"] = ours[k]
    print(f"(the peer on the {family} files: {time.time() - start:.0f} s)")
print("our default below the peer in: " + (", ".join(below_peer) or "no condition"))
print("our default below the stock model in: " + (", ".join(below_stock) or "no condition"))
out["default_model"] = default_model
ratios = [v for k, v in out.items() if k.startswith("ratio_") and k.endswith("_vs_peer")]
if ratios:
    out["ratio_min_accuracy_vs_peer"] = min(ratios)
print(json.dumps(out))
PY_END
