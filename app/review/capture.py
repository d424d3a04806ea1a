"""The review's long work on the rig, as generators a worker runs off the UI thread: building the
preview scenes before the first capture, and a capture with its first look, its first passes and the
records read back after it."""
from __future__ import annotations

import queue
import threading
import time
from typing import Generator

import cv2
import numpy as np

from hairdigi.app.review.payloads import Captured, FirstLook, FrameCheck, Warmed
from hairdigi.app.review.previews import PassTag, PreviewSettings, hairstyle_passes, twin_passes, twin_view
from hairdigi.app.review.reads import read_capture, read_records
from hairdigi.app.session import rig_session as rs
from hairdigi.inference.calibration import CalibrationError, apply_profile, detect_chart
from hairdigi.inference.refine import refine
from hairdigi.render import denoise as dn
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.srgb import linear_to_srgb8


def warm_scenes(session: rs.RigSession, settings: PreviewSettings, spec: SceneSpec, twin_renderer: Renderer,
                style_renderer: Renderer) -> Generator[None, None, Warmed]:
    """Build and compile the twin and hairstyle scenes (and refinement's); yields between the steps."""
    seconds, roi = {}, session.swatch_roi
    placeholder = HairParams()
    start = time.perf_counter()
    session.prepare_refinement()
    seconds["refinement_curve"] = time.perf_counter() - start
    yield None
    if roi is not None:
        frame = session.frames.latest() or session.frame()
        start = time.perf_counter()
        for scale in sorted({scale for scale, _ in settings.twin_passes}):
            tspec, tsize = twin_view(roi, (frame.srgb.shape[1], frame.srgb.shape[0]), session.simulated, scale)
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
    warm_refinement(session)
    seconds["refinement"] = time.perf_counter() - start
    return Warmed(seconds)


def capture_passes(session: rs.RigSession, settings: PreviewSettings, spec: SceneSpec, label: str, on: bool,
                   tags: tuple[PassTag, PassTag], renderers: tuple[Renderer, Renderer]) -> Generator[object, None, Captured]:
    """Capture, estimate and refine; between the encoder and refinement yield the :class:`FirstLook`
    and its first twin and hairstyle passes (``tags``, ``renderers``: the twin's and the hairstyle's).
    Returns the capture with the session's records and the capture read back. The capture itself runs
    to its end even when the work is cancelled."""
    out: queue.Queue = queue.Queue()
    done = object()
    (tag, style_tag), (twin_renderer, style_renderer) = tags, renderers

    def on_encoder(params: HairParams) -> None:
        """In the capture's thread, between the encoder and refinement."""
        look = first_look(session, params, tag.key)
        out.put(look)
        n = settings.first_look_passes
        view = lambda scale: twin_view(look.roi, look.frame_size, session.simulated, scale)  # noqa: E731
        for p in twin_passes(twin_renderer, params, look.real, view, settings.twin_passes[:n], settings, on, tag):
            out.put(p)
        for p in hairstyle_passes(style_renderer, params, spec, label, settings.hairstyle_passes[:n], settings,
                                  on, style_tag):
            out.put(p)

    def capture() -> None:
        try:
            out.put(read_back(session, session.capture(on_encoder_estimate=on_encoder)))
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


def read_back(session: rs.RigSession, result: rs.CaptureResult) -> Captured:
    """A capture saved, with the session's records and the capture as the review shows it."""
    return Captured(result, read_records(session.folder), read_capture(session, result.capture_id))


def first_look(session: rs.RigSession, params: HairParams, key: int) -> FirstLook:
    """The encoder's parameters with the swatch they came from: the captured frame's swatch area,
    corrected with the session's profile (as the estimate saw it)."""
    image = session.last_frame.srgb
    x, y, w, h = session.swatch_roi or (0, 0, image.shape[1], image.shape[0])
    real = image[y:y + h, x:x + w].copy()
    if session.profile is not None:
        real = linear_to_srgb8(apply_profile(real, session.profile))
    return FirstLook(params, real, (x, y, w, h), (image.shape[1], image.shape[0]), key)


def warm_refinement(session: rs.RigSession) -> None:
    """Build the scene refinement renders for this rig's swatch area once, and compile its kernels
    (its response curve is prepared first, or read from the disk cache)."""
    frame = session.frames.latest() or session.frame()
    refine(HairParams(), np.array([0.08, 0.05, 0.03]), session.region(frame.srgb))


def check_frame(session: rs.RigSession, image: np.ndarray) -> FrameCheck:
    """Find the chart and check the exposure of one frame."""
    try:
        try:
            box = detect_chart(image).box
        except CalibrationError:
            box = None
        return FrameCheck(box, session.exposure(image))
    except cv2.error:    # cv2.mcc's assertion on an odd frame (seen once in ~20 tours): try the next one
        return FrameCheck(None, None)
