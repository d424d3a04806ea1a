"""Hair-dye development: characterise a dye from (natural base, dyed) swatch pairs, predict it on any hair.

**The model.** A fibre's colour reaches the image through its absorption ``sigma_a`` (per fibre
radius; Chiang et al. 2016's ``hair`` BSDF, as Mitsuba 3 renders it). In a natural base all of it
is melanin (d'Eon et al. 2011; eumelanin and pheomelanin coefficients as in pbrt). A dye acts in two
ways (the oxidative-dye chemistry every colourist knows: developer lightens, dye molecules deposit):

- **deposit**: an added absorption, a ``sigma_a`` 3-vector ``D >= 0``. Kips et al. 2022's Table 1
  writes it as a dye colour and concentration (``render.domain.absorption.dye_sigma_a``); any ``D`` Table 1
  can make is one such pair.
- **lift**: the developer removes a share ``L`` in [0, 1) of the melanin.

``sigma_dyed = (1 - L) * sigma_melanin(base) + D``. **Identifiability:** one pair gives 3 equations
for 4 unknowns, so with one base the lift is assumed (0, or the least lift that explains a dyed hair
lighter than its base) and the record says so. Two distinct bases or more give a weighted linear
least-squares fit of ``L`` and ``D`` (bounded: ``0 <= L <= LIFT_MAX``, ``D >= 0``), with residuals.

**Weights and intervals.** Each record's 68% interval of its mean colour (ΔE2000, measured on
held-out swatches: ``inference.uncertainty``) becomes a ``sigma_a`` interval per channel through the
rig's response curve (``inference.refine.response_curve``: the swatch's mean linear colour of each
channel against that channel's ``sigma_a``). A dark channel, where the curve is flat, gets a wide
interval and little weight. Intervals of ``L`` and ``D`` are the 16th–84th percentiles of the fit
over Monte Carlo draws of every record within its interval.

**Colour without rendering.** ``dose`` and the predictions' colours read the swatch's mean linear
RGB off the same response curve; the shade card and the evaluation render.
"""
from __future__ import annotations

import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear, minimize_scalar

from hairdigi.inference.refine import ResponseCurve, params_for_sigma, response_curve
from hairdigi.render.domain.absorption import MELANIN_REMAP, albedo_from_sigma_a, melanin_quantity
from hairdigi.render.domain.dye_record import DyePairRecord, DyeRecord
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.estimate_parts import Provenance, Region, Uncertainty
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import (CaptureRecord, EstimateRecord, EstimateWarning, RefinementRecord,
                                            WarningKind, read_record, record_sha256)
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.render.domain.session_folder import capture_record_beside, is_result_record
from hairdigi.render.domain.text_enum import TextEnum
from hairdigi.render.domain.version import version
from hairdigi.render.metrics import delta_e2000, linear_rgb_to_lab
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear

#: The largest share of melanin a developer may remove (a high-lift bleach). A dyed hair lighter than
#: even this lift leaves is refused: no dye explains it.
LIFT_MAX = 0.95
#: Deposit scales ``dose`` searches (1 = the characterised dye).
DOSE_MAX = 3.0
#: A colour further than this (ΔE2000) from the target is "out of reach" (as refinement's reachability).
REACHABLE_DE = 1.0
#: The 68% mean-colour interval assumed for a record that carries none (a parameter file): the
#: shipped estimate's held-out figure (resources/models/uncertainty.json, p68 0.34).
DEFAULT_COLOUR_DE68 = 0.34
#: Pairs whose fit leaves a larger mean-colour residual (ΔE2000) are reported as disagreeing.
DISAGREE_DE = 2.0
#: Two bases whose ``sigma_a`` differ by less than this (relative, largest channel) are one base.
SAME_BASE_REL = 0.05
CHANNELS = ("red", "green", "blue")
_MC_DRAWS = 200


class DyeError(HairdigiError, ValueError):
    """A dye cannot be characterised, applied or dosed as asked; the message says why and what to do."""


# --- the swatch's colour of a sigma_a (the rig's response curve) ------------------------------------
def rig_curve() -> ResponseCurve:
    """The response curve at the rig's pose (rendered once, then read from the disk cache)."""
    return response_curve(RIG_SWATCH_POSE)


