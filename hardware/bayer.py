"""Bayer mosaics: GenICam pixel formats unpacked to sensor counts, demosaiced in linear light, saved as DNG.

A machine-vision camera's raw frame is one colour sample per pixel (the colour filter array). Its
counts are proportional to the light once the black level (the camera's pedestal) is subtracted, so
the frame is scaled to [0, 1] by ``(count - black) / (white - black)`` and each missing colour is the
mean of its nearest samples of that colour (bilinear, in linear light: no curve, no white balance,
no colour matrix). The rig's colour calibration (a CCM on the chart) takes it from there, as it takes
a RAW still's camera RGB. A capture keeps the mosaic itself, untouched, as a DNG that rawpy reads as
any RAW still (``hardware.cameras.read_raw``).
"""
from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass

import cv2
import numpy as np

#: The 2x2 colour layout of each PFNC Bayer name, read row by row from the top-left pixel.
LAYOUTS = {"RG": "RGGB", "GR": "GRBG", "GB": "GBRG", "BG": "BGGR"}
#: Unpacked depths, as PFNC names them; data is LSB-aligned in 16-bit little-endian words above 8 bits.
DEPTHS = (8, 10, 12, 14, 16)
#: The DNG CFAPattern code of each colour.
_CFA_CODE = {"R": 0, "G": 1, "B": 2}
_KERNEL = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]], np.float32)


@dataclass(frozen=True)
class BayerFormat:
    """One unpacked Bayer pixel format: its PFNC name, 2x2 layout and bit depth."""

    name: str
    layout: str      # "RGGB", "GRBG", "GBRG" or "BGGR"
    bits: int

    @property
    def white(self) -> int:
        return (1 << self.bits) - 1


def bayer_format(name: str) -> BayerFormat | None:
    """The unpacked Bayer format a PFNC name gives (``BayerRG12``), or None for any other format."""
    match = re.fullmatch(r"Bayer(RG|GR|GB|BG)(\d+)", name or "")
    if match is None or int(match.group(2)) not in DEPTHS:
        return None
    return BayerFormat(name, LAYOUTS[match.group(1)], int(match.group(2)))


def unpack(data: bytes, fmt: BayerFormat, width: int, height: int) -> np.ndarray:
    """The (height, width) uint16 sensor counts of a frame's bytes in ``fmt``."""
    dtype = np.uint8 if fmt.bits == 8 else np.dtype("<u2")
    need = width * height * np.dtype(dtype).itemsize
    if len(data) < need:
        raise ValueError(f"{fmt.name} frame of {width}x{height} needs {need} bytes, got {len(data)}")
    counts = np.frombuffer(data, dtype, width * height).reshape(height, width).astype(np.uint16)
    return counts & np.uint16(fmt.white)


def channel_masks(layout: str, shape: tuple[int, int]) -> np.ndarray:
    """(3, H, W) float32 masks: 1 where the mosaic samples R, G, B."""
    masks = np.zeros((3, *shape), np.float32)
    for i, colour in enumerate(layout):
        masks[_CFA_CODE[colour], i // 2::2, i % 2::2] = 1.0
    return masks


def demosaic(cfa: np.ndarray, layout: str, black: float, white: float) -> np.ndarray:
    """(H, W, 3) float32 linear RGB in [0, 1]: black subtracted, scaled by the white level, each colour
    kept where sampled and the mean of its neighbours elsewhere."""
    scaled = (np.asarray(cfa, np.float32) - np.float32(black)) / np.float32(max(white - black, 1))
    np.clip(scaled, 0.0, 1.0, out=scaled)
    masks = channel_masks(layout, scaled.shape)
    out = np.empty((*scaled.shape, 3), np.float32)
    for c in range(3):
        weight = cv2.filter2D(masks[c], -1, _KERNEL, borderType=cv2.BORDER_REFLECT)
        total = cv2.filter2D(scaled * masks[c], -1, _KERNEL, borderType=cv2.BORDER_REFLECT)
        out[..., c] = np.where(masks[c] > 0, scaled, total / np.maximum(weight, 1e-6))
    return out


@functools.lru_cache(maxsize=1)
def _srgb_table() -> np.ndarray:
    from hairdigi.render.srgb import linear_to_srgb8   # deferred: loads colour-science (~1 s)

    return linear_to_srgb8(np.arange(65536, dtype=np.float64) / 65535.0)


def srgb8(linear: np.ndarray) -> np.ndarray:
    """8-bit sRGB of linear RGB in [0, 1] through a 16-bit table: 10x faster than the formula, at most one
    code off (a live frame's display and the chart finder's input; the estimate takes the linear frame)."""
    return _srgb_table()[(np.clip(linear, 0.0, 1.0) * 65535.0 + 0.5).astype(np.uint16)]


def write_dng(path: str | os.PathLike, cfa: np.ndarray, layout: str, black: float, white: int,
              model: str = "hairdigi GenICam camera") -> str | os.PathLike:
    """Write a raw mosaic as a linear DNG (its layout, black and white levels as tags) that rawpy reads."""
    import tifffile   # deferred: tifffile only for RAW stills

    identity = [(1, 1), (0, 1), (0, 1), (0, 1), (1, 1), (0, 1), (0, 1), (0, 1), (1, 1)]
    tags = [
        (50706, "B", 4, (1, 4, 0, 0), True),          # DNGVersion
        (50707, "B", 4, (1, 1, 0, 0), True),          # DNGBackwardVersion
        (50708, "s", 0, model, True),                 # UniqueCameraModel
        (33421, "H", 2, (2, 2), True),                # CFARepeatPatternDim
        (33422, "B", 4, tuple(_CFA_CODE[c] for c in layout), True),   # CFAPattern
        (50714, "H", 1, int(round(black)), True),     # BlackLevel
        (50717, "H", 1, int(white), True),            # WhiteLevel
        (50721, "2i", 9, [v for pair in identity for v in pair], True),  # ColorMatrix1 (SRATIONAL)
        (50778, "H", 1, 21, True),                    # CalibrationIlluminant1: D65
        (50728, "2I", 3, (1, 1, 1, 1, 1, 1), True),   # AsShotNeutral: no white balance
    ]
    tifffile.imwrite(path, np.ascontiguousarray(cfa, np.uint16), photometric=32803, extratags=tags, subfiletype=0)
    return path
