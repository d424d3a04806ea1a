"""Exposure checks: clipping (on 8-bit sRGB frames, or on a RAW still's sensor data against its white
level), the level of a reference area, and dead lights."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.text_enum import TextEnum
from hairdigi.render.srgb import srgb8_to_linear

#: The white patch should sit in this 8-bit band: bright, with headroom before clipping.
WHITE_BAND = (185.0, 240.0)
WHITE_TARGET_LINEAR = 0.62    # the middle of the band, linear
CLIP_LIMIT = 0.005            # white patch: more than 0.5 % of a channel at 254+ counts as clipped
#: The swatch may clip on specular glints, which carry no dye colour; past 2 % the exposure hides colour.
SWATCH_CLIP_LIMIT = 0.02
SWATCH_BAND = (12.0, 235.0)   # loose: black hair is dark, platinum is bright
#: A photosite at this share of the range from its black to its white level, or above, is saturated.
SENSOR_SATURATION = 0.99
_BAND_ROWS = 512              # sensor rows judged at once (a 48 MP still's mask stays tens of MB)


class ExposureError(HairdigiError, ValueError):
    """An area to judge lies outside the frame (a swatch region larger than the camera's image)."""


def _linear(v: np.ndarray | float) -> np.ndarray:
    """8-bit sRGB levels (any float) to linear, through the one sRGB decoding (``render.srgb``)."""
    return srgb8_to_linear(v)


def luminance8(img: np.ndarray) -> np.ndarray:
    """Rec. 709 luma-like weighting of 8-bit sRGB values (for levels, not colour)."""
    return img[..., :3].astype(float) @ np.array([0.2126, 0.7152, 0.0722])


class ExposureStatus(TextEnum):
    """An area's exposure: within its band, or over (clipped or too bright) or under (too dark or crushed)."""

    OK = "ok"
    OVER = "over"
    UNDER = "under"


@dataclass
class ExposureReport:
    region: str
    clipped: tuple[float, float, float]   # share of pixels at 254+ (or saturated on the sensor) per channel
    crushed: tuple[float, float, float]   # share of pixels at 1- per channel
    level: float                          # mean luminance, 8-bit
    status: ExposureStatus
    suggested_ev: float                   # exposure change that would centre the level
    message: str


def sensor_clipped(raw_image: np.ndarray, colours: np.ndarray, colour_desc: str, black: float, white: float,
                   half: bool) -> np.ndarray:
    """Which pixels of a RAW still's developed image have a saturated photosite behind them, per
    channel: (H, W, 3) bool, from the sensor's counts (``raw_image``, with ``colours`` each photosite's
    index into ``colour_desc``, e.g. ``"RGBG"``) against the white level. Judged per 2 x 2 Bayer cell
    (demosaicing spreads a photosite over its neighbours); ``half``: one pixel per cell, as a
    half-size development gives, else each cell's verdict on its four pixels."""
    threshold = black + SENSOR_SATURATION * (white - black)
    rows, cols = raw_image.shape[0] // 2 * 2, raw_image.shape[1] // 2 * 2
    # each photosite's channel; an index past ``colour_desc`` (LibRaw gives 0-3, but a DNG may say more
    # than its description: a 48 MP test still's CFA read 6) counts as green, the Bayer's most common
    channel = np.ones(256, np.int8)
    channel[:len(colour_desc)] = ["RGB".find(c) if c in "RGB" else 1 for c in colour_desc]
    cells = np.zeros((rows // 2, cols // 2, 3), bool)
    for r in range(0, rows, _BAND_ROWS):
        r1 = min(rows, r + _BAND_ROWS)
        saturated = raw_image[r:r1, :cols] >= threshold
        which = channel[colours[r:r1, :cols]]
        for c in range(3):
            cells[r // 2:r1 // 2, :, c] = (saturated & (which == c)).reshape((r1 - r) // 2, 2, cols // 2, 2).any((1, 3))
    if half:
        return cells
    full = np.zeros(raw_image.shape[:2] + (3,), bool)
    full[:rows, :cols] = cells.repeat(2, 0).repeat(2, 1)
    return full


def check_region(img: np.ndarray, box: tuple[int, int, int, int], region: str,
                 band: tuple[float, float] = SWATCH_BAND, target_linear: float | None = None,
                 clip_limit: float = SWATCH_CLIP_LIMIT, clipped_mask: np.ndarray | None = None) -> ExposureReport:
    """Clipping and level in ``box`` (x, y, w, h); suggests an EV change toward ``target_linear``.
    ``clipped_mask``: the sensor's saturation per pixel and channel (a RAW still's, ``sensor_clipped``),
    judged instead of the 8-bit values (an 8-bit code of 255 need not be a saturated photosite)."""
    x, y, w, h = box
    patch = img[y:y + h, x:x + w].reshape(-1, 3)
    if patch.size == 0:
        raise ExposureError(f"the {region} area {box} lies outside the {img.shape[1]}x{img.shape[0]} frame")
    clipped = tuple(float(v) for v in (patch >= 254 if clipped_mask is None else
                                       clipped_mask[y:y + h, x:x + w].reshape(-1, 3)).mean(0))
    crushed = tuple(float(v) for v in (patch <= 1).mean(0))
    level = float(luminance8(patch).mean())
    target = target_linear if target_linear is not None else float(_linear(np.mean(band)))
    ev = float(np.log2(target / max(float(_linear(level)), 1e-4)))
    if max(clipped) > clip_limit or level > band[1]:
        status, msg = ExposureStatus.OVER, (f"{region}: over-exposed ({100 * max(clipped):.1f}% clipped, level {level:.0f}); "
                                          f"lower the exposure by {abs(min(ev, -0.3)):.1f} EV")
        ev = min(ev, -0.3)
    elif level < band[0] or max(crushed) > 0.2:
        status, msg = ExposureStatus.UNDER, (f"{region}: under-exposed (level {level:.0f}); raise the exposure by "
                                           f"{max(ev, 0.3):.1f} EV")
        ev = max(ev, 0.3)
    else:
        status, msg = ExposureStatus.OK, f"{region}: exposure ok (level {level:.0f}, {100 * max(clipped):.2f}% clipped)"
    return ExposureReport(region, clipped, crushed, level, status, ev, msg)


def check_exposure(img: np.ndarray, swatch_box: tuple[int, int, int, int],
                   white_box: tuple[int, int, int, int] | None = None,
                   clipped_mask: np.ndarray | None = None) -> list[ExposureReport]:
    """The swatch (clipping, loose band) and, when the chart is in view, its white patch (tight band);
    ``clipped_mask`` as in :func:`check_region`."""
    reports = [check_region(img, swatch_box, "swatch", clipped_mask=clipped_mask)]
    if white_box is not None:
        reports.append(check_region(img, white_box, "white patch", WHITE_BAND, WHITE_TARGET_LINEAR, CLIP_LIMIT,
                                    clipped_mask))
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
