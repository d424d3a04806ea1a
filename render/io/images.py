"""Atomic image writers: PNG from 8-bit sRGB, EXR from linear float RGB."""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import atomic_path


class ImageWriteError(HairdigiError, ValueError):
    """An image cannot be written under the name asked (its extension says another format)."""


def _check_suffix(path: Path, suffix: str) -> None:
    """The file's name must say what it holds: a PNG ends in .png, an EXR in .exr."""
    if path.suffix.lower() != suffix:
        raise ImageWriteError(f"{path}: this writes {suffix[1:].upper()} data; name the file with {suffix}")


def save_png(path: str | os.PathLike, srgb: np.ndarray) -> Path:
    """Write an (H, W, 3) RGB uint8 image as PNG, atomically."""
    path = Path(path)
    _check_suffix(path, ".png")

    with atomic_path(path, ".png") as tmp:
        if not cv2.imwrite(str(tmp), cv2.cvtColor(np.ascontiguousarray(srgb), cv2.COLOR_RGB2BGR)):
            raise OSError(f"{path}: the PNG could not be written (disk full, or the folder not writable?)")
    return path


def save_exr(path: str | os.PathLike, linear: np.ndarray) -> Path:
    """Write linear float32 RGB as OpenEXR through Mitsuba's Bitmap, atomically."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.variant import mi, select_variant

    select_variant()

    path = Path(path)
    _check_suffix(path, ".exr")

    with atomic_path(path, ".exr") as tmp:
        try:
            mi.Bitmap(np.ascontiguousarray(linear, dtype=np.float32), mi.Bitmap.PixelFormat.RGB).write(str(tmp))
        except RuntimeError as exc:   # Mitsuba reports I/O failures as RuntimeError
            raise OSError(f"{path}: the EXR could not be written ({exc})") from None
    return path
