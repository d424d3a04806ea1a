"""Numpy images to Qt pixmaps, and the live-feed overlays (drawing only, no measurement)."""
from __future__ import annotations

import cv2
import numpy as np
from PySide6.QtGui import QImage, QPixmap


def to_pixmap(rgb: np.ndarray) -> QPixmap:
    rgb = np.ascontiguousarray(rgb)
    h, w, _ = rgb.shape
    image = QImage(rgb.data, w, h, 3 * w, QImage.Format.Format_RGB888)
    return QPixmap.fromImage(image.copy())


def overlay(rgb: np.ndarray, roi=None, chart_box=None, zebra: bool = True) -> np.ndarray:
    """The swatch area (green), the chart outline (cyan) and clipped pixels as zebra stripes."""
    out = rgb.copy()
    if zebra:
        clipped = (rgb >= 254).any(axis=2)
        if clipped.any():
            yy, xx = np.nonzero(clipped)
            stripes = ((xx + yy) // 3) % 2 == 0
            out[yy[stripes], xx[stripes]] = (255, 0, 255)
    if roi is not None:
        x, y, w, h = (int(v) for v in roi)
        cv2.rectangle(out, (x, y), (x + w, y + h), (0, 255, 0), 1)
    if chart_box is not None:
        cv2.polylines(out, [np.asarray(chart_box, np.int32).reshape(-1, 1, 2)], True, (0, 255, 255), 1)
    return out


#: The ΔE2000 map's scale: black (no difference) through blue, green and yellow to red at DELTA_E_MAX and over.
DELTA_E_MAX = 6.0
_SCALE = np.array([(0, 0, 0), (30, 30, 130), (0, 140, 170), (60, 190, 60), (230, 210, 40), (240, 120, 30),
                   (220, 30, 30)], dtype=float)


def delta_e_colours(delta_e: np.ndarray, max_de: float = DELTA_E_MAX) -> np.ndarray:
    """An (H, W) ΔE2000 map as an RGB uint8 image on the window's colour scale."""
    x = np.clip(np.asarray(delta_e, dtype=float), 0.0, max_de) / max_de * (len(_SCALE) - 1)
    out = np.stack([np.interp(x, np.arange(len(_SCALE)), _SCALE[:, c]) for c in range(3)], axis=-1)
    return np.round(out).astype(np.uint8)


def colour_scale(width: int, height: int, max_de: float = DELTA_E_MAX) -> np.ndarray:
    """The colour bar of :func:`delta_e_colours`, 0 on the left, ``max_de`` on the right."""
    row = delta_e_colours(np.linspace(0.0, max_de, width), max_de)
    return np.ascontiguousarray(np.repeat(row[None], height, axis=0))
