"""The review of captures, free of Qt: what the window shows, and the work behind it.

napari-style. :class:`ReviewModel` holds the review state: the session's records, the shown capture
(with its own calibration profile), its parameters, the twin preview (real, synthetic raw and
denoised, the ΔE2000 map, the mean-colour ΔE2000), the hairstyle choice, camera orbit and passes, the
strand preview, the lights and the feed rate, and the light the capture and its twin are compared
under (all lights, or one alone: :meth:`ReviewModel.set_light_view`). Widgets subscribe to its events
(``model.events.twin.connect(callback)``) and read its views (:meth:`ReviewModel.parameter_view`).

Long work is a :class:`Work`: a generator function whose yields are progress and whose return is the
result, as napari's ``thread_worker``. A worker runs it and hands each value to
:meth:`ReviewModel.apply` on the model's thread, the only thread that changes the model's state; it
stops at a yield when cancelled, and calls ``Work.ended`` on the model's thread at the end.
:func:`run_now` does the same in the calling thread (tests, headless use). A new capture, a new
selection or new parameters bump the model's generation: stale work stops before its next pass, and
whatever it still yields is dropped.

The order after a capture: the capture's work yields the encoder's estimate (the first look, from the
session's ``on_encoder_estimate`` hook) and its first twin and hairstyle passes, then the refined
record; the refined estimate's twin renders until it is clean, and only then its hairstyle passes
take turns with it. The scenes are built by :meth:`ReviewModel.warm_work` when the window opens, so a
capture only updates parameters. Every render in the process takes one lock
(``render.renderer.RENDER_LOCK``).

Why one module of about 1,100 lines: :class:`ReviewModel` (about 630 of them) is one state machine
whose works and appliers read and change the same state, and its two rules (only ``apply`` changes
state, on the model's thread; stale work is dropped by generation) hold only if every work and every
applier is checked against them together. The records and view functions above it are its
vocabulary, the words the window and the tests read it through; moved out, each would still be
read only beside the class.
"""
from __future__ import annotations

import dataclasses
import itertools
import queue
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Generator

import numpy as np

from hairdigi.app.session import rig_session as rs
from hairdigi.app.review.events import EventGroup
from hairdigi.app.review.previews import (HairstylePass, PassTag, PreviewSettings, Stage, TwinPreview,
                                          hair_colour_rgb8, hairstyle_passes, orbit_pose, scalp_linear,
                                          scene_appearance, strand_colour, twin_passes, twin_view)
from hairdigi.render import denoise as dn
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance, AppearanceEstimate
from hairdigi.render.domain.bounds import ILLUMINANTS, SceneKind
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.estimate_parts import Uncertainty
from hairdigi.render.domain.params import VECTOR_FIELDS, HairParams
from hairdigi.render.domain.records import CalibrationProfile, EstimateRecord, EstimateWarning, WarningKind
from hairdigi.render.domain.rig_geometry import N_LIGHTS
from hairdigi.render.domain.session_folder import SessionFolder
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.srgb import linear_to_srgb8

#: ``set_view``'s "leave this as it is" (None is a value of its ``illuminant``).
KEEP: object = object()
#: The lights a hairstyle can be seen under: (label, ``SceneSpec.illuminant``); None is the RGB world's white.
HAIRSTYLE_LIGHTS = (("rig lights (RGB)", None), ("daylight (D65)", "D65"), ("tungsten (A)", "A"),
                    ("shop LED (LED-B3)", "shop-led"), ("fluorescent (FL11)", "FL11"))

__all__ = ["Events", "ReviewModel", "Work", "run_now", "Shown", "Stage", "PreviewSettings", "TwinPreview",
           "HairstylePass", "ParameterView", "Entry", "hair_colour_rgb8", "appearance_lines", "light_name"]

Cancelled = Callable[[], bool]


class ReviewError(HairdigiError, ValueError):
    """What the review cannot do for the operator now (nothing to export yet), with what to do."""


# --- work ------------------------------------------------------------------------------------------
@dataclass
class Work:
    """A generator function run by a worker: its yields are progress, its return value the result.

    ``ended`` (when given) runs on the model's thread once the work is over: done, failed or cancelled.
    """

    name: str
    run: Callable[[], Generator[object, None, object]]
    ended: Callable[[], None] | None = None


def run_now(work: Work | None, apply: Callable[[object], None], cancelled: Cancelled = lambda: False) -> object:
    """Run ``work`` in this thread, handing what it yields and returns to ``apply``; returns the result."""
    if work is None:
        return None
    result = None
    try:
        generator = work.run()
        while True:
            try:
                value = next(generator)
            except StopIteration as stop:
                result = stop.value
                break
            if cancelled():           # stop at a yield
                generator.close()
                return None
            apply(value)
        if result is not None:
            apply(result)
        return result
    finally:
        if work.ended is not None:
            work.ended()


def _returns(fn: Callable[[], object]) -> Callable[[], Generator[object, None, object]]:
    """A plain function as a work generator that yields nothing."""
    def run():
        return fn()
        yield  # noqa: unreachable: makes this a generator
    return run


