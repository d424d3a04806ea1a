"""Draw the app icon, packaging/hairdigi.png: a swatch of wavy hair strands on a rounded tile.

Run once with the project venv (``.venv/bin/python packaging/make_icon.py``); the PNG is committed.
"""
from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

SIZE = 256
SCALE = 4            # drawn at 4x, then area-downsampled: smooth edges
OUT = Path(__file__).with_name("hairdigi.png")


def rounded_mask(size: int, radius: int) -> np.ndarray:
    """A filled rounded square, 255 inside."""
    mask = np.zeros((size, size), np.uint8)
    cv2.rectangle(mask, (radius, 0), (size - radius, size), 255, -1)
    cv2.rectangle(mask, (0, radius), (size, size - radius), 255, -1)
    for cx in (radius, size - radius):
        for cy in (radius, size - radius):
            cv2.circle(mask, (cx, cy), radius, 255, -1, cv2.LINE_AA)
    return mask


def draw(seed: int = 7) -> np.ndarray:
    """The icon as 8-bit RGBA."""
    rng = np.random.default_rng(seed)
    s = SIZE * SCALE
    bgr = np.zeros((s, s, 3), np.uint8)
    bgr[:] = (58, 40, 34)                                         # dark slate tile (BGR)
    holder = (int(0.22 * s), int(0.10 * s), int(0.78 * s), int(0.90 * s))
    cv2.rectangle(bgr, holder[:2], holder[2:], (200, 196, 190), -1)   # the swatch holder's card
    x0, y0, x1, y1 = holder[0] + 0.05 * s, holder[1] + 0.06 * s, holder[2] - 0.05 * s, holder[3] - 0.04 * s
    ys = np.linspace(y0, y1, 80)
    for i in range(170):                                          # strands: auburn, each its own shade and wave
        x = x0 + (x1 - x0) * rng.random()
        phase, amp = rng.uniform(0, 2 * np.pi), rng.uniform(0.006, 0.016) * s
        xs = x + amp * np.sin(ys / (0.09 * s) + phase)
        tone = rng.uniform(0.6, 1.15)
        colour = tuple(int(min(255, c * tone)) for c in (38, 72, 168))   # BGR of auburn
        pts = np.stack([xs, ys], 1).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(bgr, [pts], False, colour, max(2, s // 256), cv2.LINE_AA)
    cv2.rectangle(bgr, (holder[0], holder[1]), (holder[2], int(holder[1] + 0.05 * s)), (90, 90, 96), -1)  # clamp
    alpha = rounded_mask(s, int(0.18 * s))
    rgba = np.dstack([bgr[..., ::-1], alpha])
    return cv2.resize(rgba, (SIZE, SIZE), interpolation=cv2.INTER_AREA)


def main() -> int:
    rgba = draw()
    ok = cv2.imwrite(str(OUT), cv2.cvtColor(rgba, cv2.COLOR_RGBA2BGRA))
    print(f"wrote {OUT}" if ok else f"could not write {OUT}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
