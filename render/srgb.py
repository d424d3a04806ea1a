"""8-bit sRGB and linear RGB, both ways, through colour-science's sRGB transfer functions."""
from __future__ import annotations

import colour
import numpy as np


def linear_to_srgb8(linear: np.ndarray) -> np.ndarray:
    """Clip to [0, 1], apply the sRGB encoding curve and quantise to 8 bits."""
    encoded = colour.cctf_encoding(np.clip(linear, 0.0, 1.0), function="sRGB")
    return np.round(encoded * 255.0).astype(np.uint8)


def srgb8_to_linear(srgb8: np.ndarray) -> np.ndarray:
    """8-bit sRGB values (any shape) to linear RGB in [0, 1]."""
    return colour.cctf_decoding(np.asarray(srgb8, dtype=np.float64) / 255.0, function="sRGB")


#: 8-bit sRGB code to linear light, as a lookup table (``to_linear``).
_LINEAR_LUT = srgb8_to_linear(np.arange(256)).astype(np.float32)


def to_linear(img: np.ndarray) -> np.ndarray:
    """Linear float32 RGB of an image: 8-bit sRGB decoded, linear float as it is."""
    return _LINEAR_LUT[img] if img.dtype == np.uint8 else np.asarray(img, np.float32)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear RGB to sRGB-encoded values in [0, 1], float32 and unquantised (for the encoder's input)."""
    return colour.cctf_encoding(np.clip(np.asarray(linear, dtype=np.float32), 0.0, 1.0),
                                function="sRGB").astype(np.float32)
