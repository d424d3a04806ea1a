"""The bench session, free of Qt: lights, exposure, calibration, capture and estimate in one object.

The GUI and ``hairdigi rig`` both drive this; it calls ``hardware/``, ``inference/`` and ``render/``
and holds no science of its own. Every capture is written to disk before anything reads it.

Why one module over 600 lines: what a capture writes (``RigSession.capture``, ``import_still``,
``_write_result``) and what reads a session folder back (``load_capture``, ``load_results``) are
one contract on the folder's layout; kept in one module, a change to either is made beside the other.
"""
from __future__ import annotations

import os
import shutil
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from hairdigi.hardware.cameras import MAX_RAW_BYTES, RAW_EXTENSIONS, CameraError, OpenCVCamera, read_raw
from hairdigi.hardware.capture import save_capture
from hairdigi.app.session.blockers import Blocker, BlockerKind, messages
from hairdigi.hardware.exposure import ExposureReport, ExposureStatus, check_exposure, dead_lights
from hairdigi.hardware.frame_source import FrameSource
from hairdigi.hardware.genicam import FAKE_ID, GenICamCamera
from hairdigi.hardware.lights import N_LIGHTS, LightController, LightError, discover
from hairdigi.hardware.sim_genicam import open_lab_camera
from hairdigi.hardware.sim_lights import SimulatedLightBoard
from hairdigi.inference.instrument_reading import with_instrument
from hairdigi.inference.calibration import (DEFAULT_METHOD, CalibrationError, apply_profile, calibrate,
                                            correction_warnings, detect_chart, light_colour_warnings, load_profile,
                                            profile_warnings, save_profile, staleness)
from hairdigi.inference.preprocess import find_swatch_core, to_linear
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE
from hairdigi.render.camera_model import CameraModel
from hairdigi.inference.refine import RefineSettings, fitted_pixels, mean_linear, response_curve, scene_for
from hairdigi.inference.shine import shine_tables
from hairdigi.inference.structure import READ_MEMBERS, family_curves, family_view
from hairdigi.inference.spectral_reading import RigSpectra, spectral_record
from hairdigi.inference.estimate import calibration_summary, estimate_image, read_rig_structure, record
from hairdigi.inference.encoder import Encoder, ModelError
from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE, StructureMode
from hairdigi.render.domain.files import write_json_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import (CalibrationProfile, CaptureRecord, EstimateRecord, EstimateWarning,
                                            WarningKind, read_record, read_session_capture, write_record)
from hairdigi.render.domain.session_folder import SessionFolder, capture_id_of
from hairdigi.render.domain.text_enum import TextEnum
from hairdigi.render.domain.rig_geometry import RIG_HALF_WIDTH, CameraPose, RigRegion
from hairdigi.render.srgb import linear_to_srgb8

#: How much longer a single-light frame is exposed, where the camera can (``RigSession.light_frames``).
LIGHT_FRAME_EV = 1.5


@dataclass
class CaptureResult:
    capture_id: str
    image_path: Path
    meta_path: Path
    params: HairParams | None = None
    record: EstimateRecord | None = None
    blocked: list[Blocker] = field(default_factory=list)   # why no estimate was made
    corrected: np.ndarray | None = None                # the colour-corrected frame that was estimated (linear)
    seconds: float = 0.0
    curve: object | None = None                        # the response curve the refinement inverted


class CalibrationStatus(TextEnum):
    """The rig's calibration: none yet, stale (the camera's settings or the profile's age say so), or ok."""

    UNCALIBRATED = "uncalibrated"
    STALE = "stale"
    OK = "ok"


@dataclass
class LoadedCapture:
    """A capture read back for review: its frame, swatch area, records and own calibration."""

    capture_id: str
    frame: np.ndarray                  # RGB, as captured (before colour correction)
    roi: tuple[int, int, int, int]
    record: EstimateRecord | None      # None: no result was saved (or it could not be read)
    profile: CalibrationProfile | None  # the profile it was corrected with; None if uncalibrated
    capture: CaptureRecord | None = None
    linear: np.ndarray | None = None   # linear RGB where the source has it (a RAW still)
    problems: list[str] = field(default_factory=list)   # files of this capture that could not be read
    light_frames: list = field(default_factory=list)     # each light's own frame (RGB), None where unreadable
    light_exposures: tuple[float, ...] = ()              # each one's exposure over the frame's

    def corrected_swatch_linear(self) -> np.ndarray:
        """The swatch area, colour-corrected with the capture's own profile, in linear light."""
        x, y, w, h = self.roi
        source = self.linear if self.linear is not None else self.frame
        real = source[y:y + h, x:x + w]
        return to_linear(real) if self.profile is None else apply_profile(real, self.profile)

    def corrected_swatch(self) -> np.ndarray:
        """The swatch area, colour-corrected with the capture's own profile, as 8-bit sRGB for display."""
        return linear_to_srgb8(self.corrected_swatch_linear())


