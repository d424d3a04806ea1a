"""Cem Yuksel's ``.hair`` format (www.cemyuksel.com/research/hairmodels), read and written.

Layout, little-endian: a 128-byte header, then the arrays the flags name, in this order.

==========  =====================================================================
bytes       header field
==========  =====================================================================
0–3         ``b"HAIR"``
4–7         uint32 number of strands S
8–11        uint32 total number of points P
12–15       uint32 flags: bit 0 segments array, 1 points array, 2 thickness array,
            3 transparency array, 4 colour array
16–19       uint32 default segments per strand (when there is no segments array)
20–23       float32 default thickness (diameter)
24–27       float32 default transparency
28–39       float32[3] default colour
40–127      88 bytes of free text
==========  =====================================================================

Arrays: segments ``uint16[S]`` (points per strand = segments + 1), points ``float32[P, 3]``,
thickness ``float32[P]``, transparency ``float32[P]``, colour ``float32[P, 3]``.
Thickness is a diameter; :class:`Strands` holds radii.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from hairdigi.render.strands import Strands

_HEADER = struct.Struct("<4sIIIIff3f88s")
assert _HEADER.size == 128
HAS_SEGMENTS, HAS_POINTS, HAS_THICKNESS, HAS_TRANSPARENCY, HAS_COLOR = (1 << i for i in range(5))


class HairFileError(ValueError):
    """A ``.hair`` file is malformed; the message says which part."""


def read_hair(path: str | os.PathLike) -> Strands:
    """Load a ``.hair`` file as :class:`Strands`; strands with fewer than 4 points are dropped."""
    path = Path(path)
    data = path.read_bytes()
    if len(data) < 128:
        raise HairFileError(f"{path}: {len(data)} bytes is too short for the 128-byte .hair header")
    magic, n_strands, n_points, flags, def_segments, def_thickness, _tr, _r, _g, _b, _info = \
        _HEADER.unpack_from(data)
    if magic != b"HAIR":
        raise HairFileError(f"{path}: not a .hair file (starts with {magic!r}, expected b'HAIR')")
    if not flags & HAS_POINTS:
        raise HairFileError(f"{path}: the file has no points array")
    offset = 128

    def take(dtype: str, count: int) -> np.ndarray:
        nonlocal offset
        size = np.dtype(dtype).itemsize * count
        if offset + size > len(data):
            raise HairFileError(f"{path}: truncated at byte {len(data)}, expected {offset + size}")
        arr = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
        offset += size
        return arr

    if flags & HAS_SEGMENTS:
        segments = take("<u2", n_strands).astype(np.int64)
    else:
        segments = np.full(n_strands, def_segments, dtype=np.int64)
    counts = segments + 1
    if counts.sum() != n_points:
        raise HairFileError(f"{path}: segments add up to {counts.sum()} points, header says {n_points}")
    points = take("<f4", 3 * n_points).reshape(-1, 3)
    if flags & HAS_THICKNESS:
        radii = take("<f4", n_points) / 2.0
    else:
        radii = np.full(n_points, def_thickness / 2.0, dtype=np.float32)
    keep = np.repeat(counts >= 4, counts)
    return Strands(points[keep].astype(np.float32), radii[keep].astype(np.float32), counts[counts >= 4])


def write_hair(path: str | os.PathLike, strands: Strands, info: str = "hairdigi") -> Path:
    """Write :class:`Strands` as a ``.hair`` file with segments, points and thickness arrays."""
    path = Path(path)
    flags = HAS_SEGMENTS | HAS_POINTS | HAS_THICKNESS
    header = _HEADER.pack(b"HAIR", strands.n_strands, len(strands.points), flags, 0, 1.0, 0.0,
                          0.5, 0.5, 0.5, info.encode()[:88].ljust(88, b"\0"))
    with open(path, "wb") as f:
        f.write(header)
        f.write((strands.counts - 1).astype("<u2").tobytes())
        f.write(strands.points.astype("<f4").tobytes())
        f.write((2.0 * strands.radii).astype("<f4").tobytes())
    return path
