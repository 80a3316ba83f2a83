#!/usr/bin/env bash
# Renders every synthetic evaluation set listed in models/eval-sets.tsv that is
# not on disk yet, with the command recorded there, so that a fresh machine can
# rerun the model card's numbers. With --check, reads each set's data
# fingerprint (`phyllo eval --fingerprint-only`: no model, seconds) and compares
# it with the recorded one: a mismatch means the generator has changed since
# the card's numbers were measured.
# Usage: scripts/make-eval-sets.sh [--check] [SET...]   (default: every set)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
check=0
if [[ "${1:-}" == --check ]]; then
  check=1
  shift
fi
wanted=("$@")
cargo build -q --release -p phyllo -p phyllo-gen
status=0
while IFS=$'\t' read -r set fingerprint command; do
  [[ "$set" == \#* || -z "$set" ]] && continue
  [[ "$command" == target/release/phyllo-gen* ]] || continue
  name=${set%%/*}
  split=${set#*/}
  if ((${#wanted[@]})) && ! printf '%s\n' "${wanted[@]}" | grep -qx "$name"; then
    continue
  fi
  out=$(sed -E 's/.*--out ([^ ]+).*/\1/' <<<"$command")
  if [[ -e "$out/manifest.jsonl" ]]; then
    echo "$name: $out exists, not rendered again"
  else
    echo "$name: rendering into $out"
    read -ra argv <<<"$command"
    "${argv[@]}"
  fi
  if ((check)); then
    got=$(target/release/phyllo eval --fingerprint-only --json --dataset "$out" --split "$split" 2>/dev/null |
      scripts/eval_json.py field fingerprint)
    if [[ "$got" == "$fingerprint" ]]; then
      echo "$name: fingerprint $got as recorded"
    else
      echo "$name: fingerprint $got, recorded $fingerprint: the generator has changed since" >&2
      status=1
    fi
  fi
done <models/eval-sets.tsv
exit $status