def rig_region(frame_size: tuple[int, int], roi, pose: CameraPose = CameraPose(),
               half_width: float = RIG_HALF_WIDTH) -> RigRegion:
    """The swatch area ``roi`` of a frame of the rig camera (the bench camera unless ``pose`` and
    ``half_width`` say otherwise): what the refinement fits and renders."""
    return RigRegion((int(frame_size[0]), int(frame_size[1])), tuple(int(v) for v in roi), pose,
                     half_width=half_width)


class RigSession:
    """One camera (owned by its frame source), one light board, one session folder, and the current
    calibration profile."""

    def __init__(self, camera, lights: LightController | None, folder: str | Path, swatch_roi=None,
                 encoder=None, simulated: bool = False, spectra=None, structure: str = DEFAULT_STRUCTURE) -> None:
        self.camera = camera
        #: how its estimates treat the swatch's physical structure (``render.domain.bounds.STRUCTURE_MODES``:
        #: ``inference.estimate.estimate_image``'s ``structure``)
        self.structure = StructureMode(structure)
        #: the rig's LEDs and camera sensitivities (``inference.spectral_reading.RigSpectra``): declared, a capture's
        #: record carries its reading in the camera's RGB and colour under other lights; None on a real rig,
        #: its colour interval carries the metamerism of an undeclared camera
        self.spectra = spectra
        #: how the records' instrument readings are stated (``inference.instrument_reading.with_instrument``'s options:
        #: observer, aperture_mm); empty: D65, 10°, 8 mm
        self.instrument: dict = {}
        self.frames = FrameSource(camera)   # every read of the camera goes through here
        self.lights = lights
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.swatch_roi = swatch_roi
        self._encoder = encoder
        self.simulated = simulated
        #: where the camera stands around the rig's target, and what its view shows there
        self.pose, self.half_width = getattr(camera, "pose", CameraPose()), getattr(camera, "half_width", RIG_HALF_WIDTH)
        self.profile_path = SessionFolder(self.folder).calibration
        self.notices: list[str] = []     # what the session set aside on opening, for the operator
        self.profile = self._load_profile()
        self.last_frame = None
        self._board = None

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def simulated_rig(cls, folder: str | Path, hidden: HairParams | None = None, camera_model=None,
                      dead: set[int] | None = None, spp: int = 32, encoder=None,
                      pose: CameraPose = CameraPose(), half_width: float = RIG_HALF_WIDTH,
                      appearance=None, strand_seed: int = 0, genicam: str | None = None,
                      illuminant: str | None = None, sensitivities: str | None = None,
                      swatch_model: str | None = None, structure: str = DEFAULT_STRUCTURE) -> "RigSession":
        """The bench in software: a pty light board, the rendered rig, and a camera model; the hidden
        swatch is ``hidden`` with ``appearance`` (shine and fibre variation; default uniform). With
        ``genicam`` (Aravis's fake camera ID) the frames come through the GenICam path as 12-bit Bayer.
        ``illuminant`` makes it a spectral rig: LEDs of that SPD, the chart's measured spectra, seen by
        a camera's ``sensitivities`` (or the CIE observer); ``hidden`` may then be an absorption spectrum.
        ``swatch_model``: the hidden swatch's physical structure (``render.swatch_family``; None: layered);
        ``structure``: how the session's estimates treat it."""
        # deferred: sim_rig loads Mitsuba (the simulated rig renders); a real rig never does
        from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN, SimRig
        board = SimulatedLightBoard()
        lights = LightController(board.port)
        rig = SimRig(DEFAULT_HIDDEN if hidden is None else hidden, camera_model or CameraModel(), spp=spp,
                     dead_lights=set(dead or ()), board=board, pose=pose, half_width=half_width,
                     appearance=appearance or DEFAULT_APPEARANCE, strand_seed=strand_seed,
                     illuminant=illuminant, sensitivities=sensitivities, swatch_model=swatch_model)
        camera = rig
        if genicam is not None:    # the same rig seen through Aravis's fake camera, as a 12-bit lab camera
            response = np.asarray(rig.camera.cast, np.float32) * np.float32(2.0 ** rig.camera.exposure_ev)
            camera = open_lab_camera(rig.radiance, response=response, size=rig.size, device_id=genicam)[0]
            camera.hidden, camera.appearance = rig.hidden, rig.appearance   # the truth, as SimRig tells it
            camera.swatch_model = rig.swatch_model                            # and the strands it lies on
        spectra = None
        if illuminant is not None:
            spectra = RigSpectra(illuminant, sensitivities)
        session = cls(camera, lights, folder, rig.roi, encoder, simulated=True, spectra=spectra, structure=structure)
        session._board = board
        for i in range(N_LIGHTS):
            lights.set_light(i, True, 255)
        return session

    def close(self) -> None:
        if self.lights is not None:
            self.lights.close()
        if self._board is not None:
            self._board.close()
        self.frames.close()

    def _load_profile(self) -> CalibrationProfile | None:
        """The session's profile; a corrupt one is set aside (kept, renamed) and the rig starts
        uncalibrated, so one bad file never locks the operator out."""
        if not self.profile_path.exists():
            return None
        try:
            return load_profile(self.profile_path)
        except CalibrationError as exc:
            aside = self.profile_path.with_name(f"calibration.unreadable-{time.strftime('%Y%m%d-%H%M%S')}.json")
            self.profile_path.replace(aside)
            self.notices.append(f"{exc}; it was set aside as {aside.name}: calibrate again with the chart in view")
            return None

    @property
    def encoder(self):
        if self._encoder is None:
            self._encoder = Encoder()
        return self._encoder

    # -- lights and frames -------------------------------------------------------------------
    def set_light(self, index: int, on: bool) -> None:
        self.lights.set_light(index, on)

    def set_all(self, on: bool) -> None:
        if on:
            for i in range(N_LIGHTS):
                self.lights.set_light(i, True)
        else:
            self.lights.all_off()

    def light_states(self):
        return self.lights.status()

    def frame(self):
        """A frame exposed after this call (so after any light switched before it)."""
        self.last_frame = self.frames.next_frame()
        return self.last_frame

    def settings(self) -> dict:
        """Camera and light settings a calibration depends on."""
        s = {"camera": getattr(self.camera, "name", "camera"), **self.frames.settings()}
        try:
            s["lights"] = [[int(st.on), st.intensity] for st in self.lights.status()]
        except (LightError, AttributeError):
            pass
        return s

    def prepare_refinement(self) -> float:
        """Render (or load) what an estimate of the rig's swatch area needs in the session's structure mode:
        the refinement's response curve and the shine's per-light tables; in the family and read modes every
        read member's tables, and in the family mode the family's curves. Returns their seconds (0 when cached)."""
        region = self.region(self.frame().srgb)
        curve = response_curve(region, RefineSettings())
        start = time.perf_counter()
        for member in (None,) if self.structure is StructureMode.ASSUMED else READ_MEMBERS:
            shine_tables(region, RefineSettings(), swatch_model=member)
        if self.structure is StructureMode.FAMILY:
            family_curves(family_view(region), RefineSettings())
        return (0.0 if curve.cached else curve.seconds) + time.perf_counter() - start

    def region(self, image: np.ndarray) -> RigRegion:
        """The swatch area of a frame of this rig's camera, as the refinement fits and renders it."""
        return rig_region((image.shape[1], image.shape[0]), self._roi(image), self.pose, self.half_width)

    # -- checks ------------------------------------------------------------------------------
    def exposure(self, image: np.ndarray | None = None) -> list[ExposureReport]:
        image = self.frame().srgb if image is None else image
        try:
            white = detect_chart(image).white_patch_box()
        except CalibrationError:
            white = None
        return check_exposure(image, self._roi(image), white)

    def check_lights(self) -> list[int]:
        """Switch each light alone and return the ones that do not light the scene; restores the state."""
        before = self.lights.status()
        self.lights.all_off()
        dark = self.frame().srgb
        singles = []
        for i in range(N_LIGHTS):
            self.lights.all_off()
            self.lights.set_light(i, True)
            singles.append(self.frame().srgb)
        self.lights.all_off()
        for i, st in enumerate(before):
            self.lights.set_light(i, st.on)
        # the whole frame, not the swatch: glossy hair sends light 0 (along the fibres) almost nothing,
        # though the light works (it lights the holder and the chart as the others do)
        return dead_lights(dark, singles, (0, 0, dark.shape[1], dark.shape[0]))

    def _roi(self, image: np.ndarray) -> tuple[int, int, int, int]:
        if self.swatch_roi is not None:
            return tuple(self.swatch_roi)
        r = find_swatch_core(image)[0]
        return r.x, r.y, r.w, r.h

    # -- calibration -------------------------------------------------------------------------
    def calibrate(self, method: str | None = None, frames: int = 4) -> CalibrationProfile:
        """Fit a CCM on the mean of a few frames, averaged in linear light (less noise), and save the profile."""
        linear = np.mean([frame_linear(self.frame()) for _ in range(frames)], axis=0)
        self.profile = calibrate(linear_to_srgb8(linear), method or DEFAULT_METHOD, settings=self.settings(),
                                 linear=linear)
        save_profile(self.profile_path, self.profile)
        return self.profile

    def calibration_status(self) -> tuple[CalibrationStatus, list[str]]:
        """The calibration's status and the reasons behind it (none when it is ok)."""
        if self.profile is None:
            return CalibrationStatus.UNCALIBRATED, ["the rig is not calibrated: press Calibrate with the chart in view"]
        reasons = staleness(self.profile, self.settings())
        return (CalibrationStatus.STALE if reasons else CalibrationStatus.OK), reasons

    # -- capture -----------------------------------------------------------------------------
    def light_frames(self) -> tuple[list, list[float]]:
        """One frame per light alone, at full power, in light order, and each one's exposure over the
        bench's; the board's state is restored after. Where the camera can (``set_exposure_offset``),
        a light's frame is exposed ``LIGHT_FRAME_EV`` longer, since one light gives about a third of
        the light (the light along the fibres far less on glossy hair); a frame whose swatch clips
        is taken again at the bench's exposure."""
        before = self.lights.status()
        adjustable = callable(getattr(self.camera, "set_exposure_offset", None))
        frames, factors = [], []
        try:
            for i in range(N_LIGHTS):
                self.lights.all_off()
                self.lights.set_light(i, True, 255)
                ev = LIGHT_FRAME_EV if adjustable and self.camera.set_exposure_offset(LIGHT_FRAME_EV) else 0.0
                frame = self.frame()
                if ev and check_exposure(frame.srgb, self._roi(frame.srgb))[0].status is ExposureStatus.OVER:
                    self.camera.set_exposure_offset(0.0)
                    ev, frame = 0.0, self.frame()
                frames.append(frame)
                factors.append(2.0 ** ev)
        finally:
            if adjustable:
                self.camera.set_exposure_offset(0.0)
            self.lights.all_off()
            for i, st in enumerate(before):
                self.lights.set_light(i, st.on, st.intensity)
        return frames, factors

    def capture(self, estimate: bool = True,
                on_encoder_estimate: Callable[[HairParams], None] | None = None,
                per_light: bool | None = None) -> CaptureResult:
        """Take one frame per light alone, then the frame with the lights as set; save them and the
        capture record first; then check, correct and estimate, or say why not.

        ``per_light`` (default: when the rig has a light board) takes the single-light frames, from
        which the estimate reads the shine. ``on_encoder_estimate`` is told the encoder's parameters
        before refinement starts."""
        start = time.perf_counter()
        singles, factors = self.light_frames() if (self.lights is not None if per_light is None else per_light) \
            else ([], [])
        frame = self.frame()
        roi = self._roi(frame.srgb)
        image_path, meta_path, capture = save_capture(
            SessionFolder(self.folder).captures, frame.srgb, lights=self.settings().get("lights"), frame_meta=frame.meta,
            calibration=self.profile, simulated=self.simulated, swatch_roi=roi,
            light_frames=[f.srgb for f in singles], light_exposures=tuple(factors),
            mosaic=None if frame.mosaic is None else (frame.mosaic, frame.meta["bayer"]))
        result = CaptureResult(capture.id, image_path, meta_path)
        result.blocked, chart = self._check(frame.srgb)
        if estimate and not result.blocked:   # a raw frame is estimated from its linear light, as a RAW still
            _estimate(result, frame.srgb, frame.linear, self.encoder_or_reason, self.profile, self.region(frame.srgb),
                      profile_warnings(self.profile, self.settings()), on_encoder_estimate,
                      [(f.srgb if f.linear is None else f.linear, k) for f, k in zip(singles, factors)], chart,
                      structure=self.structure)
        result.seconds = time.perf_counter() - start    # capture to parameters; the spectral reading follows
        if result.record is not None:
            result.record = with_instrument(self.in_spectral_world(result.record, curve=result.curve), **self.instrument)
        _write_result(self.folder, result, roi)
        return result

    def in_spectral_world(self, record: EstimateRecord, profile: CalibrationProfile | None = None,
                          curve=None) -> EstimateRecord:
        """``record`` with its spectral reading (the rig's spectra declared) or the metamerism of an
        undeclared camera in its colour interval (a real rig); the simulated RGB rig's is left as it is.
        ``profile``: the chart correction the capture was made with (default: the session's); ``curve``:
        the response curve its refinement inverted (default: the rig's swatch crop's)."""
        if self.simulated and self.spectra is None:
            return record
        profile = profile or self.profile
        return spectral_record(record, self.spectra, profile, curve)

    def load_capture(self, capture_id: str) -> "LoadedCapture":
        """A saved capture with what reviewing it needs: the frame, its swatch area, its result record,
        and the calibration profile it was taken with (not the session's current one). A result or
        capture record that cannot be read is named in ``problems``, and the frame is still shown."""
        session = SessionFolder(self.folder)
        read = read_session_capture(session, capture_id)
        record, capture, profile, problems = read.result, read.capture, read.profile, list(read.problems)
        image = session.image((capture.image if capture else "") or f"{capture_id}.png")
        linear = None
        if not image.is_file():      # missing, or a FIFO or device that would hang the reader
            raise FileNotFoundError(f"{image}: the capture's image is missing or not a regular file")
        if image.suffix.lower() in RAW_EXTENSIONS:
            still = read_raw(image)
            rgb, linear = still.srgb, still.linear
        else:
            bgr = cv2.imread(str(image))
            if bgr is None:
                raise FileNotFoundError(f"{image}: the capture's image is missing or not one OpenCV reads")
            rgb = bgr[..., ::-1].copy()
        roi = ((record.swatch_roi if record else None) or (capture.swatch_roi if capture else None)
               or self.swatch_roi or (0, 0, rgb.shape[1], rgb.shape[0]))
        lights = []
        for i, name in enumerate(capture.light_images if capture else ()):
            bgr = cv2.imread(str(session.image(name))) if session.image(name).is_file() else None
            if bgr is None:
                problems.append(f"{name}: light {i}'s own frame is missing or unreadable; the capture's shine "
                                f"cannot be re-read (its all-lights frame and result are intact)")
            lights.append(None if bgr is None else bgr[..., ::-1].copy())
        return LoadedCapture(capture_id, rgb, tuple(roi), record, profile, capture, linear, problems, lights,
                             capture.light_exposures if capture else ())

    def import_still(self, path: str | Path) -> CaptureResult:
        """A RAW still of the rig as a capture, in this session (see :func:`import_still`). In the family mode the
        rig's lights and camera read the swatch's structure and shine as it is imported (``borrowed_reading``)."""
        borrowed = self.borrowed_reading() if self.structure is StructureMode.FAMILY else None
        return import_still(self.folder, path, self.encoder_or_reason, self.in_spectral_world, self.structure,
                            borrowed, self.instrument)

    def borrowed_reading(self):
        """The texture, and the structure and shine the rig's single-light frames read decisively, of the swatch on
        the bench now (``inference.estimate.read_rig_structure``), for a RAW still of it, which has no frames of its
        own; None without lights or a calibration, or where the lights or the camera fail (the still is then
        estimated without the reading, and nothing is lost). (Through the simulated rig, RAW stills of swatches built
        another way came out 0.87 / 3.56 mapped to the family's mean: a spread swatch, which only the frames tell,
        2.9-4.1.)"""
        if self.lights is None or self.profile is None:
            return None
        try:
            singles, factors = self.light_frames()
            frame = self.frame()
        except (CameraError, LightError):
            return None

        def corrected(f):   # as a capture's frames are (``_estimate``)
            return apply_profile(f.srgb if f.linear is None else f.linear, self.profile)

        lights = [corrected(f) / np.float32(k) for f, k in zip(singles, factors)]
        return read_rig_structure(corrected(frame), lights, self.region(frame.srgb))

    def encoder_or_reason(self):
        """The encoder, or the one-line reason it cannot be loaded (a missing or broken model file)."""
        try:
            return self.encoder
        except ModelError as exc:
            return str(exc)

    def _check(self, image: np.ndarray):
        """The reasons not to estimate from this frame, and its chart detection (None if not found)."""
        reasons, chart = [], None
        status, why = self.calibration_status()
        if status is CalibrationStatus.UNCALIBRATED:
            reasons += [Blocker(BlockerKind.UNCALIBRATED, w) for w in why]
        try:
            chart = detect_chart(image)
        except CalibrationError as exc:
            reasons.append(Blocker(BlockerKind.NO_CHART, str(exc)))
        swatch = check_exposure(image, self._roi(image))[0]
        if swatch.status is ExposureStatus.OVER:
            reasons.append(Blocker(BlockerKind.OVER_EXPOSED, swatch.message))
        return reasons, chart


