"""Which leaf tips a person would click: the truth rule of the tip heatmap and of tip counts.

The real frames' annotators (Miao et al. 2021; ``leaf_tips.csv``) click the tip of each leaf they
can see, intact or cut. Their marks on the dev frames settle the two open questions: a furled leaf
standing out of the whorl is clicked like any other (``402-127…05-10`` has two marks in its whorl,
``402-204…05-28`` one on its spike), and a leaf whose tip is behind another leaf is not. So, from a
phyllo-gen manifest row, a tip counts when

* its leaf is visible (it has label pixels: the keys of ``leaf_tips``);
* its tip is seen: ``leaf_tip_gaps`` (projected blade tip to the nearest pixel of that leaf) is at
  most ``max_gap`` image pixels. Gaps spread smoothly (median 2.5 px, 90th percentile 7 px over the
  withheld set's leaves, models/EXPERIMENTS.md "The visible-tip truth rule"), so the limit sits
  above the tapering blade's last pixels and below a tip hidden behind another leaf;
* it is a point of its own: tips closer than ``MERGE_PX`` to a tip already counted (taken top to
  bottom) look like one point, as nested leaves of the whorl often do in renders.

The crops' counts (``crops_counts.csv``, no marks) look like expanded leaves only on young plants
(models/EXPERIMENTS.md, session 47), so :func:`open_tips` gives that reading too, for reports
only: the same rule without the leaves still furled in the whorl (``leaf_furl`` ≥ ``WHORL_FURL``,
phyllo-gen since session 48; rows without it count every leaf as open).
"""

from __future__ import annotations

import math

# Tip gaps above this many image pixels (at the contract's frame scale) are hidden tips.
MAX_TIP_GAP = 12.0
# Tips nearer each other than this many image pixels (at frame scale) are one point to a person.
MERGE_PX = 3.0
# A leaf at least this rolled (the growth model's furl: 1 furled, 0 open) is still in the whorl.
WHORL_FURL = 0.5
# The truth rules a tip target can follow.
TIP_RULES = ("visible", "person")


def person_tips(row: dict, max_gap: float = MAX_TIP_GAP) -> dict[str, list[float]]:
    """``{instance: [x, y]}`` of the tips a person would click on one manifest row (see the module)."""
    gaps = row.get("leaf_tip_gaps", {})
    seen = sorted(((xy[1], xy[0], int(k), k) for k, xy in row.get("leaf_tips", {}).items()
                   if gaps.get(k, 0.0) <= max_gap))
    out: dict[str, list[float]] = {}
    for y, x, _, k in seen:
        if all(math.hypot(x - p[0], y - p[1]) >= MERGE_PX for p in out.values()):
            out[k] = [x, y]
    return out


def open_tips(row: dict, max_gap: float = MAX_TIP_GAP) -> dict[str, list[float]]:
    """:func:`person_tips` without the leaves still furled in the whorl (the crops' apparent reading)."""
    furl = row.get("leaf_furl", {})
    return {k: xy for k, xy in person_tips(row, max_gap).items() if furl.get(k, 0.0) < WHORL_FURL}


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


def open_count(row: dict, max_gap: float = MAX_TIP_GAP) -> int:
    """:func:`person_count` of expanded leaves only."""
    return len(open_tips(row, max_gap))