# --- events and payloads -----------------------------------------------------------------------------
class Events(EventGroup):
    """The model's events; each carries the new value of the state it names."""

    NAMES = ("records",      # list[Entry]: the session's result records, oldest first
             "thumbnail",    # Thumbnail: a capture's small picture, read off the model's thread
             "shown",        # Shown: the capture under review (or its first look, before its record)
             "parameters",   # Shown: new parameters to preview (start the twin and hairstyle work)
             "twin",         # TwinPreview: a twin pass
             "hairstyle",    # HairstylePass: a hairstyle pass
             "warnings",     # tuple[EstimateWarning]: the shown capture's warnings, previews' included
             "view",         # str: the hairstyle, environment, orbit or hair file changed (start the hairstyle work)
             "hair_model",   # HairModel: a .hair file opened (the view follows)
             "strands",      # StrandPreview: the strands and colours of the 3-D view
             "calibration",  # CalibrationProfile: a new calibration profile
             "lights",       # Lights: the light board's states
             "feed_fps",     # float: the rate the live feed should run at now
             "warmed",       # Warmed: the preview scenes are built (captures now only update parameters)
             "frame_check",  # FrameCheck: the chart outline and exposure of a recent frame
             "display",      # bool: denoised (True) or raw passes shown
             "light_view",   # int | None: the light the capture and its twin are compared under (None: all)
             "status",       # str: one line for the status bar
             "error")        # str: one line naming the problem and the fix


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


@dataclass
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


@dataclass(frozen=True)
class ParameterView:
    """The shown parameters as the window writes them: one line per parameter (with its measured 68%
    interval), the dye chip, and the lines under them (provenance, refinement, warnings)."""

    lines: tuple[tuple[str, str], ...]       # (parameter, "dye_r: 120 ± 14")
    dye_rgb8: tuple[int, int, int] | None
    dye_tooltip: str
    info: str
    appearance: tuple[tuple[str, str], ...] = ()   # (field, "shine β_m: 0.27 (68%: 0.25–0.29)") or "not measured"


@dataclass
class StrandPreview:
    of: tuple                       # (style or hair file, strands): what the strands are of
    strands: object                 # render.strands.Strands
    colour_rgb8: tuple[int, int, int]
    scalp_linear: tuple[float, float, float] | None = None   # the renderer's scalp colour (linear)


@dataclass
class FrameCheck:
    chart_box: np.ndarray | None    # the chart's corners in the frame, or None when not found
    exposure: list | None           # hardware.exposure.ExposureReport, swatch first; None: the frame was unreadable


@dataclass
class Warmed:
    seconds: dict                   # what each scene cost to build and compile


@dataclass
class HairModel:
    """A ``.hair`` model read, checked and fitted to the head: ready to render."""

    path: Path
    summary: str


@dataclass
class Captured:
    result: rs.CaptureResult


@dataclass
class Calibrated:
    profile: CalibrationProfile


@dataclass
class Lights:
    """The light board: each light on or off, what it says it is, and where."""

    on: tuple[bool, ...]
    identity: str
    port: str


@dataclass
class Thumbnail:
    capture_id: str
    rgb: np.ndarray | None          # None: its image is missing


@dataclass
class FirstLook:
    """The encoder's parameters, before refinement: what the operator sees within a second."""

    params: HairParams
    real: np.ndarray
    roi: tuple[int, int, int, int]
    frame_size: tuple[int, int]
    key: int


#: Review keys: one per capture under review, unique in the process.
_KEYS = itertools.count(1)


# --- records and their presentation -----------------------------------------------------------------
def as_profile(profile) -> CalibrationProfile | None:
    """A calibration profile, typed (from a profile or its JSON dict)."""
    if profile is None or isinstance(profile, CalibrationProfile):
        return profile
    return CalibrationProfile.from_json(profile)


def calibration_text(profile: CalibrationProfile | None, status: str, reasons: list[str],
                     now: float | None = None) -> str:
    """One line on the calibration: method, ΔE2000 before and after, age, and why it is stale."""
    if profile is None:
        return "calibration: none — press Calibrate with the chart in view"
    age_min = ((now or time.time()) - profile.time) / 60
    de = profile.delta_e2000
    text = (f"calibration: {profile.method}, ΔE2000 {de['before']['mean']:.2f} → {de['after']['mean']:.2f} "
            f"(max {de['after']['max']:.2f}), {age_min:.0f} min old")
    if reasons:
        text += " — STALE: " + "; ".join(reasons)
    return text


def parameter_lines(params: HairParams, uncertainty: Uncertainty | None) -> tuple[tuple[str, str], ...]:
    """Each Table 1 parameter with its measured 68% interval ("± w"), or "(undetermined)"."""
    intervals = {} if uncertainty is None else uncertainty.parameters
    values = dict(zip([f[0] for f in VECTOR_FIELDS], [*params.dye_rgb, params.dye_concentration,
                                                      params.melanin_concentration, params.melanin_ratio]))
    lines = []
    for name, _, _ in VECTOR_FIELDS:
        fmt = "{:.0f}" if name.startswith("dye_") and name[-1] in "rgb" else "{:.2f}"
        iv = intervals.get(name)
        if iv and not iv.determined:
            u = " (undetermined)"
        elif iv:
            u = f" ± {fmt.format(iv.half_width)}"
        else:
            u = ""
        lines.append((name, f"{name}: {fmt.format(values[name])}{u}"))
    return tuple(lines)


#: The appearance fields as the window names them, and how each value is written.
APPEARANCE_LABELS = {"longitudinal_roughness": ("shine β_m", "{:.2f}"), "fibre_spread": ("fibre spread", "{:.2f}"),
                     "grey_fraction": ("grey share", "{:.0%}")}


def record_appearance(record: EstimateRecord | None) -> Appearance:
    """The appearance a record's previews render with: its estimate's, or the default (uniform hair)."""
    if record is None or record.appearance is None:
        return DEFAULT_APPEARANCE
    return record.appearance.value


