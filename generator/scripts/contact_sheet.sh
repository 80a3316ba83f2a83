#!/usr/bin/env bash
# Builds docs/contact_sheet.png: real LemnaTec dev frames (resized to the
# contract's 514-px frame height) beside phyllo-gen renders and their masks
# at the same scale. Needs ImageMagick (convert, montage).
# Usage: generator/scripts/contact_sheet.sh [path/to/unl-maize-dev] [out.png]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
real=${1:-$root/../shared/data/unl-maize-dev}
out=${2:-$root/docs/contact_sheet.png}
gen=$root/target/release/phyllo-gen
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cargo build -q -p phyllo-gen --release --manifest-path "$root/Cargo.toml"
tiles=()
reals=(
  402-127-N55-WW-1_2019-05-10_09-18-07.937_Vis_SV_108.jpg
  402-348-N276-WW-1_2019-05-27_11-19-59.832_Vis_SV_108.jpg
  81-061-NC368_2018-09-07_06-59-46_Vis_SV_108.jpg
  402-204-N132-WW-1_2019-05-28_11-13-20.830_Vis_SV_108.jpg
)
renders=("btx623 1 30 108" "maize 3 44 0" "sc301 2 40 36" "rtx430 4 50 72")
for i in 0 1 2 3; do
  convert "$real/images/${reals[$i]}" -resize x514 -gravity south -pointsize 16 -fill black -annotate +0+4 "real (maize, dev set)" "$tmp/real$i.png"
  read -r preset seed age view <<<"${renders[$i]}"
  "$gen" render --preset "$preset" --seed "$seed" --age "$age" --view "$view" --spp 4 --out "$tmp/syn$i.png" >/dev/null
  convert "$tmp/syn$i.png" -gravity south -pointsize 16 -fill black -annotate +0+4 "phyllo-gen $preset ${age}d view $view" "$tmp/synl$i.png"
  convert "$tmp/syn$i.mask.png" -gravity south -pointsize 16 -fill white -annotate +0+4 "panoptic mask" "$tmp/mask$i.png"
  tiles+=("$tmp/real$i.png" "$tmp/synl$i.png" "$tmp/mask$i.png")
done
"$gen" render --preset btx623 --seed 1 --age 30 --view top --spp 4 --out "$tmp/top.png" >/dev/null
montage "${tiles[@]}" -tile 3x -geometry 614x514+2+2 -background white "$out"
echo "wrote $out"
