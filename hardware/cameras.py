"""One small camera interface, several backends: live OpenCV, RAW stills, files, and the simulated rig.

Every backend's ``read()`` returns a :class:`Frame` of 8-bit sRGB (what the encoder takes) and,
where the source has it, linear RGB. ``close()`` releases the device.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from hairdigi.hardware.exposure import sensor_clipped
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.srgb import linear_to_srgb8

IMAGE_EXTENSIONS = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"}
RAW_EXTENSIONS = {".dng", ".cr2", ".cr3", ".nef", ".arw", ".raf", ".orf", ".rw2", ".pef", ".srw"}


class CameraError(HairdigiError, RuntimeError):
    """The camera cannot deliver a frame; the message says what to check."""


@dataclass
class Frame:
    srgb: np.ndarray                      # (H, W, 3) uint8, sRGB
    linear: np.ndarray | None = None      # (H, W, 3) float32 linear RGB where the source has it
    meta: dict = field(default_factory=dict)
    time: float = field(default_factory=time.time)
    mosaic: np.ndarray | None = None      # (H, W) uint16 sensor counts where the source gives raw Bayer data
    clipped: np.ndarray | None = None     # (H, W, 3) bool: a saturated photosite behind the pixel (RAW stills)


class Camera(Protocol):
    name: str

    def read(self) -> Frame: ...

    def settings(self) -> dict:
        """What a colour calibration depends on (exposure, gain, ...), as the device reports it now."""

    def close(self) -> None: ...


class OpenCVCamera:
    """A live camera through ``cv2.VideoCapture``: a device index or a stream URL."""

    def __init__(self, source: int | str = 0, width: int | None = None, height: int | None = None,
                 exposure: float | None = None, gain: float | None = None) -> None:
        self.name = f"opencv:{source}"
        self.capture = cv2.VideoCapture(source)
        if not self.capture.isOpened():
            self.capture.release()
            raise CameraError(f"no camera at {source!r}: check that it is plugged in and not used by another "
                              f"program, or run with --sim for the simulated rig")
        for prop, value in ((cv2.CAP_PROP_FRAME_WIDTH, width), (cv2.CAP_PROP_FRAME_HEIGHT, height),
                            (cv2.CAP_PROP_EXPOSURE, exposure), (cv2.CAP_PROP_GAIN, gain)):
            if value is not None:
                self.capture.set(prop, value)   # drivers ignore what they do not support

    #: The properties a calibration depends on, read back from the driver (what it does, not what was asked).
    PROPERTIES = (("width", cv2.CAP_PROP_FRAME_WIDTH), ("height", cv2.CAP_PROP_FRAME_HEIGHT),
                  ("exposure", cv2.CAP_PROP_EXPOSURE), ("gain", cv2.CAP_PROP_GAIN),
                  ("auto_exposure", cv2.CAP_PROP_AUTO_EXPOSURE), ("wb_temperature", cv2.CAP_PROP_WB_TEMPERATURE),
                  ("auto_wb", cv2.CAP_PROP_AUTO_WB))

    def settings(self) -> dict:
        """The driver's current width, height, exposure, gain and white balance (0 where unsupported)."""
        return {key: float(self.capture.get(prop)) for key, prop in self.PROPERTIES}

    def read(self) -> Frame:
        ok, bgr = self.capture.read()
        if not ok or bgr is None:
            raise CameraError(f"{self.name} stopped delivering frames: check the cable")
        return Frame(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB),
                     meta={"camera": self.name, "camera_settings": self.settings()})

    def close(self) -> None:
        self.capture.release()


class FileCamera:
    """Replays a video file (looping) or shows one image file: for replaying sessions."""

    def __init__(self, path: str | os.PathLike, loop: bool = True) -> None:
        self.path = Path(path)
        self.name = f"file:{self.path.name}"
        self.loop = loop
        if not self.path.exists():
            raise CameraError(f"{self.path}: no such video or image file")
        self.image: np.ndarray | None = None
        self.capture = None
        if self.path.suffix.lower() in IMAGE_EXTENSIONS:
            bgr = cv2.imread(str(self.path), cv2.IMREAD_COLOR)
            if bgr is None:
                raise CameraError(f"{self.path}: OpenCV cannot read this image")
            self.image = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            self.frames = 1
            return
        self.capture = cv2.VideoCapture(str(self.path))
        if not self.capture.isOpened():
            raise CameraError(f"{self.path}: OpenCV cannot open this file as video")
        self.frames = int(self.capture.get(cv2.CAP_PROP_FRAME_COUNT))

    def settings(self) -> dict:
        """A replayed file has no exposure to change: the file stands for its settings."""
        return {"file": self.path.name}

    def read(self) -> Frame:
        if self.image is not None:
            return Frame(self.image.copy(), meta={"camera": self.name, "frame": 0})
        ok, bgr = self.capture.read()
        if not ok and self.loop:
            self.capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, bgr = self.capture.read()
        if not ok:
            raise CameraError(f"{self.path}: no more frames")
        index = int(self.capture.get(cv2.CAP_PROP_POS_FRAMES)) - 1
        return Frame(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), meta={"camera": self.name, "frame": index})

    def close(self) -> None:
        if self.capture is not None:
            self.capture.release()


