#!/usr/bin/env python3
"""Does bfloat16 autocast change what a network counts, or only the old Python peak rule?

Runs one network on whole full frames of a phyllo-gen set (no small-plant zoom, the frame padded
to a multiple of 32), once in float32 and once under CPU bfloat16 autocast (as `train --bf16` ran
it), and counts centre peaks under two rules: every pixel equal to its max-pool (the Python
decoder's rule until session 48) and one peak per plateau (the Rust decoder's, now the Python
one's too). Also the leaf counts of the whole decode, against the frames' visible leaves.

    models/.venv/bin/python scripts/experiments/bf16-peaks.py MODEL.onnx DATASET [FRAMES]

Prints a Markdown table. From the repository root.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import torch
from torch.nn import functional as F

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "models"))
from phyllo_train.contract import load_contract  # noqa: E402
from phyllo_train.dataset import PanopticDataset  # noqa: E402
from phyllo_train.tools.from_onnx import architecture_of, load_folded  # noqa: E402
from phyllo_train.model import build_model  # noqa: E402
from phyllo_train.tools.postprocess import decode, find_centers  # noqa: E402


def plateau_peaks(center: torch.Tensor, threshold: float, kernel: int) -> int:
    """Peaks under the old Python rule: every pixel equal to its window's maximum."""
    pooled = F.max_pool2d(center[None], kernel, stride=1, padding=kernel // 2)[0]
    return int(((center == pooled) & (center > threshold)).sum())


def main() -> int:
    model_path, data = Path(sys.argv[1]), Path(sys.argv[2])
    frames = int(sys.argv[3]) if len(sys.argv) > 3 else 100
    torch.set_num_threads(2)
    contract = load_contract()
    pp = contract.raw["postprocess"]
    thr, k = float(pp["center_threshold"]), int(pp["nms_kernel"])
    import onnx

    meta = {p.key: p.value for p in onnx.load(str(model_path)).metadata_props}
    model = build_model(contract.num_classes, seed=0, **architecture_of(model_path, meta, {}))
    load_folded(model, model_path, contract)  # folded convolutions; BatchNorm the identity, as exported
    model.eval()
    ds = PanopticDataset(data, None, None, contract, limit=frames)
    rows = {name: [] for name in ("old32", "oldbf", "rust32", "rustbf", "count32", "countbf", "truth")}
    for i in range(len(ds)):
        img, _ = ds.decode(i)
        x = torch.from_numpy(np.asarray(img, np.float32) / 255.0).permute(2, 0, 1)
        mean = torch.tensor(contract.mean)[:, None, None]
        std = torch.tensor(contract.std)[:, None, None]
        x = (x - mean) / std
        h, w = x.shape[1:]
        x = F.pad(x, (0, (-w) % 32, 0, (-h) % 32))[None]
        for tag, bf in (("32", False), ("bf", True)):
            with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf):
                sem, ctr, off = (o.float()[0] for o in model(x)[:3])
            rows["old" + tag].append(plateau_peaks(ctr, thr, k))
            rows["rust" + tag].append(len(find_centers(ctr, thr, k, int(pp["top_k"]))))
            rows["count" + tag].append(decode(sem, ctr, off, contract).leaf_count)
        rows["truth"].append(int(ds.rows[i]["visible_leaf_count"]))
    a = {k: np.asarray(v) for k, v in rows.items()}
    print(f"{model_path.name} on the first {len(ds)} frames of {data}, centre threshold {thr}, NMS {k}\n")
    print("| peak rule | peaks, float32 | peaks, bfloat16 autocast | frames whose peak count changes |")
    print("|---|---:|---:|---:|")
    for name, key in (("every pixel equal to its max-pool (old Python)", "old"), ("one per plateau (Rust)", "rust")):
        print(f"| {name} | {a[key + '32'].sum()} | {a[key + 'bf'].sum()} | "
              f"{int((a[key + '32'] != a[key + 'bf']).sum())} |")
    print()
    print("| decode (Rust peak rule) | exact against visible leaves | bias |")
    print("|---|---:|---:|")
    for tag, name in (("32", "float32"), ("bf", "bfloat16 autocast")):
        e = a["count" + tag] - a["truth"]
        print(f"| {name} | {100 * np.mean(e == 0):.1f} % | {e.mean():+.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
