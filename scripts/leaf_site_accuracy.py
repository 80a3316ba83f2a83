"""Scores where phyllo says each new leaf emerged against the generator's labels.

Called by scripts/leaf-site-accuracy.sh with a sequence rendered with
`--labels` and the events.csv `phyllo export` wrote after `phyllo serve`
counted its frames. For each event with a site, the site's leaf instance (its
predicted centre, else its box) is looked up in the frame's panoptic label:
which true leaf is it on? The generator numbers the living leaves of a frame
from 1, bottom to top, so the leaves new in a session are the top ones:
instances living - (emerged - emerged the session before) + 1 ... living.
Needs numpy and pillow (models/.venv has both).
"""

import argparse
import collections
import csv
import json
import os
import sqlite3

import numpy as np
from PIL import Image

DIVISOR = 1000  # models/contract.toml [label] divisor
LEAF = 1


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def true_new_instances(truth):
    """(plant, date) -> (set of instance ids new that session, living leaves)."""
    out = {}
    by_plant = collections.defaultdict(list)
    for t in truth:
        by_plant[t["plant"]].append(t)
    for plant, rows in by_plant.items():
        rows.sort(key=lambda r: r["date"])
        for prev, cur in zip(rows, rows[1:]):
            living, emerged = int(cur["living_leaves"]), int(cur["leaves_emerged"])
            new = emerged - int(prev["leaves_emerged"])
            out[(plant, cur["date"])] = (set(range(living - new + 1, living + 1)), living)
    return out


def leaf_under(label, centre, bbox):
    """The leaf instance the site lies on: the most common leaf label in a
    9x9 window round its centre, else in its box; None when neither holds leaf."""
    h, w = label.shape
    x, y = int(round(centre[0])), int(round(centre[1]))
    for x0, y0, x1, y1 in ((x - 4, y - 4, x + 5, y + 5), tuple(bbox)):
        patch = label[max(0, y0):min(h, y1), max(0, x0):min(w, x1)]
        leaves = patch[(patch // DIVISOR) == LEAF] % DIVISOR
        leaves = leaves[leaves > 0]
        if leaves.size:
            values, counts = np.unique(leaves, return_counts=True)
            return int(values[np.argmax(counts)])
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sequence", required=True, help="a phyllo-gen sequence rendered with --labels")
    ap.add_argument("--events", required=True, help="phyllo export --what events")
    ap.add_argument("--db", help="the store: also say in how many events any side view shows the new leaf")
    a = ap.parse_args()
    db = sqlite3.connect(f"file:{a.db}?mode=ro", uri=True) if a.db else None

    def session_views(db, e):
        """The side views' (image, leaf instances) of the session that first counted the event's leaf."""
        rows = db.execute(
            "SELECT i.path, o.instances FROM observations o JOIN images i ON i.id = o.image_id "
            "JOIN plants p ON p.id = o.plant_id JOIN sessions s ON s.plant_id = p.id AND s.start = ? "
            "WHERE p.name = ? AND o.view LIKE 'SV%' AND o.taken_at >= s.start "
            "AND o.taken_at < COALESCE((SELECT MIN(start) FROM sessions t WHERE t.plant_id = p.id AND t.start > s.start), '9')",
            (e["seen_at"], e["plant"])).fetchall()
        return [(path, json.loads(inst)) for path, inst in rows]

    def on_leaves(view):
        path, instances = view
        label = np.asarray(Image.open(os.path.join(a.sequence, "labels", os.path.basename(path))))
        return {leaf_under(label, i["centre"], i["bbox"]) for i in instances if i["class"] == LEAF}
    truth = read_csv(os.path.join(a.sequence, "truth.csv"))
    new_by_session = true_new_instances(truth)
    events = read_csv(a.events)
    tally = collections.Counter()
    chance = []
    for e in events:
        tally["events"] += 1
        if not e.get("site_view"):
            continue
        tally["located"] += 1
        key = (e["plant"], e["seen_at"][:10])
        new, living = new_by_session.get(key, (set(), 0))
        if not new:
            # The timeline put a leaf in a session where none emerged: no site can be right.
            tally["no true new leaf that session"] += 1
            continue
        tally["true new leaf that session"] += 1
        label = np.asarray(Image.open(os.path.join(a.sequence, "labels", os.path.basename(e["site_image"]))))
        on = leaf_under(label, (float(e["site_x"]), float(e["site_y"])), json.loads(e["site_bbox"]))
        visible = {int(v) % DIVISOR for v in np.unique(label) if int(v) // DIVISOR == LEAF and int(v) % DIVISOR > 0}
        if on in new:
            tally["on a new leaf"] += 1
        elif on is None:
            tally["on no leaf"] += 1
        elif on == max(visible, default=-1):
            tally["on the top visible leaf, not new"] += 1
        else:
            tally["on an older leaf"] += 1
        # A leaf picked at random among those the view shows.
        chance.append(len(new & visible) / max(len(visible), 1))
        if db is not None:
            tally["some view shows it"] += any(new & on_leaves(v) for v in session_views(db, e))
    n = tally["true new leaf that session"]
    pct = lambda k, d=n: f"{100 * tally[k] / max(d, 1):.1f} %"  # noqa: E731
    print(f"sequence {a.sequence}: {tally['events']} emergence events, {tally['located']} with a site")
    print(f"sites in a session where a leaf truly emerged: {n} (the other {tally['no true new leaf that session']} "
          "are timeline errors no site can fix)")
    print("| site lies on | events | share |")
    print("|---|---:|---:|")
    for k in ("on a new leaf", "on the top visible leaf, not new", "on an older leaf", "on no leaf"):
        print(f"| {k} | {tally[k]} | {pct(k)} |")
    if db is not None:
        print(f"events where some side view shows a new leaf as a leaf instance of its own (the best any rule "
              f"choosing one instance could do): {tally['some view shows it']} ({pct('some view shows it')})")
    if chance:
        print(f"a leaf of the view picked at random: {100 * sum(chance) / len(chance):.1f} % on a new leaf")


if __name__ == "__main__":
    main()
