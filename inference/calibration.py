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

from hairdigi.render.base.files import read_json
from hairdigi.render.chart import WHITE_PATCH, colorchecker_reflectances, rig_chart_targets
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.base.files import write_json_atomic
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear

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


#: Pixels corrected at once: bounds the float64 temporaries of a large frame to about 100 MB.
APPLY_CHUNK_PIXELS = 1 << 20


def apply_profile(image_rgb8: np.ndarray, profile: dict) -> np.ndarray:
    """Colour-correct an 8-bit sRGB image with a profile: linearise, CCM, re-encode (in row chunks)."""
    ccm = np.asarray(profile["matrix"])
    lut = srgb8_to_linear(np.arange(256))
    out = np.empty_like(image_rgb8)
    rows = max(1, APPLY_CHUNK_PIXELS // max(1, image_rgb8.shape[1]))
    for y in range(0, image_rgb8.shape[0], rows):
        linear = lut[image_rgb8[y:y + rows]]
        out[y:y + rows] = linear_to_srgb8(correct_linear(linear, ccm, profile["method"], profile.get("degree", 1)))
    return out


def save_profile(path: str | os.PathLike, profile: dict) -> Path:
    return write_json_atomic(path, profile)


def load_profile(path: str | os.PathLike) -> dict:
    """Read a saved profile; a missing, malformed or corrupt one raises CalibrationError naming the field."""
    path = Path(path)
    profile = read_json(path, CalibrationError, "no calibration profile; calibrate the rig first",
                        "not a calibration profile ({exc}); calibrate again")
    try:
        check_profile(profile)
    except CalibrationError as exc:
        raise CalibrationError(f"{path}: {exc}") from None
    return profile


def _is_real(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and bool(np.isfinite(value))


def check_profile(profile: dict) -> None:
    """Raise CalibrationError naming the first field of ``profile`` that is missing or corrupt."""
    def bad(field: str, what: str) -> CalibrationError:
        return CalibrationError(f"the profile's {field!r} {what}; calibrate again")

    if not isinstance(profile, dict):
        raise CalibrationError(f"a calibration profile is a JSON object, not {type(profile).__name__}; "
                               f"calibrate again")
    for key in ("matrix", "method", "time"):
        if key not in profile:
            raise bad(key, "is missing")
    if profile["method"] not in METHODS:
        raise bad("method", f"is {profile['method']!r}, not one of {', '.join(METHODS)}")
    degree = profile.get("degree", 1)
    if not isinstance(degree, int) or isinstance(degree, bool) or not 1 <= degree <= 4:
        raise bad("degree", f"is {degree!r}, not a whole number from 1 to 4")
    if not _is_real(profile["time"]) or profile["time"] <= 0:
        raise bad("time", f"is {profile['time']!r}, not a time in seconds since 1970")
    matrix = profile["matrix"]
    rows_ok = isinstance(matrix, list) and len(matrix) == 3 and all(
        isinstance(row, list) and len(row) == len(matrix[0]) and all(_is_real(v) for v in row) for row in matrix)
    if not rows_ok:
        raise bad("matrix", "is not 3 rows of finite numbers")
    try:
        out = correct_linear(np.full((1, 3), 0.5), np.asarray(matrix, float), profile["method"], degree)
    except Exception:   # colour-science raises several types for a matrix of the wrong width
        out = None
    if out is None or not np.all(np.isfinite(out)):
        raise bad("matrix", f"does not fit method {profile['method']!r} at degree {degree}")
    for key, kind in (("settings", dict), ("delta_e2000", dict), ("id", str)):
        if key in profile and not isinstance(profile[key], kind):
            raise bad(key, f"is {type(profile[key]).__name__}, not {'an object' if kind is dict else 'a string'}")


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


def profile_warnings(profile: dict, current_settings: dict | None = None, now: float | None = None) -> list[str]:
    """Human-readable warnings for a profile that should be renewed (the rule is ``staleness``), each
    with the fix; ``now`` is when the image was taken (default: now)."""
    now = time.time() if now is None else now
    warnings = [f"calibration: {reason}; calibrate again with the chart in view"
                for reason in staleness(profile, current_settings, now)]
    if float(profile["time"]) > now + 300:
        warnings.append(f"calibration: the profile is dated {(float(profile['time']) - now) / 3600:.1f} h after "
                        f"the image; check the computer's clock, then calibrate again")
    return warnings


def capture_settings(image_path: str | os.PathLike) -> tuple[dict | None, float | None]:
    """The settings and time of a rig capture, from the ``<id>.json`` saved beside it (None, None for
    an image without one): the same keys as ``RigSession.settings``, to compare with a profile's."""
    import datetime
    import hashlib

    image_path = Path(image_path)
    try:
        record = json.loads(image_path.with_suffix(".json").read_text(encoding="utf-8"))
        if record.get("image_sha256") != hashlib.sha256(image_path.read_bytes()).hexdigest():
            return None, None    # not this image's record
    except (OSError, ValueError, AttributeError):
        return None, None
    frame = record.get("frame_meta") or {}
    settings = {}
    if isinstance(frame, dict) and "camera" in frame:
        settings["camera"] = frame["camera"]
        camera = frame.get("camera_settings")
        model = frame.get("camera_model")       # records made before cameras reported their settings
        if isinstance(camera, dict):
            settings.update(camera)
        elif isinstance(model, dict):
            settings.update({k: v for k, v in model.items() if k in ("exposure_ev", "gain")})
    if record.get("lights") is not None:
        settings["lights"] = record["lights"]
    try:
        taken = datetime.datetime.strptime(record["captured"], "%Y-%m-%dT%H:%M:%S%z").timestamp()
    except (KeyError, TypeError, ValueError):
        taken = None
    return settings or None, taken


def calibration_warnings(profile_path: str | os.PathLike, image_path: str | os.PathLike) -> list[str]:
    """``profile_warnings`` for estimating ``image_path`` with the profile at ``profile_path``: against
    the capture's own settings and time when a rig record sits beside the image, else against now."""
    settings, taken = capture_settings(image_path)
    return profile_warnings(load_profile(profile_path), settings, taken)