def _estimate(result: CaptureResult, image: np.ndarray, linear: np.ndarray | None, encoder_or_reason,
              profile: CalibrationProfile, view: RigRegion, stale: list[str],
              on_encoder_estimate: Callable[[HairParams], None] | None = None,
              singles: list[tuple[np.ndarray, float]] = (), chart=None, clipped: np.ndarray | None = None,
              structure: str = DEFAULT_STRUCTURE, borrowed=None) -> None:
    """Colour-correct the frame (``linear`` where the source has it, else the 8-bit ``image``) with
    ``profile``, keep it linear, estimate the swatch area ``view`` as the rig sees it, and fill ``result``.

    ``singles``: each light's own frame and its exposure over the frame's, corrected with the same
    profile (the rig's LEDs are one make; a profile fitted on a chart lit from one side would fold
    that light's geometry into the colour) and scaled back to the frame's exposure; ``chart``, the
    frame's chart detection, checks that one profile holds for each light. ``clipped``: a RAW still's
    saturated photosites (``Frame.clipped``), on which clipping is judged; ``structure``, how the estimate
    treats the swatch's physical structure; ``borrowed``, a reading of it from other frames (``import_still``)."""
    encoder = encoder_or_reason() if callable(encoder_or_reason) else encoder_or_reason
    if isinstance(encoder, str):
        result.blocked.append(Blocker(BlockerKind.NO_MODEL, encoder))
        return
    source = image if linear is None else linear
    corrected = apply_profile(source, profile)
    warnings = [EstimateWarning(WarningKind.CALIBRATION, w) for w in stale + correction_warnings(
        profile, mean_linear(fitted_pixels(to_linear(source), view)), mean_linear(fitted_pixels(corrected, view)))]
    lights = [apply_profile(frame, profile) / np.float32(factor) for frame, factor in singles] or None
    if lights and chart is not None:   # judged as the camera read them: see light_colour_warnings
        raw_lights = [to_linear(frame) / np.float32(factor) for frame, factor in singles]
        warnings += [EstimateWarning(WarningKind.CALIBRATION, w)
                     for w in light_colour_warnings(chart, raw_lights)]
    estimate = estimate_image(corrected, encoder, view=view, extra_warnings=warnings,
                              on_encoder_estimate=on_encoder_estimate, light_images=lights, sensor_clipped=clipped,
                              structure=structure, borrowed=borrowed)
    result.params = estimate.params
    result.corrected = corrected
    result.curve = None if estimate.refinement is None else estimate.refinement.curve
    result.record = record(estimate, encoder, result.image_path.read_bytes(), result.image_path,
                           calibration_summary(profile), view)


