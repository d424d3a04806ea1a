"""RAW stills of the simulated rig: a linear image mosaicked onto an RGGB sensor, written as a DNG.

A 12-bit linear Bayer DNG (tifffile's CFA and DNG tags), which rawpy reads as it reads a camera's
file: the simulated rig's stills (``hairdigi evaluate --rig``) and the tests' go through the same
RAW path (``hardware.cameras.read_raw``) as a real still camera's.
"""
from __future__ import annotations

import os

import numpy as np

WHITE = 4095


def write_raw_still(path: str | os.PathLike, linear: np.ndarray):
    """Mosaic an (H, W, 3) linear image in [0, 1] (even H and W) onto an RGGB sensor and write it as DNG."""
    import tifffile   # deferred: tifffile only for RAW stills

    linear = np.clip(np.asarray(linear, float), 0.0, 1.0)
    cfa = np.empty(linear.shape[:2], np.uint16)
    counts = np.round(linear * WHITE).astype(np.uint16)
    cfa[0::2, 0::2] = counts[0::2, 0::2, 0]
    cfa[0::2, 1::2] = counts[0::2, 1::2, 1]
    cfa[1::2, 0::2] = counts[1::2, 0::2, 1]
    cfa[1::2, 1::2] = counts[1::2, 1::2, 2]
    identity = [(1, 1), (0, 1), (0, 1), (0, 1), (1, 1), (0, 1), (0, 1), (0, 1), (1, 1)]
    tags = [
        (50706, "B", 4, (1, 4, 0, 0), True),          # DNGVersion
        (50707, "B", 4, (1, 1, 0, 0), True),          # DNGBackwardVersion
        (50708, "s", 0, "hairdigi simulated still camera", True),  # UniqueCameraModel
        (33421, "H", 2, (2, 2), True),                # CFARepeatPatternDim
        (33422, "B", 4, (0, 1, 1, 2), True),          # CFAPattern: RGGB
        (50714, "H", 1, 0, True),                     # BlackLevel
        (50717, "H", 1, WHITE, True),                 # WhiteLevel
        (50721, "2i", 9, [v for pair in identity for v in pair], True),  # ColorMatrix1 (SRATIONAL)
        (50778, "H", 1, 21, True),                    # CalibrationIlluminant1: D65
        (50728, "2I", 3, (1, 1, 1, 1, 1, 1), True),   # AsShotNeutral
    ]
    tifffile.imwrite(path, cfa, photometric=32803, extratags=tags, subfiletype=0)
    return path
