"""The estimate as the lab's colour instrument reads it: instrument-equivalent CIELAB with an interval.

A lab records a tress as its spectrophotometer reads it (d/8° SCI or SCE, or 45°/0°; D65 and the 10°
observer; ``render.instrument_geometry``). The swatch's reflectance factor in a geometry depends on each
wavelength's absorption alone, so each family member's response in each geometry is one curve of a flat
``sigma_a`` (``render.instrument_geometry.reflectance_ladder``), rendered once and shipped
(``INSTRUMENT_TABLES``, built by ``python -m hairdigi.inference.instrument_reading``). A record's reading is then
its hair's ``sigma_a(λ)`` (``render.spectra.hair_sigma_a_spectrum``: the spectral answer where the rig's
spectra are declared, else the record's Table 1 hair) read per wavelength through the curve of the
structure its estimate was read on (the geometric mean of the members its structure map averaged, as
``inference.structure`` averages the rig's curves), weighed by the illuminant and the observer: no
render, a few milliseconds.

Its interval is what ``hairdigi evaluate --instrument`` measured against a virtual instrument (a
spectral render of the truth in the same geometry, on structures hairdigi did not build), shipped in
``INSTRUMENT_UNCERTAINTY``; the record's ``spread`` says how far the family's members read apart at
the answer.
"""
from __future__ import annotations

import argparse
import functools
import os
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from hairdigi.inference.refine import SIGMA_LEVELS, ResponseCurve
from hairdigi.inference.structure import family_curves, family_view, family_weight
from hairdigi.render.domain.files import cache_dir, read_json, write_json_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, InstrumentReading
from hairdigi.render.instrument_geometry import (DEFAULT_APERTURE_MM, GEOMETRIES, InstrumentError, check_aperture,
                                                 check_illuminant, check_observer, geometry, lab_of_reflectance,
                                                 reflectance_ladder)
from hairdigi.render.metrics import delta_e2000_lab
from hairdigi.render.domain.bounds import SwatchModel
from hairdigi.render.domain.text_enum import text_of
from hairdigi.render.spectra import hair_sigma_a_spectrum, srgb_weights
from hairdigi.render.swatch_family import FAMILY, structure_strands
from hairdigi.resources import MODELS, ROOT

#: The shipped curves: every family member in every geometry.
INSTRUMENT_TABLES = ROOT / "tables" / "instrument_curves.npz"
#: The measured intervals, per geometry (``hairdigi evaluate --instrument --ship``).
INSTRUMENT_UNCERTAINTY = MODELS / "instrument_uncertainty.json"


@dataclass(frozen=True)
class BuildSettings:
    """How the tables are rendered. Measured on the layered swatch at 48² (``hairdigi bench instrument``):
    64 spp left the curve 1-2% from a 256-spp one; two layouts of 256 spp each average the spot's fibres."""

    size: int = 48
    spp: int = 256
    layouts: int = 2
    strands: int = 8000
    aperture_mm: float = DEFAULT_APERTURE_MM
    levels: tuple[float, ...] = SIGMA_LEVELS


@dataclass(frozen=True)
class InstrumentCurves:
    """Reflectance factor against flat ``sigma_a``: ``means[g, m, k]`` for geometry ``geometries[g]``,
    member ``members[m]``, level ``levels[k]``."""

    levels: np.ndarray
    geometries: tuple[str, ...]
    members: tuple[str, ...]
    means: np.ndarray

    def member_curve(self, geom: str, member: str) -> ResponseCurve:
        g = self.geometries.index(geometry(geom).name)
        return ResponseCurve(np.asarray(self.levels, float).copy(), self.means[g, self.members.index(member)].copy(),
                             0.0, True)


# -- the tables -----------------------------------------------------------------------------------
def member_ladder(geom: str, member: str, layout: int, settings: BuildSettings = BuildSettings()) -> np.ndarray:
    """One member's reflectance at ``settings.levels`` in ``geom``, strand layout ``layout``; cached on disk."""
    key = f"{geometry(geom).name.replace('/', '-').replace(' ', '_')}-{member}-{layout}-" \
          f"{settings.size}-{settings.spp}-{settings.strands}-{settings.aperture_mm:g}"
    path = cache_dir() / "instrument" / f"ladder-{key}.json"
    if path.exists():
        try:
            data = read_json(path, InstrumentError, "no ladder", "a damaged ladder ({exc})")
            if data["levels"] == list(settings.levels):
                return np.asarray(data["means"], float)
        except (InstrumentError, KeyError, TypeError):
            pass   # rebuilt
    means = reflectance_ladder(structure_strands(member, settings.strands, seed=layout), geom,
                               np.asarray(settings.levels, float), settings.aperture_mm, settings.size,
                               settings.spp, seed=7 + 101 * layout)
    write_json_atomic(path, {"levels": list(settings.levels), "means": means.tolist()})
    return means


