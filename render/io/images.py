"""Atomic image writers: PNG from 8-bit sRGB, EXR from linear float RGB."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from hairdigi.render.io.files import publish


def _check_suffix(path: Path, suffix: str) -> None:
    """The file's name must say what it holds: a PNG ends in .png, an EXR in .exr."""
    if path.suffix.lower() != suffix:
        raise ValueError(f"{path}: this writes {suffix[1:].upper()} data; name the file with {suffix}")


def _write_atomic(path: Path, suffix: str, write: Callable[[str], None]) -> Path:
    """Write through a temporary file beside ``path`` and a rename; the temporary file never stays behind."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=suffix)
    os.close(fd)
    try:
        write(tmp)
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def save_png(path: str | os.PathLike, srgb: np.ndarray) -> Path:
    """Write an (H, W, 3) RGB uint8 image as PNG, atomically."""
    path = Path(path)
    _check_suffix(path, ".png")

    def write(tmp: str) -> None:
        if not cv2.imwrite(tmp, cv2.cvtColor(np.ascontiguousarray(srgb), cv2.COLOR_RGB2BGR)):
            raise OSError(f"{path}: the PNG could not be written (disk full, or the folder not writable?)")
    return _write_atomic(path, ".png", write)


def save_exr(path: str | os.PathLike, linear: np.ndarray) -> Path:
    """Write linear float32 RGB as OpenEXR through Mitsuba's Bitmap, atomically."""
    from hairdigi.render.variant import mi

    path = Path(path)
    _check_suffix(path, ".exr")

    def write(tmp: str) -> None:
        try:
            mi.Bitmap(np.ascontiguousarray(linear, dtype=np.float32), mi.Bitmap.PixelFormat.RGB).write(tmp)
        except RuntimeError as exc:   # Mitsuba reports I/O failures as RuntimeError
            raise OSError(f"{path}: the EXR could not be written ({exc})") from None
    return _write_atomic(path, ".exr", write)
