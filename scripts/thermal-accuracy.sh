#!/usr/bin/env bash
# Measures the phyllochron in degree-days per leaf, with the model in the
# loop: renders the same plants under several greenhouse climates
# (phyllo-gen sequence --climate: development by degree-days above 10 °C,
# the temperature log written as climate.csv), counts every frame with the
# model, imports counts and log (`phyllo import`) and compares each plant's
# phyllochron, in days and in degree-days, with the truth's; a second row
# per climate imports the true living-leaf counts instead.
# Usage: scripts/thermal-accuracy.sh
# Environment: CLIMATES ["19:14:30 29:7:14"], each CLIMATE:START_AGE:DAYS, the
#   climate a --climate value MEAN[,SWING[,DRIFT]]: by default a cool and a warm
#   greenhouse over the same stretch of development (about 8 to 27 days at
#   25 °C: the warm plants grow twice as fast, so fewer calendar days, and
#   neither reaches the leaf deaths a living-leaf count cannot date);
#   PLANTS [16], SEED [810001] (the same plants in every climate), DATA
#   [/work/data] (sequences go to DATA/seq-s<SEED>-c<CLIMATE>-a<START_AGE>-d<DAYS>,
#   rendered only when missing; a partial render resumes), MODEL
#   [models/phyllo.onnx], THREADS [2].
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seed=${SEED:-810001}
model=${MODEL:-$root/models/phyllo.onnx}
cargo build -q --release -p phyllo -p phyllo-gen --manifest-path "$root/Cargo.toml"
bin=$root/target/release
runs=()
for spec in ${CLIMATES:-19:14:30 29:7:14}; do
  IFS=: read -r climate start_age days <<<"$spec"
  if [ -z "$climate" ] || [ -z "$start_age" ] || [ -z "$days" ]; then
    echo "CLIMATES: '$spec' is not CLIMATE:START_AGE:DAYS" >&2
    exit 2
  fi
  dir=${DATA:-/work/data}/seq-s$seed-c$climate-a$start_age-d$days
  if [ ! -e "$dir/truth.csv" ]; then
    "$bin/phyllo-gen" sequence --out "$dir" --plants "${PLANTS:-16}" --days "$days" \
      --start-age "$start_age" --seed "$seed" --views 0,36,72,108,144 --climate "$climate" --quiet
  fi
  runs+=(--run "$dir" "$("$root/scripts/count-sequence.sh" "$dir" "$model")")
done
python3 "$root/scripts/thermal_accuracy.py" --phyllo "$bin/phyllo" "${runs[@]}"
