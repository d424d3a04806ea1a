"""The review of captures, free of Qt: :class:`ReviewModel`, the state the window shows and the work behind it.

napari-style. The model holds the review state: the session's records, the shown capture (with its
own calibration profile), its parameters, the twin preview (real, synthetic raw and denoised, the
ΔE2000 map, the mean-colour ΔE2000), the hairstyle choice, camera orbit and passes, the strand
preview, the lights and the feed rate, and the light the capture and its twin are compared under (all
lights, or one alone: :meth:`ReviewModel.set_light_view`). Widgets subscribe to its typed events
(``app/review/payloads.py``: ``model.events.twin.connect(callback)``) and read its views
(:meth:`ReviewModel.parameter_view`, written by ``app/review/text.py``).

It is a :class:`~hairdigi.app.models.panel.PanelModel` (``app/models/``), as the Dye and Library panels'
models are: everything slow is a ``Work`` a worker runs off the UI thread: reading the records, a capture
and the thumbnails (``reads.py``, ``thumbnails.py``), the capture and warm-up (``capture.py``), the
previews. Its values come back to ``apply`` on the model's thread, the only thread that changes the
model's state; it stops at a yield when cancelled, and ``Work.ended`` runs on the model's thread at the
end. A new capture, selection or parameters bump the generation of the work they make stale: stale work
stops before its next pass, and whatever it still yields is dropped.

The order after a capture: the capture's work yields the encoder's estimate (the first look, from the
session's ``on_encoder_estimate`` hook) and its first twin and hairstyle passes, then the refined
record with the records read back; the refined twin renders until it is clean, and only then its
hairstyle passes take turns with it. Every render takes one lock (``render.renderer.RENDER_LOCK``).
"""
from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path

import numpy as np

from hairdigi.app.models.events import Status
from hairdigi.app.models.panel import PanelModel
from hairdigi.app.models.work import Work, returns
from hairdigi.app.review.capture import capture_passes, check_frame, read_back, warm_scenes
from hairdigi.app.review.payloads import (KEYS, CaptureRead, Calibrated, Captured, Display, Entry, Events, FeedRate,
                                          FirstLook, FrameCheck, HairModel, LightView, Lights, Problem, Records, Shown,
                                          StrandPreview, Thumbnail, View, Warmed, Warnings)
from hairdigi.app.review.previews import (HairstylePass, PassTag, PreviewSettings, Stage, TwinPreview,
                                          hairstyle_passes, orbit_pose, scalp_linear, scene_appearance,
                                          strand_colour, twin_passes, twin_view)
from hairdigi.app.review.reads import read_capture, read_hair_model, read_records
from hairdigi.app.review.text import (ParameterView, as_profile, calibration_text, light_name, nonfinite_warning,
                                      parameter_view)
from hairdigi.app.review.thumbnails import thumbnail_work
from hairdigi.app.session import rig_session as rs
from hairdigi.render import denoise as dn
from hairdigi.render.domain.bounds import ENVIRONMENTS, HAIRSTYLES, ILLUMINANTS, SceneKind, defaults_for
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, EstimateWarning
from hairdigi.render.domain.rig_geometry import N_LIGHTS
from hairdigi.render.hairfile import hair_model_strands
from hairdigi.render.io import images
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.srgb import linear_to_srgb8
from hairdigi.render.strands import hairstyle_strands

#: ``set_view``'s "leave this as it is" (None is a value of its ``illuminant``).
KEEP: object = object()
#: The lights a hairstyle can be seen under: (label, ``SceneSpec.illuminant``); None is the RGB world's white.
HAIRSTYLE_LIGHTS = (("rig lights (RGB)", None), ("daylight (D65)", "D65"), ("tungsten (A)", "A"),
                    ("shop LED (LED-B3)", "shop-led"), ("fluorescent (FL11)", "FL11"))

__all__ = ["ReviewModel", "ReviewError", "KEEP", "HAIRSTYLE_LIGHTS"]


