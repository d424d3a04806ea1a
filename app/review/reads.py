"""Reading a session's records and captures back for the review. Disk and colour work: run in the
review model's works, off the UI thread, never by the model's own methods."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hairdigi.app.review.payloads import CaptureRead, Entry, HairModel, Problem, Records
from hairdigi.app.session import rig_session as rs
from hairdigi.inference.calibration import apply_profile
from hairdigi.inference.preprocess import to_linear
from hairdigi.render.domain.records import EstimateRecord
from hairdigi.render.hairfile import hair_model_strands, model_summary
from hairdigi.render.srgb import linear_to_srgb8


def read_records(folder, generation: int = 0) -> Records:
    """The session's result records, oldest first; an unreadable one is named in ``left_out``."""
    entries, left_out = [], []
    for capture_id, record in rs.load_results(folder):
        if isinstance(record, str):     # unreadable: named, and the others still listed
            left_out.append(f"capture {capture_id} is left out: {record}")
        else:
            entries.append(Entry(capture_id, record))
    return Records(tuple(entries), tuple(left_out), generation)


def read_capture(session: rs.RigSession, capture_id: str, same_capture: bool = False,
                 generation: int = 0) -> CaptureRead | Problem:
    """A saved capture with its own calibration profile, as the review shows it; a :class:`Problem`
    when its image cannot be read."""
    try:
        loaded = session.load_capture(capture_id)
    except (FileNotFoundError, OSError, ValueError) as exc:
        return Problem(str(exc))
    rec = loaded.record if loaded.record is not None else EstimateRecord(hair=None)
    x, y, w, h = loaded.roi
    frame_size = (loaded.frame.shape[1], loaded.frame.shape[0])
    real = loaded.frame[y:y + h, x:x + w].copy() if rec.hair is None else loaded.corrected_swatch()
    return CaptureRead(capture_id, rec, real, tuple(loaded.roi), frame_size, light_swatches(loaded),
                       tuple(loaded.problems), same_capture, generation)


def light_swatches(loaded: rs.LoadedCapture) -> tuple[np.ndarray | None, ...]:
    """Each light's own frame of the capture's swatch area, corrected with the capture's profile and
    divided by its exposure factor (on the all-lights frame's scale, as the twin lit by that light
    alone renders it), as 8-bit sRGB; None where a frame is unreadable; empty for older captures."""
    x, y, w, h = loaded.roi
    exposures = tuple(loaded.light_exposures)
    out = []
    for i, frame in enumerate(loaded.light_frames):
        if frame is None:
            out.append(None)
            continue
        crop = frame[y:y + h, x:x + w]
        linear = to_linear(crop) if loaded.profile is None else apply_profile(crop, loaded.profile)
        factor = float(exposures[i]) if i < len(exposures) and exposures[i] else 1.0
        out.append(linear_to_srgb8(np.asarray(linear, np.float32) / np.float32(factor)))
    return tuple(out)



def read_hair_model(model: Path, strands: int) -> HairModel:
    """Read, check and fit a ``.hair`` model; a bad file raises its one-line error (HairFileError)."""
    if not model.is_file():
        raise FileNotFoundError(f"{model}: no such .hair file; choose another")
    hair_model_strands(model, strands)        # read once here: the render and the 3-D view reuse it
    return HairModel(model, model_summary(model, strands))