def colour_of(sigma: np.ndarray, curve: ResponseCurve) -> np.ndarray:
    """The swatch's mean linear RGB for ``sigma_a`` (any shape ending in 3), read off the curve."""
    return curve(np.clip(np.asarray(sigma, float), 0.0, None))


def sigma_interval(sigma: np.ndarray, de68: float, curve: ResponseCurve) -> tuple[np.ndarray, np.ndarray]:
    """Per channel, the ``sigma_a`` range whose colour stays within ``de68`` (ΔE2000) of ``sigma``'s."""
    sigma = np.asarray(sigma, float)
    if de68 <= 0:
        return sigma.copy(), sigma.copy()
    c = colour_of(sigma, curve)
    # rows: each channel made lighter (x e^t), then each made darker (x e^-t); bisect t for all six at once
    sign = np.repeat([1.0, -1.0], 3)
    channel = np.tile(np.arange(3), 2)
    reference = np.tile(c, (6, 1))
    lo, hi = np.zeros(6), np.full(6, 6.0)
    for _ in range(30):
        t = 0.5 * (lo + hi)
        moved = reference.copy()
        moved[np.arange(6), channel] *= np.exp(sign * t)
        inside = delta_e2000(np.clip(moved, 1e-9, None), reference) < de68
        lo, hi = np.where(inside, t, lo), np.where(inside, hi, t)
    lighter, _ = curve.inverse(c * np.exp(lo[:3]))
    darker, _ = curve.inverse(c * np.exp(-lo[3:]))
    return np.minimum(lighter, sigma), np.maximum(darker, sigma)


# --- a hair record, as the dye reads it --------------------------------------------------------------
class IntervalSource(TextEnum):
    """Where a hair sample's colour interval comes from: its record's own, or ``DEFAULT_COLOUR_DE68`` assumed."""

    RECORD = "record"
    ASSUMED = "assumed"


@dataclass(frozen=True)
class HairSample:
    """One estimate (or parameter) record read for a dye: its ``sigma_a``, calibration and interval."""

    record: EstimateRecord
    sigma_a: np.ndarray
    path: str = ""
    sha256: str = ""
    calibration: str | None = None
    colour_de68: float = DEFAULT_COLOUR_DE68
    interval_source: IntervalSource = IntervalSource.ASSUMED
    _intervals: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def label(self) -> str:
        return self.path or "the record"


def sigma_of(record: EstimateRecord) -> np.ndarray:
    """The ``sigma_a`` that reaches the image: the refinement's, else Table 1's mapping of ``hair``."""
    if record.sigma_a is None:
        raise DyeError("the record holds no estimate")
    return np.asarray(record.sigma_a, float)


def sample_of(record: EstimateRecord, path: str = "", sha256: str = "", calibration: str | None = None) -> HairSample:
    """A record in memory as a :class:`HairSample` (its calibration from its provenance unless given)."""
    if record.hair is None:
        why = "; ".join(record.blocked) or "no estimate was made"
        raise DyeError(f"{path or 'the record'}: the capture has no estimate ({why}); choose an estimated capture")
    if calibration is None:
        calibration = record.provenance.calibration_id
    de68 = record.uncertainty.mean_colour_de2000_p68
    source = IntervalSource.RECORD if isinstance(de68, (int, float)) and de68 > 0 else IntervalSource.ASSUMED
    return HairSample(record, sigma_of(record), path, sha256, calibration,
                      float(de68) if source is IntervalSource.RECORD else DEFAULT_COLOUR_DE68, source)


def load_sample(path: str | Path) -> HairSample:
    """Read an estimate record, a session capture's ``<id>.result.json`` or a Table 1 parameter file."""
    path = Path(path)
    try:
        record = read_record(path, EstimateRecord)
    except RecordError as exc:
        raise DyeError(str(exc)) from None
    calibration = record.provenance.calibration_id
    if calibration is None and is_result_record(path):     # a session capture: its capture record's
        meta = capture_record_beside(path)
        if meta.exists():
            try:
                calibration = read_record(meta, CaptureRecord).calibration_id
            except RecordError:
                calibration = None
    return sample_of(record, str(path), record_sha256(path), calibration)


