"""Scores the daemon's phyllochron in degree-days against growth sequences
rendered under different greenhouse climates.

Called by scripts/thermal-accuracy.sh with, per sequence, its folder
(`phyllo-gen sequence --climate`: truth.csv with each leaf's exact emergence
time and degree-days, climate.csv the temperature log) and the model's counts
of its frames. Each sequence's counts and its temperature log go through
`phyllo import` into a fresh store; plants.csv is exported and every plant's
phyllochron, in days and in degree-days per leaf, is compared with the
truth's; then the same with the true living-leaf counts imported instead.
The same plants grown under two climates show what thermal time is for:
their days per leaf differ with the temperature, their degree-days should
not. Standard library only.
"""

import argparse
import datetime as dt
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from timeline_accuracy import observations, read_csv, run_timeline, truth_observations  # noqa: E402


def least_squares_slope(xs, ys):
    """Slope of `ys` on `xs`; None under three points."""
    if len(xs) < 3:
        return None
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx


def true_phyllochrons(truth):
    """Per plant, (days per leaf, degree-days per leaf) over the leaves that
    emerged after its first imaging session (the ones the images can date),
    from each leaf's exact emergence time and degree-days."""
    out = {}
    plants = {}
    for t in truth:
        plants.setdefault(t["plant"], []).append(t)
    for plant, rows in plants.items():
        if "emergence_cd" not in rows[-1]:
            raise SystemExit("truth.csv has no emergence_cd column: render the sequence with --climate")
        first = dt.datetime.fromisoformat(f"{rows[0]['date']}T{rows[0]['time']}")
        at = [dt.datetime.fromisoformat(a) for a in rows[-1]["emergence_at"].split(";") if a]
        cd = [float(c) for c in rows[-1]["emergence_cd"].split(";") if c]
        leaves = [(k + 1, a, c) for k, (a, c) in enumerate(zip(at, cd)) if a > first]
        xs = [k for k, _, _ in leaves]
        days = least_squares_slope(xs, [(a - first).total_seconds() / 86400 for _, a, _ in leaves])
        degree_days = least_squares_slope(xs, [c for _, _, c in leaves])
        out[plant] = (days, degree_days)
    return out


def phyllo_phyllochrons(phyllo, obs, climate_csv, work):
    """Imports `obs` and the temperature log into a fresh store under the
    daemon's default fusion; per plant (days per leaf, degree-days per leaf)
    from the exported plants.csv, None where it gives none."""
    run_timeline(phyllo, obs, "second-max-side", work)
    cfg = os.path.join(work, "phyllo.toml")
    subprocess.run([phyllo, "import", "-c", cfg, climate_csv], check=True, capture_output=True)
    path = os.path.join(work, "plants.csv")
    subprocess.run([phyllo, "export", "-c", cfg, "--what", "plants", "--out", path], check=True, capture_output=True)

    def num(v):
        return float(v) if v not in ("", None) else None

    return {r["plant"]: (num(r["phyllochron_days"]), num(r["phyllochron_cd"])) for r in read_csv(path)}


def compare(truth_values, phyllo_values):
    """Per measure (0: days, 1: degree-days), the (phyllo, truth) pairs of the
    plants where both have a value."""
    return [
        [(phyllo_values[p][i], t[i]) for p, t in truth_values.items()
         if t[i] is not None and phyllo_values.get(p, (None, None))[i] is not None]
        for i in (0, 1)
    ]


def summary(pairs):
    """'phyllo mean / truth mean | MAE (MAE as % of the truth mean) | n' of (phyllo, truth) pairs."""
    if not pairs:
        return "- | - | 0"
    mp = statistics.mean(p for p, _ in pairs)
    mt = statistics.mean(t for _, t in pairs)
    mae = statistics.mean(abs(p - t) for p, t in pairs)
    return f"{mp:.2f} / {mt:.2f} | {mae:.2f} ({100 * mae / mt:.1f} %) | {len(pairs)}"


def cv(values):
    """Coefficient of variation in percent (sample standard deviation over mean)."""
    return 100 * statistics.stdev(values) / statistics.mean(values) if len(values) > 1 else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--phyllo", required=True)
    ap.add_argument("--run", nargs=2, action="append", required=True, metavar=("SEQUENCE", "COUNTS"),
                    help="a sequence rendered with --climate and the model's counts of its frames (repeat)")
    a = ap.parse_args()
    print("phyllochron per plant over the leaves that emerged after its first imaging session, days and")
    print("degree-days (above 10 °C) per leaf: phyllo's mean / the truth's, mean absolute error (and as % of")
    print("the truth's mean), plants; phyllo imports the counts and climate.csv (`phyllo import`), default fusion")
    print("| sequence | logged mean °C | counts | days per leaf: phyllo / truth | MAE (d) | plants | degree-days per leaf: phyllo / truth | MAE (°Cd) | plants |")
    print("|---|---:|---|---|---|---:|---|---|---:|")
    per_run = []
    with tempfile.TemporaryDirectory() as scratch:
        for i, (seq, counts) in enumerate(a.run):
            truth = read_csv(os.path.join(seq, "truth.csv"))
            climate_csv = os.path.join(seq, "climate.csv")
            temps = [float(r["temp_c"]) for r in read_csv(climate_csv)]
            true_values = true_phyllochrons(truth)
            values = {}
            for source, obs in (("model", observations(counts)), ("truth", truth_observations(truth))):
                values[source] = phyllo_phyllochrons(a.phyllo, obs, climate_csv, os.path.join(scratch, f"{i}-{source}"))
                days, degree_days = compare(true_values, values[source])
                print(f"| {os.path.basename(seq.rstrip('/'))} | {statistics.mean(temps):.1f} | {source} | "
                      f"{summary(days)} | {summary(degree_days)} |")
            per_run.append((os.path.basename(seq.rstrip("/")), true_values, values["model"]))
    print("between the sequences: the same plants (those with a value in every sequence) under each climate,")
    print("mean phyllochron as phyllo reads it with the model / as the truth has it, and the coefficient of")
    print("variation of those means across the climates (a unit that does not depend on the climate spreads little):")
    print("| unit | plants | " + " | ".join(name for name, _, _ in per_run) + " | CV phyllo | CV truth |")
    print("|---|---:|" + "---|" * len(per_run) + "---:|---:|")
    for i, unit in ((0, "days per leaf"), (1, "degree-days per leaf")):
        by_run = [{p: (pv[p][i], t[i]) for p, t in tv.items()
                   if t[i] is not None and pv.get(p, (None, None))[i] is not None} for _, tv, pv in per_run]
        common = set.intersection(*(set(r) for r in by_run))
        if not common:
            print(f"| {unit} | 0 |" + " - |" * len(per_run) + " - | - |")
            continue
        phyllo_means = [statistics.mean(r[p][0] for p in common) for r in by_run]
        truth_means = [statistics.mean(r[p][1] for p in common) for r in by_run]
        cells = " | ".join(f"{pm:.2f} / {tm:.2f}" for pm, tm in zip(phyllo_means, truth_means))
        print(f"| {unit} | {len(common)} | {cells} | {cv(phyllo_means):.1f} % | {cv(truth_means):.1f} % |")


if __name__ == "__main__":
    main()
