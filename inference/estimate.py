"""Estimate hair parameters from an image file, with provenance, as ``hairdigi estimate`` does."""
from __future__ import annotations

import hashlib
import os
import time
from pathlib import Path

import numpy as np

from inference.encoder import Encoder, Estimate
from inference.preprocess import Roi, read_image


def provenance(estimate: Estimate, encoder: Encoder, image_bytes: bytes | None = None,
               image_path: str | os.PathLike | None = None, calibration: dict | None = None,
               **extra) -> dict:
    """The record written beside every estimate: what model, what image, what calibration, when."""
    record = {
        "model": {"path": str(encoder.path), "sha256": encoder.sha256, "input_size": encoder.input_size},
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "roi": None if estimate.roi is None else [estimate.roi.x, estimate.roi.y, estimate.roi.w, estimate.roi.h],
        "at_range_edge": estimate.at_range_edge,
        "uncertainty": estimate.uncertainty,
        "encoder_ms": round(estimate.seconds * 1000.0, 3),
        "calibration": calibration,
    }
    if image_path is not None:
        record["image"] = str(image_path)
    if image_bytes is not None:
        record["image_sha256"] = hashlib.sha256(image_bytes).hexdigest()
    record.update(extra)
    return record


def estimate_file(image_path: str | os.PathLike, encoder: Encoder, roi: Roi | None = None,
                  calibration_path: str | os.PathLike | None = None) -> tuple[Estimate, dict, np.ndarray]:
    """Read, colour-correct (when a calibration profile is given) and estimate; returns the estimate,
    its JSON record (``{"hair": ..., "provenance": ...}``) and the corrected image."""
    image_path = Path(image_path)
    image = read_image(image_path)
    calibration = None
    if calibration_path is not None:
        from inference.calibration import apply_profile, load_profile

        profile = load_profile(calibration_path)
        image = apply_profile(image, profile)
        calibration = {"path": str(calibration_path), "id": profile.get("id"), "method": profile.get("method"),
                       "delta_e2000_after": profile.get("delta_e2000", {}).get("after")}
    estimate = encoder.estimate(image, roi)
    record = {"hair": estimate.params.to_dict(),
              "provenance": provenance(estimate, encoder, image_path.read_bytes(), image_path, calibration)}
    return estimate, record, image