# --- checks ------------------------------------------------------------------------------------------
def interval_of(sample: HairSample, curve: ResponseCurve) -> tuple[np.ndarray, np.ndarray]:
    """The sample's 68% ``sigma_a`` interval (computed once per sample and curve)."""
    cache = sample._intervals
    key = id(curve)
    if key not in cache:
        cache[key] = sigma_interval(sample.sigma_a, sample.colour_de68, curve)
    return cache[key]


def check_explainable(base: HairSample, dyed: HairSample, curve: ResponseCurve) -> None:
    """Refuse a pair whose dyed hair is lighter than its base beyond what any lift and deposit explain."""
    m, s = base.sigma_a, dyed.sigma_a
    m_lo, _ = interval_of(base, curve)
    _, s_hi = interval_of(dyed, curve)
    # the least lift a channel needs, giving the pair every benefit of its intervals
    needed = np.where(m_lo > 1e-6, 1.0 - s_hi / np.maximum(m_lo, 1e-12), 0.0)
    worst = int(np.argmax(needed))
    if needed[worst] > LIFT_MAX:
        raise DyeError(
            f"{dyed.label} cannot be {base.label} dyed: it is lighter in {CHANNELS[worst]} (sigma_a "
            f"{s[worst]:.3f} against {m[worst]:.3f}) than even a {LIFT_MAX:.0%} lift of the melanin leaves; "
            f"check that the pair is not swapped and the base is this swatch's")


def check_calibrations(pairs: list[tuple[HairSample, HairSample]], allow_mixed: bool) -> list[str]:
    """Refuse records corrected with different calibration profiles, unless ``allow_mixed`` (then warn)."""
    ids = sorted({str(s.calibration) for pair in pairs for s in pair})
    if len(ids) <= 1:
        return []
    text = ", ".join("none" if i == "None" else i for i in ids)
    if not allow_mixed:
        raise DyeError(f"the records were colour-corrected with different calibrations ({text}); their colours "
                       f"may not compare: recapture under one calibration, or pass --allow-mixed-calibrations")
    return [f"calibration: the records were corrected with different calibrations ({text}); allowed by "
            f"--allow-mixed-calibrations, so colour differences between them are part of the dye"]


def check_distinct_records(base: HairSample, dyed: HairSample) -> None:
    """Refuse a pair whose base and dyed records are one file (same path or checksum)."""
    same_path = bool(base.path) and base.path == dyed.path
    if same_path or (base.sha256 and base.sha256 == dyed.sha256):
        raise DyeError(f"{dyed.label} is the same record as its base {base.label}: a dye is measured from the "
                       f"hair before and after dyeing; give the dyed swatch's record as the second of --pair")


#: A base whose Table 1 dye concentration is above this reads as dyed hair, not a natural base.
DYED_BASE_CONCENTRATION = 0.3


def dyed_base_warnings(base: HairSample) -> list[str]:
    """Warn when a base is a dye prediction or reads as dyed: the model takes all its absorption as melanin."""
    record = base.record
    if record.provenance.prediction:
        return [f"dyed base: {base.label} is a dye prediction, not natural hair; the model reads all its absorption "
                f"as melanin, so the result is a second dye on top of the first"]
    hair = record.hair
    if hair is not None and hair.dye_concentration > DYED_BASE_CONCENTRATION:
        return [f"dyed base: {base.label} reads as dyed hair (Table 1 dye concentration {hair.dye_concentration:.2f}); "
                f"the model takes a natural base, so its dye is counted as melanin"]
    return []


def same_base_spread(pairs: list[tuple[HairSample, HairSample]], curve: ResponseCurve) -> float:
    """The largest ΔE2000 between two dyed swatches of one base (0 with one pair per base)."""
    worst = 0.0
    for i, (base_i, dyed_i) in enumerate(pairs):
        for base_j, dyed_j in pairs[i + 1:]:
            if _distinct_bases(np.array([base_i.sigma_a, base_j.sigma_a])) == 1:
                worst = max(worst, float(delta_e2000(colour_of(dyed_i.sigma_a, curve), colour_of(dyed_j.sigma_a, curve))))
    return worst


