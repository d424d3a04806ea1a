"""The review of captures, free of Qt: what the window shows, and the long work behind it.

napari-style. :class:`ReviewModel` holds the review state: the shown capture (with its own
calibration profile), its parameters, the twin preview (real, synthetic raw and denoised, the ΔE2000
map, the mean-colour ΔE2000), the hairstyle choice, camera orbit and passes, and the strand preview.
Widgets subscribe to its events (``model.events.twin.connect(callback)``).

Long work is plain functions ``work(report, cancelled)`` made by the model (``model.twin_work()``
and so on). The window runs them in its workers and hands what they report and return back to
:meth:`ReviewModel.apply` on the UI thread, which stores it and emits the event. A new capture, a
new selection or new parameters bump the model's generation: stale work stops at its next pass, and
whatever it still reports is dropped. A denoised image is for the eye only: every number (ΔE, the
chip's colour, exports' metrics) comes from the raw path-traced image.

The order after a capture: the capture worker reports the encoder's estimate (the first look), then
renders its first twin and hairstyle passes itself, then refines; the refined estimate's twin renders
until it is clean, and only then its hairstyle passes take turns with it. The scenes are built by
:meth:`ReviewModel.warm_work` when the window opens, so a capture only updates parameters. Every
render in the process takes one lock (``render.renderer.RENDER_LOCK``).
"""
from __future__ import annotations

import itertools
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from hairdigi.app import rig_session as rs
from hairdigi.render import denoise as dn
from hairdigi.render.metrics import delta_e_map, mean_colour_delta_e
from hairdigi.render.base.params import HairParams
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.base.rig_geometry import CameraPose
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear

Report = Callable[[object], None]
Cancelled = Callable[[], bool]
Work = Callable[[Report, Cancelled], object]


# --- events ----------------------------------------------------------------------------------
class Event:
    """Callbacks called with one value, in the order they connected."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._callbacks: list[Callable[[object], None]] = []

    def connect(self, callback: Callable[[object], None]) -> Callable[[object], None]:
        self._callbacks.append(callback)
        return callback

    def disconnect(self, callback: Callable[[object], None]) -> None:
        if callback in self._callbacks:
            self._callbacks.remove(callback)

    def emit(self, value: object = None) -> None:
        for callback in list(self._callbacks):
            callback(value)


class Events:
    """The model's events; each carries the new value of the state it names."""

    NAMES = ("records",      # list[dict]: the session's result records, oldest first
             "shown",        # Shown: the capture under review (or its first look, before its record)
             "parameters",   # Shown: new parameters to preview (start the twin and hairstyle work)
             "twin",         # TwinPreview: a twin pass
             "hairstyle",    # HairstylePass: a hairstyle pass
             "view",         # str: the hairstyle, environment, orbit or hair file changed (start the hairstyle work)
             "hair_model",   # HairModel: a .hair file opened (the view follows)
             "strands",      # StrandPreview: the strands and colour of the 3-D view
             "calibration",  # dict: a new calibration profile
             "warmed",       # Warmed: the preview scenes are built (captures now only update parameters)
             "frame_check",  # FrameCheck: the chart outline and exposure of a recent frame
             "display",      # bool: denoised (True) or raw passes shown
             "status",       # str: one line for the status bar
             "error")        # str: one line naming the problem and the fix

    def __init__(self) -> None:
        for name in self.NAMES:
            setattr(self, name, Event(name))


