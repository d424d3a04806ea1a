"""The bench session, free of Qt: lights, exposure, calibration, capture and estimate in one object.

The GUI and ``hairdigi rig`` both drive this; it calls ``hardware/``, ``inference/`` and ``render/``
and holds no science of its own. Every capture is written to disk before anything reads it.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hairdigi.hardware.cameras import RAW_EXTENSIONS, read_raw
from hairdigi.hardware.capture import save_capture
from hairdigi.hardware.exposure import ExposureReport, check_exposure, dead_lights
from hairdigi.hardware.frame_source import FrameSource
from hairdigi.hardware.lights import N_LIGHTS, LightController, LightError
from hairdigi.inference.calibration import (CalibrationError, ChartDetection, apply_profile, calibrate, detect_chart,
                                   load_profile, profile_warnings, save_profile, staleness)
from hairdigi.render.base.params import HairParams
from hairdigi.render.base.files import write_json_atomic


@dataclass
class CaptureResult:
    capture_id: str
    image_path: Path
    meta_path: Path
    params: HairParams | None = None
    record: dict = field(default_factory=dict)
    blocked: list[str] = field(default_factory=list)   # why no estimate was made
    corrected: np.ndarray | None = None                # the colour-corrected frame that was estimated
    seconds: float = 0.0


@dataclass
class LoadedCapture:
    """A capture read back for review: its frame, swatch area, result record and own calibration."""

    capture_id: str
    frame: np.ndarray                  # RGB, as captured (before colour correction)
    roi: tuple[int, int, int, int]
    record: dict
    profile: dict | None               # the profile it was corrected with; None if uncalibrated

    def corrected_swatch(self) -> np.ndarray:
        """The swatch area, colour-corrected with the capture's own profile."""
        x, y, w, h = self.roi
        real = self.frame[y:y + h, x:x + w].copy()
        return real if self.profile is None else apply_profile(real, self.profile)


def white_patch_box(detection: ChartDetection) -> tuple[int, int, int, int]:
    """A box inside the chart's white patch, from the chart's corners (patch 19 of 24: row 4, column 1)."""
    box = detection.box  # tl, tr, br, bl
    def at(u, v):
        top = box[0] + (box[1] - box[0]) * u
        bottom = box[3] + (box[2] - box[3]) * u
        return top + (bottom - top) * v
    centre = at((0 + 0.5) / 6, (3 + 0.5) / 4)
    half = 0.25 * np.linalg.norm(box[1] - box[0]) / 6
    return int(centre[0] - half), int(centre[1] - half), int(2 * half), int(2 * half)


