"""Which leaf tips a person would click: the truth rule of the tip heatmap and of tip counts.

The real sets' annotators (Miao et al. 2021; ``leaf_tips.csv``) click the tip of each leaf they
can see, intact or cut by the image's edge. Three things in a phyllo-gen manifest decide whether
a leaf has such a tip:

* the leaf is visible at all (it has label pixels: the keys of ``leaf_tips``);
* its tip is seen: ``leaf_tip_gaps`` (projected blade tip to the nearest pixel of that leaf) is at
  most ``max_gap`` image pixels. Gaps spread smoothly (median 2.5 px, 90th percentile 7 px over the
  withheld set's leaves, models/EXPERIMENTS.md "The visible-tip truth rule"), so the limit sits
  above the tapering blade's few pixels and below a tip hidden behind another leaf;
* furled leaves are one spike: leaves still rolled in the whorl (``leaf_furl`` ≥ ``WHORL_FURL``)
  stand nested in one cone, and a person sees the cone's point, not one point per leaf. Of the
  whorl's furled leaves with a seen tip, only the one whose tip is highest in the image counts.

Manifests without ``leaf_furl`` (written before it existed) treat every leaf as open.
"""

from __future__ import annotations

# Tip gaps above this many image pixels (at the contract's frame scale) are hidden tips.
MAX_TIP_GAP = 12.0
# A leaf at least this rolled (the growth model's furl: 1 furled, 0 open) is still in the whorl.
WHORL_FURL = 0.5
# The truth rules a tip target or a tip count can follow.
TIP_RULES = ("visible", "person")


def person_tips(row: dict, max_gap: float = MAX_TIP_GAP) -> dict[str, list[float]]:
    """``{instance: [x, y]}`` of the tips a person would click on one manifest row (see the module)."""
    tips = row.get("leaf_tips", {})
    gaps = row.get("leaf_tip_gaps", {})
    furl = row.get("leaf_furl", {})
    seen = {k: xy for k, xy in tips.items() if gaps.get(k, 0.0) <= max_gap}
    out = {k: xy for k, xy in seen.items() if furl.get(k, 0.0) < WHORL_FURL}
    whorl = [(xy[1], int(k), k) for k, xy in seen.items() if furl.get(k, 0.0) >= WHORL_FURL]
    if whorl:
        _, _, k = min(whorl)  # highest tip; ties go to the lower instance number
        out[k] = seen[k]
    return out


def tip_targets(row: dict, rule: str, max_gap: float | None) -> dict[str, list[float]]:
    """The tips a tip heatmap is trained on under ``rule``: ``visible`` (every visible leaf's
    apparent tip, those with a gap above ``max_gap`` left out when it is given) or ``person``."""
    if rule == "person":
        return person_tips(row, MAX_TIP_GAP if max_gap is None else max_gap)
    if rule != "visible":
        raise ValueError(f"unknown tip rule {rule!r} (expected one of {', '.join(TIP_RULES)})")
    tips = row.get("leaf_tips", {})
    if max_gap is None:
        return dict(tips)
    gaps = row.get("leaf_tip_gaps", {})
    return {k: xy for k, xy in tips.items() if gaps.get(k, 0.0) <= max_gap}


def person_count(row: dict, max_gap: float = MAX_TIP_GAP) -> int:
    """The leaf count a person clicking tips would give this row."""
    return len(person_tips(row, max_gap))
