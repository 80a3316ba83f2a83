"""How closely one network's centre heatmap follows another's: near the peaks, and away from them.

    python -m phyllo_train.peak_match --data /work/data/own300 --split all --limit 60 \\
        runs/s10-onnx/best.pt:0.3 runs/fit-dist-fp32/step-000400.pt:0.3

A student trained on a teacher's heatmap (``train --teacher``) may fit its
smooth background and miss its peaks, or the reverse; only the peaks count.
Per network pair, on whole tiles without augmentation: the squared error
within ``--radius`` output pixels of the reference's peaks and elsewhere,
and how many reference peaks the other network has a peak of its own
within that radius (and the reverse), each cut at its own threshold.
"""

from __future__ import annotations

import torch
from torch.nn import functional as F

from .contract import load_contract
from .head_swap import open_tiles, outputs, pair_parser, parse_spec
from .postprocess import find_centers


def near_mask(peaks: torch.Tensor, shape: tuple[int, int], radius: int) -> torch.Tensor:
    """Boolean (h, w) map of the pixels within ``radius`` (Chebyshev) of any peak."""
    mask = torch.zeros(shape, dtype=torch.float32)
    if len(peaks):
        mask[peaks[:, 0], peaks[:, 1]] = 1.0
    return F.max_pool2d(mask[None, None], 2 * radius + 1, stride=1, padding=radius)[0, 0] > 0


def matched(peaks: torch.Tensor, other: torch.Tensor, radius: int) -> int:
    """How many of ``peaks`` have one of ``other`` within ``radius`` (Chebyshev) output pixels."""
    if not len(peaks) or not len(other):
        return 0
    d = (peaks[:, None, :] - other[None, :, :]).abs().amax(dim=2)
    return int((d.amin(dim=1) <= radius).sum())


def main(argv: list[str] | None = None) -> int:
    """CLI entry point: prints one Markdown table row."""
    ap = pair_parser("python -m phyllo_train.peak_match", __doc__, "reference: the reference network (the teacher)",
                     "other: the network compared with it", limit=60)
    ap.add_argument("--radius", type=int, default=2, help="output pixels that count as near a peak")
    args = ap.parse_args(argv)
    contract = load_contract()
    pp = contract.raw["postprocess"]
    ds = open_tiles(args, contract)
    (ref_path, ref_thr), (oth_path, oth_thr) = parse_spec(args.reference), parse_spec(args.other)
    ref, oth = outputs(ref_path, ds, 4, 1.0), outputs(oth_path, ds, 4, 1.0)
    sq_near = sq_far = n_near = n_far = 0.0
    ref_peaks = oth_peaks = ref_found = oth_found = 0
    for (_, rc, _), (_, oc, _) in zip(ref, oth):
        rp = find_centers(rc, ref_thr, int(pp["nms_kernel"]), int(pp["top_k"]))
        op = find_centers(oc, oth_thr, int(pp["nms_kernel"]), int(pp["top_k"]))
        near = near_mask(rp, tuple(rc.shape[1:]), args.radius)
        sq = (rc[0] - oc[0]) ** 2
        sq_near += float(sq[near].sum())
        n_near += float(near.sum())
        sq_far += float(sq[~near].sum())
        n_far += float((~near).sum())
        ref_peaks += len(rp)
        oth_peaks += len(op)
        ref_found += matched(rp, op, args.radius)
        oth_found += matched(op, rp, args.radius)
    print(f"{len(ds)} images of {args.data} ({args.split}); reference {ref_path} at {ref_thr:g}, "
          f"other {oth_path} at {oth_thr:g}; near = within {args.radius} output px of a reference peak\n")
    print("| MSE near peaks | MSE elsewhere | share of squared error near | reference peaks | found by other "
          "| other's peaks | near a reference peak |\n|---:|---:|---:|---:|---:|---:|---:|")
    print(f"| {sq_near / max(n_near, 1):.5f} | {sq_far / max(n_far, 1):.6f} | "
          f"{100 * sq_near / max(sq_near + sq_far, 1e-12):.0f} % | {ref_peaks} | {ref_found} | {oth_peaks} | "
          f"{oth_found} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