# --- settings and state ----------------------------------------------------------------------
@dataclass(frozen=True)
class PreviewSettings:
    """How previews render; the defaults are chosen by ``hairdigi bench previews`` (render/bench_previews.py).

    Mean per-pixel ΔE2000 against 1024 spp, not denoised (clean: 3 or less), OIDN without guides: the
    twin (130 x 154) is 3.34 at 1 spp, 3.13 at 2, 3.06 at 4, 2.89 at 8 (clean), 2.75 at 16; raw it is
    6.1 even at 64 spp. At half resolution (65 x 77, a quarter of the samples per spp) it is clean
    at 4 spp: 3.1–3.6 at 1, 2.8–3.0 at 2, 2.69 at 4, in 0.19 s instead of 1.44 s for 8 spp at full
    resolution; the half-resolution twin is flat, the full-resolution one shows the fibres' streaks,
    so the twin goes from one to the other. The 512² hairstyle is clean from its first pass: 1.08 at
    1 spp, 0.89 at 2 (raw: 6.0 and 4.6). Albedo and normal guides never helped (twin 3.48 at 1 spp,
    3.13 at 8; hairstyle 1.08 at 1) and cost an AOV render.

    ``fibre_px``: the ΔE2000 map smooths real and twin over 6 px (at full resolution; 3 at half), about a clump of fibres in the rig
    view (0.04 swatch widths). Measured on a simulated capture whose mean colours differ by ΔE2000
    0.47: the map's mean is 2.38 at 2 px (noise and single fibres), 1.47 at 4, 1.17 at 6, 1.04 at 8.
    """

    #: (scale, spp) of each twin pass: at half the capture's resolution first (running totals 1, 4),
    #: then at full resolution (8, 16, 32) for the streaks of the fibres.
    twin_passes: tuple[tuple[float, int], ...] = ((0.5, 1), (0.5, 3), (1.0, 8), (1.0, 8), (1.0, 16))
    twin_clean_spp: tuple[tuple[float, int], ...] = ((0.5, 4), (1.0, 8))   # (scale, spp) from which it is clean
    hairstyle_size: int = 512
    hairstyle_strands: int | None = None                   # None: the scene's default
    hairstyle_passes: tuple[int, ...] = (1, 1, 2, 4, 8)    # running totals 1, 2, 4, 8, 16
    hairstyle_clean_spp: int = 1
    first_look_passes: int = 1                             # passes rendered for the encoder's (unrefined) estimate
    denoise: bool = True
    fibre_px: float = 6.0                                  # smoothing of the ΔE2000 map (pixels), see below
    view_strands: int = 1500                               # strands drawn in the 3-D view
    warm: bool = True                                      # build the preview scenes before the first capture


@dataclass
class Shown:
    """The capture under review: its corrected swatch, its parameters and where they came from."""

    capture_id: str | None          # None for the encoder's first look, before the record is written
    real: np.ndarray                # (h, w, 3) uint8 sRGB swatch, corrected with the capture's own profile
    roi: tuple[int, int, int, int]
    frame_size: tuple[int, int]     # (width, height) of the rig view
    params: HairParams | None
    stage: str                      # "encoder" (first look), "refined" (the record's), "blocked"
    record: dict = field(default_factory=dict)
    simulated: bool = True
    key: int = 0                    # one per capture under review: its first look and refined estimate share it


@dataclass
class TwinPreview:
    """One pass of the synthetic twin beside the real swatch."""

    generation: int
    raw: np.ndarray                 # linear float32, path-traced running mean: what every number uses
    clean: np.ndarray | None        # denoised copy, for the eye only (None without a denoiser)
    spp: int
    final: bool                     # the last pass
    clean_enough: bool              # spp >= PreviewSettings.twin_clean_spp
    delta_e: float                  # mean-colour ΔE2000, real vs raw twin
    delta_e_map: np.ndarray         # (h, w) ΔE2000 of real vs raw twin, both smoothed at the fibre scale
    hair_linear: np.ndarray         # the raw twin's mean linear colour: the estimated hair colour
    stage: str
    seconds: float                  # since the work began
    key: int = 0                    # the Shown.key it previews
    scale: float = 1.0              # of the capture's resolution


@dataclass
class HairstylePass:
    """One pass of the hairstyle render."""

    generation: int
    raw: np.ndarray
    clean: np.ndarray | None
    spp: int
    index: int
    passes: int
    clean_enough: bool
    label: str                      # "straight, studio" or the hair file's name
    stage: str
    seconds: float
    key: int = 0

    @property
    def final(self) -> bool:
        return self.index == self.passes


@dataclass
class StrandPreview:
    of: tuple                       # (style or hair file, strands): what the strands are of
    strands: object                 # render.strands.Strands
    colour_rgb8: tuple[int, int, int]


@dataclass
class FrameCheck:
    chart_box: np.ndarray | None    # the chart's corners in the frame, or None when not found
    exposure: list                  # hardware.exposure.ExposureReport, swatch first


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
class FirstLook:
    """The encoder's parameters, before refinement: what the operator sees within a second."""

    params: HairParams
    real: np.ndarray
    roi: tuple[int, int, int, int]
    frame_size: tuple[int, int]
    key: int


#: Review keys: one per capture under review, unique in the process (the capture worker takes one).
_KEYS = itertools.count(1)


# --- pure functions: views, passes, colours ----------------------------------------------------
def twin_view(roi: tuple[int, int, int, int], frame_size: tuple[int, int], simulated: bool,
              scale: float = 1.0) -> tuple[SceneSpec, tuple]:
    """The twin's scene and size: the rig camera over exactly the ROI (simulated geometry), or a crop;
    ``scale`` < 1 renders the same view with fewer pixels."""
    if simulated:
        spec, (w, h) = rs.twin_spec(roi, frame_size)
    else:
        spec, (w, h) = SceneSpec("swatch", framing="crop"), (int(roi[2]), int(roi[3]))
    return spec, (max(8, round(w * scale)), max(8, round(h * scale)))