class RigSession:
    """One camera (owned by its frame source), one light board, one session folder, and the current
    calibration profile."""

    def __init__(self, camera, lights: LightController | None, folder: str | Path, swatch_roi=None,
                 encoder=None, simulated: bool = False) -> None:
        self.camera = camera
        self.frames = FrameSource(camera)   # every read of the camera goes through here
        self.lights = lights
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.swatch_roi = swatch_roi
        self._encoder = encoder
        self.simulated = simulated
        self.profile_path = self.folder / "calibration.json"
        self.profile = load_profile(self.profile_path) if self.profile_path.exists() else None
        self.last_frame = None
        self._board = None

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def simulated_rig(cls, folder: str | Path, hidden: HairParams | None = None, camera_model=None,
                      dead: set[int] | None = None, spp: int = 32, encoder=None) -> "RigSession":
        """The bench in software: a pty light board, the rendered rig, and a camera model."""
        from hairdigi.hardware.sim_lights import SimulatedLightBoard
        from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN, SimRig
        from hairdigi.render.camera_model import CameraModel

        board = SimulatedLightBoard()
        lights = LightController(board.port)
        rig = SimRig(hidden or DEFAULT_HIDDEN, camera_model or CameraModel(), spp=spp,
                     dead_lights=set(dead or ()), board=board)
        session = cls(rig, lights, folder, rig.roi, encoder, simulated=True)
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

    @property
    def encoder(self):
        if self._encoder is None:
            from hairdigi.inference.encoder import Encoder
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
        """Render (or load) the refinement's response curve for the rig's camera; returns its seconds."""
        from hairdigi.inference.refine import RefineSettings, response_curve
        from hairdigi.render.base.rig_geometry import RIG_SWATCH_POSE

        return response_curve(RIG_SWATCH_POSE, RefineSettings()).seconds

    # -- checks ------------------------------------------------------------------------------
    def exposure(self, image: np.ndarray | None = None) -> list[ExposureReport]:
        image = self.frame().srgb if image is None else image
        try:
            white = white_patch_box(detect_chart(image))
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
        return dead_lights(dark, singles, self._roi(dark))

    def _roi(self, image: np.ndarray) -> tuple[int, int, int, int]:
        if self.swatch_roi is not None:
            return tuple(self.swatch_roi)
        from hairdigi.inference.preprocess import find_swatch_roi
        r = find_swatch_roi(image)
        return r.x, r.y, r.w, r.h

    # -- calibration -------------------------------------------------------------------------
    def calibrate(self, method: str | None = None, frames: int = 4) -> dict:
        """Fit a CCM on the mean of a few frames (less noise) and save the profile."""
        from hairdigi.inference.calibration import DEFAULT_METHOD

        stack = np.mean([self.frame().srgb.astype(np.float32) for _ in range(frames)], axis=0)
        image = np.round(stack).astype(np.uint8)
        self.profile = calibrate(image, method or DEFAULT_METHOD, settings=self.settings())
        save_profile(self.profile_path, self.profile)
        return self.profile

    def calibration_status(self) -> tuple[str, list[str]]:
        if self.profile is None:
            return "uncalibrated", ["the rig is not calibrated: press Calibrate with the chart in view"]
        reasons = staleness(self.profile, self.settings())
        return ("stale" if reasons else "ok"), reasons

    # -- capture -----------------------------------------------------------------------------
    def capture(self, estimate: bool = True) -> CaptureResult:
        """Save the frame and its metadata first; then check, correct and estimate, or say why not."""
        start = time.perf_counter()
        frame = self.frame()
        meta = {"lights": self.settings().get("lights"), "frame_meta": frame.meta,
                "calibration_id": None if self.profile is None else self.profile["id"],
                "calibration": self.profile,   # the capture keeps its own profile: a later one replaces the file
                "simulated": self.simulated, "swatch_roi": list(self._roi(frame.srgb))}
        image_path, meta_path = save_capture(self.folder / "captures", frame.srgb, meta=meta)
        result = CaptureResult(image_path.stem, image_path, meta_path)
        result.blocked = self.blockers(frame.srgb)
        if estimate and not result.blocked:
            _estimate(result, frame.srgb, self.encoder_or_reason, self.profile, self._roi(frame.srgb),
                      profile_warnings(self.profile, self.settings()))
        result.seconds = time.perf_counter() - start
        record = {"capture": image_path.name, "blocked": result.blocked, **result.record}
        write_json_atomic(self.folder / "captures" / f"{result.capture_id}.result.json", record)
        return result

    def load_capture(self, capture_id: str) -> "LoadedCapture":
        """A saved capture with what reviewing it needs: the frame, its swatch area, its result record,
        and the calibration profile it was taken with (not the session's current one)."""
        import cv2

        folder = self.folder / "captures"
        meta_path = folder / f"{capture_id}.json"
        meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
        image = folder / meta.get("image", f"{capture_id}.png")
        if image.suffix.lower() in RAW_EXTENSIONS:
            rgb = read_raw(image).srgb
        else:
            bgr = cv2.imread(str(image))
            if bgr is None:
                raise FileNotFoundError(f"{image}: the capture's image is missing or not one OpenCV reads")
            rgb = bgr[..., ::-1].copy()
        result_path = folder / f"{capture_id}.result.json"
        record = json.loads(result_path.read_text()) if result_path.exists() else {}
        profile = meta.get("calibration") or record.get("calibration_profile")   # a still calibrates itself
        if profile is None and self.profile is not None and meta.get("calibration_id") == self.profile["id"]:
            profile = self.profile          # captures saved before profiles were kept with them
        roi = tuple(record.get("swatch_roi") or meta.get("swatch_roi") or self.swatch_roi
                    or (0, 0, rgb.shape[1], rgb.shape[0]))
        return LoadedCapture(capture_id, rgb, roi, record, profile)

    def import_still(self, path: str | Path) -> CaptureResult:
        """A RAW still of the rig as a capture, in this session (see :func:`import_still`)."""
        return import_still(self.folder, path, self.encoder_or_reason)

    def encoder_or_reason(self):
        """The encoder, or the one-line reason it cannot be loaded (a missing or broken model file)."""
        from hairdigi.inference.encoder import ModelError

        try:
            return self.encoder
        except ModelError as exc:
            return str(exc)

    def blockers(self, image: np.ndarray) -> list[str]:
        """Reasons not to estimate from this frame; empty when it is fit."""
        reasons = []
        status, why = self.calibration_status()
        if status == "uncalibrated":
            reasons += why
        try:
            detect_chart(image)
        except CalibrationError as exc:
            reasons.append(str(exc))
        swatch = check_exposure(image, self._roi(image))[0]
        if swatch.status == "over":
            reasons.append(swatch.message)
        return reasons