def _write_result(folder: Path, result: CaptureResult, roi) -> None:
    """The capture's result record: its estimate (when one was made), or why it was blocked."""
    base = result.record if result.record is not None else EstimateRecord(hair=None)
    done = replace(base, capture=result.image_path.name, blocked=messages(result.blocked),
                   swatch_roi=None if roi is None else tuple(int(v) for v in roi))
    result.record = done if result.record is not None else None
    write_record(SessionFolder(folder).result_record(result.capture_id), done)


class StillError(HairdigiError, ValueError):
    """A file given as a RAW still that is not one."""


#: The largest file taken as a RAW still: the reader's own bound (``hardware.cameras.MAX_RAW_BYTES``, 512 MiB: a
#: 150 MP medium-format back's uncompressed 16-bit RAW is about 300 MB, a 61 MP full-frame camera's 120 MB), checked
#: before the copy, so a huge or sparse file never reaches the session's disk.
MAX_STILL_BYTES = MAX_RAW_BYTES
#: What a still's capture needs on the disk beside its copy: its records and the result.
STILL_SPARE_BYTES = 16 * 1024 * 1024
#: The smallest still read: the chart's 24 patches and a swatch need more pixels than this a side.
MIN_STILL_SIDE = 64


def check_still_size(path: Path, captures: Path) -> None:
    """A still's size, before it is copied: no more than a RAW file's (``MAX_STILL_BYTES``), and room for it on the
    session's disk; StillError naming the size and the fix otherwise."""
    size = path.stat().st_size
    if size > MAX_STILL_BYTES:
        raise StillError(f"{path}: {size / 1e6:.0f} MB is more than any RAW still of the rig (at most "
                         f"{MAX_STILL_BYTES / 1e6:.0f} MB); is it a RAW still? nothing was copied")
    where = next(p for p in (captures, *captures.parents) if p.exists())
    free = shutil.disk_usage(where).free
    if size + STILL_SPARE_BYTES > free:
        raise StillError(f"{path}: {size / 1e6:.0f} MB does not fit in the {free / 1e6:.0f} MB free on the session's "
                         f"disk ({where}); free some space or use a session on another disk")


