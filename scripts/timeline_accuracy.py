"""Scores the daemon's timeline against a growth sequence's truth.csv.

Called by scripts/timeline-accuracy.sh with the model's counts of every
frame (`phyllo count --json` lines). For each view-fusion rule the counts go
through `phyllo import` into a fresh SQLite store, the timeline and events
are exported, and every plant-day is compared with the generator's truth;
then the same with the true living-leaf counts imported instead (the
timeline's own error). Standard library only.
"""

import argparse
import csv
import datetime as dt
import hashlib
import json
import math
import os
import random
import re
import shutil
import subprocess
import tempfile

NAME = re.compile(r"^(?P<plant>[^_]+)_(?P<date>\d{4}-\d\d-\d\d)_(?P<time>\d\d-\d\d-\d\d)_Vis_(?P<view>[ST]V_\d+)\.png$")


def fingerprint(sequence, frames):
    """SHA-256 over truth.csv and every frame's name and bytes: says whether two runs scored the same renders."""
    h = hashlib.sha256()
    for name in ["truth.csv"] + sorted(frames):
        h.update(name.encode() + b"\0")
        with open(os.path.join(sequence, name), "rb") as f:
            h.update(hashlib.sha256(f.read()).digest())
    return h.hexdigest()[:16]


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def observations(counts_path):
    """(plant, ISO timestamp, view, count) per counted frame of the sequence."""
    rows = []
    for line in open(counts_path):
        r = json.loads(line)
        m = NAME.match(os.path.basename(r["file"]))
        if m is None:
            raise SystemExit(f"{r['file']}: not a phyllo-gen sequence frame name")
        ts = f"{m['date']}T{m['time'].replace('-', ':')}"
        rows.append((m["plant"], ts, m["view"], r["leaf_count"]))
    return rows


def lost_by_last_day(rows, lost_of):
    """(leaves lost, plants with a loss) on each plant's last row, `lost_of(row)` giving its leaves lost."""
    last = {}
    for r in rows:
        last[r["plant"]] = r
    lost = [lost_of(r) for r in last.values()]
    return sum(lost), sum(x > 0 for x in lost)


def ms_per_frame(counts_path):
    """Mean milliseconds per frame (the pipeline's own `ms` stages) of side and of top views."""
    ms = {"side": [], "top": []}
    for line in open(counts_path):
        r = json.loads(line)
        kind = "top" if "_Vis_TV_" in os.path.basename(r["file"]) else "side"
        ms[kind].append(r["ms"]["total"] if "total" in r["ms"] else sum(r["ms"].values()))
    return {k: (sum(v) / len(v), len(v)) for k, v in ms.items() if v}


def truth_observations(truth):
    """The true living-leaf count in each of the five side views: the model taken out."""
    return [(t["plant"], f"{t['date']}T{t['time']}", f"SV_{a}", int(t["living_leaves"]))
            for t in truth for a in (0, 36, 72, 108, 144)]


def timeline_section(spec):
    """The `[timeline]` lines of a spec `RULE[,KEY=VALUE...]`, e.g. `second-max-side,death_penalty=2`."""
    rule, *settings = spec.split(",")
    lines = [f'fusion = "{rule}"']
    for kv in settings:
        key, sep, value = kv.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise SystemExit(f"{spec}: expected RULE[,KEY=VALUE...]")
        lines.append(f"{key.strip()} = {value.strip()}")
    return "\n".join(lines) + "\n"


def run_timeline(phyllo, obs, rule, work):
    """Imports `obs` under the fusion spec `rule` into a new store; returns (timeline, events) rows."""
    os.makedirs(work)
    cfg = os.path.join(work, "phyllo.toml")
    with open(cfg, "w") as f:
        f.write(f'drop_dir = "{work}/drop"\ndatabase = "{work}/db.sqlite"\n[timeline]\n{timeline_section(rule)}'
                f"[groups]\npattern = '{GENOTYPE_PATTERN}'\n")
    obs_csv = os.path.join(work, "obs.csv")
    with open(obs_csv, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["plant", "timestamp", "view", "leaf_count"])
        w.writerows(obs)
    subprocess.run([phyllo, "import", "-c", cfg, obs_csv], check=True, capture_output=True)
    return exported(phyllo, cfg, work)


