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

import datetime
import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import colour
import cv2
import numpy as np

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import CalibrationProfile, CaptureRecord, read_record, write_record
from hairdigi.render.chart import WHITE_PATCH, colorchecker_reflectances, rig_chart_targets
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear, to_linear

METHODS = ("Cheung 2004", "Finlayson 2015", "Vandermonde")
DEFAULT_METHOD = "Finlayson 2015"
STALE_AFTER_S = 8 * 3600   # a shift: recalibrate every morning


class CalibrationError(HairdigiError, RuntimeError):
    """Calibration cannot proceed; the message says why and what to do."""


@dataclass
class ChartDetection:
    patches_srgb8: np.ndarray   # (24, 3) mean 8-bit sRGB of each patch, in the standard order
    box: np.ndarray             # (4, 2) corners of the chart in pixels
    cost: float
    quads: np.ndarray | None = None   # (24, 4, 2) corners of each patch in pixels

    def patch_linear(self, linear: np.ndarray, inset: float = 0.6) -> np.ndarray:
        """(24, 3) mean linear RGB of each patch's central ``inset``, averaged in linear light.

        Averaging 8-bit codes and then linearising (as ``cv2.mcc``'s own means do) reads a noisy
        patch dark; the mean of the linearised pixels is the light that reached the sensor.
        """
        if self.quads is None:
            return srgb8_to_linear(self.patches_srgb8)
        out = np.empty((24, 3))
        for i, quad in enumerate(self.quads):
            centre = quad.mean(0)
            inner = centre + inset * (quad - centre)
            mask = np.zeros(linear.shape[:2], np.uint8)
            cv2.fillConvexPoly(mask, np.round(inner).astype(np.int32), 1)
            pixels = linear[mask.astype(bool)]
            out[i] = pixels.mean(0) if len(pixels) else srgb8_to_linear(self.patches_srgb8[i])
        return out

    def white_patch_box(self) -> tuple[int, int, int, int]:
        """A box (x, y, w, h) inside the chart's white patch."""
        x0, y0 = self.quads[WHITE_PATCH].min(0) if self.quads is not None else self.box.min(0)
        x1, y1 = self.quads[WHITE_PATCH].max(0) if self.quads is not None else self.box.max(0)
        cx, cy, half = (x0 + x1) / 2, (y0 + y1) / 2, 0.25 * (x1 - x0)
        return int(cx - half), int(cy - half), max(1, int(2 * half)), max(1, int(2 * half))


def detect_chart(image_rgb8: np.ndarray) -> ChartDetection:
    """Find a 24-patch ColorChecker with ``cv2.mcc``; raises ``CalibrationError`` when none is found.

    ``cv2.mcc`` occasionally fails an internal assertion on a frame that holds a chart (about one
    simulated frame in twenty, and RAW stills at twice the feed's size); the frame is then searched
    again at half size, and the patches' corners scaled back.
    """
    for scale in (1, 2):
        image = image_rgb8 if scale == 1 else cv2.resize(image_rgb8, None, fx=0.5, fy=0.5,
                                                          interpolation=cv2.INTER_AREA)
        try:
            found = _detect(image)
        except cv2.error:
            found = None
        if found is not None:
            means, box, cost, quads = found
            if scale != 1:   # the means are re-read at full size from the scaled patch corners
                box, quads = box * scale, None if quads is None else quads * scale
                detection = ChartDetection(means, box, cost, quads)
                if quads is not None:
                    means = linear_to_srgb8(detection.patch_linear(to_linear(image_rgb8))).astype(float)
            return ChartDetection(means, box, cost, quads)
    raise CalibrationError("no ColorChecker found: put the 24-patch chart flat in view, fully lit, "
                           "without glare, and try again")


def _detect(image_rgb8: np.ndarray):
    detector = cv2.mcc.CCheckerDetector.create()
    detector.setColorChartType(cv2.mcc.MCC24)
    if not detector.process(np.ascontiguousarray(image_rgb8[..., ::-1]), 1):
        return None
    checker = detector.getBestColorChecker()
    stats = np.asarray(checker.getChartsRGB())          # (72, 5): per patch and channel: size, mean, sd, max, min
    quads = np.asarray(checker.getColorCharts(), float)
    return (stats[:, 1].reshape(24, 3), np.asarray(checker.getBox(), float), float(checker.getCost()),
            quads.reshape(24, 4, 2) if quads.size == 24 * 4 * 2 else None)


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