class ReviewError(HairdigiError, ValueError):
    """What the review cannot do for the operator now (nothing to export yet), with what to do."""


class ReviewModel(PanelModel):
    """The review state of one rig session, and the work that updates it (see the module's note)."""

    Events = Events

    def __init__(self, session: rs.RigSession, settings: PreviewSettings | None = None) -> None:
        super().__init__()
        self.session = session
        self.settings = settings or PreviewSettings()
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
        # the kinds of work a generation makes stale, there before any work reads them from its thread
        self._generation.update(dict.fromkeys(("twin", "hairstyle", "records", "select"), 0))
        self._twin_state = threading.Condition()
        self._twin_ready = 0                    # the twin generation that is clean (or done): the hairstyle waits for it
        self._style_state = threading.Condition()
        self._style_ready = 0                   # the hairstyle generation with a refined pass: the clean twin's next waits
        self._style_wanted = 0                  # the hairstyle generation whose passes run
        self._capturing = False
        self._strand_cache: dict[tuple, object] = {}
        self._last_check = 0.0
        self._checking = False
        self._feed_fps = self.settings.feed_fps

    # -- the twin goes first: the hairstyle and the 3-D view wait until it is clean -------------
    def _twin_is_ready(self, generation: int) -> None:
        with self._twin_state:
            self._twin_ready = max(self._twin_ready, generation)
            self._twin_state.notify_all()

    def _wait_for_twin(self, timeout_s: float = 30.0) -> None:
        """Until the current twin is clean (the hairstyle and the 3-D view let the twin go first)."""
        with self._twin_state:
            self._twin_state.wait_for(lambda: self._twin_ready >= self._generation["twin"], timeout_s)

    # -- then the hairstyle's first refined pass: the clean twin's further passes wait for it -----------
    def _style_is_ready(self, generation: int) -> None:
        with self._style_state:
            self._style_ready = max(self._style_ready, generation)
            self._style_state.notify_all()

    def _wait_for_style(self, timeout_s: float = 10.0) -> None:
        """Until the current hairstyle, where its passes run, has a refined pass (the clean twin's further
        passes, 2-3 s each at full resolution, let its first one go: the tour's clean hairstyle came 4.3 s after the
        clean twin)."""
        with self._style_state:
            self._style_state.wait_for(lambda: self._style_ready >= self._generation["hairstyle"]
                                       or self._style_wanted < self._generation["hairstyle"], timeout_s)

    def stop(self) -> None:
        """Make all running work stale (closing the window), and let no one wait for the twin or the hairstyle."""
        super().stop()
        self._twin_is_ready(self._generation["twin"])
        self._style_is_ready(self._generation["hairstyle"])

    # -- the live feed and the lights ----------------------------------------------------------
    def busy(self) -> bool:
        """A capture is estimated, or the shown estimate's twin is not clean yet."""
        return self._capturing or self._twin_ready < self._generation["twin"]

    def _update_feed(self) -> None:
        fps = self.settings.busy_feed_fps if self.busy() else self.settings.feed_fps
        if fps != self._feed_fps:
            self._feed_fps = fps
            self.events.feed_fps.emit(FeedRate(fps))

    def feed_period(self) -> float:
        """Seconds between the live feed's frames, now."""
        return 1.0 / self._feed_fps

    @staticmethod
    def light_count() -> int:
        return N_LIGHTS

    def lights_work(self) -> Work:
        """Read the light board: each light's state, and what the board says it is."""
        session = self.session
        return Work("lights", returns(lambda: Lights(tuple(st.on for st in session.light_states()),
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

    # -- records and selection: read by works, shown by apply ---------------------------------
    def reload_work(self) -> Work:
        """Re-read the session's result records (an unreadable one is named in an ``error``)."""
        folder, generation = self.session.folder, self._bump("records")
        return Work("records", returns(lambda: read_records(folder, generation)))

    def _apply_records(self, records: Records) -> None:
        if records.generation and not self._current("records", records.generation):
            return
        for line in records.left_out:
            self.events.error.emit(Problem(line))
        self.records = list(records.entries)
        self.events.records.emit(records)

    def thumbnail_work(self) -> Work | None:
        """Read the thumbnails not read yet, off the model's thread; None when there are none."""
        return thumbnail_work(self.session.folder, [e for e in self.records if e.id not in self.thumbnails])

    def select_work(self, capture_id: str) -> Work:
        """Read a saved capture back with its own calibration profile; its apply emits ``shown`` and
        ``parameters``. A newer selection drops this one."""
        session, generation = self.session, self._bump("select")
        return Work("select", returns(lambda: read_capture(session, capture_id, False, generation)))

    def _apply_read(self, read: CaptureRead) -> None:
        """Review the capture read: the same estimate again (a reload) keeps the previews running."""
        if read.generation and not self._current("select", read.generation):
            return
        if read.problems:
            self.events.error.emit(Problem("; ".join(read.problems)))
        rec, shown, capture_id = read.record, self.shown, read.capture_id
        same = shown is not None and (read.same_capture or shown.capture_id == capture_id)
        new = Shown(capture_id, read.real, read.roi, read.frame_size, rec.hair,
                    Stage.BLOCKED if rec.hair is None else Stage.REFINED, rec, self.session.simulated,
                    shown.key if same else next(KEYS), read.light_frames)
        if shown is not None and shown.capture_id == capture_id and shown.params == rec.hair:
            self.shown = new
            return
        self._show(new)

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

    def _shows(self, payload, kind: str, showing) -> bool:
        """A pass is shown when its work is current, or when it is the first pass of the shown capture
        (a first-look pass that finished after the refined estimate came beats an empty panel)."""
        if self._current(kind, payload.generation):
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
        self.events.view.emit(View(self.view_label()))

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
        self.events.light_view.emit(LightView(light))

    def twin_scene(self, scale: float = 1.0) -> tuple[SceneSpec, tuple[int, int]] | None:
        """The shown capture's twin at ``scale``: its appearance, lit by the chosen light; None with no capture."""
        shown = self.shown
        if shown is None:
            return None
        return twin_view(shown.roi, shown.frame_size, shown.simulated, scale, shown.appearance, self.light,
                         shown.swatch_model)

    def view_label(self) -> str:
        light = "" if self.illuminant is None else f", under {self.illuminant}"
        return f"{self.hair_file.name if self.hair_file else self.style}, {self.env}{light}"

    def set_denoised(self, on: bool) -> None:
        """Show the denoised passes (True) or the raw path-traced ones; no re-render."""
        self._owner()
        self.show_denoised = bool(on) and dn.available()
        self.events.display.emit(Display(self.show_denoised))
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
        session, settings, spec = self.session, self.settings, self.hairstyle_spec()
        twin_renderer, style_renderer = self.twin_renderer, self.style_renderer
        return Work("warm-up", lambda: warm_scenes(session, settings, spec, twin_renderer, style_renderer))

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
            self.events.light_view.emit(LightView(None))
        self._bump("twin", "hairstyle")       # stale previews stop now and leave the cores to the capture
        self._twin_is_ready(self._generation["twin"])
        self._capturing = True
        self._update_feed()
        tag = PassTag(self._generation["twin"], next(KEYS), Stage.ENCODER)
        style_tag = PassTag(self._generation["hairstyle"], tag.key, Stage.ENCODER)
        tags, renderers = (tag, style_tag), (self.twin_renderer, self.style_renderer)
        return Work("capture", lambda: capture_passes(session, settings, spec, label, on, tags, renderers),
                    ended=self._capture_ended, must_start=True)

    def import_still_work(self, path: str | Path) -> Work:
        """A RAW still of the rig as a capture (copied, calibrated on its own chart, estimated)."""
        session = self.session
        return Work("RAW still", returns(lambda: read_back(session, session.import_still(path))))

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
                                           appearance, light, shown.swatch_model)
            yield from twin_passes(renderer, shown.twin_hair, real, view, settings.twin_passes, settings, on, tag,
                                   self._stale("twin", generation), after_clean=self._wait_for_style)
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
            with self._style_state:             # running: the clean twin's further passes wait for its first
                self._style_wanted = max(self._style_wanted, generation)
            yield from hairstyle_passes(renderer, shown.params, spec, label, settings.hairstyle_passes, settings, on,
                                        tag, self._stale("hairstyle", generation), self._wait_for_twin)
        return Work("hairstyle", run, ended=lambda: self._style_is_ready(generation))

    def warm_view_work(self) -> Work:
        """Build the chosen hairstyle's scene before any capture needs it (a style picked before a capture)."""
        spec, size, renderer = self.hairstyle_spec(), self.settings.hairstyle_size, self.style_renderer
        return Work("hairstyle", returns(lambda: renderer.render(HairParams(), spec, size, 1) and None))

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
            self._wait_for_twin()
            yield None                  # cancelled meanwhile: stop here
            strands = grown or (hair_model_strands(hair_file, n) if hair_file else hairstyle_strands(style, n, seed=0))
            return StrandPreview(which, strands, colour, scalp)
        return Work("strands", run)

    def open_hair_work(self, path: str | Path) -> Work:
        """Read, check and fit a ``.hair`` model; a bad file raises its one-line error (HairFileError)."""
        n = self.settings.hairstyle_strands or defaults_for("hairstyle").strands
        return Work("hair model", returns(lambda: read_hair_model(Path(path), n)))

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
        return Work("chart", returns(lambda: check_frame(session, image)), ended=self._check_ended)

    def _check_ended(self) -> None:
        self._checking = False

    def calibrate_work(self) -> Work:
        session = self.session
        return Work("calibration", returns(lambda: Calibrated(as_profile(session.calibrate()))))

    # -- results back from work (the model's thread: PanelModel.apply hands them here) ---------
    def show_status(self, text: str) -> None:
        """The status line: the review's ``status`` event carries a :class:`Status` (the panels' a str)."""
        self.status = text
        self.events.status.emit(Status(text))

    def _apply_twin(self, t: TwinPreview) -> None:
        if not self._shows(t, "twin", self.twin):
            return
        self.twin = t
        if t.clean_enough and t.stage == Stage.REFINED and self._current("twin", t.generation):
            self._twin_is_ready(t.generation)   # clean: the hairstyle's passes may take turns with the twin
            self._update_feed()
        if t.nonfinite:
            self._warn(nonfinite_warning("twin", t.nonfinite))
        self.events.twin.emit(t)

    def _apply_hairstyle(self, p: HairstylePass) -> None:
        if not self._shows(p, "hairstyle", self.hairstyle):
            return
        self.hairstyle = p
        if p.stage == Stage.REFINED and self._current("hairstyle", p.generation):
            self._style_is_ready(p.generation)   # the clean twin's further passes may go on
        if p.nonfinite:
            self._warn(nonfinite_warning("hairstyle", p.nonfinite))
        self.events.hairstyle.emit(p)

    def _warn(self, warning: EstimateWarning) -> None:
        if warning.kind not in {w.kind for w in self.preview_warnings}:
            self.preview_warnings += (warning,)
            self.events.warnings.emit(Warnings(self.preview_warnings))

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
        if isinstance(captured.read, Problem):
            self.events.error.emit(captured.read)
        elif captured.read is not None:
            self._bump("select")          # an older selection's read is dropped
            self._apply_read(dataclasses.replace(captured.read, same_capture=first_look,
                                                 generation=self._generation["select"]))
        if captured.records is not None:
            self._bump("records")
            self._apply_records(dataclasses.replace(captured.records, generation=self._generation["records"]))

    def _apply_hair_model(self, model: HairModel) -> None:
        self.events.hair_model.emit(model)
        self.show_status(model.summary)
        self.set_view(hair_file=model.path)

    def _apply_frame_check(self, check: FrameCheck) -> None:
        self._checking = False
        if check.exposure is not None:
            self.frame_check = check
            self.events.frame_check.emit(check)

    def _apply_warmed(self, warmed: Warmed) -> None:
        parts = ", ".join(f"{k} {v:.1f} s" for k, v in warmed.seconds.items())
        self.show_status(f"previews ready ({parts})")
        self.events.warmed.emit(warmed)

    def _apply_calibrated(self, calibrated: Calibrated) -> None:
        self.events.calibration.emit(calibrated)

    def _apply_lights(self, lights: Lights) -> None:
        self.events.lights.emit(lights)

    def _apply_thumbnail(self, thumb: Thumbnail) -> None:
        self.thumbnails[thumb.capture_id] = thumb.rgb
        self.events.thumbnail.emit(thumb)

    def _apply_problem(self, problem: Problem) -> None:
        self.events.error.emit(problem)

    _HANDLERS = {Records: _apply_records, CaptureRead: _apply_read, Problem: _apply_problem,
                 TwinPreview: _apply_twin, HairstylePass: _apply_hairstyle, StrandPreview: _apply_strands,
                 FirstLook: _apply_first_look, Captured: _apply_captured, HairModel: _apply_hair_model,
                 FrameCheck: _apply_frame_check, Warmed: _apply_warmed, Calibrated: _apply_calibrated,
                 Lights: _apply_lights, Thumbnail: _apply_thumbnail}

    # -- what the window reads ---------------------------------------------------------------
    def calibration(self) -> tuple[rs.CalibrationStatus, str]:
        """(status, one line) of the session's calibration."""
        status, reasons = self.session.calibration_status()
        return status, calibration_text(as_profile(self.session.profile), status, reasons)

    def calibration_work(self) -> Work:
        """:meth:`calibration` in a worker: it returns (status, one line)."""
        return Work("calibration status", returns(self.calibration))

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
        return write_render(self._shown_render(which), path)

    def save_render_work(self, which: str, path: str | Path) -> Work:
        """:meth:`save_render` in a worker, of the render shown now (checked here); it returns the paths."""
        linear = self._shown_render(which)
        return Work(f"save {which}", returns(lambda: write_render(linear, path)))

    def _shown_render(self, which: str) -> np.ndarray:
        """The shown ``"hairstyle"`` or ``"twin"`` render, linear (denoised when shown so)."""
        if which not in ("hairstyle", "twin"):
            raise ValueError(f"save which render? 'hairstyle' or 'twin', got {which!r}")
        item = self.hairstyle if which == "hairstyle" else self.twin
        if item is None:
            raise ReviewError(f"no {which} render yet: capture or select a swatch first")
        return item.clean if self.show_denoised and item.clean is not None else item.raw

    def export(self, path: str | Path, all_: bool = True) -> Path:
        """The estimates as JSON: all of the session's, or the shown capture's."""
        return rs.export_records(self._to_export(all_), path)

    def export_work(self, path: str | Path, all_: bool = True) -> Work:
        """:meth:`export` in a worker, of the records chosen now (checked here); it returns the path."""
        records = self._to_export(all_)
        return Work("export", returns(lambda: rs.export_records(records, path)))

    def _to_export(self, all_: bool) -> list[EstimateRecord]:
        """The records to export: all of the session's with an estimate, or the shown capture's."""
        entries = [e for e in self.records if e.record.hair is not None]
        if not all_ and self.shown is not None and self.shown.capture_id is not None:
            entries = [e for e in entries if e.id == self.shown.capture_id]
        if not entries:
            raise ReviewError("nothing to export: no capture has an estimate yet")
        return [e.record for e in entries]


def write_render(linear: np.ndarray, path: str | Path) -> list[Path]:
    """A linear render as ``path`` (.png, sRGB) and beside it linear .exr; the written paths."""
    path = Path(path)
    if path.suffix.lower() not in (".png", ".exr"):
        path = path.with_name(path.name + ".png")
    png, exr = path.with_suffix(".png"), path.with_suffix(".exr")
    return [images.save_png(png, linear_to_srgb8(linear)), images.save_exr(exr, linear)]
