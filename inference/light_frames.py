"""The single-light frames ``estimate --lights`` reads: 8- or 16-bit sRGB PNGs (and what OpenCV reads) or
linear OpenEXR (read through Mitsuba's Bitmap: OpenCV 5's headless build reads no EXR).

Each file is read as a regular file of bounded size before it is decoded. An 8-bit frame comes back as
8-bit sRGB (as the all-lights image); a 16-bit or EXR frame as linear float32 RGB, which the estimate
takes as it is (``preprocess.to_linear``)."""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from hairdigi.inference.preprocess import MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS, ImageError, read_image
from hairdigi.render.domain.files import read_bytes


def _rgb_only(img: np.ndarray, path: Path) -> np.ndarray:
    """Three colour channels (alpha dropped); a greyscale frame is refused."""
    if img.ndim == 2 or img.shape[2] < 3:
        raise ImageError(f"{path}: a greyscale frame has no colour; give the light's colour frame")
    if img.shape[0] * img.shape[1] > MAX_IMAGE_PIXELS:
        raise ImageError(f"{path}: {img.shape[1]}x{img.shape[0]} px is more than hairdigi takes "
                         f"({MAX_IMAGE_PIXELS / 1e6:.0f} MP); crop it as the all-lights image")
    return img[..., :3]


def _read_exr(path: Path) -> np.ndarray:
    """A linear OpenEXR frame as float32 RGB."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.variant import mi, select_variant

    select_variant()
    try:
        bitmap = mi.Bitmap(str(path))
    except RuntimeError as exc:
        raise ImageError(f"{path}: not an OpenEXR image Mitsuba reads ({' '.join(str(exc).split())[:160]})") from None
    img = np.asarray(bitmap, dtype=np.float32)
    img = _rgb_only(img if img.ndim == 3 else img[..., None], path)
    if not np.isfinite(img).all() or img.min() < 0:
        raise ImageError(f"{path}: the EXR holds negative, NaN or infinite values; export it clamped to 0 and up")
    return np.ascontiguousarray(img)


def read_light_frame(path: str | os.PathLike) -> np.ndarray:
    """One light's frame: 8-bit sRGB (uint8, as ``read_image``), or linear float32 RGB from a 16-bit PNG/TIFF
    (sRGB-encoded) or an OpenEXR file."""
    path = Path(path)
    data = read_bytes(path, ImageError, "a light's frame", MAX_IMAGE_BYTES, "export a smaller PNG or EXR")
    if data[:4] == b"\x76\x2f\x31\x01":                      # OpenEXR's magic number
        return _read_exr(path)
    if not (data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 25 and data[24] == 16) and data[:2] not in (b"II", b"MM"):
        return read_image(path)                               # 8-bit: as the all-lights image is read
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ImageError(f"{path}: not an image OpenCV can read (PNG, TIFF, ...) or an OpenEXR file")
    if img.dtype == np.uint8:
        return read_image(path)
    if img.dtype != np.uint16:
        raise ImageError(f"{path}: {img.dtype} frame; give 8- or 16-bit sRGB, or linear OpenEXR")
    img = _rgb_only(img, path)
    srgb = cv2.cvtColor(img, cv2.COLOR_BGR2RGB).astype(np.float32) / 65535.0
    return np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4).astype(np.float32)