def build(out: str | os.PathLike = INSTRUMENT_TABLES, settings: BuildSettings = BuildSettings(),
          members: tuple[str, ...] = FAMILY, say=print) -> Path:
    """Render every member's curve in every geometry (resumable: each ladder is cached) and write the table."""
    means = np.empty((len(GEOMETRIES), len(members), len(settings.levels)))
    start = time.perf_counter()
    for g, geom in enumerate(GEOMETRIES):
        for m, member in enumerate(members):
            ladders = [member_ladder(geom, member, k, settings) for k in range(settings.layouts)]
            means[g, m] = np.exp(np.mean(np.log(np.clip(ladders, 1e-12, None)), axis=0))
            say(f"{geom} {member}: {np.round(means[g, m], 4).tolist()} ({time.perf_counter() - start:.0f} s)")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.stem + ".tmp.npz")
    np.savez_compressed(tmp, levels=np.asarray(settings.levels, float), geometries=np.array(list(GEOMETRIES)),
                        members=np.array(list(members)), means=means,
                        settings=np.array([settings.size, settings.spp, settings.layouts, settings.strands,
                                           settings.aperture_mm], float))
    os.replace(tmp, out)
    return out


@functools.lru_cache(maxsize=4)
def _load(path: str, mtime: float) -> InstrumentCurves:
    with np.load(path) as data:
        return InstrumentCurves(data["levels"], tuple(str(g) for g in data["geometries"]),
                                tuple(str(m) for m in data["members"]), data["means"])


def load_curves(path: str | os.PathLike | None = None) -> InstrumentCurves | None:
    """The shipped instrument curves (None when the table is missing: ``python -m hairdigi.inference.instrument_reading``)."""
    path = Path(path or INSTRUMENT_TABLES)
    if not path.exists():
        return None
    return _load(str(path), path.stat().st_mtime)


@functools.lru_cache(maxsize=1)
def _intervals(path: str, mtime: float) -> dict:
    return read_json(Path(path), InstrumentError, "no interval table", "a damaged interval table ({exc})")


def measured_intervals(path: str | os.PathLike | None = None) -> dict:
    """geometry -> {"p68", "p95", "source"}: what ``hairdigi evaluate --instrument --ship`` measured; {} if none."""
    path = Path(path or INSTRUMENT_UNCERTAINTY)
    if not path.exists():
        return {}
    return _intervals(str(path), path.stat().st_mtime)


# -- a record's reading ---------------------------------------------------------------------------
#: The geometries a record carries by default: the integrating sphere's two and the 45°/0° colorimeter's.
DEFAULT_GEOMETRIES = tuple(GEOMETRIES)


def hair_of(record: EstimateRecord) -> HairParams | None:
    """The hair whose spectrum the reading takes: the spectral world's answer where the rig declared its
    spectra, else the record's Table 1 answer."""
    return record.spectral.hair if record.spectral is not None else record.hair


def answer_curve(rig, members: dict[str, float] | None, swatch_model: str | None,
                 family_share: float = 1.0) -> Callable[[np.ndarray], np.ndarray]:
    """The rig's reflectance of an absorption through the curve the record's answer was read with, at its view
    (``rig``: ``inference.structure.FamilyCurves``): the mean curve of the ``members`` its family map averaged,
    blended toward the default structure's by ``family_share`` (as ``to_family`` blends dark hair); else the
    curve of the structure its refinement rendered (``swatch_model``: a member the frames read, or the default)."""
    if members:
        mean = rig.mean_of(members)
        return lambda sigma: mean(sigma) ** family_share * rig.default(sigma) ** (1.0 - family_share)
    name = text_of(swatch_model)          # a member in the process, its text in a record read back
    if name in rig.members and name != SwatchModel.LAYERED.value:
        return rig.members[name]
    return rig.default