# --- the fit -------------------------------------------------------------------------------------------
def _distinct_bases(bases: np.ndarray) -> int:
    """How many of the bases' ``sigma_a`` differ (relative difference, largest channel) from each other."""
    kept: list[np.ndarray] = []
    for m in bases:
        if all(np.max(np.abs(m - k) / np.maximum(np.maximum(m, k), 1e-6)) > SAME_BASE_REL for k in kept):
            kept.append(m)
    return len(kept)


def fit(bases: np.ndarray, dyed: np.ndarray, weights: np.ndarray, lift_measurable: bool) -> tuple[float, np.ndarray]:
    """Lift and deposit from (n, 3) base and dyed ``sigma_a``; ``weights`` (n, 3) are 1 / interval.

    Measurable: weighted least squares of ``dyed - base = -L * base + D``, ``0 <= L <= LIFT_MAX``,
    ``D >= 0``. Not measurable (one base): the least lift that leaves ``D >= 0`` on average (0 when
    the dyed hair is nowhere lighter than its base), and the mean deposit.
    """
    bases, dyed, weights = (np.asarray(a, float).reshape(-1, 3) for a in (bases, dyed, weights))
    if not lift_measurable:
        m, s = bases.mean(0), dyed.mean(0)
        lift = float(np.clip(np.max(np.where(m > 1e-6, 1.0 - s / np.maximum(m, 1e-12), 0.0)), 0.0, LIFT_MAX))
        return lift, np.clip(s - (1.0 - lift) * m, 0.0, None)
    n = len(bases)
    a = np.zeros((3 * n, 4))
    a[:, 0] = -bases.ravel()
    a[:, 1:] = np.tile(np.eye(3), (n, 1))
    w = weights.ravel()
    b = (dyed - bases).ravel()
    sol = lsq_linear(a * w[:, None], b * w, bounds=([0.0, 0.0, 0.0, 0.0], [LIFT_MAX, np.inf, np.inf, np.inf]),
                     method="bvls")
    return float(sol.x[0]), np.clip(sol.x[1:], 0.0, None)


def predict_sigma(lift: float, deposit: np.ndarray, base_sigma: np.ndarray, dose: float = 1.0) -> np.ndarray:
    """``(1 - lift) * base + dose * deposit``: the dyed hair's ``sigma_a``."""
    return (1.0 - float(lift)) * np.asarray(base_sigma, float) + float(dose) * np.asarray(deposit, float)


