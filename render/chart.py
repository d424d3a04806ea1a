"""The ColorChecker in the rig: reference reflectances (colour-science) and their rendered values.

Calibration maps a camera's view of the chart onto the chart **as the renderer renders it in the
rig** (:func:`rig_chart_targets`), not onto the chart's published values: the encoder was trained
on renders, so a corrected capture must land in the renderer's colour space, lighting included
(``render.chart_targets`` renders them; this module renders nothing).
The published values (:func:`colorchecker_reflectances`) are the fallback when no rig render is
available; they agree with the rendered ones up to the rig's irradiance.
"""
from __future__ import annotations

import json
from functools import lru_cache

import colour
import numpy as np

from hairdigi.resources import CHARTS

from hairdigi.render.domain import rig_geometry
from hairdigi.render.spectra import WAVELENGTHS, rgb_projection

CHART_NAME = "ColorChecker24 - After November 2014"
TARGETS_FILE = CHARTS / "rig_chart_targets.json"
WHITE_PATCH = 18   # "white 9.5"


@lru_cache(maxsize=1)
def colorchecker_reflectances() -> np.ndarray:
    """(24, 3) linear sRGB (D65) reflectances of the X-Rite ColorChecker, from colour-science's xyY (D50)."""
    chart = colour.CCS_COLOURCHECKERS[CHART_NAME]
    xyy = np.array(list(chart.data.values()))
    xyz = colour.xyY_to_XYZ(xyy)
    rgb = colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], illuminant=chart.illuminant,
                            chromatic_adaptation_transform="CAT02", apply_cctf_encoding=False)
    return np.clip(rgb, 0.0, 1.0)


#: colour-science's measured spectral reflectances of the chart (same patch order as ``CHART_NAME``).
SPECTRA_NAME = "BabelColor Average"


@lru_cache(maxsize=1)
def colorchecker_spectra() -> np.ndarray:
    """(24, n) spectral reflectances of the ColorChecker on ``render.spectra.WAVELENGTHS``: what a spectral
    rig puts in view instead of :func:`colorchecker_reflectances`.

    colour-science's measured spectra (``SPECTRA_NAME``, held constant past 380-730 nm) are an average of
    charts, 0.1-2.9 ΔE2000 (median 0.9) from the reference colours the calibration's targets are made of.
    A lab calibrates with its own chart's values; so each spectrum here is bent by a smooth factor (a
    quadratic in wavelength) until its colour under D65 is the reference colour, keeping its measured
    shape: the chart in view is the chart the targets describe, and what a camera adds is metamerism
    alone (measured: calibrating the CIE observer on the unbent spectra left 1.42 ΔE2000)."""
    sds = colour.SDS_COLOURCHECKERS[SPECTRA_NAME]
    if list(sds) != list(colour.CCS_COLOURCHECKERS[CHART_NAME].data):
        raise ValueError(f"{SPECTRA_NAME}'s patches are not in {CHART_NAME}'s order")
    measured = np.array([np.interp(WAVELENGTHS, sd.wavelengths, sd.values) for sd in sds.values()])
    x = (WAVELENGTHS - 555.0) / 200.0
    basis = np.stack([np.ones_like(x), x, x * x])                       # (3, n) smooth factors
    out = []
    for spectrum, target in zip(measured, colorchecker_reflectances()):
        effect = np.array([rgb_projection(spectrum * b) for b in basis]).T   # colour of each factor
        c = np.linalg.solve(effect, target)
        out.append(np.clip(spectrum * (c @ basis), 1e-4, 1.0))
    return np.array(out)


def is_colorchecker(chart) -> bool:
    """Whether a scene's (24, 3) chart is the ColorChecker (:func:`colorchecker_reflectances`)."""
    return chart is not None and np.allclose(np.asarray(chart, float), colorchecker_reflectances(), atol=1e-9)


def patch_boxes(size: tuple[int, int], inset: float = 0.6) -> list[tuple[int, int, int, int]]:
    """Pixel boxes (x0, y0, x1, y1) of the central ``inset`` of each patch in the rig view."""
    half = rig_geometry.CHART_PATCH * inset / 2
    boxes = []
    for cx, cy in rig_geometry.chart_patch_centres():
        (x0, x1), (y1, y0) = rig_geometry.rig_pixel(np.array([cx - half, cx + half]),
                                              np.array([cy - half, cy + half]), size)
        boxes.append((int(np.ceil(x0)), int(np.ceil(y0)), int(np.floor(x1)), int(np.floor(y1))))
    return boxes


def patch_means(image: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(24, 3) mean of each patch's centre in a rig-view image of ``size``."""
    return np.array([image[y0:y1, x0:x1].reshape(-1, 3).mean(0) for x0, y0, x1, y1 in patch_boxes(size)])


def rig_chart_targets() -> tuple[np.ndarray, str]:
    """The rendered chart values (linear RGB) and their source; falls back to the reflectances."""
    if TARGETS_FILE.exists():
        data = json.loads(TARGETS_FILE.read_text())
        return np.array(data["linear_rgb"]), "rendered in the rig (resources/charts/rig_chart_targets.json)"
    return colorchecker_reflectances(), f"colour-science reference values ({CHART_NAME}), unrendered"
