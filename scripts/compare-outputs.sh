#!/usr/bin/env bash
# Compares what two phyllo binaries write, for a restructuring that must not
# change behaviour: `phyllo count --json` on the samples (and the real dev
# frames when ../shared is there), and a scratch site served, exported and
# reported on by each. Times of the run itself (today's date) are masked.
#   scripts/compare-outputs.sh OLD_PHYLLO NEW_PHYLLO
# Prints one line per output, "same" or the diff; exits 1 on any difference.
set -euo pipefail
cd "$(dirname "$0")/.."
old=$(realpath "$1") new=$(realpath "$2")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
today=$(date -u +%Y-%m-%d)
mask() { sed -E "s#$work/(old|new)#<site>#g; s/${today}[T ][0-9:.]+Z?/<now>/g; s/\(pid [0-9]+/(pid <x>/; s/^queue: .*/queue: <x>/; s/(@[0-9a-f]{12}(\+[^,]*)?),[0-9.]+,/\1,<ms>,/; s/\"ms\":\{[^}]*\}/\"ms\":<t>/g; s/\"(total_ms|ms_total|pid|started_at|heartbeat)\":[^,}]*/\"\1\":<x>/g; s/\(([0-9]+) tiles, [0-9]+ ms\)/(\1 tiles)/; s/[0-9]+ h ago/<h> ago/g"; }
frames=(docs/samples/*.jpg)
dev=../shared/data/unl-maize-dev/images
[[ -d $dev ]] && frames+=("$dev"/*.jpg)

site() { # BIN DIR: a served, exported site of the samples
  local bin=$1 dir=$2
  mkdir -p "$dir/drop"
  cp -p docs/samples/*.jpg "$dir/drop/"
  printf 'drop_dir = "drop"\ndatabase = "state/phyllo.sqlite"\n[watch]\nstable_secs = 0.2\n' > "$dir/phyllo.toml"
  "$bin" serve -c "$dir/phyllo.toml" 2>"$dir/serve.log" &
  local pid=$! n=0 c
  while (( n < 300 )); do # the three samples counted, or five minutes
    c=$("$bin" status -c "$dir/phyllo.toml" --json 2>/dev/null | grep -o '"counted": *[0-9]*' | grep -o '[0-9]*$' || true)
    (( ${c:-0} >= 3 )) && break
    sleep 1; n=$((n + 1))
  done
  kill -TERM $pid; wait $pid || true
  "$bin" export -c "$dir/phyllo.toml" > "$dir/export.out"
  "$bin" status -c "$dir/phyllo.toml" > "$dir/status.out" || true
  "$bin" timeline -c "$dir/phyllo.toml" 402-127-N55-WW-1 > "$dir/timeline.out" || true
}

rc=0
compare() { # NAME OLDFILE NEWFILE
  if diff <(mask < "$2") <(mask < "$3") > "$work/diff"; then echo "same: $1"; else echo "DIFFERENT: $1"; head -20 "$work/diff"; rc=1; fi
}
"$old" count --json "${frames[@]}" > "$work/count.old" 2>/dev/null
"$new" count --json "${frames[@]}" > "$work/count.new" 2>/dev/null
compare "count --json (${#frames[@]} frames)" "$work/count.old" "$work/count.new"
site "$old" "$work/old"
site "$new" "$work/new"
for f in export.out status.out timeline.out; do compare "$f" "$work/old/$f" "$work/new/$f"; done
for f in $(cd "$work/old/state/exports" && ls *.csv); do
  compare "exports/$f" "$work/old/state/exports/$f" "$work/new/state/exports/$f"
done
compare "exports/index.html" "$work/old/state/exports/index.html" "$work/new/state/exports/index.html"
exit $rc
