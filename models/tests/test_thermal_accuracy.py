"""scripts/thermal_accuracy.py: phyllochrons in days and degree-days against a climate sequence's truth."""

import importlib.util
import sys
from pathlib import Path

import pytest

_SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"
sys.path.insert(0, str(_SCRIPTS))
_SPEC = importlib.util.spec_from_file_location("thermal_accuracy", _SCRIPTS / "thermal_accuracy.py")
th = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(th)


def climate_row(plant, date, at, cd):
    return {"plant": plant, "date": date, "time": "08:00:00", "emergence_at": ";".join(at),
            "emergence_cd": ";".join(cd)}


def test_true_phyllochrons_use_only_leaves_after_the_first_session():
    # Leaf 1 came out before imaging began; leaves 2-4 every 2.5 days, 50 °Cd apart.
    at = ["2018-04-01T10:00:00", "2018-04-10T20:00:00", "2018-04-13T08:00:00", "2018-04-15T20:00:00"]
    cd = ["10.0", "200.0", "250.0", "300.0"]
    truth = [climate_row("P", "2018-04-10", at[:1], cd[:1]), climate_row("P", "2018-04-16", at, cd)]
    days, degree_days = th.true_phyllochrons(truth)["P"]
    assert days == pytest.approx(2.5)
    assert degree_days == pytest.approx(50.0)


def test_a_plant_with_under_three_dateable_leaves_has_no_phyllochron():
    truth = [climate_row("P", "2018-04-10", ["2018-04-11T00:00:00", "2018-04-13T00:00:00"], ["1", "2"])]
    assert th.true_phyllochrons(truth)["P"] == (None, None)


def test_a_sequence_without_a_climate_is_refused():
    with pytest.raises(SystemExit, match="--climate"):
        th.true_phyllochrons([{"plant": "P", "date": "2018-04-10", "time": "08:00:00", "emergence_dates": ""}])


def test_compare_pairs_only_plants_with_both_values():
    truth = {"A": (3.0, 45.0), "B": (None, None), "C": (2.0, 40.0)}
    phyllo = {"A": (3.5, None), "B": (1.0, 1.0), "C": (2.5, 42.0)}
    days, degree_days = th.compare(truth, phyllo)
    assert days == [(3.5, 3.0), (2.5, 2.0)]
    assert degree_days == [(42.0, 40.0)]
    assert th.summary(days) == "3.00 / 2.50 | 0.50 (20.0 %) | 2"
    assert th.summary([]) == "- | - | 0"
