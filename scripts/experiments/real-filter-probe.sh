#!/usr/bin/env bash
# Asks whether smoothing the real images before counting would close the
# sensor-noise gap (models/EXPERIMENTS.md, "Real against synthetic inputs"):
# writes filtered copies of the real frames and crops (JPEG re-encode at
# quality 95 alone, Gaussian blur of radius 0.6 and 1.0, 3×3 median) and
# counts each with one model, one table row per filter and set.
# Usage: scripts/experiments/real-filter-probe.sh [MODEL] [REAL_DIR]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
model=${1:-$root/models/phyllo.onnx}
real=${2:-$root/../shared/data/unl-maize-dev}
py=${PYTHON:-$root/models/.venv/bin/python}
bin=$root/target/release/phyllo
cargo build -q --release -p phyllo --manifest-path "$root/Cargo.toml"
filters=(q95 gauss0.6 gauss1.0 median3)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$py" - "$real" "$tmp" "${filters[@]}" <<'PY'
import pathlib, sys
from PIL import Image, ImageFilter

real, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
apply = {
    "q95": lambda im: im,  # the re-encode alone, which every filter below adds
    "gauss0.6": lambda im: im.filter(ImageFilter.GaussianBlur(0.6)),
    "gauss1.0": lambda im: im.filter(ImageFilter.GaussianBlur(1.0)),
    "median3": lambda im: im.filter(ImageFilter.MedianFilter(3)),
}
for name in sys.argv[3:]:
    for sub in ("images", "crops"):
        dest = out / name / sub
        dest.mkdir(parents=True)
        for path in sorted((real / sub).glob("*.jpg")):
            apply[name](Image.open(path).convert("RGB")).save(dest / path.name, quality=95)
PY
echo "| filter | set | images | exact | within ±1 | RMSE | MAE | bias | R² |"
echo "|---|---|---:|---:|---:|---:|---:|---:|---:|"
for f in none "${filters[@]}"; do
  dir=$tmp/$f
  [[ $f == none ]] && dir=$real # the untouched files: the daemon's own numbers
  for set in "frames leaf_tips.csv images" "crops crops_counts.csv crops"; do
    read -r label csv sub <<<"$set"
    "$bin" eval --threads "${THREADS:-2}" --model "$model" --counts "$real/$csv" --images "$dir/$sub" --json 2>/dev/null |
      "$root/scripts/eval_json.py" row "$f | $label"
  done
done
