"""The estimate in a spectral world: colour under any light from the rig's response curve, and Table 1
read so that its spectral hair has the measured colour.

A swatch's mean colour in the rig depends on each wavelength's absorption alone, through the same
response curve at every wavelength: the rig's holder is grey, its lights white, and a path's weight
at one wavelength involves that wavelength only. The curve the refinement renders in RGB
(``inference.refine.response_curve``, a flat ``sigma_a``) is therefore the swatch's reflectance as a
function of ``sigma_a(λ)``; read per wavelength and weighed by a light and an observer or a camera
(``render.spectra.swatch_colour``), it gives a spectral render's mean colour without the render.
Measured (``hairdigi bench spectral``'s hairs, rig swatch, 48² at 128 spp): within 0.10–0.67 ΔE2000
of the spectral render under D65 and tungsten, the spectral render's own noise.

The chain reads an RGB ``sigma_a`` whose RGB render matches the capture. Table 1's RGB mapping and its
spectral mapping (``render.spectra``) are not the same hair (brown 1.0, a saturated red 2.2 ΔE2000
apart at D65), so the record's parameters are refitted (:func:`spectral_answer`): the Table 1 hair,
nearest the RGB answer, whose spectral colour under D65 is the colour the chain measured. Its colour
under another light is then :func:`colour_under`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hairdigi.render.domain.estimate_parts import SpectralInterval, Uncertainty
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateWarning, SpectralReading, WarningKind
from hairdigi.inference.uncertainty import load_table, widen_colour
from hairdigi.render.spectra import balanced, hair_sigma_a_spectrum, rgb_projection, swatch_colour
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.resources import MODELS

#: How much a refit may move the parameters (normalised to [0, 1]) for one unit of CIELAB distance.
STAY = 1.0
#: The refit's finite-difference step in normalised parameters. At 1e-3 a saturated purple (dye
#: (107, 7, 243) at 0.94, held-out seed 29) was left 1.36 ΔE76 from its own colour, and of 14 hairs (the
#: rig's hard cases and 8 drawn, each started 0.1 off) the worst 2.16: the landscape has flats a small
#: step cannot see past. At 1e-2: worst 0.12, the refit's colour under tungsten 0.12 median / 0.76 worst
#: ΔE2000 from the truth's, 0.09 s median (0.25 s worst) a refit.
FIT_STEP = 1e-2
#: The lights a customer sees hair under: daylight, tungsten, a shop's white LED.
UNDER = ("D65", "A", "shop-led")
#: The spectral world's colour intervals (``hairdigi evaluate --spectral --ship``): per camera, the
#: camera answer's ΔE2000 at the rig and away, under each of ``UNDER``; ``unknown``: the RGB answer under
#: daylight through a camera the rig does not declare (the chart's correction cannot undo metamerism).
SPECTRAL_TABLE = MODELS / "spectral_uncertainty.json"


def colour_under(curve, hair: HairParams | np.ndarray, light: str, sensitivities: str | None = None) -> np.ndarray:
    """Mean linear colour of a swatch of ``hair`` (Table 1, or ``sigma_a(λ)``) under ``light``, from the
    response ``curve`` read per wavelength: the CIE observer's linear sRGB, or a camera's raw RGB."""
    sigma = hair_sigma_a_spectrum(hair) if isinstance(hair, HairParams) else np.asarray(hair, float)
    return swatch_colour(curve(sigma), light, sensitivities)


def spectral_answer(rgb_answer: HairParams, target_linear: np.ndarray, curve) -> tuple[HairParams, float]:
    """The Table 1 hair nearest ``rgb_answer`` whose spectral mean colour under D65 is ``target_linear``
    (the chain's measured colour, linear sRGB); returns it and its colour residual (CIELAB ΔE76)."""
    return fit_table1(rgb_answer, target_linear, lambda hair: colour_under(curve, hair, "D65"))


def camera_answer(rgb_answer: HairParams, target_linear: np.ndarray, curve, ccm: np.ndarray, led: str,
                  sensitivities: str, chart_targets: np.ndarray,
                  patches: np.ndarray | None = None) -> tuple[HairParams, float]:
    """The Table 1 hair nearest ``rgb_answer`` read in the camera's own RGB, where the rig's LEDs and the
    camera's sensitivities are known: its raw RGB under the LEDs (the curve read per wavelength), through
    the chart's linear correction ``ccm`` (a 3 x 3, as ``colour.apply_matrix_colour_correction`` applies
    it), matches the corrected capture ``target_linear``. So no colour-correction matrix stands between the
    hair and its model: the chart fixes exposure and white balance only. The camera's channel gains come
    from the chart's neutral patches (their measured spectra, ``render.chart``), seen through the same
    correction, or better, where the profile kept them, from what the camera measured of those patches
    (``patches``, the chart's linear patch means before correction): the correction is fitted over all
    24 patches and misses a neutral by up to 5-18% in one channel through the Sigma SD Merrill, where a
    gain 0.7% off moves the answer 2.7 ΔE2000. Returns the hair and its residual (CIELAB ΔE76 in the
    corrected space)."""
    # deferred: loads colour-science (~1 s); spectral_reading stays light for declared_spectra and the library
    from hairdigi.render.chart import colorchecker_spectra

    ccm = np.asarray(ccm, float)
    if ccm.shape != (3, 3):
        raise ValueError(f"a camera answer needs a linear 3 x 3 correction, got a {ccm.shape} matrix")
    spectra = colorchecker_spectra()[list(NEUTRALS)]
    targets = np.asarray(chart_targets, float)[list(NEUTRALS)]
    raw_measured = (np.linalg.solve(ccm, targets.T).T if patches is None     # what the camera read
                    else np.asarray(patches, float)[list(NEUTRALS)])
    irradiance = (targets / rgb_projection(spectra)).mean(1, keepdims=True)
    raw_model = irradiance * swatch_colour(spectra, led, sensitivities)
    gains = np.median(raw_measured / raw_model, axis=0)
    return fit_table1(rgb_answer, target_linear,
                      lambda hair: ccm @ (gains * colour_under(curve, hair, led, sensitivities)))


@dataclass(frozen=True)
class RigSpectra:
    """What a rig declares of its spectra: its LEDs' SPD (a light's name or a CSV) and its camera's
    sensitivities (a name or a CSV; None: a colorimetric camera, the CIE observer)."""

    led: str
    sensitivities: str | None = None


#: A declared rig's record whose chart correction cannot carry the camera answer.
NOT_LINEAR = ("spectral: the camera answer needs a linear 3x3 chart correction, and this calibration's has more "
              "terms (a root-polynomial of degree 2 or more, or a Vandermonde), so the colour is read as an undeclared "
              "camera's, its interval widened for metamerism; recalibrate at degree 1 (the rig's calibration, "
              "Finlayson 2015 at degree 1: hairdigi rig, or Calibrate in hairdigi app)")


def spectral_record(record, spectra: RigSpectra | None, profile, curve=None, table: dict | None = None):
    """``record`` (an ``EstimateRecord``) in the spectral world: with the rig's ``spectra`` declared and a
    calibration ``profile`` whose chart correction is linear, its :class:`SpectralReading` and that camera's colour interval; with
    none declared, its colour interval widened by the metamerism an undeclared camera leaves. ``curve``:
    the response curve the record's refinement inverted (the capture's region, at its appearance), so
    that the colour read and its model agree; default, the rig's swatch crop's. A camera whose bands
    overlap (the Sigma's CCM has coefficients to 7.5) amplifies any disagreement between the two.
    The profile's measured chart patches (``CalibrationProfile.patches``) give the camera's gains.
    A declared rig whose chart correction is not 3 x 3 (a root-polynomial of a higher degree, a
    Vandermonde) is read as an undeclared one, and its record says so in a warning."""
    table = load_table(SPECTRAL_TABLE) if table is None else table
    if record.hair is None:
        return record
    ccm = None if profile is None else np.asarray(profile.matrix, float)
    if spectra is None or ccm is None or np.shape(ccm) != (3, 3):
        unknown = replace(record, uncertainty=with_spectral(record.uncertainty, table, "unknown"))
        if spectra is None or ccm is None:
            return unknown
        return replace(unknown, warnings=(*record.warnings, EstimateWarning(WarningKind.OTHER, NOT_LINEAR)))
    # deferred: loads colour-science (~1 s); spectral_reading stays light for declared_spectra and the library
    from hairdigi.inference.refine import RefineSettings, response_curve
    from hairdigi.render.chart import rig_chart_targets

    measured = record.refinement.target_linear_rgb
    if curve is None or measured is None:   # no capture's own curve: the crop's, and the answer's colour on it
        curve = curve or response_curve(RIG_SWATCH_POSE, RefineSettings())
        sigma = np.asarray(record.sigma_a, float)
        measured = curve(sigma)
    reading = read_spectral(record.hair, np.asarray(measured, float), curve, ccm, spectra.led,
                            spectra.sensitivities, rig_chart_targets()[0], profile.patches)
    return replace(record, spectral=reading, warnings=(*record.warnings, *residual_warnings(reading)),
                   uncertainty=with_spectral(record.uncertainty, table, reading.camera))


#: The camera answer's colour residual (CIELAB ΔE76) beyond which the declared spectra do not explain the capture:
#: held-out spectral-rig captures read at most 0.41 (``packaging/evaluation/spectral-heldout*``: nikon-5100,
#: sigma-sdmerill, CIE observer; a normal one 0.01); a single-wavelength LED read 21.4.
MAX_CAMERA_RESIDUAL = 1.0


def residual_warnings(reading: SpectralReading) -> list[EstimateWarning]:
    """An unreliable-making warning where the camera answer misses the capture's colour by more than any held-out
    capture did (``MAX_CAMERA_RESIDUAL``), naming the likely causes; none otherwise."""
    if reading.residual <= MAX_CAMERA_RESIDUAL:
        return []
    return [EstimateWarning(WarningKind.UNREACHABLE, (
        f"spectral: no hair seen through the declared camera ({reading.camera}) under the declared LEDs "
        f"({reading.led}) has this capture's colour (residual ΔE76 {reading.residual:.2f}; held-out captures "
        f"{MAX_CAMERA_RESIDUAL:g} at most): LEDs that are not white, or a camera CSV that is not this camera's "
        "(its columns or units); check --led and --sensor against the rig"))]


def read_spectral(rgb_answer: HairParams, target_linear: np.ndarray, curve, ccm: np.ndarray, led: str,
                  sensitivities: str | None, chart_targets: np.ndarray, patches=None) -> SpectralReading:
    """The record's spectral reading: :func:`camera_answer` (the CIE observer where ``sensitivities`` is
    None) and its colour under each of ``UNDER``, as an observer adapted to that light sees it."""
    # deferred: loads colour-science (~1 s); spectral_reading stays light for declared_spectra and the library
    from hairdigi.render.metrics import linear_rgb_to_lab

    start = time.perf_counter()
    hair, residual = camera_answer(rgb_answer, target_linear, curve, ccm, led, sensitivities, chart_targets, patches)
    under = {light: tuple(float(v) for v in linear_rgb_to_lab(np.maximum(
        balanced(colour_under(curve, hair, light), light), 1e-9))) for light in UNDER}
    return SpectralReading(hair, led=spectrum_name(led), camera=spectrum_name(sensitivities), residual=residual,
                           under=under, seconds=time.perf_counter() - start)


def spectrum_name(name: str | None) -> str:
    """How a record names a light or a camera: its name, a CSV's file name, or "cie" for the observer."""
    if name is None:
        return "cie"
    return Path(name).name if str(name).lower().endswith(".csv") else str(name)


def with_spectral(uncertainty: Uncertainty, table: dict | None, camera: str) -> Uncertainty:
    """``uncertainty`` with the spectral world's colour interval for ``camera`` (a declared camera's
    ``spectrum_name``, or "unknown" where the rig declares none): the camera answer's where the table
    measured that camera, the widest camera's for a camera it did not, and for "unknown" the metamerism
    of the RGB answer through the chart's correction. The colour interval is widened to it (the larger,
    per level); a ``spectral`` entry names what it holds for."""
    cameras = (table or {}).get("cameras", {})
    measured = cameras.get(camera)
    if measured is None and camera != "unknown":
        read = [c for c in cameras.values() if c.get("answer") == "camera"]
        measured = max(read, key=lambda c: c["p95"]) if read else None
    if measured is None:
        return uncertainty
    out = widen_colour(uncertainty, measured["p68"], measured["p95"],
                       f"{table.get('source', 'hairdigi evaluate --spectral')} ({camera} camera)")
    return replace(out, spectral=SpectralInterval(camera, measured["answer"], measured["holds_for"], measured["p68"],
                                                  measured["p95"], table.get("source", "")))


#: The chart's neutral patches used for the camera's gains: neutral 8 to neutral 3.5 (the white may
#: clip, the black is mostly noise).
NEUTRALS = (19, 20, 21, 22)


#: A refit left this far from its colour (CIELAB ΔE76) starts again from ``RESTARTS`` too.
RESTART_DE = 1.0
#: Where a refit starts again: the start's melanins under a mid-grey dye at half concentration. Without
#: a dye (concentration 0, or a white dye), neither the dye's colour nor its concentration moves the
#: colour, so a refit started there cannot find a dye at all.
RESTARTS = ((0.5, 0.5, 0.5, 0.5),)


def fit_table1(start_hair: HairParams, target_linear: np.ndarray, forward) -> tuple[HairParams, float]:
    """The Table 1 hair nearest ``start_hair`` whose ``forward(hair)`` (linear sRGB) is ``target_linear``:
    least squares of CIELAB differences and ``STAY`` times the move in normalised parameters; where that
    is left more than ``RESTART_DE`` away, the best of it and fits started from ``RESTARTS``."""
    # deferred: loads scipy and colour-science (~1 s); spectral_reading stays light for declared_spectra and the library
    from scipy.optimize import least_squares

    from hairdigi.render.metrics import linear_rgb_to_lab

    target = linear_rgb_to_lab(np.maximum(np.asarray(target_linear, float), 1e-6))
    start = start_hair.to_vector().astype(float)

    def residuals(v: np.ndarray) -> np.ndarray:
        colour = forward(HairParams.from_vector(v))
        return np.concatenate([linear_rgb_to_lab(np.maximum(colour, 1e-6)) - target, STAY * (v - start)])

    def fit(v0: np.ndarray):
        return least_squares(residuals, v0, bounds=(0.0, 1.0), diff_step=FIT_STEP, max_nfev=200)

    best = fit(start)
    if np.linalg.norm(best.fun[:3]) > RESTART_DE:
        for dye in RESTARTS:
            again = fit(np.concatenate([dye, start[4:]]))
            best = again if again.cost < best.cost else best
    return HairParams.from_vector(best.x), float(np.linalg.norm(best.fun[:3]))
