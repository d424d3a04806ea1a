"""Measured intervals: fitted at 68% on one half of a set, their coverage checked on the other."""
import numpy as np

from hairdigi.inference.uncertainty import NAMES, band, coverage_of, fit_intervals, intervals
from hairdigi.render.domain.params import HairParams


def _rows(seed, n=600):
    rng = np.random.default_rng(seed)
    rows = []
    for _ in range(n):
        truth = {name: float(rng.uniform(0, 255 if name.startswith("dye_") and len(name) == 5 else 1))
                 for name in NAMES}
        dark = truth["melanin_concentration"] > 0.75
        est = {name: v + float(rng.normal(0, (120 if dark else 20) if len(name) == 5 else 0.05))
               for name, v in truth.items()}
        rows.append({"estimate": est, "truth": truth, "mean_colour_de2000": float(abs(rng.normal(0, 0.5)))})
    return rows


def test_coverage_is_measured_near_the_nominal_68_percent():
    table = fit_intervals(_rows(0))
    coverage = coverage_of(table, _rows(1))
    assert all(0.63 <= c <= 0.73 for c in coverage.values()), coverage
    # the dye is far less certain in dark hair, and the table says so
    assert table["half_width"]["dye_r"][2] > 2.5 * table["half_width"]["dye_r"][0]
    assert 0.3 < table["mean_colour_de2000"]["p68"] < 0.7


def test_intervals_say_undetermined_instead_of_a_small_plus_minus():
    table = fit_intervals(_rows(0))
    dark = intervals(HairParams((120, 100, 90), 0.4, 0.9, 0.8), table)
    pale = intervals(HairParams((120, 100, 90), 0.4, 0.1, 0.8), table)
    assert band(0.9) == 2 and band(0.1) == 0
    assert dark.parameters["dye_r"].determined is False
    assert pale.parameters["dye_r"].determined is True
    p = pale.parameters["dye_r"]
    assert p.low <= p.value <= p.high and 0 <= p.low and p.high <= 255
    assert intervals(HairParams(), None).note.startswith("no interval table")
