#!/usr/bin/env python3
"""Times models side by side: runs `phyllo count --json --model M` on the same
images for each model in turn, `--rounds` times (the models alternate, so a
busy machine slows both alike), and prints one markdown row per model: tiles,
inference ms per tile (ONNX Runtime's run, from the `ms` each count reports),
whole-pipeline ms per image, and the ratio to the first model.

    scripts/time_models.py --label L --rounds N --model NAME=FILE... \\
        -- PHYLLO_COMMAND... -- IMAGES...

PHYLLO_COMMAND is the binary, with its runner in front where there is one
(`qemu-aarch64 -L /usr/aarch64-linux-gnu out/aarch64/bin/phyllo`).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys


def one_run(command: list[str], model: str, images: list[str]) -> tuple[int, float, float, int]:
    """Tiles, inference ms, total ms and images of one `count --json` run."""
    out = subprocess.run(command + ["count", "--json", "--top-model", "none", "--model", model] + images,
                         check=True, capture_output=True, text=True).stdout
    tiles = inference = total = n = 0
    for line in out.splitlines():
        if not line.strip():
            continue
        o = json.loads(line)
        tiles += o["tiles"]
        inference += o["ms"]["inference"]
        total += o["ms"]["total"]
        n += 1
    return tiles, inference, total, n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--label", required=True)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--model", action="append", required=True, help="NAME=FILE")
    ap.add_argument("rest", nargs=argparse.REMAINDER)
    args = ap.parse_args()
    rest = args.rest[1:] if args.rest[:1] == ["--"] else args.rest
    if "--" not in rest:
        ap.error("give -- PHYLLO_COMMAND... -- IMAGES...")
    cut = rest.index("--")
    command, images = rest[:cut], rest[cut + 1:]
    models = [m.split("=", 1) for m in args.model]
    sums = {name: [0, 0.0, 0.0, 0] for name, _ in models}
    for name, path in models:  # warm-up: first loads and page-ins are not timed
        one_run(command, path, images[:1])
    for _ in range(args.rounds):
        for name, path in models:
            for i, v in enumerate(one_run(command, path, images)):
                sums[name][i] += v
    base = None
    for name, _ in models:
        tiles, inference, total, n = sums[name]
        per_tile = inference / tiles
        base = base or per_tile
        print(f"| {args.label} | {name} | {tiles // args.rounds} tiles on {n // args.rounds} images | "
              f"{per_tile:.1f} ms | {total / n:.1f} ms | {per_tile / base:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
