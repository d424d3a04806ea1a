"""What the Library panel shows, free of Qt: rows, a capture's swatch image, two swatches compared."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.app.library.store import Swatch
from hairdigi.app.library.swatch_colour import COLOURS, ILLUMINANTS, delta_e, lab_hex
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import read_swatch_record


def chip_hex(swatch: Swatch, under: str = "daylight") -> str | None:
    lab = swatch.labs.get(under)
    return None if lab is None else lab_hex(lab)


def lab_text(swatch: Swatch, under: str = "daylight") -> str:
    """The swatch's CIELAB under ``under`` (a light, or an instrument geometry's reading), as a table shows it."""
    lab = swatch.labs.get(under)
    return "–" if lab is None else f"{lab[0]:.1f} {lab[1]:.1f} {lab[2]:.1f}"


def describe(swatch: Swatch) -> str:
    """Two lines: where it came from, and its Table 1 parameters."""
    where = f"{Path(swatch.session).name} / {swatch.capture_id}" if swatch.session else Path(swatch.record_path or "").name
    hair = swatch.hair
    if hair is None:
        params = "no estimate (blocked)"
    else:
        dye = ", ".join(f"{v:.0f}" for v in hair.dye_rgb)
        params = (f"dye ({dye}) at {hair.dye_concentration:.2f}, melanin {hair.melanin_concentration:.2f}, "
                  f"ratio {hair.melanin_ratio:.2f}")
    return f"{where}\n{params}"


def capture_image(swatch: Swatch) -> np.ndarray | None:
    """The captured swatch area (8-bit sRGB), or None when the image is not on this machine."""
    import cv2   # deferred: OpenCV takes ~0.3 s; only this step needs it

    if not swatch.image_path or not Path(swatch.image_path).is_file():
        return None
    bgr = cv2.imread(swatch.image_path)
    if bgr is None:
        return None
    roi = None
    if swatch.record_path and Path(swatch.record_path).is_file():
        try:   # a regular file of bounded size
            roi = read_swatch_record(swatch.record_path).swatch_roi
        except RecordError:
            roi = None
    if roi:
        x, y, w, h = roi
        bgr = bgr[y:y + h, x:x + w] if w > 0 and h > 0 else bgr
    return np.ascontiguousarray(bgr[..., ::-1])


@dataclass(frozen=True)
class Comparison:
    """Two swatches side by side: their colours under each light and the ΔE2000 between them."""

    left: Swatch
    right: Swatch
    delta_e: dict[str, float | None]

    def text(self) -> str:
        parts = [f"{ill}: ΔE2000 {de:.2f}" if de is not None else f"{ill}: –" for ill, de in self.delta_e.items()]
        return " · ".join(parts)


def compare(left: Swatch, right: Swatch) -> Comparison:
    des = {}
    for ill in COLOURS:      # the lights always; an instrument's reading where either swatch has it
        a, b = left.labs.get(ill), right.labs.get(ill)
        if ill not in ILLUMINANTS and a is None and b is None:
            continue
        des[ill] = None if a is None or b is None else float(delta_e(np.asarray(a), np.asarray(b)))
    return Comparison(left, right, des)
