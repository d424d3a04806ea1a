"""Exposure checks on 8-bit sRGB frames: clipping, the level of a reference area, and dead lights."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hairdigi.render.srgb import srgb8_to_linear

#: The white patch should sit in this 8-bit band: bright, with headroom before clipping.
WHITE_BAND = (185.0, 240.0)
WHITE_TARGET_LINEAR = 0.62    # the middle of the band, linear
CLIP_LIMIT = 0.005            # white patch: more than 0.5 % of a channel at 254+ counts as clipped
#: The swatch may clip on specular glints, which carry no dye colour; past 2 % the exposure hides colour.
SWATCH_CLIP_LIMIT = 0.02
SWATCH_BAND = (12.0, 235.0)   # loose: black hair is dark, platinum is bright


def _linear(v: np.ndarray | float) -> np.ndarray:
    """8-bit sRGB levels (any float) to linear, through the one sRGB decoding (``render.srgb``)."""
    return srgb8_to_linear(v)


def luminance8(img: np.ndarray) -> np.ndarray:
    """Rec. 709 luma-like weighting of 8-bit sRGB values (for levels, not colour)."""
    return img[..., :3].astype(float) @ np.array([0.2126, 0.7152, 0.0722])


@dataclass
class ExposureReport:
    region: str
    clipped: tuple[float, float, float]   # share of pixels at 254+ per channel
    crushed: tuple[float, float, float]   # share of pixels at 1- per channel
    level: float                          # mean luminance, 8-bit
    status: str                           # "ok", "over" or "under"
    suggested_ev: float                   # exposure change that would centre the level
    message: str


def check_region(img: np.ndarray, box: tuple[int, int, int, int], region: str,
                 band: tuple[float, float] = SWATCH_BAND, target_linear: float | None = None,
                 clip_limit: float = SWATCH_CLIP_LIMIT) -> ExposureReport:
    """Clipping and level in ``box`` (x, y, w, h); suggests an EV change toward ``target_linear``."""
    x, y, w, h = box
    patch = img[y:y + h, x:x + w].reshape(-1, 3)
    if patch.size == 0:
        raise ValueError(f"the {region} area {box} lies outside the {img.shape[1]}x{img.shape[0]} frame")
    clipped = tuple(float(v) for v in (patch >= 254).mean(0))
    crushed = tuple(float(v) for v in (patch <= 1).mean(0))
    level = float(luminance8(patch).mean())
    target = target_linear if target_linear is not None else float(_linear(np.mean(band)))
    ev = float(np.log2(target / max(float(_linear(level)), 1e-4)))
    if max(clipped) > clip_limit or level > band[1]:
        status, msg = "over", (f"{region}: over-exposed ({100 * max(clipped):.1f}% clipped, level {level:.0f}); "
                               f"lower the exposure by {abs(min(ev, -0.3)):.1f} EV")
        ev = min(ev, -0.3)
    elif level < band[0] or max(crushed) > 0.2:
        status, msg = "under", (f"{region}: under-exposed (level {level:.0f}); raise the exposure by "
                                f"{max(ev, 0.3):.1f} EV")
        ev = max(ev, 0.3)
    else:
        status, msg = "ok", f"{region}: exposure ok (level {level:.0f}, {100 * max(clipped):.2f}% clipped)"
    return ExposureReport(region, clipped, crushed, level, status, ev, msg)


def check_exposure(img: np.ndarray, swatch_box: tuple[int, int, int, int],
                   white_box: tuple[int, int, int, int] | None = None) -> list[ExposureReport]:
    """The swatch (clipping, loose band) and, when the chart is in view, its white patch (tight band)."""
    reports = [check_region(img, swatch_box, "swatch")]
    if white_box is not None:
        reports.append(check_region(img, white_box, "white patch", WHITE_BAND, WHITE_TARGET_LINEAR, CLIP_LIMIT))
    return reports


def dead_lights(dark: np.ndarray, singles: list[np.ndarray], box: tuple[int, int, int, int],
                min_share: float = 0.25) -> list[int]:
    """Lights that do not light the scene: each lone light must add at least ``min_share`` of a fair
    third of what all of them add together, measured in linear light on ``box``."""
    x, y, w, h = box

    def light(img):
        return float(_linear(luminance8(img[y:y + h, x:x + w])).mean())

    base = light(dark)
    gains = [light(s) - base for s in singles]
    fair = max(sum(gains), 1e-6) / len(gains)
    return [i for i, g in enumerate(gains) if g < min_share * fair]