def calibrate(image: np.ndarray, method: str = DEFAULT_METHOD, degree: int = 1,
              settings: dict | None = None, linear: np.ndarray | None = None) -> CalibrationProfile:
    """Detect the chart in the 8-bit ``image``, fit the CCM on its patches in linear light (from
    ``linear``, the same view as linear RGB, when the source has it: a RAW still), and return the
    profile (not yet saved)."""
    detection = detect_chart(image)
    if (detection.patches_srgb8 >= 254).any():
        raise CalibrationError("chart patches are clipped: lower the exposure, then calibrate again")
    targets, source = rig_chart_targets()
    measured = detection.patch_linear(to_linear(image) if linear is None else linear)
    ccm = fit_ccm(measured, targets, method, degree)
    corrected = correct_linear(measured, ccm, method, degree)
    s = _perceptual_scale(targets)
    shift = delta_e2000(measured * s, corrected * s)
    data = {
        "method": method, "degree": degree, "matrix": ccm.tolist(),
        "delta_e2000": {"before": delta_e_stats(measured, targets), "after": delta_e_stats(corrected, targets),
                        "patch_shift_max": float(shift.max())},
        "targets": source, "chart_box": detection.box.tolist(), "detection_cost": detection.cost,
        "time": time.time(), "time_iso": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "settings": settings or {},
        "patches": np.asarray(measured, float).round(7).tolist(),
    }
    data["id"] = hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:12]
    return CalibrationProfile.from_json(data)


#: Pixels corrected at once: bounds the float64 temporaries of a large frame to about 100 MB.
APPLY_CHUNK_PIXELS = 1 << 20