def read_still_or_remove(original: Path, image_path: Path, meta_path: Path, made: list[Path]):
    """The copied still, decoded (``read_raw``); one that cannot be read (not RAW, truncated, too small to hold the
    chart) is removed with its record and the folders made for it, and StillError names it: nothing is left."""
    try:
        with _native_stderr_silenced():   # LibRaw writes its own complaint to the process's stderr
            still = read_raw(image_path)
        height, width = still.srgb.shape[:2]
        if min(height, width) < MIN_STILL_SIDE:
            raise StillError(f"{width}x{height} px is too small to hold the chart and the swatch")
    except (CameraError, StillError, MemoryError) as exc:
        for p in (image_path, meta_path):
            p.unlink(missing_ok=True)
        for d in made:
            if d.is_dir() and not any(d.iterdir()):
                d.rmdir()
        why = str(exc).replace(str(image_path), "").lstrip(": ") or type(exc).__name__
        raise StillError(f"{original}: not a RAW still hairdigi can read ({why}); nothing was kept in the "
                         "session: give the camera's own RAW file, as shot, with the chart in view") from None
    return still


class _native_stderr_silenced:
    """File descriptor 2 pointed at /dev/null while native code runs (Python's own ``sys.stderr`` is untouched)."""

    def __enter__(self):
        sys.stderr.flush()
        self._saved = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 2)
        os.close(null)

    def __exit__(self, *exc) -> None:
        os.dup2(self._saved, 2)
        os.close(self._saved)


