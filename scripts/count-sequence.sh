#!/usr/bin/env bash
# Counts every frame of a rendered sequence with a model, once: the counts
# (`phyllo count --json` lines) are kept beside the frames per model file,
# DIR/counts-<sha256 of the model, 12 hex>.jsonl, so a rerun only counts
# when frames were added. Prints the counts file's path.
# Usage: scripts/count-sequence.sh SEQUENCE_DIR MODEL
# Environment: THREADS [2]; TOP_MODEL [none: MODEL counts the top views too;
# models/phyllo-top.onnx counts them as the shipped pair does, and its hash
# joins the counts file's name]. Expects target/release/phyllo built.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
dir=$1
model=$2
top=${TOP_MODEL:-none}
counts=$dir/counts-$(sha256sum "$model" | cut -c1-12)
[ "$top" = none ] || counts=$counts+$(sha256sum "$top" | cut -c1-12)
counts=$counts.jsonl
frames=$(find "$dir" -maxdepth 1 -name '*.png' | wc -l)
if [ ! -s "$counts" ] || [ "$(wc -l <"$counts")" -ne "$frames" ]; then
  echo "counting $frames frames of $dir with $(basename "$model")" >&2
  find "$dir" -maxdepth 1 -name '*.png' -print0 | sort -z |
    xargs -0 "$root/target/release/phyllo" count --threads "${THREADS:-2}" --model "$model" --top-model "$top" --json >"$counts.part"
  mv "$counts.part" "$counts"
fi
echo "$counts"