def measured_ratio(measured_rgb, sigma_rgb, reference: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Per wavelength, the capture's measured rig colour over the colour the answer's ``sigma_rgb`` renders
    through the curve it was read with (``reference``, :func:`answer_curve`): 1 where the answer reaches the
    capture; below 1 where the capture is darker than any hair of that structure (a black deposited swatch under
    the layered floor). Each channel's ratio is spread over the wavelengths that channel sees (linear sRGB's
    weights, their negative lobes dropped). (Against the answer's spectral colour instead, the RGB and spectral
    mappings' difference entered the ratio and a saturated dye's a* moved by 8-10: ``hairdigi evaluate --instrument``.)"""
    shown = reference(np.asarray(sigma_rgb, float))
    ratio = np.clip(np.asarray(measured_rgb, float) / np.clip(shown, 1e-12, None), 0.25, 4.0)
    weights = np.clip(srgb_weights(), 0.0, None)
    weights = weights / np.clip(weights.sum(1, keepdims=True), 1e-12, None)
    return weights @ ratio


def member_reflectances(sigma: np.ndarray, geom: str, curves: InstrumentCurves, members: tuple[str, ...],
                        rig=None, reference: Callable[[np.ndarray], np.ndarray] | None = None,
                        ratio: np.ndarray | float = 1.0) -> dict[str, np.ndarray]:
    """Each member's reflectance in ``geom`` of a hair whose answer is ``sigma`` (per wavelength).

    Without ``rig`` (``inference.structure.FamilyCurves`` at the capture's view): each member's curve at
    ``sigma``. With it, each member's reading of the colour the capture showed: per wavelength the colour the
    answer gives through the curve it was read with (``reference``, :func:`answer_curve`; default: the rig's
    default structure's), times ``ratio`` (:func:`measured_ratio`: what the capture measured over that);
    member ``m`` shows that colour at ``F_m^-1(target)``, and reads ``I_m`` of it in the instrument. Where ``m``
    cannot show it (a black swatch below its floor), the shortfall scales its reading: both are the same
    fibres' surface reflection."""
    sigma = np.asarray(sigma, float)
    if rig is None:
        return {m: curves.member_curve(geom, m)(sigma) for m in members}
    target = (reference or rig.default)(sigma) * ratio
    out = {}
    for m in members:
        shown, _ = rig.members[m].inverse(target)
        scale = target / np.clip(rig.members[m](shown), 1e-12, None)
        out[m] = curves.member_curve(geom, m)(shown) * scale
    return out


def weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per column of ``values`` (members, n), the median weighted by ``weights`` (members,): the lowest value
    whose members below and at it weigh half the total or more."""
    order = np.argsort(values, axis=0)
    cumulative = np.cumsum(np.asarray(weights, float)[order], axis=0)
    pick = np.argmax(cumulative >= 0.5 * cumulative[-1], axis=0)
    columns = np.arange(values.shape[1])
    return values[order[pick, columns], columns]


def read_instrument(hair: HairParams, members: dict[str, float] | None = None, rig=None,
                    reference: Callable[[np.ndarray], np.ndarray] | None = None, ratio: np.ndarray | float = 1.0,
                    geometries: tuple[str, ...] = DEFAULT_GEOMETRIES, aperture_mm: float = DEFAULT_APERTURE_MM,
                    illuminant: str = "D65", observer: str = "10", curves: InstrumentCurves | None = None,
                    intervals: dict | None = None) -> tuple[InstrumentReading, ...]:
    """``hair``'s readings in ``geometries``: per wavelength, the weighted median of the ``members``' readings
    (:func:`member_reflectances`; None: the whole family), with ``rig`` the family's curves at the capture's
    view, so that each member reads the colour the capture showed. The median, not the mean: in the sphere one
    member (``spread``) reads black hair 6 L* below the others even after the transfer; the geometric mean of
    the members read 2.43 / 2.99 ΔE2000 (median / p95, d/8 SCI, ``hairdigi evaluate --instrument``), the median
    1.69 / 2.22. Raises InstrumentError when the tables are missing."""
    curves = curves if curves is not None else load_curves()
    if curves is None:
        raise InstrumentError(f"no instrument tables at {INSTRUMENT_TABLES}; build them with "
                              f"python -m hairdigi.inference.instrument_reading (about 10 minutes)")
    check_aperture(aperture_mm)
    observer, illuminant = check_observer(observer), check_illuminant(illuminant)
    intervals = measured_intervals() if intervals is None else intervals
    sigma = hair_sigma_a_spectrum(hair)
    weights = {m: w for m, w in (members or {}).items() if m in curves.members and w > 0} or \
        {m: 1.0 for m in curves.members}
    if rig is not None:
        weights = {m: w for m, w in weights.items() if m in rig.members}
    out = []
    for name in geometries:
        geom = geometry(name).name
        each = member_reflectances(sigma, geom, curves, tuple(weights), rig, reference, ratio)
        centre = weighted_median(np.array(list(each.values())), np.array(list(weights.values())))
        lab = lab_of_reflectance(centre, illuminant, observer)
        spread = float(max(delta_e2000_lab(lab_of_reflectance(r, illuminant, observer), lab) for r in each.values()))
        measured = intervals.get(geom, {})
        how = "each reading the colour the capture showed" if rig is not None else "at the answer's absorption"
        out.append(InstrumentReading(
            geometry=geom, lab=tuple(float(v) for v in lab), observer=observer, illuminant=illuminant,
            aperture_mm=float(aperture_mm), p68=measured.get("p68"), p95=measured.get("p95"), spread=spread,
            method=(f"the hair's spectral absorption read per wavelength through the {geom} reflectance curves of "
                    f"{', '.join(weights)} ({how}; their weighted median per wavelength); interval: "
                    f"{measured.get('source', 'not measured')}")))
    return tuple(out)


def record_view(record: EstimateRecord):
    """The view the record's estimate was read at (a rig region or an all-hair crop's pose), or None."""
    region = record.refinement.region
    if region is None:
        return None
    return region.rig if region.rig is not None else region.crop_pose


def reading_members(record: EstimateRecord) -> dict[str, float] | None:
    """The structures a record's reading weighs: those its family map averaged; the one member its frames read
    (its refinement rendered that member); else None, the whole family (a swatch assumed layered may be any)."""
    region = record.refinement.region
    if region is None:
        return None
    if region.members:
        return region.members
    name = text_of(region.swatch_model)
    if name in FAMILY and name != SwatchModel.LAYERED.value:
        return {name: 1.0}
    return None


def with_instrument(record: EstimateRecord, path: str | os.PathLike | None = None, **kwargs) -> EstimateRecord:
    """``record`` with its instrument readings (``read_instrument``: each structure reading the colour the capture
    measured, through the family's curves at its view); unchanged when it has no hair or no tables are shipped."""
    hair = hair_of(record)
    curves = load_curves(path)
    if hair is None or curves is None:
        return record
    view = record_view(record)
    members = reading_members(record)
    if view is None or not record.refinement.ran:
        return replace(record, instrument=read_instrument(hair, members, curves=curves, **kwargs))
    rig = family_curves(family_view(view))
    region = record.refinement.region
    if record.spectral is not None:
        # the camera answer is read through the refinement's own curve, before any family map (its RGB twin is
        # the refinement's fitted sigma_a): read through the family's mean, a spectral rig's readings were 1.6 L* dark
        reference = answer_curve(rig, None, region.swatch_model)
        sigma_rgb = record.refinement.fitted_sigma_a or record.sigma_a
    else:
        share = family_weight(np.asarray(record.refinement.fitted_sigma_a or record.sigma_a, float)) \
            if region.members else 0.0
        reference = answer_curve(rig, region.members, region.swatch_model, share)
        sigma_rgb = record.sigma_a
    measured = record.refinement.target_linear_rgb
    ratio = 1.0 if measured is None or sigma_rgb is None else measured_ratio(measured, sigma_rgb, reference)
    return replace(record, instrument=read_instrument(hair, members, rig, reference, ratio, curves=curves, **kwargs))


def main(argv: list[str] | None = None) -> int:
    """``python -m hairdigi.inference.instrument_reading [--out PATH] [--spp N]``: build the instrument tables."""
    parser = argparse.ArgumentParser(prog="python -m hairdigi.inference.instrument_reading", description=main.__doc__)
    parser.add_argument("--out", default=str(INSTRUMENT_TABLES))
    parser.add_argument("--spp", type=int, default=BuildSettings.spp)
    parser.add_argument("--layouts", type=int, default=BuildSettings.layouts)
    args = parser.parse_args(argv)
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.variant import select_variant

    select_variant()
    print(build(args.out, BuildSettings(spp=args.spp, layouts=args.layouts)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
