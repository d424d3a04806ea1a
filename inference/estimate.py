"""From a colour-corrected image to hair parameters and the one record written beside every estimate.

The steps: find the swatch crop, run the encoder (``inference.encoder``), refine by synthesis so the
swatch re-renders with the crop's mean colour (``inference.refine``), attach measured intervals
(``inference.uncertainty``), and collect warnings: out-of-domain inputs (``inference.domain``), a
colour no Table 1 hair renders, parameters at the edge of the range, a stale calibration. ``hairdigi
estimate``, ``hairdigi rig`` and the app all go through :func:`estimate_image` and :func:`record`.
"""
from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hairdigi.inference.domain import domain_stats, domain_warnings
from hairdigi.inference.encoder import Encoder, Estimate
from hairdigi.inference.preprocess import Roi, read_image, swatch_crop
from hairdigi.inference.refine import Refinement, RefineSettings, mean_linear, refine
from hairdigi.inference.uncertainty import intervals, load_table
from hairdigi.render.base.version import version
from hairdigi.render.base.params import HairParams
from hairdigi.render.base.rig_geometry import RIG_SWATCH_POSE, CameraPose
from hairdigi.resources import MODELS

UNCERTAINTY_TABLE = MODELS / "uncertainty.json"


@dataclass
class EstimateResult:
    """Everything one estimate produced: the final parameters and how they were reached."""

    params: HairParams                   # refined when refinement ran, else the encoder's
    encoder: Estimate
    refinement: Refinement | None
    warnings: list[str] = field(default_factory=list)
    domain: dict = field(default_factory=dict)
    uncertainty: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def reliable(self) -> bool:
        """False when a warning says the input is not a swatch the encoder knows."""
        return not any(w.startswith(("out of domain", "unreachable")) for w in self.warnings)


def estimate_image(image: np.ndarray, encoder: Encoder, roi: Roi | None = None,
                   camera: CameraPose = RIG_SWATCH_POSE, refine_colour: bool = True,
                   settings: RefineSettings = RefineSettings(), extra_warnings: list[str] | None = None,
                   renderer=None) -> EstimateResult:
    """Estimate an 8-bit, colour-corrected RGB image (a rig frame or an all-hair crop).

    ``camera`` is the pose from which the camera sees the swatch (the rig's by default); the
    refinement renders the swatch from there.
    """
    start = time.perf_counter()
    crop, roi = swatch_crop(image, roi)
    est = encoder.estimate(image, roi)
    stats = domain_stats(crop)
    spread = max(est.view_spread.values()) if est.view_spread else None
    warnings = domain_warnings(stats, spread)
    refinement = None
    params = est.params
    if refine_colour:
        refinement = refine(est.params, mean_linear(crop), camera, settings, renderer)
        params = refinement.params
        if not refinement.reachable:
            warnings.append(f"unreachable: no Table 1 hair renders this swatch's colour (residual ΔE2000 "
                            f"{refinement.residual_de2000:.2f}); the parameters are the nearest colour")
    if est.at_range_edge:
        warnings.append(f"at the edge of the range: {', '.join(est.at_range_edge)} (the encoder pressed "
                        "against the limit of what it was trained on)")
    warnings += list(extra_warnings or [])
    return EstimateResult(params, est, refinement, warnings, stats.to_dict(),
                          intervals(params, load_table(UNCERTAINTY_TABLE)), time.perf_counter() - start)


def record(result: EstimateResult, encoder: Encoder, image_bytes: bytes | None = None,
           image_path: str | os.PathLike | None = None, calibration: dict | None = None,
           camera: CameraPose = RIG_SWATCH_POSE, **extra) -> dict:
    """The JSON record of an estimate: parameters, warnings, intervals and provenance."""
    est = result.encoder
    provenance = {
        "hairdigi_version": version(),
        "model": {"path": str(encoder.path), "sha256": encoder.sha256, "input_size": encoder.input_size},
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "roi": None if est.roi is None else [est.roi.x, est.roi.y, est.roi.w, est.roi.h],
        "camera": {"polar_deg": camera.polar_deg, "azimuth_deg": camera.azimuth_deg, "distance": camera.distance},
        "encoder_ms": round(est.seconds * 1000.0, 3),
        "seconds": round(result.seconds, 3),
        "calibration": calibration,
        "domain": result.domain,
    }
    if image_path is not None:
        provenance["image"] = str(image_path)
    if image_bytes is not None:
        provenance["image_sha256"] = hashlib.sha256(image_bytes).hexdigest()
    provenance.update(extra)
    return {"hair": result.params.to_dict(),
            "reliable": result.reliable,
            "warnings": list(result.warnings),
            "uncertainty": result.uncertainty,
            "encoder": {"hair": est.params.to_dict(), "at_range_edge": est.at_range_edge,
                        "view_spread": est.view_spread},
            "refinement": result.refinement.to_record() if result.refinement else {"ran": False},
            "provenance": provenance}


def calibration_summary(profile: dict, path: str | os.PathLike | None = None) -> dict:
    """What an estimate records of the calibration profile it was corrected with."""
    summary = {"id": profile.get("id"), "method": profile.get("method"),
               "delta_e2000_after": profile.get("delta_e2000", {}).get("after")}
    if path is not None:
        summary["path"] = str(path)
    return summary


def estimate_file(image_path: str | os.PathLike, encoder: Encoder, roi: Roi | None = None,
                  calibration_path: str | os.PathLike | None = None, camera: CameraPose = RIG_SWATCH_POSE,
                  refine_colour: bool = True, settings: RefineSettings = RefineSettings()
                  ) -> tuple[EstimateResult, dict, np.ndarray]:
    """Read, colour-correct (when a calibration profile is given) and estimate; returns the result,
    its JSON record and the corrected image."""
    image_path = Path(image_path)
    image = read_image(image_path)
    calibration, stale = None, []
    if calibration_path is not None:
        from hairdigi.inference.calibration import apply_profile, calibration_warnings, load_profile

        profile = load_profile(calibration_path)
        image = apply_profile(image, profile)
        calibration = calibration_summary(profile, calibration_path)
        # against the capture's own settings and time when the rig's record sits beside the image
        stale = calibration_warnings(calibration_path, image_path)
    result = estimate_image(image, encoder, roi, camera, refine_colour, settings, stale)
    return result, record(result, encoder, image_path.read_bytes(), image_path, calibration, camera), image