def _estimate(result: CaptureResult, image: np.ndarray, encoder_or_reason, profile: dict | None,
              roi: tuple[int, int, int, int], calibration_warnings: list[str]) -> None:
    """Colour-correct ``image`` with ``profile``, estimate the swatch in ``roi`` and fill ``result``."""
    from hairdigi.inference.estimate import calibration_summary, estimate_image, record
    from hairdigi.inference.preprocess import Roi
    from hairdigi.render.base.rig_geometry import RIG_SWATCH_POSE

    encoder = encoder_or_reason() if callable(encoder_or_reason) else encoder_or_reason
    if isinstance(encoder, str):
        result.blocked.append(encoder)
        return
    corrected = apply_profile(image, profile)
    estimate = estimate_image(corrected, encoder, Roi(*roi), RIG_SWATCH_POSE, extra_warnings=calibration_warnings)
    result.params = estimate.params
    result.corrected = corrected
    result.record = record(estimate, encoder, result.image_path.read_bytes(), result.image_path,
                           calibration_summary(profile), RIG_SWATCH_POSE)


def import_still(folder: str | Path, path: str | Path, encoder_or_reason) -> CaptureResult:
    """A RAW still (DNG, CR2, NEF, ...) of the rig, taken with the chart in view, as a capture.

    The file is copied into the session first, untouched. Then rawpy decodes it (linear, the
    camera's own colour space); the still is calibrated on its own chart, since a still camera's
    processing is not the live feed's; the swatch is found, corrected and estimated. The still's
    profile is kept in its result record, so reviewing it later corrects it the same way.
    """
    start = time.perf_counter()
    path = Path(path)
    if path.suffix.lower() not in RAW_EXTENSIONS:
        raise ValueError(f"{path}: not a RAW still ({', '.join(sorted(RAW_EXTENSIONS))}); "
                         "open images and videos with hairdigi estimate")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such RAW file")
    image_path, meta_path = save_capture(Path(folder) / "captures", raw_path=path,
                                         meta={"source": "raw still", "original": path.name})
    result = CaptureResult(image_path.stem, image_path, meta_path)
    still = read_raw(image_path)
    profile = None
    try:
        profile = calibrate(still.srgb, settings={"camera": still.meta.get("camera"), "still": image_path.name})
    except CalibrationError as exc:
        result.blocked.append(f"the still cannot calibrate itself: {exc}")
    roi = None
    if profile is not None:
        from hairdigi.inference.preprocess import find_swatch_roi

        found = find_swatch_roi(still.srgb)
        roi = (found.x, found.y, found.w, found.h)
        swatch = check_exposure(still.srgb, roi)[0]
        if swatch.status == "over":
            result.blocked.append(swatch.message)
    if not result.blocked:
        _estimate(result, still.srgb, encoder_or_reason, profile, roi, profile_warnings(profile, None))
    result.seconds = time.perf_counter() - start
    record = {"capture": image_path.name, "blocked": result.blocked, "swatch_roi": list(roi) if roi else None,
              "calibration_profile": profile, **result.record}
    write_json_atomic(Path(folder) / "captures" / f"{result.capture_id}.result.json", record)
    return result