def appearance_lines(estimate: AppearanceEstimate | None, pending: bool = False) -> tuple[tuple[str, str], ...]:
    """Shine, fibre spread and grey share, each with its 68% interval when measured, or "not measured"
    (the default the previews render with); ``pending``: the encoder's first look, read at refinement."""
    value = estimate.value if estimate is not None else DEFAULT_APPEARANCE
    measured = estimate.measured if estimate is not None else ()
    lines = []
    for name, (label, fmt) in APPEARANCE_LABELS.items():
        v = fmt.format(getattr(value, name))
        if pending:
            text = f"{label}: – (read by refinement)"
        elif name not in measured:
            text = f"{label}: {v} — not measured (default)"
        else:
            text = f"{label}: {v}" + estimate.interval_text(name, fmt, "–")
        lines.append((name, text))
    return tuple(lines)


def parameter_view(shown: Shown, extra: tuple[EstimateWarning, ...] = ()) -> ParameterView:
    """What the window writes for ``shown``: parameters, the dye chip and the lines under them."""
    rec = shown.record
    if shown.params is None:
        reasons = list(rec.blocked) if rec is not None and rec.blocked else ["none saved"]
        return ParameterView((), None, "", "no estimate: " + "; ".join(reasons))
    p = shown.params
    lines = parameter_lines(p, rec.uncertainty if rec is not None else None)
    tooltip = f"dye colour alone, at concentration {p.dye_concentration:.2f}"
    if shown.stage == Stage.ENCODER or rec is None:
        return ParameterView(lines, tuple(int(v) for v in p.dye_rgb), tooltip,
                             "encoder's estimate; refining by synthesis…", appearance_lines(None, pending=True))
    info = [f"model {rec.provenance.model_sha256[:12]}, calibration {rec.provenance.calibration_id}"]
    if rec.refinement.ran:
        residual = rec.refinement.residual_de2000   # None in a record written without it
        info.append(f"refined in {rec.refinement.seconds:.1f} s: residual ΔE2000 "
                    + ("not recorded" if residual is None else f"{residual:.2f}"))
    colour = rec.uncertainty.mean_colour_de2000_p68
    if colour is not None:
        info.append(f"colour within ΔE2000 {colour:.2f} of the truth in 68% of held-out captures "
                    f"({rec.uncertainty.mean_colour_source or 'held-out clean crop renders'})")
    info += spectral_lines(rec)
    info += [f"⚠ {w.message}" for w in (*rec.warnings, *extra)]
    return ParameterView(lines, tuple(int(v) for v in p.dye_rgb), tooltip, "\n".join(info),
                         appearance_lines(rec.appearance))


#: How the window names the lights a spectral reading gives the colour under.
UNDER_NAMES = {"D65": "daylight", "A": "tungsten", "shop-led": "shop LED"}


def spectral_lines(rec: EstimateRecord) -> list[str]:
    """A record's spectral world, for the window: the colour under each light (read in the declared
    camera's RGB) and how far it moves from daylight, or the metamerism an undeclared camera leaves."""
    import colour

    stated = rec.uncertainty.spectral
    lines = []
    if rec.spectral is not None:
        under = rec.spectral.under
        day = under.get("D65")
        cells = [f"{UNDER_NAMES.get(light, light)} L* {lab[0]:.0f}" + (
                 f" (ΔE2000 {float(colour.delta_E(day, lab, method='CIE 2000')):.1f} from daylight)" if day is not None and light != "D65" else "")
                 for light, lab in under.items()]
        lines.append(f"read in the camera's RGB ({rec.spectral.camera} under {rec.spectral.led}): " + "; ".join(cells))
    if stated is not None:
        lines.append(f"spectral world ({stated.camera} camera): within ΔE2000 {stated.mean_colour_de2000_p68:.2f} "
                     f"in 68% for {stated.holds_for}")
    return lines


def light_name(light: int | None) -> str:
    """"all lights" or "light i alone"."""
    return "all lights" if light is None else f"light {light} alone"


def light_swatches(loaded: rs.LoadedCapture) -> tuple[np.ndarray | None, ...]:
    """Each light's own frame of the capture's swatch area, corrected with the capture's profile and
    divided by its exposure factor (on the all-lights frame's scale, as the twin lit by that light
    alone renders it), as 8-bit sRGB; None where a frame is unreadable; empty for older captures."""
    from hairdigi.inference.calibration import apply_profile
    from hairdigi.inference.preprocess import to_linear

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


def nonfinite_warning(what: str, count: int) -> EstimateWarning:
    return EstimateWarning(WarningKind.NONFINITE, f"render: the {what} preview had {count} NaN or Inf values "
                                                  f"(shown as black); its colours are not to be trusted")


def read_thumbnail(folder: Path, entry: Entry, size=(64, 48)) -> np.ndarray | None:
    """A small RGB picture of a capture, or None when its image is missing."""
    import cv2

    path = SessionFolder(folder).image(entry.record.capture or "")
    img = cv2.imread(str(path)) if path.is_file() else None
    return None if img is None else cv2.resize(img[..., ::-1], size)


