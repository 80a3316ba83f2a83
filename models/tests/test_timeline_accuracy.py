"""scripts/timeline_accuracy.py: the timeline's scoring against a sequence's truth."""

import importlib.util
import json
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "scripts" / "timeline_accuracy.py"
_SPEC = importlib.util.spec_from_file_location("timeline_accuracy", _PATH)
ta = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(ta)


def truth_row(plant, date, living, emerged, dates):
    return {"plant": plant, "date": date, "time": "08:00:00", "age_days": "20",
            "living_leaves": str(living), "leaves_emerged": str(emerged), "emergence_dates": ";".join(dates)}


def test_phyllochron_is_the_least_squares_days_per_leaf():
    assert ta.phyllochron([(3, "2018-04-10"), (4, "2018-04-13"), (5, "2018-04-16")]) == pytest.approx(3.0)
    assert ta.phyllochron([(1, "2018-04-10"), (2, "2018-04-12")]) is None


def test_count_summary_rounds_a_fractional_count_half_up():
    # +0.5 rounds to +1 (not exact, within ±1); -0.5 rounds to 0 (exact).
    assert ta.count_summary([0.5, -0.5]) == "50.0 / 100.0 / 0.500 / +0.000"


def test_score_matches_events_by_leaf_number_and_counts_extra_ones():
    dates = ["2018-04-01", "2018-04-11", "2018-04-13"]
    truth = [truth_row("P", "2018-04-10", 1, 1, dates), truth_row("P", "2018-04-11", 2, 2, dates),
             truth_row("P", "2018-04-12", 2, 2, dates), truth_row("P", "2018-04-13", 3, 3, dates)]
    timeline = [{"plant": "P", "session_start": f"2018-04-{d}T08:00:00.000", "fused": str(f), "living": str(f),
                 "leaves_emerged": str(f), "phyllochron_days": ph}
                for d, f, ph in [(10, 1, ""), (11, 1, ""), (12, 2, ""), (13, 4, "1.5")]]
    events = [{"plant": "P", "leaf": "2", "emerged_at": "2018-04-12T00:00:00.000"},
              {"plant": "P", "leaf": "4", "emerged_at": "2018-04-13T00:00:00.000"}]
    fused, living, emerged, lost, date_errs, after, dateable, n_events, spurious, ph = ta.score(truth, timeline, events)
    assert fused == [0.0, -1.0, 0.0, 1.0]
    # An export without leaves_lost reads no leaf as lost, as the truth has none here.
    assert lost == [0.0] * 4
    # Leaf 2 came out on the 11th (middle: noon), seen at midnight after it: half a day late.
    assert date_errs == [pytest.approx(0.5)]
    assert after == [False]
    assert (dateable, n_events, spurious) == (2, 2, 1)
    # Two dateable leaves are too few for a true phyllochron.
    assert ph == []


def test_observations_read_the_facility_names_of_a_sequence(tmp_path):
    counts = tmp_path / "counts.jsonl"
    counts.write_text("\n".join(json.dumps({"file": f"/x/{n}", "leaf_count": c}) for n, c in [
        ("SYN-btx623-001_2018-04-10_08-02-37_Vis_SV_0.png", 7), ("SYN-maize-002_2018-04-11_09-00-05_Vis_TV_90.png", 3)]))
    assert ta.observations(counts) == [("SYN-btx623-001", "2018-04-10T08:02:37", "SV_0", 7),
                                       ("SYN-maize-002", "2018-04-11T09:00:05", "TV_90", 3)]


def test_score_marks_events_dated_after_the_plant_lost_a_leaf():
    dates = ["2018-04-01", "2018-04-02", "2018-04-12"]
    truth = [truth_row("P", "2018-04-11", 2, 2, dates), truth_row("P", "2018-04-12", 2, 3, dates)]
    timeline = [{"plant": "P", "session_start": f"2018-04-{d}T08:00:00.000", "fused": "2", "living": "2",
                 "leaves_emerged": str(e), "phyllochron_days": "", "leaves_lost": str(e - 2)} for d, e in [(11, 2), (12, 3)]]
    events = [{"plant": "P", "leaf": "3", "emerged_at": "2018-04-12T00:00:00.000"}]
    _, _, emerged, lost, date_errs, after, *_ = ta.score(truth, timeline, events)
    assert emerged == [0.0, 0.0]
    assert lost == [0.0, 0.0]
    assert date_errs == [pytest.approx(-0.5)]
    assert after == [True]


def test_sign_test_and_plant_errors():
    assert ta.sign_test(26, 9) == pytest.approx(0.0060, abs=5e-4)
    assert ta.sign_test(0, 0) == 1.0
    truth = [truth_row("P", f"2018-04-1{d}", 3, 3, []) for d in (0, 1)]
    timeline = [{"plant": "P", "session_start": f"2018-04-1{d}T08:00:00.000", "fused": f} for d, f in ((0, "4"), (1, "1"))]
    assert ta.plant_squared_errors(truth, timeline) == {"P": 5.0}
    for row, e in zip(timeline, ("3", "5")):
        row["leaves_emerged"] = e
    assert ta.plant_squared_errors(truth, timeline, "leaves_emerged", "leaves_emerged") == {"P": 4.0}


def test_timeline_section_takes_settings_after_the_rule():
    assert ta.timeline_section("median-side") == 'fusion = "median-side"\n'
    assert ta.timeline_section("second-max-side,death_penalty=0") == 'fusion = "second-max-side"\ndeath_penalty = 0\n'
    with pytest.raises(SystemExit):
        ta.timeline_section("second-max-side,death_penalty")


