"""Colour calibration from a ColorChecker in view: detect it, fit a CCM, report ΔE2000, save a profile.

- Detection: OpenCV 5's ``cv2.mcc`` (``CCheckerDetector.create()``, ``MCC24``, ``process``).
- The fit: colour-science's ``matrix_colour_correction`` (Cheung 2004, Finlayson 2015
  root-polynomial, or Vandermonde), from the camera's linearised patch values to the targets.
- The targets are the chart as the renderer renders it in the rig (``render.chart``), so corrected
  captures live in the colour space the encoder was trained in; colour-science's published values
  are the fallback.
- ΔE2000 is computed in CIELAB after scaling both sides so that the target's white patch has the
  published white's luminance, so that the figures read as they would on paper.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import colour
import cv2
import numpy as np

from render.files import read_json
from render.chart import WHITE_PATCH, colorchecker_reflectances, rig_chart_targets
from render.metrics import delta_e2000
from render.params import write_json_atomic
from render.srgb import linear_to_srgb8, srgb8_to_linear

METHODS = ("Cheung 2004", "Finlayson 2015", "Vandermonde")
DEFAULT_METHOD = "Finlayson 2015"
STALE_AFTER_S = 8 * 3600   # a shift: recalibrate every morning


class CalibrationError(RuntimeError):
    """Calibration cannot proceed; the message says why and what to do."""


@dataclass
class ChartDetection:
    patches_srgb8: np.ndarray   # (24, 3) mean 8-bit sRGB of each patch, in the standard order
    box: np.ndarray             # (4, 2) corners of the chart in pixels
    cost: float


def detect_chart(image_rgb8: np.ndarray) -> ChartDetection:
    """Find a 24-patch ColorChecker with ``cv2.mcc``; raises ``CalibrationError`` when none is found."""
    detector = cv2.mcc.CCheckerDetector.create()
    detector.setColorChartType(cv2.mcc.MCC24)
    bgr = np.ascontiguousarray(image_rgb8[..., ::-1])
    if not detector.process(bgr, 1):
        raise CalibrationError("no ColorChecker found: put the 24-patch chart flat in view, fully lit, "
                               "without glare, and try again")
    checker = detector.getBestColorChecker()
    stats = np.asarray(checker.getChartsRGB())          # (72, 5): per patch and channel: size, mean, sd, max, min
    means = stats[:, 1].reshape(24, 3)
    return ChartDetection(means, np.asarray(checker.getBox(), float), float(checker.getCost()))


def _perceptual_scale(targets: np.ndarray) -> float:
    """Scale that gives the target white patch the published white's luminance Y."""
    ref_white_y = colour.RGB_to_XYZ(colorchecker_reflectances()[WHITE_PATCH], "sRGB")[1]
    target_white_y = colour.RGB_to_XYZ(targets[WHITE_PATCH], "sRGB")[1]
    return float(ref_white_y / max(target_white_y, 1e-9))


def delta_e_stats(measured_linear: np.ndarray, targets_linear: np.ndarray) -> dict[str, float]:
    s = _perceptual_scale(targets_linear)
    de = delta_e2000(measured_linear * s, targets_linear * s)
    return {"mean": float(de.mean()), "max": float(de.max()), "median": float(np.median(de))}


def fit_ccm(measured_linear: np.ndarray, targets_linear: np.ndarray, method: str = DEFAULT_METHOD,
            degree: int = 1) -> np.ndarray:
    if method not in METHODS:
        raise CalibrationError(f"unknown CCM method {method!r}; choose one of {', '.join(METHODS)}")
    return np.asarray(colour.matrix_colour_correction(measured_linear, targets_linear, method=method,
                                                      degree=degree))


def correct_linear(linear: np.ndarray, ccm: np.ndarray, method: str, degree: int = 1) -> np.ndarray:
    shape = linear.shape
    out = colour.apply_matrix_colour_correction(linear.reshape(-1, 3), ccm, method=method, degree=degree)
    return np.asarray(out).reshape(shape)


def calibrate(image_rgb8: np.ndarray, method: str = DEFAULT_METHOD, degree: int = 1,
              settings: dict | None = None) -> dict:
    """Detect the chart, fit the CCM, and return the profile (not yet saved)."""
    detection = detect_chart(image_rgb8)
    if (detection.patches_srgb8 >= 254).any():
        raise CalibrationError("chart patches are clipped: lower the exposure, then calibrate again")
    targets, source = rig_chart_targets()
    measured = srgb8_to_linear(detection.patches_srgb8)
    ccm = fit_ccm(measured, targets, method, degree)
    corrected = correct_linear(measured, ccm, method, degree)
    profile = {
        "method": method, "degree": degree, "matrix": ccm.tolist(),
        "delta_e2000": {"before": delta_e_stats(measured, targets), "after": delta_e_stats(corrected, targets)},
        "targets": source, "chart_box": detection.box.tolist(), "detection_cost": detection.cost,
        "time": time.time(), "time_iso": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "settings": settings or {},
    }
    profile["id"] = hashlib.sha256(json.dumps(profile, sort_keys=True).encode()).hexdigest()[:12]
    return profile


def apply_profile(image_rgb8: np.ndarray, profile: dict) -> np.ndarray:
    """Colour-correct an 8-bit sRGB image with a profile: linearise, CCM, re-encode."""
    ccm = np.asarray(profile["matrix"])
    lut = srgb8_to_linear(np.arange(256))
    linear = lut[image_rgb8]
    return linear_to_srgb8(correct_linear(linear, ccm, profile["method"], profile.get("degree", 1)))


def save_profile(path: str | os.PathLike, profile: dict) -> Path:
    return write_json_atomic(path, profile)


def load_profile(path: str | os.PathLike) -> dict:
    path = Path(path)
    profile = read_json(path, CalibrationError, "no calibration profile; calibrate the rig first",
                        "not a calibration profile ({exc}); calibrate again")
    for key in ("matrix", "method", "time"):
        if key not in profile:
            raise CalibrationError(f"{path}: the profile has no {key!r}; calibrate again")
    return profile


def staleness(profile: dict, settings: dict | None = None, now: float | None = None,
              max_age_s: float = STALE_AFTER_S) -> list[str]:
    """Reasons the profile should be renewed: age, or camera/light settings that changed since."""
    reasons = []
    age = (now or time.time()) - float(profile["time"])
    if age > max_age_s:
        reasons.append(f"the calibration is {age / 3600:.1f} h old (limit {max_age_s / 3600:.0f} h)")
    if settings is not None:
        changed = sorted(k for k in set(settings) | set(profile.get("settings", {}))
                         if settings.get(k) != profile.get("settings", {}).get(k))
        if changed:
            reasons.append(f"settings changed since calibration: {', '.join(changed)}")
    return reasons