def exported(phyllo, cfg, work):
    """The store's timeline and events, exported into `work`: (timeline, events) rows."""
    out = {}
    for what in ("timeline", "events"):
        path = os.path.join(work, f"{what}.csv")
        subprocess.run([phyllo, "export", "-c", cfg, "--what", what, "--out", path], check=True, capture_output=True)
        out[what] = read_csv(path)
    return out["timeline"], out["events"]


def review_sessions(phyllo, cfg, top):
    """`phyllo review --json`: the `top` sessions most in doubt, (plant, start) each."""
    out = subprocess.run([phyllo, "review", "-c", cfg, "--json", "--top", str(top)],
                         check=True, capture_output=True, text=True).stdout
    return [(d["plant"], d["start"]) for d in json.loads(out)]


def corrected_run(phyllo, obs, rule, work, truth_by, pick):
    """A store as `run_timeline` makes it, then a person's count (the true living
    leaves) imported for the sessions `pick(cfg, timeline)` names, as a filled
    review sheet; returns (timeline, events) after."""
    timeline, _ = run_timeline(phyllo, obs, rule, work)
    cfg = os.path.join(work, "phyllo.toml")
    sheet = os.path.join(work, "sheet.csv")
    with open(sheet, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["plant", "timestamp", "view", "leaf_count"])
        for plant, start in pick(cfg, timeline):
            w.writerow([plant, start, "human", truth_by[(plant, start[:10])]])
    subprocess.run([phyllo, "import", "-c", cfg, sheet], check=True, capture_output=True)
    return exported(phyllo, cfg, work)


def review_table(phyllo, obs, rule, truth, scratch):
    """What a person's counts on the days `phyllo review` lists are worth, against
    as many days picked at random: lines of a markdown table."""
    truth_by = {(t["plant"], t["date"]): int(t["living_leaves"]) for t in truth}
    lines = []

    def row(label, k, timeline, events):
        fused, _, emerged, _, errs, _, _, _, _, ph = score(truth, timeline, events)
        exact = lambda e: 100 * sum(math.floor(x + 0.5) == 0 for x in e) / len(e)
        lines.append(f"| {label} | {k} | {exact(fused):.1f} | {exact(emerged):.1f} | "
                     f"{sum(abs(e) for e in errs) / max(len(errs), 1):.2f} | {sum(abs(e) for e in ph) / max(len(ph), 1):.3f} |")

    base = os.path.join(scratch, "review-none")
    timeline, events = run_timeline(phyllo, obs, rule, base)
    cfg = os.path.join(base, "phyllo.toml")
    row("none", 0, timeline, events)
    doubt = review_sessions(phyllo, cfg, len(timeline))
    wrong = {(r["plant"], r["session_start"]) for r in timeline
             if math.floor(float(r["fused"]) - truth_by[(r["plant"], r["session_start"][:10])] + 0.5) != 0}
    listed_wrong = sum(d in wrong for d in doubt)
    rest = len(timeline) - len(doubt)
    header = (f"`phyllo review`, {rule}: {len(doubt)} of {len(timeline)} sessions in doubt; fused count wrong on "
              f"{100 * listed_wrong / max(len(doubt), 1):.0f} % of them, on {100 * (len(wrong) - listed_wrong) / max(rest, 1):.0f} % "
              "of the rest. A person's count (the true living leaves) for the first k listed, or for k at random (3 draws, each shown):")
    for frac in (0.05, 0.10):
        k = round(frac * len(timeline))
        tl, ev = corrected_run(phyllo, obs, rule, os.path.join(scratch, f"review-{k}"), truth_by,
                               lambda c, _t, k=k: review_sessions(phyllo, c, k))
        row(f"{frac:.0%} listed by `phyllo review`", k, tl, ev)
        for seed in (1, 2, 3):
            def at_random(_cfg, t, k=k, seed=seed):
                return random.Random(seed).sample([(r["plant"], r["session_start"]) for r in t], k)
            tl, ev = corrected_run(phyllo, obs, rule, os.path.join(scratch, f"random-{k}-{seed}"), truth_by, at_random)
            row(f"{frac:.0%} at random (draw {seed})", k, tl, ev)
    return [header, "| people's counts for | sessions | fused exact % | leaves emerged exact % | date MAE (d) | phyllochron MAE (d) |",
            "|---|---:|---:|---:|---:|---:|"] + lines