def test_lost_by_last_day_and_time_per_view(tmp_path):
    rows = [{"plant": "P", "x": 1}, {"plant": "P", "x": 2}, {"plant": "Q", "x": 0}]
    assert ta.lost_by_last_day(rows, lambda r: r["x"]) == (2, 1)
    counts = tmp_path / "counts.jsonl"
    counts.write_text("\n".join(json.dumps({"file": f"/x/{n}", "ms": ms}) for n, ms in [
        ("P_2018-04-10_08-02-37_Vis_SV_0.png", {"decode": 2.0, "inference": 8.0}),
        ("P_2018-04-10_08-02-37_Vis_SV_36.png", {"total": 20.0}),
        ("P_2018-04-10_08-02-37_Vis_TV_90.png", {"total": 5.0})]))
    assert ta.ms_per_frame(counts) == {"side": (15.0, 2), "top": (5.0, 1)}


def test_true_genotypes_group_plants_by_preset():
    a = ["2018-04-01", "2018-04-11", "2018-04-13", "2018-04-15"]
    truth = [truth_row("SYN-btx623-000", "2018-04-10", 1, 1, a), truth_row("SYN-btx623-000", "2018-04-16", 4, 4, a),
             truth_row("SYN-btx623-001", "2018-04-10", 2, 2, a[:2]), truth_row("SYN-btx623-001", "2018-04-16", 2, 2, a[:2]),
             truth_row("SYN-maize-002", "2018-04-10", 3, 3, a[:1]), truth_row("SYN-maize-002", "2018-04-16", 3, 3, a[:1])]
    got = ta.true_genotypes(truth)
    # Plant 000 dates leaves 2-4 two days apart; the others have too few dateable leaves.
    assert got["btx623"] == (2, 3.0, pytest.approx(2.0), 1)
    assert got["maize"][:2] == (1, 3.0)
    assert ta.genotype_of("SYN-maize-002") == "maize" and ta.genotype_of("402-348-N276-WW-1") is None


def test_review_table_counts_the_listed_days_against_random_ones(tmp_path):
    phyllo = Path(__file__).resolve().parents[2] / "target" / "debug" / "phyllo"
    if not phyllo.exists():
        pytest.skip(f"{phyllo} not built (scripts/test.sh builds it before these tests)")
    # Two plants, 10 days, one leaf every 3 days; five side views, one of which
    # is off by one on some days, and plant B's day 4 reads two too many.
    truth, obs = [], []
    for plant in ("A", "B"):
        dates = [f"2018-04-{d:02d}" for d in (1, 2, 3, 6, 9)]
        for d in range(10, 20):
            living = 3 + (d - 10) // 3
            date = f"2018-04-{d}"
            truth.append(truth_row(plant, date, living, living, [x for x in dates + ["2018-04-12", "2018-04-15", "2018-04-18"]
                                                                  if x <= date][:living]))
            for v in range(5):
                c = living + (1 if (v == 4 and d % 2) else 0) + (2 if (plant == "B" and d == 14 and v < 3) else 0)
                obs.append((plant, f"{date}T08:00:0{v}", f"SV_{v * 72}", c))
    lines = ta.review_table(str(phyllo), obs, "second-max-side", truth, str(tmp_path))
    assert lines[0].startswith("`phyllo review`, second-max-side: ") and "of 20 sessions in doubt" in lines[0]
    rows = [line.split(" | ") for line in lines[3:]]
    assert [r[0].lstrip("| ") for r in rows] == ["none"] + [
        label for frac in ("5%", "10%")
        for label in [f"{frac} listed by `phyllo review`"] + [f"{frac} at random (draw {i})" for i in (1, 2, 3)]]
    none, listed = rows[0], rows[1]
    assert none[1] == "0" and listed[1] == "1"
    # B's day 4 is listed first; a person's true count there fixes it.
    assert float(listed[2]) > float(none[2])


def test_genotype_pairs_set_phyllos_difference_beside_the_truth(tmp_path):
    phyllo = Path(__file__).resolve().parents[2] / "target" / "debug" / "phyllo"
    if not phyllo.exists():
        pytest.skip(f"{phyllo} not built (scripts/test.sh builds it before these tests)")
    # Genotype "fast" grows a leaf every 2 days, "slow" every 4 (one plant a day off each).
    truth, obs = [], []
    for plant, every in (("SYN-fast-000", 2), ("SYN-fast-001", 2), ("SYN-fast-002", 3),
                         ("SYN-slow-003", 4), ("SYN-slow-004", 4), ("SYN-slow-005", 5)):
        for d in range(21):
            date = f"2018-04-{d + 1:02d}"
            living = 3 + d // every
            dates = [f"2018-03-2{k}" for k in range(3)] + [f"2018-04-{1 + k * every:02d}" for k in range(1, living - 2)]
            truth.append(truth_row(plant, date, living, living, dates))
            obs += [(plant, f"{date}T08:00:0{v}", f"SV_{v * 72}", living) for v in range(3)]
    work = tmp_path / "store"
    ta.run_timeline(str(phyllo), obs, "second-max-side", str(work))
    lines = ta.genotype_pairs(str(phyllo), str(work / "phyllo.toml"), truth)
    ph = next(line for line in lines if line.startswith("| phyllochron_days | fast − slow |"))
    cells = [c.strip() for c in ph.strip("|").split("|")]
    assert float(cells[2].split()[0]) == pytest.approx(-2.0, abs=0.4)
    assert float(cells[4]) == pytest.approx(-2.0, abs=0.4)
    assert cells[5] == "yes"
    assert lines[-2].startswith("phyllochron_days: the true difference lies in phyllo's 95 % interval for 1 of 1")