def orbit_pose(azimuth_deg: float, elevation_deg: float, distance: float | None = None) -> CameraPose:
    """The portrait camera turned ``azimuth_deg`` around the head and raised ``elevation_deg``.

    Portrait poses are polar from the face direction, so the orbit stays in front of the face
    (polar < 90°): ``|azimuth|`` and ``|elevation|`` are clipped to 80° and 60°.
    """
    from hairdigi.render.scenes import PORTRAIT_CAMERA

    yaw, pitch = np.radians(np.clip(azimuth_deg, -80, 80)), np.radians(np.clip(elevation_deg, -60, 60))
    d = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)])
    polar = float(np.degrees(np.arccos(np.clip(d[2], -1.0, 1.0))))
    azimuth = float(np.degrees(np.arctan2(d[1], d[0]))) if polar > 1e-6 else PORTRAIT_CAMERA.azimuth_deg
    return CameraPose(min(polar, 89.0), azimuth, distance or PORTRAIT_CAMERA.distance)


def denoised(raw: np.ndarray, on: bool, quality: str = "high") -> np.ndarray | None:
    """The display copy of a pass (None when denoising is off or there is no denoiser)."""
    if not on or not dn.available():
        return None
    return dn.denoise(raw, quality=quality)


def progressive(renderer: Renderer, params: HairParams, spec: SceneSpec, size, schedule: tuple[int, ...],
                cancelled: Cancelled, seed: int = 0, gate: Callable[[], None] | None = None
                ) -> Iterator[tuple[np.ndarray, int, int]]:
    """Render passes of ``schedule[i]`` spp with new seeds; yield (running mean, spp so far, pass number).

    ``gate()`` is called before each pass (it may wait: the hairstyle lets the twin go first).
    """
    total, spp = None, 0
    for i, n in enumerate(schedule):
        if gate is not None:
            gate()
        if cancelled():
            return
        result = renderer.render(params, spec, size, int(n), seed=seed * 1_000_003 + i)
        total = result.linear * n if total is None else total + result.linear * n
        spp += n
        yield (total / spp).astype(np.float32), spp, i + 1   # even if cancelled meanwhile: the model decides


def scaled_progressive(renderer: Renderer, params: HairParams, view: Callable[[float], tuple[SceneSpec, tuple]],
                       passes: tuple[tuple[float, int], ...], cancelled: Cancelled
                       ) -> Iterator[tuple[np.ndarray, int, int, float]]:
    """:func:`progressive` over (scale, spp) passes; each run of one scale accumulates on its own.
    Yields (running mean, spp at this scale, pass number, scale)."""
    done = 0
    for scale, run in itertools.groupby(passes, key=lambda p: p[0]):
        spec, size = view(scale)
        spps = tuple(n for _, n in run)
        for raw, spp, i in progressive(renderer, params, spec, size, spps, cancelled):
            yield raw, spp, done + i, scale
        done += len(spps)


def hair_colour_rgb8(linear: np.ndarray) -> tuple[int, int, int]:
    """An sRGB 8-bit chip colour from a mean linear colour."""
    return tuple(int(v) for v in linear_to_srgb8(np.asarray(linear, dtype=np.float32)))


def strand_colour(params: HairParams) -> tuple[int, int, int]:
    """The strands' colour in the 3-D view: the fibre albedo, a little darkened (as lit hair looks)."""
    from hairdigi.render.absorption import approximate_albedo

    return hair_colour_rgb8(approximate_albedo(params) * 0.8)


def record_title(rec: dict) -> str:
    """A session-list line: the capture id and its estimate, or why there is none."""
    if rec.get("blocked"):
        return f"{rec['id']}  (blocked)"
    h = rec.get("hair", {})
    return f"{rec['id']}  rgb {[round(v) for v in h.get('dye_rgb', [])]}  mel {h.get('melanin_concentration', 0):.2f}"


def thumbnail(folder: Path, rec: dict, size=(64, 48)) -> np.ndarray | None:
    """A small RGB picture of a capture, or None when its image is missing."""
    import cv2

    path = Path(folder) / "captures" / rec.get("capture", "")
    img = cv2.imread(str(path)) if path.is_file() else None
    return None if img is None else cv2.resize(img[..., ::-1], size)