# Synthetic plant ids are SYN-<preset>-<n>: the preset plays the genotype.
GENOTYPE_PATTERN = r"^SYN-(?P<genotype>[a-z0-9]+)-\d+$"


def genotype_of(plant):
    m = re.match(GENOTYPE_PATTERN, plant)
    return m.group("genotype") if m else None


def true_genotypes(truth):
    """Per genotype, from the generator's truth: (plants, mean leaves emerged on each plant's last day,
    mean true phyllochron over the plants with one, how many have one)."""
    out = {}
    for plant in sorted({t["plant"] for t in truth}):
        rows = [t for t in truth if t["plant"] == plant]
        first, dates = rows[0]["date"], [d for d in rows[-1]["emergence_dates"].split(";") if d]
        rate = phyllochron([(k + 1, d) for k, d in enumerate(dates) if d > first])
        g = out.setdefault(genotype_of(plant), {"plants": 0, "emerged": [], "phyllochron": []})
        g["plants"] += 1
        g["emerged"].append(int(rows[-1]["leaves_emerged"]))
        if rate is not None:
            g["phyllochron"].append(rate)
    mean = lambda xs: sum(xs) / len(xs) if xs else float("nan")
    return {k: (v["plants"], mean(v["emerged"]), mean(v["phyllochron"]), len(v["phyllochron"])) for k, v in out.items()}


def genotype_table(phyllo, cfg, truth):
    """`phyllo groups` on a store against the generator's truth, one line per genotype."""
    got = json.loads(subprocess.run([phyllo, "groups", "-c", cfg, "--json"], check=True,
                                    capture_output=True, text=True).stdout)
    want = true_genotypes(truth)
    lines, off = [], []
    for g in got["summaries"]:
        name = g["group"][0]
        plants, emerged, rate, n = want.get(name, (0, float("nan"), float("nan"), 0))
        ph = g["phyllochron_days"] or {"mean": float("nan"), "n": 0}
        lines.append(f"| {name} | {g['plants']} | {g['leaves_emerged']['mean']:.2f} / {emerged:.2f} | "
                     f"{ph['mean']:.2f} ({ph['n']}) / {rate:.2f} ({n}) |")
        if not math.isnan(ph["mean"] - rate):
            off.append(abs(ph["mean"] - rate))
    if off:
        lines.append(f"genotype mean phyllochron, |phyllo - truth|: mean {sum(off) / len(off):.2f}, "
                     f"max {max(off):.2f} d/leaf ({len(off)} genotypes)")
    return lines


def true_plant_values(truth):
    """Per plant, from the generator's truth: (true phyllochron or None, leaves emerged on its last day)."""
    out = {}
    for plant in sorted({t["plant"] for t in truth}):
        rows = [t for t in truth if t["plant"] == plant]
        first, dates = rows[0]["date"], [d for d in rows[-1]["emergence_dates"].split(";") if d]
        out[plant] = (phyllochron([(k + 1, d) for k, d in enumerate(dates) if d > first]), int(rows[-1]["leaves_emerged"]))
    return out


def genotype_pairs(phyllo, cfg, truth):
    """`phyllo groups --compare` (Welch, Holm) on a store against the same plants' true difference
    of means, one line per pair, then whether each true difference lies in phyllo's 95 % interval."""
    got = json.loads(subprocess.run([phyllo, "groups", "-c", cfg, "--json", "--compare"], check=True,
                                    capture_output=True, text=True).stdout)
    values = true_plant_values(truth)
    mean = lambda xs: sum(xs) / len(xs) if xs else float("nan")

    def true_mean(genotype, measure):
        col = 0 if measure == "phyllochron_days" else 1
        return mean([v[col] for p, v in values.items() if genotype_of(p) == genotype and v[col] is not None])

    lines, inside = [], {}
    for c in got["pairs"]:
        a, b = c["a"][0], c["b"][0]
        want = true_mean(a, c["measure"]) - true_mean(b, c["measure"])
        lo, hi = c["ci95"]
        hit = lo <= want <= hi
        inside.setdefault(c["measure"], []).append(hit)
        lines.append(f"| {c['measure']} | {a} − {b} | {c['difference']:+.2f} ({lo:+.2f} to {hi:+.2f}) | "
                     f"{c['p_holm']:.3f} | {want:+.2f} | {'yes' if hit else 'no'} |")
    for measure, hits in inside.items():
        lines.append(f"{measure}: the true difference lies in phyllo's 95 % interval for {sum(hits)} of {len(hits)} pairs")
    return lines