def _draw(sigma: np.ndarray, lo: np.ndarray, hi: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` draws of ``sigma_a`` with its 68% interval read as one standard deviation either side."""
    z = rng.standard_normal((n, 3))
    return np.clip(sigma + np.where(z > 0, z * (hi - sigma), z * (sigma - lo)), 0.0, None)


def characterise(pairs: list[tuple[HairSample, HairSample]], name: str, curve: ResponseCurve | None = None,
                 allow_mixed: bool = False, draws: int = _MC_DRAWS, seed: int = 0) -> DyeRecord:
    """Measure a dye from (natural base, dyed) pairs: deposit, lift, intervals, residuals, warnings."""
    if not pairs:
        raise DyeError("a dye is measured on at least one (base, dyed) pair; give --pair BASE.json DYED.json")
    if not name or not name.strip():
        raise DyeError("a dye needs a name; give --name")
    curve = curve or rig_curve()
    warnings = _pair_warnings(pairs, curve, allow_mixed)
    samples, keys = _distinct_samples(pairs)
    intervals = {k: interval_of(s, curve) for k, s in samples.items()}
    half = {k: np.maximum(0.5 * (hi - lo), 1e-4 + 0.01 * samples[k].sigma_a) for k, (lo, hi) in intervals.items()}
    bases = np.array([samples[b].sigma_a for b, _ in keys])
    dyed = np.array([samples[d].sigma_a for _, d in keys])
    weights = np.array([1.0 / np.hypot(half[b], half[d]) for b, d in keys])
    measurable = _distinct_bases(bases) >= 2
    lift, deposit = fit(bases, dyed, weights, measurable)
    if not measurable:
        assumed = ("assumed 0" if lift == 0 else
                   f"set to {lift:.2f}, the least lift that explains a dyed hair lighter than its base")
        warnings.insert(0, f"one base: lift cannot be measured from one natural base, so it is {assumed}; "
                           f"characterise on two bases or more to measure it")
    (dep_lo, dep_hi), (lift_lo, lift_hi) = _fit_intervals(samples, keys, intervals, weights, measurable,
                                                          (lift, deposit), draws, seed)
    pair_records, residual_de = _pair_residuals(pairs, lift, deposit, curve)
    warnings += _disagreement_warnings(pairs, residual_de, curve)
    sources = {s.interval_source for s in samples.values()}
    return DyeRecord(
        name=name.strip(), deposit_sigma_a=tuple(float(v) for v in deposit), lift=lift, lift_measured=measurable,
        pairs=tuple(pair_records), deposit_low=tuple(dep_lo), deposit_high=tuple(dep_hi),
        lift_low=lift_lo if measurable else None,
        lift_high=lift_hi if measurable else None,
        residual_de2000_max=max(residual_de), residual_de2000_mean=float(np.mean(residual_de)),
        shine_change=None, warnings=tuple(warnings),
        intervals={"coverage": 0.68, "method": "16th-84th percentiles of the fit over Monte Carlo draws of each "
                   "record's sigma_a within its interval (the record's mean-colour ΔE2000 p68 through the rig's "
                   "response curve)", "draws": draws, "seed": seed,
                   "record_intervals": "the records' own" if sources == {IntervalSource.RECORD} else
                   f"assumed ΔE2000 {DEFAULT_COLOUR_DE68} where a record carries none"},
        provenance={"hairdigi_version": version(), "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                    "model": "Kips et al. 2022 Table 1 absorption; deposit + lift of the melanin (d'Eon et al. 2011)",
                    "fit": "weighted bounded least squares" if measurable else "one base: lift assumed",
                    "lift_max": LIFT_MAX, "shine_change": "not measured: the records carry no shine"})


def _pair_warnings(pairs: list[tuple[HairSample, HairSample]], curve: ResponseCurve, allow_mixed: bool) -> list[str]:
    """Refuse pairs that cannot measure a dye (one record twice, a dyed hair no lift and deposit explain);
    the warnings of the rest: mixed calibrations, dyed bases, unreliable records."""
    for base, dyed in pairs:
        check_distinct_records(base, dyed)
    warnings = check_calibrations(pairs, allow_mixed)
    for base, dyed in pairs:
        check_explainable(base, dyed, curve)
        warnings += dyed_base_warnings(base)
        for s in (base, dyed):
            if not s.record.reliable:
                warnings.append(f"unreliable record: {s.label} is flagged ({'; '.join(s.record.warning_messages())})")
    return warnings


def _distinct_samples(pairs: list[tuple[HairSample, HairSample]]) -> tuple[dict[str, HairSample], list[list[str]]]:
    """Each distinct record once (a base dyed twice is one measurement, drawn once per Monte Carlo draw):
    (samples by key, each pair's [base key, dyed key])."""
    samples: dict[str, HairSample] = {}
    keys = []
    for base, dyed in pairs:
        pair_keys = []
        for s in (base, dyed):
            key = s.sha256 or f"{id(s)}"
            samples.setdefault(key, s)
            pair_keys.append(key)
        keys.append(pair_keys)
    return samples, keys


def _fit_intervals(samples: dict[str, HairSample], keys: list[list[str]], intervals: dict, weights: np.ndarray,
                   measurable: bool, estimate: tuple[float, np.ndarray], draws: int, seed: int):
    """The deposit's and the lift's 68% intervals: the fit redone over draws of every record within its
    interval, each widened to hold the estimate: ((deposit low, high), (lift low, high))."""
    lift, deposit = estimate
    rng = np.random.default_rng(seed)
    drawn = {k: _draw(samples[k].sigma_a, *intervals[k], rng, draws) for k in samples}
    lifts, deposits = [], []
    for j in range(draws):
        b_j = np.array([drawn[b][j] for b, _ in keys])
        d_j = np.array([drawn[d][j] for _, d in keys])
        l_j, dep_j = fit(b_j, d_j, weights, measurable)
        lifts.append(l_j)
        deposits.append(dep_j)
    dep_lo, dep_hi = np.percentile(deposits, [16, 84], axis=0)
    # a bounded fit's draws can all fall on one side of the estimate: an interval always holds its estimate
    dep_lo, dep_hi = np.minimum(dep_lo, deposit), np.maximum(dep_hi, deposit)
    lift_lo, lift_hi = (min(float(np.percentile(lifts, 16)), lift), max(float(np.percentile(lifts, 84)), lift))
    return (dep_lo, dep_hi), (lift_lo, lift_hi)


def _pair_residuals(pairs: list[tuple[HairSample, HairSample]], lift: float, deposit: np.ndarray,
                    curve: ResponseCurve) -> tuple[list[DyePairRecord], list[float]]:
    """Each pair's record with its residual, in sigma_a and as the swatch's mean-colour ΔE2000."""
    pair_records, residual_de = [], []
    for base, dyed_s in pairs:
        fitted = predict_sigma(lift, deposit, base.sigma_a)
        de = float(delta_e2000(colour_of(fitted, curve), colour_of(dyed_s.sigma_a, curve)))
        residual_de.append(de)
        pair_records.append(DyePairRecord(base.path, base.sha256, dyed_s.path, dyed_s.sha256,
                                          tuple(base.sigma_a), tuple(dyed_s.sigma_a), base.calibration,
                                          dyed_s.calibration, tuple(dyed_s.sigma_a - fitted), de))
    return pair_records, residual_de


def _disagreement_warnings(pairs: list[tuple[HairSample, HairSample]], residual_de: list[float],
                           curve: ResponseCurve) -> list[str]:
    """A warning when one lift and deposit leave a pair far from its dyed swatch, or two dyed swatches of
    one base differ."""
    if max(residual_de) > DISAGREE_DE:
        return [f"the pairs disagree: one lift and deposit leave a pair {max(residual_de):.1f} ΔE2000 from "
                f"its dyed swatch; were they all dyed with this product, developer and time?"]
    if (spread := same_base_spread(pairs, curve)) > DISAGREE_DE:
        return [f"the pairs disagree: two dyed swatches of one base are {spread:.1f} ΔE2000 apart; were "
                f"they all dyed with this product, developer and time?"]
    return []


# --- prediction ----------------------------------------------------------------------------------------
@dataclass
class Prediction:
    """A dye applied to a base: the predicted ``sigma_a``, its Table 1 hair, colour and the record."""

    sigma_a: np.ndarray
    params: HairParams
    linear_rgb: np.ndarray          # the swatch's mean linear colour, from the response curve
    record: EstimateRecord
    exact: bool                     # the Table 1 hair renders exactly this sigma_a


def lifted_melanin(hair: HairParams, lift: float) -> float:
    """The melanin concentration that a lift of ``lift`` leaves (through the rig's melanin remap)."""
    m, q = zip(*MELANIN_REMAP)
    return float(np.interp((1.0 - lift) * melanin_quantity(hair.melanin_concentration), q, m))


def deposit_as_dye(deposit: np.ndarray) -> tuple[tuple[float, float, float], float]:
    """Table 1's dye colour and concentration for a deposit (concentration 1; colour from Chiang's albedo)."""
    deposit = np.asarray(deposit, float)
    if np.all(deposit <= 1e-9):
        return (255.0, 255.0, 255.0), 0.0
    rgb = np.clip(255.0 * albedo_from_sigma_a(deposit), 0.0, 255.0)
    return tuple(float(v) for v in rgb), 1.0


def _spread(dye: DyeRecord, base: HairSample, dose: float, curve: ResponseCurve, draws: int = _MC_DRAWS,
            seed: int = 0) -> tuple[np.ndarray, np.ndarray, float]:
    """68% interval of the predicted ``sigma_a`` and its colour's ΔE2000 p68: dye and base both drawn."""
    rng = np.random.default_rng(seed)
    lo, hi = interval_of(base, curve)
    bases = _draw(base.sigma_a, lo, hi, rng, draws)
    dep = np.asarray(dye.deposit_sigma_a)
    deps = _draw(dep, np.asarray(dye.deposit_low or dep), np.asarray(dye.deposit_high or dep), rng, draws)
    if dye.lift_measured and dye.lift_low is not None:
        z = rng.standard_normal(draws)
        lifts = np.clip(dye.lift + np.where(z > 0, z * (dye.lift_high - dye.lift), z * (dye.lift - dye.lift_low)),
                        0.0, LIFT_MAX)
    else:
        lifts = np.full(draws, dye.lift)
    sig = (1.0 - lifts)[:, None] * bases + dose * deps
    centre = predict_sigma(dye.lift, dep, base.sigma_a, dose)
    de = delta_e2000(colour_of(sig, curve), np.tile(colour_of(centre, curve), (draws, 1)))
    s_lo, s_hi = np.percentile(sig, [16, 84], axis=0)
    return s_lo, s_hi, float(np.percentile(de, 68))


def apply(dye: DyeRecord, base: HairSample, dose: float = 1.0, curve: ResponseCurve | None = None,
          dye_path: str = "", dye_sha256: str = "") -> Prediction:
    """The dye (its deposit scaled by ``dose``) on a natural base: ``sigma_a``, Table 1 hair and record."""
    if not 0.0 <= dose <= 10.0 or not np.isfinite(dose):
        raise DyeError(f"dose {dose} is outside [0, 10] (1: the dye as characterised)")
    curve = curve or rig_curve()
    sigma = predict_sigma(dye.lift, dye.deposit_sigma_a, base.sigma_a, dose)
    hair = base.record.hair
    rgb, conc = deposit_as_dye(dose * np.asarray(dye.deposit_sigma_a))
    prior = HairParams(rgb, conc, lifted_melanin(hair, dye.lift), hair.melanin_ratio)
    params, exact = params_for_sigma(sigma, prior)
    colour = colour_of(sigma, curve)
    s_lo, s_hi, de68 = _spread(dye, base, dose, curve)
    warnings = [EstimateWarning(WarningKind.OTHER, f"prediction: {dye.name} at dose {dose:g} on {base.label}, "
                                                   f"not a capture")]
    warnings += [EstimateWarning(WarningKind.CALIBRATION if w.startswith("calibration") else WarningKind.OTHER,
                                 f"dye: {w}") for w in dye.warnings]
    warnings += [EstimateWarning(WarningKind.OTHER, w) for w in dyed_base_warnings(base)]
    if not exact:
        warnings.append(EstimateWarning(WarningKind.UNREACHABLE, "unreachable: no Table 1 hair has the predicted "
                                        "sigma_a; the hair block is the nearest, refinement.sigma_a the prediction"))
    refinement = RefinementRecord(ran=True, sigma_a=tuple(float(v) for v in sigma), residual_de2000=0.0,
                                  iterations=0, reachable=exact, rendered_linear_rgb=tuple(float(v) for v in colour),
                                  region=Region(source="dye prediction: sigma_a from the dye model, colour from the "
                                                       "rig's response curve; nothing was captured or rendered"))
    provenance = Provenance(
        hairdigi_version=version(), time=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        prediction={"dye": dye.name, "dye_file": dye_path, "dye_sha256": dye_sha256, "base": base.path,
                    "base_sha256": base.sha256, "dose": dose, "lift": dye.lift, "lift_measured": dye.lift_measured,
                    "deposit_sigma_a": [round(v, 6) for v in dye.deposit_sigma_a],
                    "melanin_concentration_left": round(prior.melanin_concentration, 6)},
        calibration=base.record.provenance.calibration, camera=base.record.provenance.camera)
    uncertainty = Uncertainty(method="Monte Carlo over the dye's intervals and the base's", coverage=0.68,
                              sigma_a_low=tuple(round(float(v), 6) for v in s_lo),
                              sigma_a_high=tuple(round(float(v), 6) for v in s_hi),
                              mean_colour_de2000_p68=round(de68, 3))
    record = EstimateRecord(hair=params, warnings=tuple(warnings), uncertainty=uncertainty, refinement=refinement,
                            provenance=provenance, appearance=base.record.appearance)
    return Prediction(sigma, params, colour, record, exact)


# --- dose ------------------------------------------------------------------------------------------------
@dataclass
class DoseResult:
    """The deposit scale that brings a base nearest a target colour, and how near it gets."""

    scale: float
    de2000: float
    reachable: bool
    linear_rgb: np.ndarray          # what the base reaches at ``scale``
    target_linear_rgb: np.ndarray
    sigma_a: np.ndarray
    message: str = ""
    curve_de: list[tuple[float, float]] = field(default_factory=list)


def dose(dye: DyeRecord, base: HairSample, target_linear: np.ndarray, curve: ResponseCurve | None = None,
         dose_max: float = DOSE_MAX) -> DoseResult:
    """Scale the deposit (lift unchanged) so the base's swatch comes nearest ``target_linear`` (ΔE2000)."""
    curve = curve or rig_curve()
    target = np.clip(np.asarray(target_linear, float), 1e-9, None)

    def de(x: float) -> float:
        return float(delta_e2000(colour_of(predict_sigma(dye.lift, dye.deposit_sigma_a, base.sigma_a, x), curve),
                                 target))

    grid = np.linspace(0.0, dose_max, 61)
    values = [de(x) for x in grid]
    k = int(np.argmin(values))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    best = minimize_scalar(de, bounds=(lo, hi), method="bounded", options={"xatol": 1e-4})
    x, d = (float(best.x), float(best.fun)) if best.fun <= values[k] else (float(grid[k]), float(values[k]))
    sigma = predict_sigma(dye.lift, dye.deposit_sigma_a, base.sigma_a, x)
    reachable = d <= REACHABLE_DE
    if np.all(np.asarray(dye.deposit_sigma_a) <= 1e-9):
        message = (f"out of reach: {dye.name} deposits nothing, so its dose changes nothing; its lift alone leaves "
                   f"ΔE2000 {d:.2f}")
        reachable = False
    elif reachable:
        message = f"dose {x:.2f} x {dye.name} reaches the target within ΔE2000 {d:.2f}"
    else:
        edge = " (the largest dose searched)" if x >= dose_max - 1e-3 else (" (no dye)" if x <= 1e-3 else "")
        message = (f"out of reach: the nearest {dye.name} brings this base to the target is ΔE2000 {d:.2f}, at dose "
                   f"{x:.2f}{edge}; the target needs another dye, base or lift")
    return DoseResult(x, d, reachable, colour_of(sigma, curve), target, sigma, message,
                      [(float(g), float(v)) for g, v in zip(grid, values)])


_HEX = re.compile(r"^#?([0-9a-fA-F]{6})$")


def target_colour(text: str, curve: ResponseCurve | None = None) -> tuple[np.ndarray, str]:
    """A target's mean linear RGB: ``#RRGGBB`` (sRGB) or a record file (the swatch its sigma_a renders); and a label."""
    match = _HEX.match(text.strip())
    if match:
        value = match.group(1)
        rgb = np.array([int(value[i:i + 2], 16) for i in (0, 2, 4)], float)
        return srgb8_to_linear(rgb), f"#{value.upper()}"
    if not Path(text).exists():
        raise DyeError(f"--target {text}: neither a #RRGGBB colour nor an existing record file")
    # the record's sigma_a through the same curve as the predictions (a capture's own measured mean is
    # of its rig-view region, another framing than the curve's all-hair crop)
    return colour_of(load_sample(text).sigma_a, curve or rig_curve()), text


def describe_colour(linear_rgb: np.ndarray) -> dict:
    """sRGB hex and CIE L*a*b* (D65) of a linear colour, for reports and the shade card."""
    srgb = linear_to_srgb8(np.asarray(linear_rgb, float))
    lab = linear_rgb_to_lab(np.asarray(linear_rgb, float))
    return {"srgb": "#" + "".join(f"{int(v):02X}" for v in srgb), "lab": [round(float(v), 2) for v in lab]}

