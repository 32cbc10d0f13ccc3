#!/usr/bin/env bash
# Speech recognition: robocog speech_recognition (end-pointer + PocketSphinx JSGF + garbage-model
# confidence, decoding while the person speaks, on the adapted acoustic model) vs the
# pocketsphinx_continuous program (stock model) with the same grammar on the same audio files, for
# both games. Extra flags go to the benchmark: `--acoustic-model stock` measures ours on the stock
# model, `--denoise` adds the enhancement.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_voice_debs
work="$CARGO_TARGET_DIR/bench/speech"
rm -rf "$work" && mkdir -p "$work/wav"
step "building the speech benchmark (release)"
cargo build --release -p speech_recognition --example bench_speech --bin speech_model
need_speech_model
step "robocog speech_recognition: both games' commands x 6 voices x 3 speeds, clean and at 20/10/5 dB SNR, plus out-of-grammar sentences"
"$BIN/examples/bench_speech" --write-wav "$work/wav" "$@" | tee "$work/ours.txt"
step "pocketsphinx_continuous on the same files, same grammar"
ok=0; n=0; start=$(date +%s.%N)
declare -A ok_k n_k
while IFS=$'\t' read -r id game snr phrase; do
  gram="components/speech_recognition/grammars/$game.gram"
  hyp=$(pocketsphinx_continuous -infile "$work/wav/$id.wav" -jsgf "$gram" -logfn /dev/null 2>/dev/null | tr '\n' ' ' | sed 's/ *$//')
  k="$game SNR $snr"
  n=$((n+1)); n_k[$k]=$(( ${n_k[$k]:-0} + 1 ))
  # The grammar allows "robot"/"please" fillers; compare without them.
  norm=$(echo "$hyp" | sed -E 's/\b(robot|please)\b//g; s/  +/ /g; s/^ //; s/ $//')
  if [ "$norm" = "$phrase" ]; then ok=$((ok+1)); ok_k[$k]=$(( ${ok_k[$k]:-0} + 1 )); fi
done < "$work/wav/truth.tsv"
end=$(date +%s.%N)
for k in "${!n_k[@]}"; do
  echo "pocketsphinx_continuous $k dB: ${ok_k[$k]:-0}/${n_k[$k]}"
done | sort | tee "$work/peer.txt"
echo "pocketsphinx_continuous: $ok/$n correct, $(echo "$end - $start" | bc) s wall for all files (incl. model loading per file)" | tee -a "$work/peer.txt"
# The last line: our figures, the peer's per game and SNR, and the ratios at 10 dB.
python3 - "$work/ours.txt" "$work/peer.txt" <<'PY_END'
import json, re, sys
ours = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
for line in open(sys.argv[2]):
    m = re.match(r"pocketsphinx_continuous (\w+) SNR (\w+) dB: (\d+)/(\d+)", line)
    if m:
        game, snr, ok, n = m.group(1), m.group(2), int(m.group(3)), int(m.group(4))
        ours[f"peer_{game}_accuracy_{snr}"] = round(ok / n, 4) if n else 0.0
for game in ("touch", "coach"):
    peer = ours.get(f"peer_{game}_accuracy_10")
    if peer:
        ours[f"ratio_{game}_accuracy_10_vs_peer"] = round(ours[f"{game}_accuracy_10"] / peer, 3)
print(json.dumps(ours))
PY_END