#: RAW stills above this many pixels are decoded at half size (2x2 Bayer blocks: 48 MP gives 12 MP).
HALF_SIZE_ABOVE = 16_000_000
#: The largest RAW still read (a 150 MP medium-format back's), and its file size.
MAX_RAW_PIXELS = 160_000_000
MAX_RAW_BYTES = 512 * 1024 * 1024


def read_raw(path: str | os.PathLike) -> Frame:
    """A RAW still (DNG, CR2, NEF, ...) through rawpy as linear camera RGB, white-balanced as shot.

    No auto-brightening, a linear curve and the camera's own colour space (no matrix to sRGB): the
    values are proportional to the light on each channel, and the rig's colour calibration (a CCM
    fitted on the chart) takes them to the renderer's colour space. The file is left untouched.
    """
    import rawpy   # deferred: rawpy (LibRaw) only to decode a RAW file

    path = Path(path)
    if not path.exists():
        raise CameraError(f"{path}: no such RAW file")
    if path.stat().st_size > MAX_RAW_BYTES:
        raise CameraError(f"{path}: {path.stat().st_size / 1e6:.0f} MB is more than hairdigi reads for a RAW "
                          f"still ({MAX_RAW_BYTES / 1e6:.0f} MB); is it a RAW still of the rig?")
    try:
        with rawpy.imread(str(path)) as raw:
            width, height = int(raw.sizes.width), int(raw.sizes.height)
            if width * height > MAX_RAW_PIXELS:
                raise CameraError(f"{path}: {width}x{height} px is more than hairdigi reads for a RAW still "
                                  f"({MAX_RAW_PIXELS / 1e6:.0f} MP); shoot at a smaller RAW size")
            # above HALF_SIZE_ABOVE pixels, each 2x2 Bayer block is one pixel: a quarter of the memory
            # and no demosaicing; the swatch and chart keep hundreds of pixels a side
            half = width * height > HALF_SIZE_ABOVE
            # adjust_maximum_thr=0: the white level is the file's, never the brightest pixel's (LibRaw's default
            # took a frame's maximum above 75% of white as white: a 12-bit frame peaking at 3300 read 1.17x bright)
            rgb16 = raw.postprocess(gamma=(1, 1), no_auto_bright=True, output_bps=16, use_camera_wb=True,
                                    output_color=rawpy.ColorSpace.raw, user_flip=0, half_size=half,
                                    adjust_maximum_thr=0.0)
            # clipping is the sensor's: counts at its white level, not the 8-bit encode's 0 or 255
            clipped = sensor_clipped(raw.raw_image_visible, raw.raw_colors_visible, raw.color_desc.decode(),
                                     float(np.mean(raw.black_level_per_channel)), float(raw.white_level), half)
            meta = {"camera": f"raw:{path.name}", "raw_pattern": raw.raw_pattern.tolist(),
                    "black_level": [int(v) for v in raw.black_level_per_channel],
                    "white_level": int(raw.white_level), "raw_size": [width, height], "half_size": half}
    except (rawpy.LibRawError, OSError) as exc:
        raise CameraError(f"{path}: rawpy cannot read this RAW file ({exc}); is it complete?") from None
    linear = rgb16.astype(np.float32)
    del rgb16
    linear *= np.float32(1.0 / 65535.0)
    srgb = np.empty(linear.shape, np.uint8)
    rows = max(1, (1 << 20) // max(1, linear.shape[1]))   # encoded in bands: colour-science works in float64
    for y in range(0, linear.shape[0], rows):
        srgb[y:y + rows] = linear_to_srgb8(linear[y:y + rows])
    if clipped.shape[:2] != srgb.shape[:2]:   # a camera whose development crops or rotates its sensor
        clipped = cv2.resize(clipped.astype(np.uint8), (srgb.shape[1], srgb.shape[0]),
                             interpolation=cv2.INTER_NEAREST).astype(bool)
    return Frame(srgb, linear, meta, clipped=clipped)