def open_rig(folder: str | Path, sim: bool = False, camera: str | int = "0", port: str | None = None, roi=None,
             fallback: bool = False, require_lights: bool = True, **simulated) -> tuple[RigSession, str | None]:
    """The rig for the command line and the window alike, and why it is the simulated one (or None).

    ``sim`` gives the simulated rig (``simulated`` goes to :meth:`RigSession.simulated_rig`). Otherwise
    the camera and the light board on ``port``, found on the serial ports when empty; without a board
    the session has no lights unless ``require_lights``. When they do not answer, ``fallback`` gives
    the simulated rig and the reason; without it the CameraError or LightError is raised.
    """
    if not sim:
        from hairdigi.hardware.cameras import CameraError, OpenCVCamera
        from hairdigi.hardware.lights import discover

        opened = None
        try:
            opened = OpenCVCamera(int(camera) if str(camera).isdigit() else camera)
            port = port or next((p for p, _ in discover()), None)
            if port is None and require_lights:
                raise LightError("no light board answered on any serial port; plug it in, or name it with --port")
            return RigSession(opened, LightController(port) if port else None, folder, roi), None
        except (CameraError, LightError) as exc:
            if opened is not None:
                opened.close()
            if not fallback:
                raise
            reason = f"{exc}; using the simulated rig"
    else:
        reason = None
    return RigSession.simulated_rig(folder, **simulated), reason


def load_results(folder: str | Path) -> list[dict]:
    """Every capture's result record in a session folder, oldest first."""
    out = []
    for path in sorted((Path(folder) / "captures").glob("*.result.json")):
        try:
            out.append({"id": path.name.split(".")[0], **json.loads(path.read_text())})
        except json.JSONDecodeError:
            continue
    return out


# --- the synthetic twin and exports (no Qt) ---------------------------------------------------
def twin_spec(roi: tuple[int, int, int, int], frame_size: tuple[int, int]):
    """A swatch scene seen by the rig camera over exactly the ROI of a rig-view frame."""
    from hairdigi.render.base import rig_geometry
    from hairdigi.render.renderer import SceneSpec

    width, _ = frame_size
    scale = width / (2 * rig_geometry.RIG_HALF_WIDTH)       # pixels per holder unit in the rig view
    x, y, w, h = roi
    cx = (x + w / 2 - frame_size[0] / 2) / scale + rig_geometry.RIG_TARGET[0]
    cy = rig_geometry.RIG_TARGET[1] - (y + h / 2 - frame_size[1] / 2) / scale
    return SceneSpec("swatch", framing="rig", target=(cx, cy, 0.0), half_width=w / 2 / scale), (w, h)


def render_twin(params: HairParams, roi, frame_size, spp: int = 16, seed: int = 0, simulated: bool = True):
    """Render the estimate as the rig camera saw the swatch (simulated geometry), or a crop view."""
    from hairdigi.render.renderer import SceneSpec, render

    if simulated:
        spec, size = twin_spec(roi, frame_size)
        return render(params, spec, size, spp, seed)
    return render(params, SceneSpec("swatch", framing="crop"), (roi[2], roi[3]), spp, seed)


def compare(real_srgb: np.ndarray, synthetic_srgb: np.ndarray) -> tuple[float, np.ndarray]:
    """Mean-colour ΔE2000 between the real and synthetic swatch, and a difference image (x4)."""
    from hairdigi.render.metrics import mean_colour_delta_e
    from hairdigi.render.srgb import srgb8_to_linear

    de = mean_colour_delta_e(srgb8_to_linear(real_srgb), srgb8_to_linear(synthetic_srgb))
    diff = np.clip(np.abs(real_srgb.astype(int) - synthetic_srgb.astype(int)) * 4, 0, 255).astype(np.uint8)
    return de, diff


def export_records(records: list[dict], path: str | Path) -> Path:
    """One record as it is, several as ``{"swatches": [...]}``; written atomically."""
    data = records[0] if len(records) == 1 else {"swatches": records, "count": len(records)}
    return write_json_atomic(path, data)