def import_still(folder: str | Path, path: str | Path, encoder_or_reason,
                 in_spectral_world: Callable[..., EstimateRecord] | None = None,
                 structure: str = DEFAULT_STRUCTURE, borrowed=None, instrument: dict | None = None) -> CaptureResult:
    """A RAW still (DNG, CR2, NEF, ...) of the rig, taken with the chart in view, as a capture.

    The file is copied into the session first, untouched. Then rawpy decodes it (linear, the
    camera's own colour space); the still is calibrated on its own chart, since a still camera's
    processing is not the live feed's; the swatch is found, corrected and estimated. The still's
    profile is kept in its result record, so reviewing it later corrects it the same way.
    ``in_spectral_world`` (``RigSession.in_spectral_world``) finishes the record as the session's captures
    are (a session's declared camera is its stills' too). ``borrowed``: the structure and shine the rig's own
    frames read of the same swatch (``RigSession.borrowed_reading``), which the family mode refines on.
    """
    start = time.perf_counter()
    path = Path(path)
    if path.suffix.lower() not in RAW_EXTENSIONS:
        raise StillError(f"{path}: not a RAW still ({', '.join(sorted(RAW_EXTENSIONS))}); "
                         "open images and videos with hairdigi estimate")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such RAW file")
    captures = SessionFolder(folder).captures
    check_still_size(path, captures)
    made = [d for d in (captures, captures.parent) if not d.exists()]
    image_path, meta_path, capture = save_capture(captures, raw_path=path, source="raw still", original=path.name)
    result = CaptureResult(capture.id, image_path, meta_path)
    still = read_still_or_remove(path, image_path, meta_path, made)
    profile = None
    try:
        profile = calibrate(still.srgb, settings={"camera": still.meta.get("camera"), "still": image_path.name},
                            linear=still.linear)
    except CalibrationError as exc:
        result.blocked.append(Blocker(BlockerKind.STILL_UNCALIBRATED, f"the still cannot calibrate itself: {exc}"))
    roi = None
    if profile is not None:
        found = find_swatch_core(still.srgb)[0]   # the swatch's core: its box holds holder and sparse edges
        roi = (found.x, found.y, found.w, found.h)
        swatch = check_exposure(still.srgb, roi, clipped_mask=still.clipped)[0]   # on the sensor's counts
        if swatch.status is ExposureStatus.OVER:
            result.blocked.append(Blocker(BlockerKind.OVER_EXPOSED, swatch.message))
        # the still's own profile belongs in its capture record, as a live capture's does
        capture = replace(capture, calibration=profile, swatch_roi=roi)
        write_record(meta_path, capture)
    if not result.blocked:
        _estimate(result, still.srgb, still.linear, encoder_or_reason, profile,
                  rig_region((still.srgb.shape[1], still.srgb.shape[0]), roi), profile_warnings(profile, None),
                  clipped=still.clipped, structure=structure, borrowed=borrowed)
    result.seconds = time.perf_counter() - start
    if result.record is not None and in_spectral_world is not None:
        result.record = in_spectral_world(result.record, profile, result.curve)
    if result.record is not None:
        result.record = with_instrument(result.record, **(instrument or {}))
    _write_result(Path(folder), result, roi)
    return result


