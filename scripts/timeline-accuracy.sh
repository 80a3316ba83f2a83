#!/usr/bin/env bash
# Measures what a breeder reads off the timeline, with the model in the loop:
# renders a growth sequence (phyllo-gen sequence: every plant imaged daily
# from five side views and the top), counts every frame with the model,
# feeds the counts through `phyllo import` (the daemon's view fusion,
# isotonic fit and emergence events) once per fusion rule, and compares the
# exported timeline with the generator's truth.csv. A last row imports the
# true living-leaf counts instead of the model's, so the timeline's own error
# shows apart from the model's.
# Usage: scripts/timeline-accuracy.sh [SEQUENCE_DIR]
# Environment: PLANTS [36], DAYS [30], START_AGE [14], SEED [800001] (the
#   sequence, rendered only when SEQUENCE_DIR has no truth.csv; a partial
#   render resumes), MODEL [models/phyllo.onnx], TOP_MODEL [none: MODEL counts top views;
#   models/phyllo-top.onnx as the shipped pair] (scripts/count-sequence.sh), THREADS [2],
#   RULES ["second-max-side median-side max-side mean-side max view:SV_108"], the first the daemon's default;
#   a rule may carry [timeline] settings after commas: "second-max-side,death_penalty=0";
#   KEEP [unset]: keep each rule's store in KEEP/<n>/ (0: the first rule), to plot any plant after;
#   REVIEW [unset]: REVIEW=1 also measures people's counts on the days `phyllo review` lists
#   against as many days at random (a table; about 20 s more per 1000 plant-days).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
plants=${PLANTS:-36}
days=${DAYS:-30}
start_age=${START_AGE:-14}
seed=${SEED:-800001}
dir=${1:-/work/data/seq-s$seed}
model=${MODEL:-$root/models/phyllo.onnx}
cargo build -q --release -p phyllo -p phyllo-gen --manifest-path "$root/Cargo.toml"
bin=$root/target/release
if [ ! -e "$dir/truth.csv" ]; then
  "$bin/phyllo-gen" sequence --out "$dir" --plants "$plants" --days "$days" --start-age "$start_age" \
    --seed "$seed" --quiet
fi
counts=$("$root/scripts/count-sequence.sh" "$dir" "$model")
# shellcheck disable=SC2086 # RULES is a word list
python3 "$root/scripts/timeline_accuracy.py" --phyllo "$bin/phyllo" --sequence "$dir" --counts "$counts" \
  --rules ${RULES:-second-max-side median-side max-side mean-side max view:SV_108} ${KEEP:+--keep "$KEEP"} \
  ${REVIEW:+--review}
