"""The review model's events and their payloads, free of Qt: small frozen dataclasses, one per kind of value
the review's works hand back and its events carry.

The event machinery (``Event``, ``EventGroup``) and the :class:`~hairdigi.app.models.events.Status` line
every model shares are ``app/models/events.py``'s; what is here is the review's alone. Widgets subscribe
with ``model.events.twin.connect(callback)``.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hairdigi.app.models.events import EventGroup, Status
from hairdigi.app.review.previews import HairstylePass, Stage, TwinPreview
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import CalibrationProfile, EstimateRecord, EstimateWarning

if TYPE_CHECKING:
    from hairdigi.app.session.rig_session import CaptureResult


@dataclass(frozen=True)
class Problem:
    """One line naming a problem and its fix (the window's banner)."""

    text: str


@dataclass(frozen=True)
class Entry:
    """One capture of the session: its id and its result record."""

    id: str
    record: EstimateRecord

    @property
    def title(self) -> str:
        """A session-list line: the capture id and its estimate, or why there is none."""
        h = self.record.hair
        if h is None:
            return f"{self.id}  (blocked)"
        return f"{self.id}  rgb {[round(v) for v in h.dye_rgb]}  mel {h.melanin_concentration:.2f}"


@dataclass(frozen=True)
class Records:
    """The session's result records, oldest first, read off the model's thread; ``left_out``: one line
    per record that could not be read (the others are still listed)."""

    entries: tuple[Entry, ...]
    left_out: tuple[str, ...] = ()
    generation: int = 0


@dataclass(frozen=True)
class CaptureRead:
    """A saved capture read back for review, off the model's thread: its record (``hair`` None when
    blocked or unsaved), the swatch shown (corrected with its own profile), and each light's frame."""

    capture_id: str
    record: EstimateRecord
    real: np.ndarray
    roi: tuple[int, int, int, int]
    frame_size: tuple[int, int]
    light_frames: tuple
    problems: tuple[str, ...] = ()
    same_capture: bool = False      # the capture whose first look is shown, now with its record
    generation: int = 0


def record_appearance(record: EstimateRecord | None) -> Appearance:
    """The appearance a record's previews render with: its estimate's, or the default (uniform hair)."""
    if record is None or record.appearance is None:
        return DEFAULT_APPEARANCE
    return record.appearance.value


@dataclass(frozen=True)
class Shown:
    """The capture under review: its corrected swatch, its parameters and where they came from."""

    capture_id: str | None          # None for the encoder's first look, before the record is written
    real: np.ndarray                # (h, w, 3) uint8 sRGB swatch, corrected with the capture's own profile
    roi: tuple[int, int, int, int]
    frame_size: tuple[int, int]     # (width, height) of the rig view
    params: HairParams | None
    stage: Stage
    record: EstimateRecord | None = None   # None for the first look
    simulated: bool = True
    key: int = 0                    # one per capture under review: its first look and refined estimate share it
    #: each light's own frame of the swatch area, corrected with the capture's profile and put on the
    #: all-lights frame's exposure (8-bit sRGB; None where unreadable); empty: the capture has none
    light_frames: tuple = ()

    @property
    def appearance(self) -> Appearance:
        """The estimate's shine, fibre spread and grey share (the defaults where there is none)."""
        return record_appearance(self.record)

    @property
    def twin_hair(self) -> HairParams | np.ndarray | None:
        """What the twin renders: where the answer was mapped to another structure's (the family's mean), the
        sigma_a fitted on the structure the estimate was read on, which renders this capture there; else the
        parameters."""
        refinement = None if self.record is None else self.record.refinement
        if refinement is not None and refinement.fitted_sigma_a is not None:
            return np.asarray(refinement.fitted_sigma_a, float)
        return self.params

    @property
    def swatch_model(self) -> str | None:
        """The swatch structure the estimate was read on (None: the default)."""
        refinement = None if self.record is None else self.record.refinement
        region = None if refinement is None else refinement.region
        return None if region is None else region.swatch_model


#: Review keys: one per capture under review, unique in the process.
KEYS = itertools.count(1)


@dataclass(frozen=True)
class Warnings:
    """The shown capture's warnings from its previews (a NaN in a pass)."""

    items: tuple[EstimateWarning, ...]


@dataclass(frozen=True)
class View:
    """The hairstyle, environment, orbit, light or hair file changed: its label ("straight, studio")."""

    label: str


@dataclass(frozen=True)
class LightView:
    """The light the capture and its twin are compared under (None: all lights)."""

    light: int | None


@dataclass(frozen=True)
class Display:
    """Denoised (True) or raw passes shown."""

    denoised: bool


@dataclass(frozen=True)
class FeedRate:
    """The rate the live feed should run at now (frames per second)."""

    fps: float


@dataclass(frozen=True)
class StrandPreview:
    """The strands and colours of the 3-D view."""

    of: tuple                       # (style or hair file, strands): what the strands are of
    strands: object                 # render.strands.Strands
    colour_rgb8: tuple[int, int, int]
    scalp_linear: tuple[float, float, float] | None = None   # the renderer's scalp colour (linear)


@dataclass(frozen=True)
class FrameCheck:
    """The chart outline and exposure of a recent frame."""

    chart_box: np.ndarray | None    # the chart's corners in the frame, or None when not found
    exposure: list | None           # hardware.exposure.ExposureReport, swatch first; None: the frame was unreadable


@dataclass(frozen=True)
class Warmed:
    """The preview scenes are built (captures now only update parameters): what each cost to build."""

    seconds: dict


@dataclass(frozen=True)
class HairModel:
    """A ``.hair`` model read, checked and fitted to the head: ready to render."""

    path: Path
    summary: str


@dataclass(frozen=True)
class Captured:
    """A capture saved, with the session's records and the capture as read back after it (off the UI
    thread; ``read`` a :class:`Problem` when the capture could not be read back)."""

    result: CaptureResult
    records: Records | None = None
    read: CaptureRead | Problem | None = None


@dataclass(frozen=True)
class Calibrated:
    """A new calibration profile."""

    profile: CalibrationProfile


@dataclass(frozen=True)
class Lights:
    """The light board: each light on or off, what it says it is, and where."""

    on: tuple[bool, ...]
    identity: str
    port: str


@dataclass(frozen=True)
class Thumbnail:
    """A capture's small picture, read off the model's thread."""

    capture_id: str
    rgb: np.ndarray | None          # None: its image is missing


@dataclass(frozen=True)
class FirstLook:
    """The encoder's parameters, before refinement: what the operator sees within a second."""

    params: HairParams
    real: np.ndarray
    roi: tuple[int, int, int, int]
    frame_size: tuple[int, int]
    key: int


class Events(EventGroup):
    """The review model's events; each carries the new value of the state it names."""

    EVENTS = {"records": Records,          # the session's result records
              "thumbnail": Thumbnail,
              "shown": Shown,              # the capture under review (or its first look, before its record)
              "parameters": Shown,         # new parameters to preview (start the twin and hairstyle work)
              "twin": TwinPreview,
              "hairstyle": HairstylePass,
              "warnings": Warnings,
              "view": View,                # start the hairstyle work
              "hair_model": HairModel,     # a .hair file opened (the view follows)
              "strands": StrandPreview,
              "calibration": Calibrated,
              "lights": Lights,
              "feed_fps": FeedRate,
              "warmed": Warmed,
              "frame_check": FrameCheck,
              "display": Display,
              "light_view": LightView,
              "status": Status,
              "error": Problem}
