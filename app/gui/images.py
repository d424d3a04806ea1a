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