def calibration_text(profile: dict | None, status: str, reasons: list[str], now: float | None = None) -> str:
    """One line on the calibration: method, ΔE2000 before and after, age, and why it is stale."""
    if profile is None:
        return "calibration: none — press Calibrate with the chart in view"
    age_min = ((now or time.time()) - profile["time"]) / 60
    de = profile["delta_e2000"]
    text = (f"calibration: {profile['method']}, ΔE2000 {de['before']['mean']:.2f} → {de['after']['mean']:.2f} "
            f"(max {de['after']['max']:.2f}), {age_min:.0f} min old")
    if reasons:
        text += " — STALE: " + "; ".join(reasons)
    return text


class _EncoderTap:
    """The session's encoder, reporting each estimate as it returns (before refinement runs)."""

    def __init__(self, encoder) -> None:
        self._encoder = encoder
        self.listener: Callable[[object, np.ndarray, object], None] | None = None

    def estimate(self, image, roi=None, *args, **kwargs):
        est = self._encoder.estimate(image, roi, *args, **kwargs)
        if self.listener is not None:
            self.listener(est, image, roi)
        return est

    def __getattr__(self, name):
        return getattr(self._encoder, name)


# --- the model ---------------------------------------------------------------------------------
class ReviewModel:
    """The review state of one rig session, and the work that updates it (see the module's note)."""

    def __init__(self, session: rs.RigSession, settings: PreviewSettings | None = None) -> None:
        from hairdigi.render.scenes import ENVIRONMENTS
        from hairdigi.render.strands import HAIRSTYLES

        self.session = session
        self.settings = settings or PreviewSettings()
        self.events = Events()
        self.records: list[dict] = []
        self.shown: Shown | None = None
        self.twin: TwinPreview | None = None
        self.hairstyle: HairstylePass | None = None
        self.strands: StrandPreview | None = None
        self.frame_check: FrameCheck | None = None
        self.style, self.env = HAIRSTYLES[0], ENVIRONMENTS[0]
        self.hair_file: Path | None = None           # a .hair model shown instead of the built-in style
        self.orbit = (0.0, 0.0)                      # azimuth, elevation (degrees)
        self.show_denoised = self.settings.denoise and dn.available()
        self.twin_renderer = Renderer(max_cached=4)      # the twin at each scale
        self.style_renderer = Renderer(max_cached=4)
        self._generation = {"twin": 0, "hairstyle": 0}
        self._twin_state = threading.Condition()
        self._twin_ready = 0                    # the twin generation that is clean (or done): the hairstyle waits for it
        self._capturing = False
        self._strand_cache: dict[tuple, object] = {}
        self._last_check = 0.0
        self._checking = False
        self._tap: _EncoderTap | None = None
        self._tap_lock = threading.Lock()

    # -- generations: what makes running work stale ------------------------------------------
    def _bump(self, *kinds: str) -> None:
        for kind in kinds:
            self._generation[kind] += 1

    def _stale(self, kind: str, generation: int, cancelled: Cancelled) -> Cancelled:
        return lambda: cancelled() or self._generation[kind] != generation

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

    # -- records and selection (UI thread) ---------------------------------------------------
    def reload(self) -> list[dict]:
        self.records = rs.load_results(self.session.folder)
        self.events.records.emit(self.records)
        return self.records

    def select(self, capture_id: str, same_capture: bool = False) -> Shown | None:
        """Review a saved capture with its own calibration profile; emits ``shown`` and ``parameters``.

        ``same_capture``: the capture whose first look is shown, now with its record (refined).
        """
        try:
            loaded = self.session.load_capture(capture_id)
        except (FileNotFoundError, OSError, ValueError) as exc:
            self.events.error.emit(str(exc))
            return None
        x, y, w, h = loaded.roi
        rec = loaded.record
        frame_size = (loaded.frame.shape[1], loaded.frame.shape[0])
        blocked = bool(rec.get("blocked")) or "hair" not in rec
        real = loaded.frame[y:y + h, x:x + w].copy() if blocked else loaded.corrected_swatch()
        params = None if blocked else HairParams.from_dict(rec)
        same = self.shown is not None and (same_capture or self.shown.capture_id == capture_id)
        shown = Shown(capture_id, real, tuple(loaded.roi), frame_size, params, "blocked" if blocked else "refined",
                      {"id": capture_id, **rec}, self.session.simulated, self.shown.key if same else self._new_key())
        if self.shown is not None and self.shown.capture_id == capture_id and self.shown.params == params:
            self.shown = shown          # the same estimate again (a reload): keep the previews running
            return shown
        self._show(shown)
        return shown

    @staticmethod
    def _new_key() -> int:
        return next(_KEYS)

    def _show(self, shown: Shown) -> None:
        """Show a capture (or new parameters of the shown one): running preview work goes stale. The
        shown capture's previews stay up until the new ones come (the first look until the refined)."""
        self._bump("twin", "hairstyle")
        if self.shown is None or shown.key != self.shown.key:
            self.twin = self.hairstyle = None
        self.shown = shown
        previews = shown.params is not None and shown.stage != "encoder"   # the capture renders the first look
        if not previews:
            self._twin_is_ready(self._generation["twin"])    # no twin work comes for this: nothing to wait for
        self.events.shown.emit(shown)
        if previews:
            self.events.parameters.emit(shown)

    def _current(self, payload, kind: str, showing) -> bool:
        """A pass is shown when its work is current, or when it is the first pass of the shown capture
        (a first-look pass that finished after the refined estimate came beats an empty panel)."""
        if payload.generation == self._generation[kind]:
            return True
        return self.shown is not None and payload.key == self.shown.key and showing is None

    # -- state set by the window (UI thread) -------------------------------------------------
    def set_view(self, style: str | None = None, env: str | None = None, orbit: tuple[float, float] | None = None,
                 hair_file: str | Path | None = None) -> None:
        """Change the hairstyle (a built-in style closes the hair file), environment, camera orbit or
        hair file; emits ``view``."""
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

    def view_label(self) -> str:
        return f"{self.hair_file.name if self.hair_file else self.style}, {self.env}"

    def set_denoised(self, on: bool) -> None:
        """Show the denoised passes (True) or the raw path-traced ones; no re-render."""
        self.show_denoised = bool(on) and dn.available()
        self.events.display.emit(self.show_denoised)
        if self.twin is not None:
            self.events.twin.emit(self.twin)
        if self.hairstyle is not None:
            self.events.hairstyle.emit(self.hairstyle)

    def hairstyle_spec(self) -> SceneSpec:
        pose, strands = orbit_pose(*self.orbit), self.settings.hairstyle_strands
        if self.hair_file is not None:
            from hairdigi.render.renderer import HAIR_FILE_SCENE

            return SceneSpec(HAIR_FILE_SCENE, hair_file=str(self.hair_file), env=self.env, strands=strands,
                             camera=pose)
        return SceneSpec(self.style, env=self.env, strands=strands, camera=pose)

    # -- work: made here, run by the window's workers ----------------------------------------
    def warm_work(self) -> Work:
        """Build and compile the twin and hairstyle scenes (and refinement's) before any capture."""
        session, settings = self.session, self.settings
        roi = session.swatch_roi
        spec = self.hairstyle_spec()

        def work(report: Report, cancelled: Cancelled) -> Warmed:
            seconds = {}
            placeholder = HairParams()
            start = time.perf_counter()
            session.prepare_refinement()
            self._install_tap()
            seconds["refinement_curve"] = time.perf_counter() - start
            if roi is not None:
                frame = session.frames.latest() or session.frame()
                start = time.perf_counter()
                for scale in sorted({scale for scale, _ in settings.twin_passes}):
                    tspec, tsize = twin_view(roi, (frame.srgb.shape[1], frame.srgb.shape[0]), session.simulated,
                                             scale)
                    self.twin_renderer.render(placeholder, tspec, tsize, 1)
                seconds["twin"] = time.perf_counter() - start
            if cancelled():
                return Warmed(seconds)
            start = time.perf_counter()
            self.style_renderer.render(placeholder, spec, settings.hairstyle_size, 1)
            seconds["hairstyle"] = time.perf_counter() - start
            if cancelled():
                return Warmed(seconds)
            if dn.available():          # OIDN's first call loads its kernels (2 s)
                start = time.perf_counter()
                dn.denoise(np.full((16, 16, 3), 0.1, np.float32))
                seconds["denoiser"] = time.perf_counter() - start
            start = time.perf_counter()
            _warm_refinement()
            seconds["refinement"] = time.perf_counter() - start
            return Warmed(seconds)
        return work

    def _install_tap(self) -> None:
        """Wrap the session's encoder so the model sees the encoder's estimate before refinement."""
        with self._tap_lock:
            if self._tap is not None:
                return
            encoder = self.session.encoder_or_reason()
            if isinstance(encoder, str):
                return                    # the capture will say why it cannot estimate
            self._tap = _EncoderTap(encoder)
            self.session._encoder = self._tap   # RigSession has no hook for the encoder's stage yet

    def capture_work(self) -> Work:
        """Capture, estimate and refine. Between the encoder and refinement the same worker reports
        the :class:`FirstLook` and renders its first twin and hairstyle passes: the operator sees
        parameters, a twin and a hairstyle before refinement takes the renderer."""
        session, settings = self.session, self.settings
        spec, label = self.hairstyle_spec(), self.view_label()
        self._bump("twin", "hairstyle")       # stale previews stop now and leave the cores to the capture
        self._twin_is_ready(self._generation["twin"])
        self._capturing = True

        def work(report: Report, cancelled: Cancelled) -> Captured:
            self._install_tap()

            def first_look(est, image, roi) -> None:
                x, y, w, h = (roi.x, roi.y, roi.w, roi.h) if roi is not None else (0, 0, image.shape[1], image.shape[0])
                look = FirstLook(est.params, image[y:y + h, x:x + w].copy(), (x, y, w, h),
                                 (image.shape[1], image.shape[0]), next(_KEYS))
                report(look)
                shown = Shown(None, look.real, look.roi, look.frame_size, look.params, "encoder", {},
                              session.simulated, look.key)
                n = settings.first_look_passes
                self._twin_passes(shown, -1, settings.twin_passes[:n], report, cancelled)
                self._hairstyle_passes(shown, -1, spec, label, settings.hairstyle_passes[:n], report, cancelled)
            if self._tap is not None:
                self._tap.listener = first_look
            try:
                return Captured(session.capture())
            finally:
                self._capturing = False
                if self._tap is not None:
                    self._tap.listener = None
        return work

    def twin_work(self) -> Work | None:
        """The twin's passes for the shown (refined) parameters; None when there is nothing to preview."""
        shown = self.shown
        if shown is None or shown.params is None:
            return None
        generation, schedule = self._generation["twin"], self.settings.twin_passes

        def work(report: Report, cancelled: Cancelled) -> None:
            try:
                self._twin_passes(shown, generation, schedule, report, self._stale("twin", generation, cancelled))
            finally:
                self._twin_is_ready(generation)
        return work

    def _twin_passes(self, shown: Shown, generation: int, schedule: tuple[tuple[float, int], ...],
                     report: Report, stale: Cancelled) -> None:
        import cv2

        settings = self.settings
        clean_at = dict(settings.twin_clean_spp)
        real_full = srgb8_to_linear(shown.real)
        on, start = self.show_denoised or settings.denoise, time.perf_counter()
        view = lambda scale: twin_view(shown.roi, shown.frame_size, shown.simulated, scale)   # noqa: E731
        for raw, spp, i, scale in scaled_progressive(self.twin_renderer, shown.params, view, schedule, stale):
            real = real_full if raw.shape == real_full.shape else \
                cv2.resize(real_full, (raw.shape[1], raw.shape[0]), interpolation=cv2.INTER_AREA)
            clean = spp >= clean_at.get(scale, spp + 1)
            report(TwinPreview(generation, raw, denoised(raw, on), spp, i == len(schedule), clean,
                               mean_colour_delta_e(real, raw), delta_e_map(real, raw, settings.fibre_px * scale),
                               raw.reshape(-1, 3).mean(0), shown.stage, time.perf_counter() - start, shown.key,
                               scale))
            if clean and generation >= 0:
                self._twin_is_ready(generation)   # clean: the hairstyle's passes may take turns with the twin

    def hairstyle_work(self) -> Work | None:
        """The hairstyle's passes for the shown parameters, in the chosen view, after the twin is clean."""
        shown = self.shown
        if shown is None or shown.params is None:
            return None
        generation, spec, label = self._generation["hairstyle"], self.hairstyle_spec(), self.view_label()
        schedule = self.settings.hairstyle_passes
        def work(report: Report, cancelled: Cancelled) -> None:
            self._hairstyle_passes(shown, generation, spec, label, schedule, report,
                                   self._stale("hairstyle", generation, cancelled), self._wait_for_twin)
        return work

    def _hairstyle_passes(self, shown: Shown, generation: int, spec: SceneSpec, label: str,
                          schedule: tuple[int, ...], report: Report, stale: Cancelled, gate=None) -> None:
        settings = self.settings
        on, start = self.show_denoised or settings.denoise, time.perf_counter()
        for raw, spp, i in progressive(self.style_renderer, shown.params, spec, settings.hairstyle_size, schedule,
                                       stale, gate=gate):
            # OIDN's "fast" on the first pass: 0.22 s instead of 0.47 s at 512², per-pixel ΔE 1.50 for 1.48
            report(HairstylePass(generation, raw, denoised(raw, on, "fast" if i == 1 else "high"), spp, i,
                                 len(schedule), spp >= settings.hairstyle_clean_spp, label, shown.stage,
                                 time.perf_counter() - start, shown.key))

    def warm_view_work(self) -> Work:
        """Build the chosen hairstyle's scene before any capture needs it (a style picked before a capture)."""
        spec, size, renderer = self.hairstyle_spec(), self.settings.hairstyle_size, self.style_renderer

        def work(report: Report, cancelled: Cancelled) -> None:
            if not cancelled():
                renderer.render(HairParams(), spec, size, 1)
        return work

    def _strand_key(self) -> tuple:
        return (str(self.hair_file) if self.hair_file else self.style, self.settings.view_strands)

    def strand_work(self) -> Work | None:
        """The 3-D view's strands (fewer than the render's) in the estimated colour, once the twin is
        clean; None when the view already shows them. Strands are grown once per style or hair file."""
        shown = self.shown
        if shown is None or shown.params is None or shown.stage == "encoder":
            return None
        which, colour = self._strand_key(), strand_colour(shown.params)
        if self.strands is not None and (self.strands.of, self.strands.colour_rgb8) == (which, colour):
            return None
        style, hair_file, n, cache = self.style, self.hair_file, self.settings.view_strands, self._strand_cache

        def work(report: Report, cancelled: Cancelled) -> StrandPreview | None:
            from hairdigi.render.hairfile import hair_model_strands
            from hairdigi.render.strands import hairstyle_strands

            self._wait_for_twin()
            if cancelled():
                return None
            if which not in cache:
                cache[which] = hair_model_strands(hair_file, n) if hair_file else hairstyle_strands(style, n, seed=0)
            return StrandPreview(which, cache[which], colour)
        return work

    def open_hair_work(self, path: str | Path) -> Work:
        """Read, check and fit a ``.hair`` model; a bad file raises its one-line error (HairFileError)."""
        from hairdigi.render.renderer import defaults_for

        n = self.settings.hairstyle_strands or defaults_for("hairstyle").strands

        def work(report: Report, cancelled: Cancelled) -> HairModel:
            from hairdigi.render.hairfile import hair_model_strands, model_summary

            model = Path(path)
            if not model.is_file():
                raise FileNotFoundError(f"{model}: no such .hair file; choose another")
            hair_model_strands(model, n)        # read once here: the render and the 3-D view reuse it
            return HairModel(model, model_summary(model, n))
        return work

    def frame_check_due(self, period_s: float = 1.5) -> bool:
        """True when a frame should be checked for the chart and exposure (none running, ``period_s`` since)."""
        now = time.monotonic()
        busy = self._capturing or self._twin_ready < self._generation["twin"]   # a capture and its twin first
        if busy or self._checking or now - self._last_check < period_s:
            return False
        self._checking, self._last_check = True, now
        return True

    def frame_check_work(self, image: np.ndarray) -> Work:
        """Find the chart and check the exposure of one frame."""
        session = self.session

        def work(report: Report, cancelled: Cancelled) -> FrameCheck | None:
            import cv2

            from hairdigi.inference.calibration import CalibrationError, detect_chart

            try:
                try:
                    box = detect_chart(image).box
                except CalibrationError:
                    box = None
                return FrameCheck(box, session.exposure(image))
            except cv2.error:    # cv2.mcc's assertion on an odd frame (seen once in ~20 tours): try the next one
                return None
            finally:
                self._checking = False
        return work

    def calibrate_work(self) -> Work:
        session = self.session
        return lambda report, cancelled: session.calibrate()

    # -- results back from work (UI thread) --------------------------------------------------
    def apply(self, payload: object) -> None:
        """Store what a work function reported or returned, and emit its event; stale passes are dropped."""
        if isinstance(payload, TwinPreview):
            if self._current(payload, "twin", self.twin):
                self.twin = payload
                self.events.twin.emit(payload)
        elif isinstance(payload, HairstylePass):
            if self._current(payload, "hairstyle", self.hairstyle):
                self.hairstyle = payload
                self.events.hairstyle.emit(payload)
        elif isinstance(payload, StrandPreview):
            if payload.of == self._strand_key():
                self.strands = payload
                self.events.strands.emit(payload)
        elif isinstance(payload, FirstLook):
            self._show(Shown(None, payload.real, payload.roi, payload.frame_size, payload.params, "encoder",
                             {}, self.session.simulated, payload.key))
        elif isinstance(payload, Captured):
            first_look = self.shown is not None and self.shown.capture_id is None
            self.select(payload.result.capture_id, same_capture=first_look)
            self.reload()
        elif isinstance(payload, HairModel):
            self.events.hair_model.emit(payload)
            self.events.status.emit(payload.summary)
            self.set_view(hair_file=payload.path)
        elif isinstance(payload, FrameCheck):
            self.frame_check = payload
            self.events.frame_check.emit(payload)
        elif isinstance(payload, Warmed):
            parts = ", ".join(f"{k} {v:.1f} s" for k, v in payload.seconds.items())
            self.events.status.emit(f"previews ready ({parts})")
            self.events.warmed.emit(payload)
        elif isinstance(payload, dict) and "delta_e2000" in payload:   # a calibration profile
            self.events.calibration.emit(payload)

    # -- what the window reads ---------------------------------------------------------------
    def calibration(self) -> tuple[str, str]:
        """(status, one line) of the session's calibration."""
        status, reasons = self.session.calibration_status()
        return status, calibration_text(self.session.profile, status, reasons)

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

        item = self.hairstyle if which == "hairstyle" else self.twin if which == "twin" else None
        if which not in ("hairstyle", "twin"):
            raise ValueError(f"save which render? 'hairstyle' or 'twin', got {which!r}")
        if item is None:
            raise ValueError(f"no {which} render yet: capture or select a swatch first")
        linear = item.clean if self.show_denoised and item.clean is not None else item.raw
        path = Path(path)
        if path.suffix.lower() not in (".png", ".exr"):
            path = path.with_name(path.name + ".png")
        png, exr = path.with_suffix(".png"), path.with_suffix(".exr")
        return [save_png(png, linear_to_srgb8(linear)), save_exr(exr, linear)]

    def export(self, path: str | Path, all_: bool = True) -> Path:
        """The estimates as JSON: all of the session's, or the shown capture's."""
        records = [r for r in self.records if not r.get("blocked") and "hair" in r]
        if not all_ and self.shown is not None and self.shown.capture_id is not None:
            records = [r for r in records if r["id"] == self.shown.capture_id]
        if not records:
            raise ValueError("nothing to export: no capture has an estimate yet")
        return rs.export_records(records, path)


