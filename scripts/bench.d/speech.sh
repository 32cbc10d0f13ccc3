#!/usr/bin/env bash
# Speech recognition: robocog speech_recognition (end-pointer + PocketSphinx JSGF + garbage-model confidence) vs
# the pocketsphinx_continuous program with the same grammar on the same audio files.
set -euo pipefail
source "$(dirname "$0")/../lib.sh"
cd "$ROOT"
need_voice_debs
work="$CARGO_TARGET_DIR/bench/speech"
rm -rf "$work" && mkdir -p "$work/wav"
step "building the speech benchmark (release)"
cargo build --release -p speech_recognition --example bench_speech
step "robocog speech_recognition: 6 voices x 3 speeds x 4 SNRs x touch-game commands, plus 72 out-of-grammar utterances"
"$BIN/examples/bench_speech" --write-wav "$work/wav" | tee "$work/ours.txt"
step "pocketsphinx_continuous on the same files, same grammar"
gram="components/speech_recognition/grammars/touch.gram"
ok=0; n=0; start=$(date +%s.%N)
declare -A ok_snr n_snr
while IFS=$'\t' read -r id snr phrase; do
  hyp=$(pocketsphinx_continuous -infile "$work/wav/$id.wav" -jsgf "$gram" -logfn /dev/null 2>/dev/null | tr '\n' ' ' | sed 's/ *$//')
  n=$((n+1)); n_snr[$snr]=$(( ${n_snr[$snr]:-0} + 1 ))
  # The grammar allows "robot"/"please" fillers; compare without them.
  norm=$(echo "$hyp" | sed -E 's/\b(robot|please)\b//g; s/  +/ /g; s/^ //; s/ $//')
  if [ "$norm" = "$phrase" ]; then ok=$((ok+1)); ok_snr[$snr]=$(( ${ok_snr[$snr]:-0} + 1 )); fi
done < "$work/wav/truth.tsv"
end=$(date +%s.%N)
for s in "${!n_snr[@]}"; do
  echo "pocketsphinx_continuous SNR $s dB: ${ok_snr[$s]:-0}/${n_snr[$s]}"
done | sort -t' ' -k3 -n -r | tee "$work/peer.txt"
echo "pocketsphinx_continuous: $ok/$n correct, $(echo "$end - $start" | bc) s wall for all files (incl. model loading per file)" | tee -a "$work/peer.txt"