def apply_profile(image: np.ndarray, profile: CalibrationProfile) -> np.ndarray:
    """Colour-correct an image (8-bit sRGB, or linear float) with a profile: linear float32 RGB out.

    The result stays linear and unquantised all the way to the estimate: hair is dark (linear
    0.02-0.2), where 8-bit sRGB codes are coarse (in row chunks, to bound memory). It is **not clipped
    at 0**: a camera whose bands overlap has a CCM with large negative coefficients (the Sigma SD
    Merrill's reach -7), which turns a dark pixel's noise into negative values; clipping them biased a
    dark swatch's mean up by 20-45% in blue (``hairdigi evaluate --spectral``). Means are taken on the
    unclipped values; what shows or encodes an image clips there.
    """
    ccm = np.asarray(profile.matrix)
    out = np.empty(image.shape, np.float32)
    rows = max(1, APPLY_CHUNK_PIXELS // max(1, image.shape[1]))
    for y in range(0, image.shape[0], rows):
        out[y:y + rows] = correct_linear(to_linear(image[y:y + rows]), ccm, profile.method, profile.degree)
    return out


def correction_warnings(profile: CalibrationProfile, raw_linear: np.ndarray, corrected_linear: np.ndarray,
                        max_after_de: float = 1.5, margin_de: float = 1.0) -> list[str]:
    """Warnings when the calibration may not fit the hair: a large residual on the chart, or a CCM
    that moves the hair's mean colour more than it moved any chart patch (the hair then lies
    outside what the chart constrains)."""
    warnings = []
    after = profile.after_mean
    if after is not None and after > max_after_de:
        warnings.append(f"calibration: the chart's residual after correction is ΔE2000 {after:.2f} (over "
                        f"{max_after_de}): the correction does not fit this camera and light; check the chart "
                        f"is flat, evenly lit and unclipped, then calibrate again")
    patch_shift = profile.delta_e2000.get("patch_shift_max")
    if patch_shift is not None:
        s = _perceptual_scale(rig_chart_targets()[0])
        hair_shift = float(delta_e2000(np.asarray(raw_linear) * s, np.asarray(corrected_linear) * s))
        if hair_shift > patch_shift + margin_de:
            warnings.append(f"calibration: the correction moves the hair's colour by ΔE2000 {hair_shift:.1f}, more "
                            f"than any chart patch ({patch_shift:.1f}): the hair lies outside what the chart "
                            f"constrains; check the camera's white balance and exposure, then calibrate again")
    return warnings


def save_profile(path: str | os.PathLike, profile: CalibrationProfile) -> Path:
    return write_record(path, profile)


def load_profile(path: str | os.PathLike) -> CalibrationProfile:
    """Read a saved profile (either layout); a missing, malformed or corrupt one raises
    CalibrationError naming the file and the field."""
    path = Path(path)
    try:
        profile = read_record(path, CalibrationProfile)
    except RecordError as exc:
        text = str(exc)
        hint = "calibrate the rig first" if "no such" in text else "calibrate again"
        raise CalibrationError(f"{text}; {hint}") from None
    try:
        check_profile(profile)
    except CalibrationError as exc:
        raise CalibrationError(f"{path}: {exc}") from None
    return profile


def check_profile(profile: CalibrationProfile) -> None:
    """Raise CalibrationError when the profile's method is unknown or its matrix does not fit it."""
    def bad(field: str, what: str) -> CalibrationError:
        return CalibrationError(f"the profile's {field!r} {what}; calibrate again")

    if profile.method not in METHODS:
        raise bad("method", f"is {profile.method!r}, not one of {', '.join(METHODS)}")
    try:
        out = correct_linear(np.full((1, 3), 0.5), np.asarray(profile.matrix, float), profile.method, profile.degree)
    except Exception:   # colour-science raises several types for a matrix of the wrong width
        out = None
    if out is None or not np.all(np.isfinite(out)):
        raise bad("matrix", f"does not fit method {profile.method!r} at degree {profile.degree}")
    if not np.any(np.asarray(profile.matrix)):
        raise bad("matrix", "is all zeros (it would make every image black)")


def staleness(profile: CalibrationProfile, settings: dict | None = None, now: float | None = None,
              max_age_s: float = STALE_AFTER_S) -> list[str]:
    """Reasons the profile should be renewed: age, or camera/light settings that changed since."""
    reasons = []
    age = (now or time.time()) - profile.time
    if age > max_age_s:
        reasons.append(f"the calibration is {age / 3600:.1f} h old (limit {max_age_s / 3600:.0f} h)")
    if settings is not None:
        changed = sorted(k for k in set(settings) | set(profile.settings)
                         if settings.get(k) != profile.settings.get(k))
        if changed:
            reasons.append(f"settings changed since calibration: {', '.join(changed)}")
    return reasons


def profile_warnings(profile: CalibrationProfile, current_settings: dict | None = None, now: float | None = None) -> list[str]:
    """Human-readable warnings for a profile that should be renewed (the rule is ``staleness``), each
    with the fix; ``now`` is when the image was taken (default: now)."""
    now = time.time() if now is None else now
    warnings = [f"calibration: {reason}; calibrate again with the chart in view"
                for reason in staleness(profile, current_settings, now)]
    if profile.time > now + 300:
        warnings.append(f"calibration: the profile is dated {(profile.time - now) / 3600:.1f} h after "
                        f"the image; check the computer's clock, then calibrate again")
    return warnings


def capture_settings(image_path: str | os.PathLike) -> tuple[dict | None, float | None]:
    """The settings and time of a rig capture, from its capture record saved beside it (None, None
    for an image without one): the same keys as ``RigSession.settings``, to compare with a profile's."""
    image_path = Path(image_path)
    try:
        record = read_record(image_path.with_suffix(".json"), CaptureRecord)
        if record.image_sha256 != hashlib.sha256(image_path.read_bytes()).hexdigest():
            return None, None    # not this image's record
    except (OSError, RecordError):
        return None, None
    frame = record.frame_meta
    settings = {}
    if "camera" in frame:
        settings["camera"] = frame["camera"]
        camera = frame.get("camera_settings")
        model = frame.get("camera_model")       # records made before cameras reported their settings
        if isinstance(camera, dict):
            settings.update(camera)
        elif isinstance(model, dict):
            settings.update({k: v for k, v in model.items() if k in ("exposure_ev", "gain")})
    if record.lights is not None:
        settings["lights"] = record.lights
    try:
        taken = datetime.datetime.strptime(record.captured, "%Y-%m-%dT%H:%M:%S%z").timestamp()
    except ValueError:
        taken = None
    return settings or None, taken


def calibration_warnings(profile_path: str | os.PathLike, image_path: str | os.PathLike) -> list[str]:
    """``profile_warnings`` for estimating ``image_path`` with the profile at ``profile_path``: against
    the capture's own settings and time when a rig record sits beside the image, else against now."""
    settings, taken = capture_settings(image_path)
    return profile_warnings(load_profile(profile_path), settings, taken)


#: The chart's mid greys (neutral 6.5 to 3.5, ColorChecker Classic order): lit well by any one light.
MID_GREYS = (19, 20, 21, 22)


def light_colour_warnings(chart: ChartDetection, singles: list[np.ndarray], tolerance_de: float = 2.0) -> list[str]:
    """Warnings for a light whose own frame turns the chart's mid greys another colour than the other
    lights' frames do: that LED differs from the others, and one profile for all does not hold for it.

    One profile serves every light (the rig's LEDs are one make, and a profile fitted on the chart lit
    from one side folds that light's geometry into the colour); this checks that it holds, per light.
    ``singles``: each light's frame as the camera read it (linear, uncorrected). Each light's greys are
    judged against the lights' median grey (per patch and channel, at that light's lightness), so the
    odd light out is named and not the others, whose mean it shifts. Judged after a 3 x 3 correction
    instead, a camera whose bands overlap (the Sigma SD Merrill's coefficients reach -7) turns the
    patches' noise into tints of ΔE2000 1-18 and warned about every light; uncorrected, 0.2-1.9.
    """
    greys = [chart.patch_linear(frame)[list(MID_GREYS)] for frame in singles]
    levels = [g.mean(1, keepdims=True) for g in greys]
    usual = np.median([g / np.maximum(level, 1e-9) for g, level in zip(greys, levels)], axis=0)
    warnings = []
    for i, (g, level) in enumerate(zip(greys, levels)):
        off = float(np.median(delta_e2000(np.clip(g, 1e-6, None), np.clip(usual * level, 1e-6, None))))
        if off > tolerance_de:
            warnings.append(f"calibration: light {i} tints the chart's greys by ΔE2000 {off:.1f} against the other "
                            f"lights: its LED differs from the others, so the shine read from it is uncertain; "
                            f"replace it or match its colour, and calibrate again")
    return warnings
