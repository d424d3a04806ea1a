"""Atomic image writers: PNG from 8-bit sRGB, EXR from linear float RGB."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from render.files import publish


def _atomic_target(path: Path, suffix: str) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=suffix)
    os.close(fd)
    return tmp


def save_png(path: str | os.PathLike, srgb: np.ndarray) -> Path:
    """Write an (H, W, 3) RGB uint8 image as PNG, atomically."""
    path = Path(path)
    tmp = _atomic_target(path, ".png")
    if not cv2.imwrite(tmp, cv2.cvtColor(np.ascontiguousarray(srgb), cv2.COLOR_RGB2BGR)):
        Path(tmp).unlink(missing_ok=True)
        raise OSError(f"could not write PNG {path}")
    publish(tmp, path)
    return path


def save_exr(path: str | os.PathLike, linear: np.ndarray) -> Path:
    """Write linear float32 RGB as OpenEXR through Mitsuba's Bitmap, atomically."""
    from render.variant import mi

    path = Path(path)
    tmp = _atomic_target(path, ".exr")
    mi.Bitmap(np.ascontiguousarray(linear, dtype=np.float32), mi.Bitmap.PixelFormat.RGB).write(tmp)
    publish(tmp, path)
    return path