def _warm_refinement() -> None:
    """Build refinement's swatch scene once (its response curve may come from the disk cache)."""
    from hairdigi.inference.refine import refine
    from hairdigi.render.base.rig_geometry import RIG_SWATCH_POSE

    refine(HairParams(), np.array([0.08, 0.05, 0.03]), RIG_SWATCH_POSE)


def bench_previews(out_dir: str | Path, quick: bool = False) -> list[str]:
    """``hairdigi bench previews``: render/bench_previews.py on the simulated rig's twin view (at the
    scales the app renders it) and the hairstyle; the summary lines say each default's measured error
    and the cheapest clean setting."""
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN, SIM_SIZE
    from hairdigi.render.base.rig_geometry import swatch_roi
    from hairdigi.render.bench_previews import CLEAN_DE, cheapest_clean, run_previews_bench

    s = PreviewSettings()
    roi = swatch_roi(SIM_SIZE)
    twins = {scale: twin_view(roi, SIM_SIZE, True, scale) for scale, _ in s.twin_passes}
    rows = run_previews_bench(out_dir, list(twins.values()), DEFAULT_HIDDEN, quick)
    mode = "oidn" if s.denoise and any(r["mode"] == "oidn" for r in rows) else "raw"
    defaults = {("hairstyle", s.hairstyle_size): [("first pass", s.hairstyle_passes[0]),
                                                  ("clean pass", s.hairstyle_clean_spp)]}
    for scale, (_, size) in twins.items():
        firsts = [n for sc, n in s.twin_passes if sc == scale]
        defaults[("twin", size[0])] = [(f"first pass at {scale:g}x resolution", firsts[0]),
                                       ("clean pass", dict(s.twin_clean_spp)[scale])]
    lines = []
    for view, width in sorted({(r["view"], r["width"]) for r in rows}):
        best = cheapest_clean(rows, view, width)
        lines.append(f"{view} {width}px: cheapest clean (per-pixel ΔE2000 <= {CLEAN_DE:g}): "
                     + (f"{best['spp']} spp {best['mode']}, {best['total_s']:.2f} s, ΔE {best['pixel_de2000']:.2f}"
                        if best else "none"))
        for label, spp in defaults.get((view, width), []):
            row = next((r for r in rows if (r["view"], r["width"], r["spp"], r["mode"]) == (view, width, spp, mode)),
                       None)
            if row is not None:
                lines.append(f"  app default {label}: {spp} spp {mode}: per-pixel ΔE2000 {row['pixel_de2000']:.2f}, "
                             f"mean colour {row['mean_colour_de2000']:.2f}, {row['total_s']:.2f} s")
    return lines