def genicam_id(camera) -> str | None:
    """The GenICam device ID a camera setting names (``genicam:ID``; "" for ``genicam``: the first found), or None."""
    name, _, device = str(camera).partition(":")
    return device if name == "genicam" else None


def frame_linear(frame) -> np.ndarray:
    """A frame's linear RGB: the camera's own where it has one (raw Bayer), else its 8-bit sRGB decoded."""
    return frame.linear if frame.linear is not None else to_linear(frame.srgb)


def open_rig(folder: str | Path, sim: bool = False, camera: str | int = "0", port: str | None = None, roi=None,
             fallback: bool = False, require_lights: bool = True, spectra=None, structure: str = DEFAULT_STRUCTURE,
             **simulated) -> tuple[RigSession, str | None]:
    """The rig for the command line and the window alike, and why it is the simulated one (or None).

    ``camera`` is an OpenCV index or URL, or ``genicam[:ID]`` (a GenICam camera; with ``sim``, the simulated
    rig through Aravis's fake camera). ``sim`` gives the simulated rig (``simulated`` goes to
    :meth:`RigSession.simulated_rig`). Otherwise
    the camera and the light board on ``port``, found on the serial ports when empty; without a board
    the session has no lights unless ``require_lights``. When they do not answer, ``fallback`` gives
    the simulated rig and the reason; without it the CameraError or LightError is raised. ``spectra``
    (``inference.spectral_reading.RigSpectra``): what the real rig declares of its LEDs and camera; ``structure``, how
    the session's estimates treat the swatch's physical structure (``RigSession.structure``).
    """
    genicam = genicam_id(camera)
    if sim and genicam is not None:
        return RigSession.simulated_rig(folder, genicam=genicam or FAKE_ID, structure=structure, **simulated), None
    if not sim:
        opened = None
        try:
            if genicam is not None:
                opened = GenICamCamera(genicam or None)
            else:
                opened = OpenCVCamera(int(camera) if str(camera).isdigit() else camera)
            port = port or next((p for p, _ in discover()), None)
            if port is None and require_lights:
                raise LightError("no light board answered on any serial port; plug it in, or name it with --port")
            return RigSession(opened, LightController(port) if port else None, folder, roi, spectra=spectra,
                              structure=structure), None
        except (CameraError, LightError) as exc:
            if opened is not None:
                opened.close()
            if not fallback:
                raise
            reason = f"{exc}; using the simulated rig"
    else:
        reason = None
    return RigSession.simulated_rig(folder, structure=structure, **simulated), reason


