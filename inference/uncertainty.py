"""Honest uncertainty: parameter intervals whose coverage is measured on held-out swatches.

The six Table 1 parameters reach the image only through the 3-vector ``sigma_a``, so some of them
cannot be read from any photograph (the dye of black hair, the split between dye and melanin of a
brown). The spread of the encoder over flips of the image says nothing about that. Instead
``hairdigi evaluate`` measures, per band of estimated melanin, the absolute error that 68% of
held-out estimates stay within (``fit_intervals``), checks that coverage on the other half of the
set, and ships the table as ``resources/models/uncertainty.json``. An interval that spans most of
a parameter's range is reported as undetermined rather than as a number with a small ±.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from hairdigi.render.domain.estimate_parts import ParameterInterval, Uncertainty
from hairdigi.render.domain.params import VECTOR_FIELDS, HairParams

COVERAGE = 0.68
MELANIN_BANDS = (0.0, 0.4, 0.75, 1.0001)   # pale, mid, dark: the dye is harder to read the darker the hair
UNDETERMINED_SHARE = 0.25                  # half-width over a quarter of the range: "undetermined"
NAMES = [name for name, _, _ in VECTOR_FIELDS]
SPANS = {name: hi - lo for name, lo, hi in VECTOR_FIELDS}


def band(melanin: float) -> int:
    """Index of the melanin band of an estimate."""
    return int(np.clip(np.searchsorted(MELANIN_BANDS, melanin, side="right") - 1, 0, len(MELANIN_BANDS) - 2))


def fit_intervals(rows: list[dict], coverage: float = COVERAGE) -> dict:
    """Half-widths per parameter and band from rows of ``{"estimate": {name: v}, "truth": {name: v}}``,
    plus the mean-colour ΔE2000 quantiles when rows carry ``"mean_colour_de2000"``."""
    table: dict = {"coverage": coverage, "melanin_bands": list(MELANIN_BANDS), "half_width": {}, "counts": []}
    bands = np.array([band(r["estimate"]["melanin_concentration"]) for r in rows])
    table["counts"] = [int((bands == b).sum()) for b in range(len(MELANIN_BANDS) - 1)]
    for name in NAMES:
        errors = np.array([abs(r["estimate"][name] - r["truth"][name]) for r in rows])
        widths = []
        for b in range(len(MELANIN_BANDS) - 1):
            e = errors[bands == b]
            widths.append(float(np.quantile(e, coverage)) if len(e) >= 5 else float(np.quantile(errors, coverage)))
        table["half_width"][name] = widths
    de = [r["mean_colour_de2000"] for r in rows if "mean_colour_de2000" in r]
    if de:
        table["mean_colour_de2000"] = {"p68": float(np.quantile(de, coverage)), "p95": float(np.quantile(de, 0.95))}
    return table


def coverage_of(table: dict, rows: list[dict]) -> dict[str, float]:
    """Share of rows whose truth lies inside the interval, per parameter (the figure to check: ~0.68)."""
    out = {}
    for name in NAMES:
        inside = [abs(r["estimate"][name] - r["truth"][name])
                  <= table["half_width"][name][band(r["estimate"]["melanin_concentration"])] for r in rows]
        out[name] = float(np.mean(inside))
    return out


def load_table(path: str | Path) -> dict | None:
    """The shipped interval table, or None when there is none yet."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def widen_colour(uncertainty: Uncertainty, p68: float, p95: float, source: str) -> Uncertainty:
    """``uncertainty`` with its colour interval widened to a measured (``p68``, ``p95``) ΔE2000, the larger
    per level (a level it does not state stays unstated); where that widens the 68%, ``source`` becomes
    the interval's source."""
    u68, u95 = uncertainty.mean_colour_de2000_p68, uncertainty.mean_colour_de2000_p95
    return replace(uncertainty,
                   mean_colour_source=source if u68 is not None and u68 < p68 else uncertainty.mean_colour_source,
                   mean_colour_de2000_p68=None if u68 is None else round(max(u68, p68), 3),
                   mean_colour_de2000_p95=None if u95 is None else round(max(u95, p95), 3))


def intervals(params: HairParams, table: dict | None, colour_table: dict | None = None) -> Uncertainty:
    """Each parameter with its measured 68% interval, or flagged undetermined; and the colour's ΔE.

    ``colour_table`` (``chain_uncertainty.json``, from ``hairdigi evaluate --rig``) gives the colour's
    ΔE2000 for a capture through the whole rig chain; without it the colour's figure is the crop
    renders' (``table``)."""
    flat = {"dye_r": params.dye_rgb[0], "dye_g": params.dye_rgb[1], "dye_b": params.dye_rgb[2],
            "dye_concentration": params.dye_concentration,
            "melanin_concentration": params.melanin_concentration, "melanin_ratio": params.melanin_ratio}
    if table is None:
        return Uncertainty(note="no interval table shipped with this model (resources/models/uncertainty.json)",
                           values=params)
    b = band(params.melanin_concentration)
    parameters = {}
    for (name, lo, hi) in VECTOR_FIELDS:
        w = table["half_width"][name][b]
        v = flat[name]
        parameters[name] = ParameterInterval(value=round(v, 4), low=round(max(lo, v - w), 4),
                                             high=round(min(hi, v + w), 4), half_width=round(w, 4),
                                             determined=bool(w <= UNDETERMINED_SHARE * (hi - lo)))
    out = Uncertainty(coverage=table["coverage"], method="held-out absolute error quantile per melanin band",
                      parameters=parameters)
    colour = colour_table if colour_table and "mean_colour_de2000" in colour_table else table
    if "mean_colour_de2000" in colour:
        out = replace(out, mean_colour_de2000_p68=round(colour["mean_colour_de2000"]["p68"], 3),
                      mean_colour_de2000_p95=round(colour["mean_colour_de2000"]["p95"], 3),
                      mean_colour_source=colour.get("source", "held-out clean crop renders (hairdigi evaluate)"))
    return out