# --- the model ---------------------------------------------------------------------------------
class ReviewModel:
    """The review state of one rig session, and the work that updates it (see the module's note)."""

    def __init__(self, session: rs.RigSession, settings: PreviewSettings | None = None) -> None:
        from hairdigi.render.scenes import ENVIRONMENTS
        from hairdigi.render.strands import HAIRSTYLES

        self.session = session
        self.settings = settings or PreviewSettings()
        self.events = Events()
        self.records: list[Entry] = []
        self.thumbnails: dict[str, np.ndarray | None] = {}
        self.shown: Shown | None = None
        self.twin: TwinPreview | None = None
        self.hairstyle: HairstylePass | None = None
        self.strands: StrandPreview | None = None
        self.frame_check: FrameCheck | None = None
        self.preview_warnings: tuple[EstimateWarning, ...] = ()
        self.style, self.env = HAIRSTYLES[0], ENVIRONMENTS[0]
        self.illuminant: str | None = None   # the hairstyles' light: None, the RGB world's white; else spectral
        self.hair_file: Path | None = None           # a .hair model shown instead of the built-in style
        self.orbit = (0.0, 0.0)                      # azimuth, elevation (degrees)
        self.light: int | None = None                # the capture and twin are compared under this light alone (None: all)
        self.show_denoised = self.settings.denoise and dn.available()
        self.twin_renderer = Renderer(max_cached=4)      # the twin at each scale
        self.style_renderer = Renderer(max_cached=4)
        self._thread = threading.get_ident()       # the one thread that changes this state
        self._generation = {"twin": 0, "hairstyle": 0}
        self._twin_state = threading.Condition()
        self._twin_ready = 0                    # the twin generation that is clean (or done): the hairstyle waits for it
        self._capturing = False
        self._strand_cache: dict[tuple, object] = {}
        self._last_check = 0.0
        self._checking = False
        self._feed_fps = self.settings.feed_fps

    def _owner(self) -> None:
        if threading.get_ident() != self._thread:
            raise RuntimeError("the review model's state changes on its own thread only: hand work results "
                               "to apply() there")

    # -- generations: what makes running work stale ------------------------------------------
    def _bump(self, *kinds: str) -> None:
        for kind in kinds:
            self._generation[kind] += 1

    def _stale(self, kind: str, generation: int) -> Cancelled:
        return lambda: self._generation[kind] != generation

    def _twin_is_ready(self, generation: int) -> None:
        with self._twin_state:
            self._twin_ready = max(self._twin_ready, generation)
            self._twin_state.notify_all()

    def _wait_for_twin(self, timeout_s: float = 30.0) -> None:
        """Until the current twin is clean (the hairstyle and the 3-D view let the twin go first)."""
        with self._twin_state:
            self._twin_state.wait_for(lambda: self._twin_ready >= self._generation["twin"], timeout_s)

    def stop(self) -> None:
        """Make all running preview work stale (closing the window)."""
        self._bump("twin", "hairstyle")
        self._twin_is_ready(self._generation["twin"])

    # -- the live feed and the lights ----------------------------------------------------------
    def busy(self) -> bool:
        """A capture is estimated, or the shown estimate's twin is not clean yet."""
        return self._capturing or self._twin_ready < self._generation["twin"]

    def _update_feed(self) -> None:
        fps = self.settings.busy_feed_fps if self.busy() else self.settings.feed_fps
        if fps != self._feed_fps:
            self._feed_fps = fps
            self.events.feed_fps.emit(fps)

    def feed_period(self) -> float:
        """Seconds between the live feed's frames, now."""
        return 1.0 / self._feed_fps

    @staticmethod
    def light_count() -> int:
        return N_LIGHTS

    def lights_work(self) -> Work:
        """Read the light board: each light's state, and what the board says it is."""
        session = self.session
        return Work("lights", _returns(lambda: Lights(tuple(st.on for st in session.light_states()),
                                                      session.lights.identify(), session.lights.port_name)))

    def set_light_work(self, index: int, on: bool) -> Work:
        """Switch one light, then read the board back."""
        session = self.session

        def run():
            session.set_light(index, on)
            return (yield from self.lights_work().run())
        return Work(f"light {index}", run)

    def set_all_work(self, on: bool) -> Work:
        session = self.session

        def run():
            session.set_all(on)
            return (yield from self.lights_work().run())
        return Work("lights", run)

    # -- records and selection ----------------------------------------------------------------
    def reload(self) -> list[Entry]:
        self._owner()
        entries = []
        for capture_id, record in rs.load_results(self.session.folder):
            if isinstance(record, str):     # unreadable: named, and the others still listed
                self.events.error.emit(f"capture {capture_id} is left out: {record}")
            else:
                entries.append(Entry(capture_id, record))
        self.records = entries
        self.events.records.emit(self.records)
        return self.records

    def thumbnail_work(self) -> Work | None:
        """Read the thumbnails not read yet, off the model's thread; None when there are none."""
        folder, todo = self.session.folder, [e for e in self.records if e.id not in self.thumbnails]
        if not todo:
            return None

        def run():
            for entry in todo:
                yield Thumbnail(entry.id, read_thumbnail(folder, entry))
        return Work("thumbnails", run)

    def select(self, capture_id: str, same_capture: bool = False) -> Shown | None:
        """Review a saved capture with its own calibration profile; emits ``shown`` and ``parameters``.

        ``same_capture``: the capture whose first look is shown, now with its record (refined).
        """
        self._owner()
        try:
            loaded = self.session.load_capture(capture_id)
        except (FileNotFoundError, OSError, ValueError) as exc:
            self.events.error.emit(str(exc))
            return None
        if loaded.problems:
            self.events.error.emit("; ".join(loaded.problems))
        rec = loaded.record if loaded.record is not None else EstimateRecord(hair=None)
        x, y, w, h = loaded.roi
        frame_size = (loaded.frame.shape[1], loaded.frame.shape[0])
        blocked = rec.hair is None
        real = loaded.frame[y:y + h, x:x + w].copy() if blocked else loaded.corrected_swatch()
        same = self.shown is not None and (same_capture or self.shown.capture_id == capture_id)
        shown = Shown(capture_id, real, tuple(loaded.roi), frame_size, rec.hair,
                      Stage.BLOCKED if blocked else Stage.REFINED, rec, self.session.simulated,
                      self.shown.key if same else next(_KEYS), light_swatches(loaded))
        if self.shown is not None and self.shown.capture_id == capture_id and self.shown.params == rec.hair:
            self.shown = shown          # the same estimate again (a reload): keep the previews running
            return shown
        self._show(shown)
        return shown

    def _show(self, shown: Shown) -> None:
        """Show a capture (or new parameters of the shown one): running preview work goes stale. The
        shown capture's previews stay up until the new ones come (the first look until the refined)."""
        self._bump("twin", "hairstyle")
        if self.shown is None or shown.key != self.shown.key:
            self.twin = self.hairstyle = None
        self.shown = shown
        self.preview_warnings = ()
        previews = shown.params is not None and shown.stage == Stage.REFINED   # the capture renders the first look
        if not previews or self.captured_image() is None:   # no frame under the chosen light: no twin either
            self._twin_is_ready(self._generation["twin"])    # no twin work comes for this: nothing to wait for
        self._update_feed()
        self.events.shown.emit(shown)
        if previews:
            self.events.parameters.emit(shown)

    def _current(self, payload, kind: str, showing) -> bool:
        """A pass is shown when its work is current, or when it is the first pass of the shown capture
        (a first-look pass that finished after the refined estimate came beats an empty panel)."""
        if payload.generation == self._generation[kind]:
            return True
        return self.shown is not None and payload.key == self.shown.key and showing is None

    def parameter_view(self) -> ParameterView | None:
        """The shown parameters, intervals, chip and lines, as the window writes them."""
        return None if self.shown is None else parameter_view(self.shown, self.preview_warnings)

    def captured_image(self) -> np.ndarray | None:
        """The captured side of the comparison under the chosen light: the corrected swatch (all
        lights), or that light's own frame; None when the capture has no frame for it."""
        shown = self.shown
        if shown is None:
            return None
        if self.light is None:
            return shown.real
        frames = shown.light_frames
        return frames[self.light] if self.light < len(frames) else None

    def captured_text(self) -> str:
        """What the captured side says when it has no image under the chosen light."""
        if self.shown is None:
            return "capture"
        if self.captured_image() is None and self.light is not None:
            if self.light < len(self.shown.light_frames):
                return f"light {self.light}'s frame of this capture is unreadable"
            return f"no frame for light {self.light} in this capture"
        return f"captured, {light_name(self.light)}"

    # -- state set by the window ---------------------------------------------------------------
    def set_view(self, style: str | None = None, env: str | None = None, orbit: tuple[float, float] | None = None,
                 hair_file: str | Path | None = None, illuminant: str | None = KEEP) -> None:
        """Change the hairstyle (a built-in style closes the hair file), environment, camera orbit, hair
        file or light (``illuminant``: a name of ``render.spectra.ILLUMINANTS``, rendered spectrally and
        shown as an eye adapted to it sees it; None, the RGB world's white lights); emits ``view``."""
        self._owner()
        if illuminant is not KEEP:
            if illuminant is not None and illuminant not in ILLUMINANTS:
                raise ValueError(f"unknown light {illuminant!r}; choose one of {', '.join(ILLUMINANTS)} or None")
            self.illuminant = illuminant
        if style is not None:
            self.style, self.hair_file = style, None
        if hair_file is not None:
            self.hair_file = Path(hair_file)
        if env is not None:
            self.env = env
        if orbit is not None:
            self.orbit = (float(orbit[0]), float(orbit[1]))
        self._bump("hairstyle")
        self.events.view.emit(self.view_label())

    def set_light_view(self, light: int | None) -> None:
        """Compare the capture and its twin under ``light`` alone (0 to N_LIGHTS - 1), or all lights
        (None): the twin re-renders lit so, beside that light's captured frame; emits ``light_view``."""
        self._owner()
        if light is not None and not 0 <= int(light) < N_LIGHTS:
            raise ValueError(f"light {light}: the rig has lights 0 to {N_LIGHTS - 1} (or None for all)")
        light = None if light is None else int(light)
        if light == self.light:
            return
        self.light = light
        self._bump("twin")
        if self.twin_work() is None:           # nothing to render under this light: nothing to wait for
            self._twin_is_ready(self._generation["twin"])
        self.events.light_view.emit(light)

    def twin_scene(self, scale: float = 1.0) -> tuple[SceneSpec, tuple[int, int]] | None:
        """The shown capture's twin at ``scale``: its appearance, lit by the chosen light; None with no capture."""
        shown = self.shown
        if shown is None:
            return None
        return twin_view(shown.roi, shown.frame_size, shown.simulated, scale, shown.appearance, self.light)

    def view_label(self) -> str:
        light = "" if self.illuminant is None else f", under {self.illuminant}"
        return f"{self.hair_file.name if self.hair_file else self.style}, {self.env}{light}"

    def set_denoised(self, on: bool) -> None:
        """Show the denoised passes (True) or the raw path-traced ones; no re-render."""
        self._owner()
        self.show_denoised = bool(on) and dn.available()
        self.events.display.emit(self.show_denoised)
        if self.twin is not None:
            self.events.twin.emit(self.twin)
        if self.hairstyle is not None:
            self.events.hairstyle.emit(self.hairstyle)

    def hairstyle_spec(self) -> SceneSpec:
        """The chosen hairstyle (or hair file), environment and orbit, with the shown estimate's
        appearance (shine, fibre spread, greys; the default before a record has one)."""
        pose, strands = orbit_pose(*self.orbit), self.settings.hairstyle_strands
        look = scene_appearance(self.shown.appearance if self.shown is not None else None)
        if self.hair_file is not None:
            return SceneSpec(SceneKind.HAIR_FILE, hair_file=str(self.hair_file), env=self.env, strands=strands,
                             camera=pose, appearance=look, illuminant=self.illuminant)
        return SceneSpec(self.style, env=self.env, strands=strands, camera=pose, appearance=look,
                         illuminant=self.illuminant)

    # -- work: made here, run by a worker ------------------------------------------------------
    def warm_work(self) -> Work:
        """Build and compile the twin and hairstyle scenes (and refinement's) before any capture."""
        session, settings = self.session, self.settings
        roi, spec = session.swatch_roi, self.hairstyle_spec()
        twin_renderer, style_renderer = self.twin_renderer, self.style_renderer

        def run():
            seconds = {}
            placeholder = HairParams()
            start = time.perf_counter()
            session.prepare_refinement()
            seconds["refinement_curve"] = time.perf_counter() - start
            yield None
            if roi is not None:
                frame = session.frames.latest() or session.frame()
                start = time.perf_counter()
                for scale in sorted({scale for scale, _ in settings.twin_passes}):
                    tspec, tsize = twin_view(roi, (frame.srgb.shape[1], frame.srgb.shape[0]), session.simulated,
                                             scale)
                    twin_renderer.render(placeholder, tspec, tsize, 1)
                seconds["twin"] = time.perf_counter() - start
            yield None
            start = time.perf_counter()
            style_renderer.render(placeholder, spec, settings.hairstyle_size, 1)
            seconds["hairstyle"] = time.perf_counter() - start
            yield None
            if dn.available():          # OIDN's first call loads its kernels (2 s)
                start = time.perf_counter()
                dn.denoise(np.full((16, 16, 3), 0.1, np.float32))
                seconds["denoiser"] = time.perf_counter() - start
            start = time.perf_counter()
            _warm_refinement(session)
            seconds["refinement"] = time.perf_counter() - start
            return Warmed(seconds)
        return Work("warm-up", run)

    def capture_work(self) -> Work:
        """Capture, estimate and refine. Between the encoder and refinement (the session's
        ``on_encoder_estimate`` hook) the capture yields the :class:`FirstLook` and its first twin and
        hairstyle passes: the operator sees parameters, a twin and a hairstyle before refinement takes
        the renderer. The capture itself runs to its end even when the work is cancelled."""
        self._owner()
        session, settings = self.session, self.settings
        # the first look has no appearance yet: the default (the warm scene), not the previous capture's
        spec, label = dataclasses.replace(self.hairstyle_spec(), appearance=None), self.view_label()
        on = self.show_denoised or settings.denoise
        if self.light is not None:            # the first look is of the all-lights frame
            self.light = None
            self.events.light_view.emit(None)
        self._bump("twin", "hairstyle")       # stale previews stop now and leave the cores to the capture
        self._twin_is_ready(self._generation["twin"])
        self._capturing = True
        self._update_feed()
        tag = PassTag(self._generation["twin"], next(_KEYS), Stage.ENCODER)
        style_tag = PassTag(self._generation["hairstyle"], tag.key, Stage.ENCODER)
        twin_renderer, style_renderer = self.twin_renderer, self.style_renderer

        def run():
            out: queue.Queue = queue.Queue()
            done = object()

            def first_look(params: HairParams) -> None:
                """In the capture's thread, between the encoder and refinement."""
                look = _first_look(session, params, tag.key)
                out.put(look)
                n = settings.first_look_passes
                view = lambda scale: twin_view(look.roi, look.frame_size, session.simulated, scale)  # noqa: E731
                for p in twin_passes(twin_renderer, params, look.real, view, settings.twin_passes[:n], settings,
                                     on, tag):
                    out.put(p)
                for p in hairstyle_passes(style_renderer, params, spec, label, settings.hairstyle_passes[:n],
                                          settings, on, style_tag):
                    out.put(p)

            def capture() -> None:
                try:
                    out.put(Captured(session.capture(on_encoder_estimate=first_look)))
                except BaseException as exc:   # raised again in the worker
                    out.put(exc)
                finally:
                    out.put(done)

            thread = threading.Thread(target=capture, name="capture", daemon=True)
            thread.start()
            result = None
            try:
                while (item := out.get()) is not done:
                    if isinstance(item, BaseException):
                        raise item
                    if isinstance(item, Captured):
                        result = item
                    else:
                        yield item
            finally:
                thread.join()                  # a capture is never left half-written
            return result
        return Work("capture", run, ended=self._capture_ended)

    def import_still_work(self, path: str | Path) -> Work:
        """A RAW still of the rig as a capture (copied, calibrated on its own chart, estimated)."""
        session = self.session
        return Work("RAW still", _returns(lambda: Captured(session.import_still(path))))

    def _capture_ended(self) -> None:
        self._capturing = False
        self._update_feed()

    def twin_work(self) -> Work | None:
        """The twin's passes for the shown (refined) parameters; None when there is nothing to preview."""
        shown, light = self.shown, self.light
        real = self.captured_image()
        if shown is None or shown.params is None or real is None:   # no frame of this capture under this light
            return None
        generation = self._generation["twin"]
        tag = PassTag(generation, shown.key, shown.stage, light)
        renderer, settings, on = self.twin_renderer, self.settings, self.show_denoised or self.settings.denoise
        appearance = shown.appearance

        def run():
            view = lambda scale: twin_view(shown.roi, shown.frame_size, shown.simulated, scale,  # noqa: E731
                                           appearance, light)
            yield from twin_passes(renderer, shown.params, real, view, settings.twin_passes, settings, on, tag,
                                   self._stale("twin", generation))
        return Work("twin", run, ended=lambda: self._twin_done(generation))

    def _twin_done(self, generation: int) -> None:
        self._twin_is_ready(generation)
        self._update_feed()

    def hairstyle_work(self) -> Work | None:
        """The hairstyle's passes for the shown parameters, in the chosen view, after the twin is clean."""
        shown = self.shown
        if shown is None or shown.params is None:
            return None
        generation, spec, label = self._generation["hairstyle"], self.hairstyle_spec(), self.view_label()
        tag = PassTag(generation, shown.key, shown.stage)
        renderer, settings, on = self.style_renderer, self.settings, self.show_denoised or self.settings.denoise

        def run():
            yield from hairstyle_passes(renderer, shown.params, spec, label, settings.hairstyle_passes, settings, on,
                                        tag, self._stale("hairstyle", generation), self._wait_for_twin)
        return Work("hairstyle", run)

    def warm_view_work(self) -> Work:
        """Build the chosen hairstyle's scene before any capture needs it (a style picked before a capture)."""
        spec, size, renderer = self.hairstyle_spec(), self.settings.hairstyle_size, self.style_renderer
        return Work("hairstyle", _returns(lambda: renderer.render(HairParams(), spec, size, 1) and None))

    def _strand_key(self) -> tuple:
        return (str(self.hair_file) if self.hair_file else self.style, self.settings.view_strands)

    def strand_work(self) -> Work | None:
        """The 3-D view's strands (fewer than the render's) in the estimated colour, once the twin is
        clean; None when the view already shows them. Strands are grown once per style or hair file."""
        shown = self.shown
        if shown is None or shown.params is None or shown.stage == Stage.ENCODER:
            return None
        which, colour = self._strand_key(), strand_colour(shown.params)
        if self.strands is not None and (self.strands.of, self.strands.colour_rgb8) == (which, colour):
            return None
        style, hair_file, n = self.style, self.hair_file, self.settings.view_strands
        grown, scalp = self._strand_cache.get(which), scalp_linear(shown.params)

        def run():
            from hairdigi.render.hairfile import hair_model_strands
            from hairdigi.render.strands import hairstyle_strands

            self._wait_for_twin()
            yield None                  # cancelled meanwhile: stop here
            strands = grown or (hair_model_strands(hair_file, n) if hair_file else hairstyle_strands(style, n, seed=0))
            return StrandPreview(which, strands, colour, scalp)
        return Work("strands", run)

    def open_hair_work(self, path: str | Path) -> Work:
        """Read, check and fit a ``.hair`` model; a bad file raises its one-line error (HairFileError)."""
        from hairdigi.render.domain.bounds import defaults_for

        n = self.settings.hairstyle_strands or defaults_for("hairstyle").strands

        def run() -> HairModel:
            from hairdigi.render.hairfile import hair_model_strands, model_summary

            model = Path(path)
            if not model.is_file():
                raise FileNotFoundError(f"{model}: no such .hair file; choose another")
            hair_model_strands(model, n)        # read once here: the render and the 3-D view reuse it
            return HairModel(model, model_summary(model, n))
        return Work("hair model", _returns(run))

    def frame_check_due(self, period_s: float = 1.5) -> bool:
        """True when a frame should be checked for the chart and exposure (none running, ``period_s`` since)."""
        self._owner()
        now = time.monotonic()
        if self.busy() or self._checking or now - self._last_check < period_s:   # a capture and its twin first
            return False
        self._checking, self._last_check = True, now
        return True

    def frame_check_work(self, image: np.ndarray) -> Work:
        """Find the chart and check the exposure of one frame."""
        session = self.session

        def run() -> FrameCheck:
            import cv2

            from hairdigi.inference.calibration import CalibrationError, detect_chart

            try:
                try:
                    box = detect_chart(image).box
                except CalibrationError:
                    box = None
                return FrameCheck(box, session.exposure(image))
            except cv2.error:    # cv2.mcc's assertion on an odd frame (seen once in ~20 tours): try the next one
                return FrameCheck(None, None)
        return Work("chart", _returns(run), ended=self._check_ended)

    def _check_ended(self) -> None:
        self._checking = False

    def calibrate_work(self) -> Work:
        session = self.session
        return Work("calibration", _returns(lambda: Calibrated(as_profile(session.calibrate()))))

    # -- results back from work (the model's thread) --------------------------------------------
    def apply(self, payload: object) -> None:
        """Store what a work yielded or returned, and emit its event; stale passes are dropped."""
        self._owner()
        if payload is None:
            return
        handler = self._HANDLERS.get(type(payload))
        if handler is None:
            raise TypeError(f"the review model has no use for {type(payload).__name__}")
        handler(self, payload)

    def _apply_twin(self, t: TwinPreview) -> None:
        if not self._current(t, "twin", self.twin):
            return
        self.twin = t
        if t.clean_enough and t.stage == Stage.REFINED and t.generation == self._generation["twin"]:
            self._twin_is_ready(t.generation)   # clean: the hairstyle's passes may take turns with the twin
            self._update_feed()
        if t.nonfinite:
            self._warn(nonfinite_warning("twin", t.nonfinite))
        self.events.twin.emit(t)

    def _apply_hairstyle(self, p: HairstylePass) -> None:
        if not self._current(p, "hairstyle", self.hairstyle):
            return
        self.hairstyle = p
        if p.nonfinite:
            self._warn(nonfinite_warning("hairstyle", p.nonfinite))
        self.events.hairstyle.emit(p)

    def _warn(self, warning: EstimateWarning) -> None:
        if warning.kind not in {w.kind for w in self.preview_warnings}:
            self.preview_warnings += (warning,)
            self.events.warnings.emit(self.preview_warnings)

    def _apply_strands(self, s: StrandPreview) -> None:
        self._strand_cache[s.of] = s.strands
        if s.of == self._strand_key():
            self.strands = s
            self.events.strands.emit(s)

    def _apply_first_look(self, look: FirstLook) -> None:
        self._show(Shown(None, look.real, look.roi, look.frame_size, look.params, Stage.ENCODER, None,
                         self.session.simulated, look.key))

    def _apply_captured(self, captured: Captured) -> None:
        self._capture_ended()
        first_look = self.shown is not None and self.shown.capture_id is None
        self.select(captured.result.capture_id, same_capture=first_look)
        self.reload()

    def _apply_hair_model(self, model: HairModel) -> None:
        self.events.hair_model.emit(model)
        self.events.status.emit(model.summary)
        self.set_view(hair_file=model.path)

    def _apply_frame_check(self, check: FrameCheck) -> None:
        self._checking = False
        if check.exposure is not None:
            self.frame_check = check
            self.events.frame_check.emit(check)

    def _apply_warmed(self, warmed: Warmed) -> None:
        parts = ", ".join(f"{k} {v:.1f} s" for k, v in warmed.seconds.items())
        self.events.status.emit(f"previews ready ({parts})")
        self.events.warmed.emit(warmed)

    def _apply_calibrated(self, calibrated: Calibrated) -> None:
        self.events.calibration.emit(calibrated.profile)

    def _apply_lights(self, lights: Lights) -> None:
        self.events.lights.emit(lights)

    def _apply_thumbnail(self, thumb: Thumbnail) -> None:
        self.thumbnails[thumb.capture_id] = thumb.rgb
        self.events.thumbnail.emit(thumb)

    _HANDLERS = {TwinPreview: _apply_twin, HairstylePass: _apply_hairstyle, StrandPreview: _apply_strands,
                 FirstLook: _apply_first_look, Captured: _apply_captured, HairModel: _apply_hair_model,
                 FrameCheck: _apply_frame_check, Warmed: _apply_warmed, Calibrated: _apply_calibrated,
                 Lights: _apply_lights, Thumbnail: _apply_thumbnail}

    # -- what the window reads ---------------------------------------------------------------
    def calibration(self) -> tuple[rs.CalibrationStatus, str]:
        """(status, one line) of the session's calibration."""
        status, reasons = self.session.calibration_status()
        return status, calibration_text(as_profile(self.session.profile), status, reasons)

    def twin_image(self, preview: TwinPreview | None = None) -> np.ndarray | None:
        """The twin as shown (denoised or raw), sRGB 8-bit."""
        preview = preview or self.twin
        if preview is None:
            return None
        return linear_to_srgb8(preview.clean if self.show_denoised and preview.clean is not None else preview.raw)

    def hairstyle_image(self, p: HairstylePass | None = None) -> np.ndarray | None:
        p = p or self.hairstyle
        if p is None:
            return None
        return linear_to_srgb8(p.clean if self.show_denoised and p.clean is not None else p.raw)

    def save_render(self, which: str, path: str | Path) -> list[Path]:
        """Write the shown ``"hairstyle"`` or ``"twin"`` render as ``path`` (.png) and beside it linear .exr."""
        from hairdigi.render.io.images import save_exr, save_png

        if which not in ("hairstyle", "twin"):
            raise ValueError(f"save which render? 'hairstyle' or 'twin', got {which!r}")
        item = self.hairstyle if which == "hairstyle" else self.twin
        if item is None:
            raise ReviewError(f"no {which} render yet: capture or select a swatch first")
        linear = item.clean if self.show_denoised and item.clean is not None else item.raw
        path = Path(path)
        if path.suffix.lower() not in (".png", ".exr"):
            path = path.with_name(path.name + ".png")
        png, exr = path.with_suffix(".png"), path.with_suffix(".exr")
        return [save_png(png, linear_to_srgb8(linear)), save_exr(exr, linear)]

    def export(self, path: str | Path, all_: bool = True) -> Path:
        """The estimates as JSON: all of the session's, or the shown capture's."""
        entries = [e for e in self.records if e.record.hair is not None]
        if not all_ and self.shown is not None and self.shown.capture_id is not None:
            entries = [e for e in entries if e.id == self.shown.capture_id]
        if not entries:
            raise ReviewError("nothing to export: no capture has an estimate yet")
        return rs.export_records([e.record for e in entries], path)


def _first_look(session: rs.RigSession, params: HairParams, key: int) -> FirstLook:
    """The encoder's parameters with the swatch they came from: the captured frame's swatch area,
    corrected with the session's profile (as the estimate saw it)."""
    from hairdigi.inference.calibration import apply_profile

    image = session.last_frame.srgb
    x, y, w, h = session.swatch_roi or (0, 0, image.shape[1], image.shape[0])
    real = image[y:y + h, x:x + w].copy()
    if session.profile is not None:
        real = linear_to_srgb8(apply_profile(real, session.profile))
    return FirstLook(params, real, (x, y, w, h), (image.shape[1], image.shape[0]), key)


def _warm_refinement(session: rs.RigSession) -> None:
    """Build the scene refinement renders for this rig's swatch area once, and compile its kernels
    (its response curve is prepared first, or read from the disk cache)."""
    from hairdigi.inference.refine import refine

    frame = session.frames.latest() or session.frame()
    refine(HairParams(), np.array([0.08, 0.05, 0.03]), session.region(frame.srgb))