def load_results(folder: str | os.PathLike) -> list[tuple[str, EstimateRecord | str]]:
    """Every capture's result record in a session folder, oldest first, as (capture id, record); a
    record that cannot be read comes as (id, the one-line reason), so one bad file hides nothing else."""
    out: list[tuple[str, EstimateRecord | str]] = []
    for path in SessionFolder(folder).result_records():
        capture_id = capture_id_of(path)
        try:
            out.append((capture_id, read_record(path, EstimateRecord)))
        except RecordError as exc:
            out.append((capture_id, str(exc)))
    return out


def twin_spec(roi: tuple[int, int, int, int], frame_size: tuple[int, int], scale: float = 1.0):
    """The twin: the bench camera over exactly the swatch area ``roi`` of a rig-view frame (the
    region the refinement fits), with about ``scale``² of its pixels; returns (scene, film size)."""
    region = rig_region(frame_size, roi)
    side = max(8, int(round(np.sqrt(roi[2] * roi[3]) * scale)))
    return scene_for(region, RefineSettings(size=side))


def export_records(records: list[EstimateRecord], path: str | Path) -> Path:
    """One record as it is, several as ``{"swatches": [...]}``; written atomically."""
    data = [r.to_json() for r in records]
    data = data[0] if len(data) == 1 else {"swatches": data, "count": len(data)}
    return write_json_atomic(path, data)