def days_from_mid(day, when):
    """Days from the middle of `day` (truth.csv dates an emergence to the day) to timestamp `when`."""
    a = dt.datetime.fromisoformat(day) + dt.timedelta(hours=12)
    return (dt.datetime.fromisoformat(when[:19]) - a).total_seconds() / 86400


def score(truth, timeline, events):
    """Per plant-day count errors and per leaf emergence-date errors."""
    by_day = {(r["plant"], r["session_start"][:10]): r for r in timeline}
    fused, living, emerged, lost_errs = [], [], [], []
    for t in truth:
        r = by_day.get((t["plant"], t["date"]))
        if r is None:
            raise SystemExit(f"no timeline row for {t['plant']} on {t['date']}")
        fused.append(float(r["fused"]) - int(t["living_leaves"]))
        living.append(float(r["living"]) - int(t["living_leaves"]))
        emerged.append(float(r["leaves_emerged"]) - int(t["leaves_emerged"]))
        # Exports from before schema 3 have no leaves_lost column: nothing read as lost.
        lost_errs.append(float(r.get("leaves_lost") or 0) - (int(t["leaves_emerged"]) - int(t["living_leaves"])))
    date_errs, after_death, dateable, spurious, phyllochron_errs = [], [], 0, 0, []
    lost = {(t["plant"], t["date"]): int(t["living_leaves"]) < int(t["leaves_emerged"]) for t in truth}
    for plant in sorted({t["plant"] for t in truth}):
        rows = [t for t in truth if t["plant"] == plant]
        first, dates = rows[0]["date"], [d for d in rows[-1]["emergence_dates"].split(";") if d]
        # Leaves out before the first imaging day cannot be dated from the images.
        dateable += sum(d > first for d in dates)
        for e in events:
            k = int(e["leaf"])
            if e["plant"] != plant:
                continue
            if k <= len(dates):
                date_errs.append(days_from_mid(dates[k - 1], e["emerged_at"]))
                # Counts of living leaves cannot number a new leaf right once an old one has died.
                after_death.append(lost.get((plant, e["emerged_at"][:10]), False))
            else:
                spurious += 1
        true_rate = phyllochron([(k + 1, d) for k, d in enumerate(dates) if d > first])
        last = [r for r in timeline if r["plant"] == plant][-1]
        if true_rate is not None and last["phyllochron_days"]:
            phyllochron_errs.append(float(last["phyllochron_days"]) - true_rate)
    return fused, living, emerged, lost_errs, date_errs, after_death, dateable, len(events), spurious, phyllochron_errs


def phyllochron(leaf_dates):
    """Least-squares days per leaf over (leaf number, date) pairs; None under three leaves."""
    if len(leaf_dates) < 3:
        return None
    xs = [k for k, _ in leaf_dates]
    ys = [dt.date.fromisoformat(d).toordinal() for _, d in leaf_dates]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx


def age_bands(truth, timeline, width=10):
    """Fused-count errors grouped by plant age in bands of `width` days."""
    by_day = {(r["plant"], r["session_start"][:10]): float(r["fused"]) for r in timeline}
    bands = {}
    for t in truth:
        age = float(t["age_days"])
        lo = int(age // width * width)
        bands.setdefault(lo, []).append(by_day[(t["plant"], t["date"])] - int(t["living_leaves"]))
    return [(f"ages {lo}-{lo + width - 1} d", bands[lo]) for lo in sorted(bands)]


def plant_squared_errors(truth, timeline, column="fused", true_column="living_leaves"):
    """Per plant, the sum over its days of the squared error of the timeline's `column`."""
    by_day = {(r["plant"], r["session_start"][:10]): float(r[column]) for r in timeline}
    out = {}
    for t in truth:
        e = by_day[(t["plant"], t["date"])] - int(t[true_column])
        out[t["plant"]] = out.get(t["plant"], 0.0) + e * e
    return out


def sign_test(wins_a, wins_b):
    """Two-sided sign test p over the plants one side wins (ties dropped)."""
    n, k = wins_a + wins_b, min(wins_a, wins_b)
    return min(1.0, 2 * sum(math.comb(n, i) for i in range(k + 1)) / 2**n) if n else 1.0


def count_summary(errs):
    n = len(errs)
    # Truth is whole, so rounding the error half up rounds a fractional fused count half up.
    rounded = [math.floor(e + 0.5) for e in errs]
    exact = sum(e == 0 for e in rounded) / n
    within1 = sum(abs(e) <= 1 for e in rounded) / n
    rmse = math.sqrt(sum(e * e for e in errs) / n)
    return f"{100 * exact:.1f} / {100 * within1:.1f} / {rmse:.3f} / {sum(errs) / n:+.3f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--phyllo", required=True)
    ap.add_argument("--sequence", required=True)
    ap.add_argument("--counts", required=True)
    ap.add_argument("--rules", nargs="+", required=True,
                    help="fusion specs RULE[,KEY=VALUE...] ([timeline] settings), the first compared with the rest")
    ap.add_argument("--keep", metavar="DIR",
                    help="keep each run's store in DIR/<n>/ (n counts the rules, then the truth run), "
                         "e.g. for `phyllo timeline -c DIR/0/phyllo.toml PLANT --plot OUT.png`")
    ap.add_argument("--review", action="store_true",
                    help="also measure what a person's counts on the days `phyllo review` lists are worth")
    a = ap.parse_args()
    truth = read_csv(os.path.join(a.sequence, "truth.csv"))
    obs = observations(a.counts)
    plants, days = len({t["plant"] for t in truth}), len({t["date"] for t in truth})
    ages = sorted(float(t["age_days"]) for t in truth)
    models = sorted({json.loads(line)["model"] for line in open(a.counts)})
    frames = [os.path.basename(json.loads(line)["file"]) for line in open(a.counts)]
    print(f"sequence {a.sequence}: {plants} plants x {days} days, ages {ages[0]:g}-{ages[-1]:g} d, {len(obs)} frames "
          f"(data {fingerprint(a.sequence, frames)}); model {', '.join(models)}")
    print("plant-days: exact / within ±1 / RMSE / bias against the true living leaves (rounded; the top view fused only by `max`)")
    print("events: emergence events exported, truth leaves that emerged after the first imaging day, events matched")
    print("to a truth leaf by number (the rest name a leaf the plant never had); dates in days from the true day's middle;")
    print("phyllochron: the timeline's days per leaf against the truth's (least squares over the dateable leaves), per plant")
    print("date MAE split: events before the plant lost its first leaf / after (n)")
    print("| counts | fusion | fused count | living leaves (smoothed) | leaves emerged | leaves lost | events | dateable | matched | extra | date MAE (d) | bias (d) | within 1 d | date MAE before / after a leaf died (n) | phyllochron MAE / bias (d, plants) |")
    print("|---|---|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|")
    runs = [("model", r, obs) for r in a.rules] + [("truth", a.rules[0], truth_observations(truth))]
    by_age, per_plant, per_plant_emerged = None, [], []
    with tempfile.TemporaryDirectory() as scratch:
        # With --keep the stores stay, so any plant's timeline can be looked at after.
        tmp = a.keep or scratch
        if a.keep:
            os.makedirs(a.keep, exist_ok=True)
            for i in range(len(runs)):
                shutil.rmtree(os.path.join(a.keep, str(i)), ignore_errors=True)
        for i, (source, rule, o) in enumerate(runs):
            timeline, events = run_timeline(a.phyllo, o, rule, os.path.join(tmp, str(i)))
            if i == 0:
                by_age = age_bands(truth, timeline)
                genotypes = genotype_table(a.phyllo, os.path.join(tmp, "0", "phyllo.toml"), truth)
                pairs = genotype_pairs(a.phyllo, os.path.join(tmp, "0", "phyllo.toml"), truth)
                first_lost = lost_by_last_day(timeline, lambda r: float(r.get("leaves_lost") or 0))
            if source == "model":
                per_plant.append(plant_squared_errors(truth, timeline))
                per_plant_emerged.append(plant_squared_errors(truth, timeline, "leaves_emerged", "leaves_emerged"))
            fused, living, emerged, lost, errs, after, dateable, n_events, spurious, ph = score(truth, timeline, events)
            n = max(len(errs), 1)
            mae = sum(abs(e) for e in errs) / n
            bias = sum(errs) / n
            within = 100 * sum(abs(e) <= 1 for e in errs) / n
            m = max(len(ph), 1)
            ph_text = f"{sum(abs(e) for e in ph) / m:.2f} / {sum(ph) / m:+.2f} ({len(ph)})"
            split = [[abs(e) for e, a in zip(errs, after) if a == side] for side in (False, True)]
            split_text = " / ".join(f"{sum(x) / max(len(x), 1):.2f} ({len(x)})" for x in split)
            print(f"| {source} | {rule} | {count_summary(fused)} | {count_summary(living)} | {count_summary(emerged)} | "
                  f"{count_summary(lost)} | {n_events} | {dateable} | {n_events - spurious} | {spurious} | {mae:.2f} | {bias:+.2f} | {within:.0f} % | {split_text} | {ph_text} |")
    for what, errors in (("fused count", per_plant), ("leaves emerged", per_plant_emerged)):
        print(f"{what} closer to the truth per plant (squared error over its days):")
        ea = errors[0]
        for rb, eb in zip(a.rules[1:], errors[1:]):
            wa = sum(ea[p] < eb[p] for p in ea)
            wb = sum(eb[p] < ea[p] for p in ea)
            print(f"  {a.rules[0]} on {wa} plants, {rb} on {wb}; sign test p = {sign_test(wa, wb):.3f}")
    print(f"per genotype (`phyllo groups`), {a.rules[0]} against the generator's truth; leaves emerged on each plant's")
    print("last day, phyllochron the mean of the plants' days per leaf (plants with one):")
    print("| genotype | plants | leaves emerged: phyllo / truth | phyllochron (d/leaf): phyllo / truth |")
    print("|---|---:|---|---|")
    print("\n".join(genotypes))
    print(f"genotype pairs (`phyllo groups --compare`: Welch's t-test over the plants, Holm-adjusted), {a.rules[0]},")
    print("against the difference of the same plants' true means:")
    print("| measure | pair | phyllo: difference (95 % CI) | p (Holm) | truth: difference | truth in the CI |")
    print("|---|---|---|---:|---:|---|")
    print("\n".join(pairs))
    if a.review:
        with tempfile.TemporaryDirectory() as scratch:
            print("\n".join(review_table(a.phyllo, obs, a.rules[0], truth, scratch)))
    print(f"fused count by plant age, {a.rules[0]}:")
    for band, errs in by_age:
        print(f"  {band}: {count_summary(errs)} ({len(errs)} plant-days)")
    # One view alone, as a person counts (SV_108), against the same truth.
    truth_by = {(t["plant"], t["date"]): int(t["living_leaves"]) for t in truth}
    true_lost = lost_by_last_day(truth, lambda t: int(t["leaves_emerged"]) - int(t["living_leaves"]))
    print(f"leaves lost by the last day, {a.rules[0]}: {first_lost[0]:g} on {first_lost[1]} plants; "
          f"truth: {true_lost[0]} on {true_lost[1]} plants")
    times = ", ".join(f"{k} {m:.0f} ms ({n} frames)" for k, (m, n) in ms_per_frame(a.counts).items())
    print(f"model time per frame when counted: {times}")
    for view in ("SV_108", "TV_90"):
        errs = [c - truth_by[(p, ts[:10])] for p, ts, v, c in obs if v == view]
        if errs:
            print(f"single view {view}, unfused, against the true living leaves: {count_summary(errs)} ({len(errs)} frames)")


if __name__ == "__main__":
    main()
