"""Cem Yuksel's ``.hair`` format (www.cemyuksel.com/research/hairmodels): read, check, write, fit to the head.

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
thickness ``float32[P]``, transparency ``float32[P]``, colour ``float32[P, 3]``. A file must hold
points; without a segments array every strand has the default segment count.

:func:`hair_model_strands` turns a file into a hairstyle for the portrait: fitted to the head
(:func:`fit_to_head`), cut to the scene's strand budget, as B-spline control points, cached per
path and modification time.
"""
from __future__ import annotations

import functools
import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.render import head
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import write_bytes_atomic
from hairdigi.render.strands import HAIR_RADIUS, Strands, scalp_roots

_HEADER = struct.Struct("<4sIIIIff3f88s")
assert _HEADER.size == 128
HAS_SEGMENTS, HAS_POINTS, HAS_THICKNESS, HAS_TRANSPARENCY, HAS_COLOR = (1 << i for i in range(5))
#: Control points a loaded model may give the renderer in all, and per strand: enough for any
#: preview (the built-in styles use 100k–400k), far under Mitsuba's limits and memory.
MAX_CONTROL_POINTS = 400_000
MAX_POINTS_PER_STRAND = 96
#: The preview's fibre radius (as the built-in styles'); a file's own thickness is in its units.
RADIUS = HAIR_RADIUS


class HairFileError(HairdigiError, ValueError):
    """A ``.hair`` file is malformed; the message says which part, in one line."""


@dataclass(frozen=True, eq=False)
class HairFile:
    """What a ``.hair`` file holds; an array the file lacks is None and its header default applies."""

    points: np.ndarray                    # (P, 3) float32
    n_strands: int
    segments: np.ndarray | None = None    # (S,) uint16
    thickness: np.ndarray | None = None   # (P,) float32, diameters
    transparency: np.ndarray | None = None
    colour: np.ndarray | None = None      # (P, 3) float32
    default_segments: int = 0
    default_thickness: float = 1.0
    default_transparency: float = 0.0
    default_colour: tuple[float, float, float] = (1.0, 1.0, 1.0)
    info: str = ""

    @property
    def flags(self) -> int:
        return (HAS_POINTS | (HAS_SEGMENTS if self.segments is not None else 0)
                | (HAS_THICKNESS if self.thickness is not None else 0)
                | (HAS_TRANSPARENCY if self.transparency is not None else 0)
                | (HAS_COLOR if self.colour is not None else 0))

    @property
    def counts(self) -> np.ndarray:
        """Points per strand."""
        if self.segments is not None:
            return self.segments.astype(np.int64) + 1
        return np.full(self.n_strands, self.default_segments + 1, dtype=np.int64)

    def strands(self) -> Strands:
        """The polylines as :class:`Strands` (radius = thickness / 2); strands of 1 point are dropped."""
        counts = self.counts
        radii = (self.thickness if self.thickness is not None
                 else np.full(len(self.points), self.default_thickness, np.float32)) / 2.0
        keep = counts >= 2
        mask = np.repeat(keep, counts)
        return Strands(self.points[mask].astype(np.float32), radii[mask].astype(np.float32), counts[keep])

    def equals(self, other: "HairFile") -> bool:
        """Same arrays (bit for bit), counts, info and defaults (as the file's float32)."""
        def same(a, b):
            return (a is None and b is None) or (a is not None and b is not None and np.array_equal(a, b))
        return (self.n_strands == other.n_strands and self.info == other.info
                and all(same(getattr(self, f), getattr(other, f))
                        for f in ("points", "segments", "thickness", "transparency", "colour"))
                and self.default_segments == other.default_segments
                and np.array_equal(np.float32([self.default_thickness, self.default_transparency, *self.default_colour]),
                                   np.float32([other.default_thickness, other.default_transparency,
                                               *other.default_colour])))


#: The largest model read: 8 M points (Cem Yuksel's largest models hold about 4 M), 1 M strands. Loading
#: one keeps its arrays and a few float64 copies while fitting it to the head: well under 2 GB.
MAX_FILE_POINTS = 8_000_000
MAX_FILE_STRANDS = 1_000_000


def _check_bounds(path: Path, n_strands: int, n_points: int, file_size: int) -> None:
    """Refuse a model over the point or strand bound, from its header, before its arrays are read."""
    if n_points > MAX_FILE_POINTS or n_strands > MAX_FILE_STRANDS:
        raise HairFileError(f"{path}: its header claims {n_strands} strands and {n_points} points, more than "
                            f"hairdigi loads ({MAX_FILE_STRANDS} strands, {MAX_FILE_POINTS} points, "
                            f"{file_size / 1e6:.0f} MB file); use a decimated copy of the model")


def _read_prefix(path: Path) -> tuple[bytes, int]:
    """The file's first bytes, as many as its header says its arrays need (bounded), and its size."""
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            header = f.read(_HEADER.size)
            if len(header) < _HEADER.size:
                return header, size
            _, n_strands, n_points, flags = _HEADER.unpack(header)[:4]
            _check_bounds(path, n_strands, n_points, size)
            need = _HEADER.size + 2 * n_strands * bool(flags & HAS_SEGMENTS) + 12 * n_points + 32 * n_points
            return header + f.read(need - _HEADER.size), size
    except HairFileError:
        raise
    except IsADirectoryError:
        raise HairFileError(f"{path}: is a folder, not a .hair file; give the file's path") from None
    except OSError as exc:
        raise HairFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None


def read_hair_file(path: str | os.PathLike) -> HairFile:
    """Read and check a ``.hair`` file; a :class:`HairFileError` names what is wrong in one line."""
    path = Path(path)
    data, _ = _read_prefix(path)
    if len(data) < _HEADER.size:
        raise HairFileError(f"{path}: truncated: {len(data)} bytes, but a .hair header alone needs 128; "
                            f"the file is cut short, copy it again")
    (magic, n_strands, n_points, flags, def_segments, def_thickness, def_transparency,
     r, g, b, info) = _HEADER.unpack_from(data)
    if magic not in (b"HAIR", b"hair"):   # cyHairFile writes upper case; some of its copies lower case
        raise HairFileError(f"{path}: not a .hair file: it starts with {magic!r}, expected b'HAIR'")
    if not flags & HAS_POINTS:
        raise HairFileError(f"{path}: has no points array (flags {flags:#x} lack bit 1); "
                            f"a .hair model must hold its points")
    if n_strands == 0:
        raise HairFileError(f"{path}: holds 0 strands, nothing to render; choose another model")
    sizes = [("segments", 2 * n_strands, HAS_SEGMENTS), ("points", 12 * n_points, HAS_POINTS),
             ("thickness", 4 * n_points, HAS_THICKNESS), ("transparency", 4 * n_points, HAS_TRANSPARENCY),
             ("colour", 12 * n_points, HAS_COLOR)]
    expected = _HEADER.size + sum(size for _, size, bit in sizes if flags & bit)
    if len(data) < expected:
        raise HairFileError(f"{path}: truncated: {len(data)} bytes, but its header's {n_strands} strands and "
                            f"{n_points} points need {expected}; the file is cut short, copy it again")
    arrays, offset = {}, _HEADER.size
    for name, size, bit in sizes:
        if flags & bit:
            dtype = "<u2" if name == "segments" else "<f4"
            arrays[name] = np.frombuffer(data, dtype=dtype, count=size // np.dtype(dtype).itemsize, offset=offset)
            offset += size
    segments = arrays.get("segments")
    total = int(segments.astype(np.int64).sum()) + n_strands if segments is not None else n_strands * (def_segments + 1)
    if total != n_points:
        source = "its segments array" if segments is not None else f"{n_strands} strands of {def_segments} default segments"
        raise HairFileError(f"{path}: counts do not add up: {source} make {total} points, the header says "
                            f"{n_points}; the file is corrupt")
    points = arrays["points"].reshape(-1, 3)
    finite = np.isfinite(points).all(axis=1)
    if not finite.all():
        raise HairFileError(f"{path}: {int((~finite).sum())} points are not finite (NaN or Inf), the first is "
                            f"point {int(np.argmin(finite))}; the model is corrupt")
    _check_not_degenerate(path, points, segments.astype(np.int64) + 1 if segments is not None
                          else np.full(n_strands, def_segments + 1, np.int64))
    colour = arrays.get("colour")
    return HairFile(points.astype(np.float32), int(n_strands), segments,
                    arrays.get("thickness"), arrays.get("transparency"),
                    None if colour is None else colour.reshape(-1, 3),
                    int(def_segments), float(def_thickness), float(def_transparency), (float(r), float(g), float(b)),
                    info.split(b"\0", 1)[0].decode("utf-8", "replace"))


def _check_not_degenerate(path: Path, points: np.ndarray, counts: np.ndarray) -> None:
    """Refuse a model with nothing to draw: no strand of 2 points, or every strand of zero length."""
    if not (counts >= 2).any():
        raise HairFileError(f"{path}: no strand has 2 or more points (all {len(counts)} are single points), "
                            f"so there is no hair to render; the model is degenerate")
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)   # float32: 4 bytes a point
    steps[(np.cumsum(counts) - 1)[:-1]] = 0.0                 # from one strand's last point to the next's first
    if not steps.any():
        raise HairFileError(f"{path}: every strand has zero length (all its points at one place), so there is "
                            f"no hair to render; the model is degenerate")


def hair_file_bytes(hair: HairFile) -> bytes:
    """The bytes of ``hair`` as a ``.hair`` file, with the arrays it has."""
    info = hair.info.encode("utf-8")[:88].ljust(88, b"\0")
    parts = [_HEADER.pack(b"HAIR", hair.n_strands, len(hair.points), hair.flags, hair.default_segments,
                          hair.default_thickness, hair.default_transparency, *hair.default_colour, info)]
    if hair.segments is not None:
        parts.append(np.asarray(hair.segments, "<u2").tobytes())
    parts.append(np.asarray(hair.points, "<f4").tobytes())
    for array in (hair.thickness, hair.transparency, hair.colour):
        if array is not None:
            parts.append(np.asarray(array, "<f4").tobytes())
    return b"".join(parts)


def write_hair_file(path: str | os.PathLike, hair: HairFile) -> Path:
    """Write ``hair`` as a ``.hair`` file, atomically."""
    return write_bytes_atomic(path, hair_file_bytes(hair))


def read_hair(path: str | os.PathLike) -> Strands:
    """A ``.hair`` file's strands as polylines, in its own units (see :func:`hair_model_strands` to render it)."""
    return read_hair_file(path).strands()


def write_hair(path: str | os.PathLike, strands: Strands, info: str = "hairdigi") -> Path:
    """Write :class:`Strands` as a ``.hair`` file with segments, points and thickness arrays."""
    if strands.counts.max(initial=0) > 65536:
        raise ValueError(f"a .hair strand holds at most 65536 points, one here has {strands.counts.max()}")
    return write_hair_file(path, HairFile(strands.points.astype(np.float32), strands.n_strands,
                                          (strands.counts - 1).astype(np.uint16),
                                          (2.0 * strands.radii).astype(np.float32), info=info))


# --- fitting a model to the head --------------------------------------------------------------

def _robust_box(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2nd and 98th percentiles per axis: a bounding box that a few stray points do not stretch."""
    return np.percentile(points, 2, axis=0), np.percentile(points, 98, axis=0)


@functools.lru_cache(maxsize=1)
def _scalp_box() -> tuple[np.ndarray, np.ndarray]:
    roots, _ = scalp_roots(4000, np.random.default_rng(0))
    return _robust_box(roots)


def _orientation(roots: np.ndarray, tips: np.ndarray) -> np.ndarray:
    """Rotation (3 x 3, rows: new x, y, z) that turns the model y up and face +z."""
    axes = np.eye(3)
    size = float(np.ptp(np.vstack([roots, tips]), axis=0).max()) or 1.0
    hang = {(a, s): s * float(np.mean(roots[:, a] - tips[:, a])) for a in (1, 2) for s in (1, -1)}
    (up_axis, up_sign), best = max(hang.items(), key=lambda kv: kv[1])
    if best < 0.05 * size:   # no clear hang (short or radial hair): Cem Yuksel's y up
        up_axis, up_sign = 1, 1
    up = up_sign * axes[up_axis]
    # the face: the horizontal direction towards which the roots rise (forehead above nape)
    height = roots @ up
    best_front, best_cov = None, 0.0
    for a in [i for i in range(3) if i != up_axis]:
        cov = float(np.mean((roots[:, a] - roots[:, a].mean()) * (height - height.mean())))
        if abs(cov) > abs(best_cov):
            best_front, best_cov = a, cov
    if best_front is None or abs(best_cov) < 1e-3 * size ** 2:   # y up: face +z; z up: face -y (Blender)
        front = axes[2] if up_axis == 1 else -axes[1]
    else:
        front = np.sign(best_cov) * axes[best_front]
    return np.stack([np.cross(up, front), up, front])


def fit_to_head(strands: Strands) -> Strands:
    """Place a model on the head, whatever its units and axes.

    The rule, from the roots (every strand's first point), which outline the scalp in any model:

    * up is whichever of ±y, ±z the roots lie above the tips along, on average (hair hangs from its
      roots); with no clear answer (short or radial hair), +y, Cem Yuksel's convention;
    * the face is the horizontal axis towards which the roots rise (a forehead hairline is higher
      than the nape);
    * the scale makes the roots' width and depth (2nd–98th percentile box, geometric mean of the two
      ratios) those of the head's scalp, so cm, mm, m or inches give the same result;
    * the roots' box is centred on the scalp's in x and z, and its top put at the scalp's top;
    * finally every point is pushed out of the bust (the model's own head differs from ours).

    Radii scale with the model.
    """
    starts = strands.starts()
    roots, tips = strands.points[starts], strands.points[starts + strands.counts - 1]
    rotation = _orientation(roots.astype(float), tips.astype(float))
    points = strands.points.astype(float) @ rotation.T
    roots = roots.astype(float) @ rotation.T
    lo, hi = _robust_box(roots)
    target_lo, target_hi = _scalp_box()
    span, target = hi - lo, target_hi - target_lo
    if min(span[0], span[2]) > 1e-6 * max(float(np.ptp(points, axis=0).max()), 1e-30):
        scale = float(np.sqrt(target[0] / span[0] * target[2] / span[2]))
    else:   # the roots do not outline a scalp (one strand, a flat patch): fit the whole model's width
        whole_lo, whole_hi = _robust_box(points)
        scale = 2.2 / max(float(whole_hi[0] - whole_lo[0]), 1e-30)
    anchor = np.array([(lo[0] + hi[0]) / 2, hi[1], (lo[2] + hi[2]) / 2])
    target_anchor = np.array([(target_lo[0] + target_hi[0]) / 2, target_hi[1], (target_lo[2] + target_hi[2]) / 2])
    points = (points - anchor) * scale + target_anchor
    radii = strands.radii * np.float32(scale)
    points = head.push_out(points, 1.5 * RADIUS + 0.004)
    return Strands(points.astype(np.float32), radii.astype(np.float32), strands.counts.copy())


def _decimate(strands: Strands, max_points: int) -> Strands:
    """Strands with at most ``max_points`` points each (evenly spaced, first and last kept)."""
    if strands.counts.max() <= max_points:
        return strands
    pieces, counts = [], []
    for line in strands.polylines():
        if len(line) > max_points:
            line = line[np.round(np.linspace(0, len(line) - 1, max_points)).astype(np.int64)]
        pieces.append(line)
        counts.append(len(line))
    points = np.concatenate(pieces)
    return Strands(points.astype(np.float32), np.full(len(points), strands.radii[0], np.float32),
                   np.asarray(counts, np.int64))


def model_strands(hair: HairFile, n_strands: int, seed: int = 0, radius: float = RADIUS) -> Strands:
    """A loaded model as a portrait hairstyle: fitted to the head, at most ``n_strands`` strands
    (a random subset when it has more; their radius then grows by sqrt(model / kept), at most 1.5x,
    to keep some of the coverage), at most ``MAX_POINTS_PER_STRAND`` and ``MAX_CONTROL_POINTS`` points, as
    B-spline control points through each polyline's ends. A file's thickness is in its own units and
    real fibres are far too thin for a preview's strand count, so every strand gets ``radius``."""
    strands = hair.strands()
    if strands.n_strands == 0:
        raise HairFileError("no strand of the model has 2 or more points; nothing to render")
    total = strands.n_strands
    if total > n_strands:
        keep = np.sort(np.random.default_rng(seed).choice(total, n_strands, replace=False))
        strands = strands.subset(keep)
    strands = fit_to_head(strands)
    per_strand = int(min(MAX_POINTS_PER_STRAND, max(2, MAX_CONTROL_POINTS // strands.n_strands - 2)))
    strands = _decimate(strands, per_strand)
    thick = radius * float(np.clip(np.sqrt(total / strands.n_strands), 1.0, 1.5))
    strands = Strands(strands.points, np.full(len(strands.points), thick, np.float32), strands.counts)
    return strands.through_ends()


def model_summary(path: str | os.PathLike, n_strands: int) -> str:
    """One line on what a render of the model at ``path`` shows: its size, and the subset kept."""
    with open(path, "rb") as f:
        header = f.read(_HEADER.size)
    _, strands, points = _HEADER.unpack(header)[:3]
    kept = min(strands, n_strands)
    cut = f"a random {kept} of them (the strand budget; --strands sets it)" if kept < strands else "all of them"
    return f"{Path(path).name}: {strands} strands, {points} points, fitted to the head; rendering {cut}"


@functools.lru_cache(maxsize=4)
def _cached_model(path: str, mtime_ns: int, size: int, n_strands: int, seed: int, radius: float) -> Strands:
    return model_strands(read_hair_file(path), n_strands, seed, radius)


def hair_model_strands(path: str | os.PathLike, n_strands: int = 4000, seed: int = 0,
                       radius: float = RADIUS) -> Strands:
    """:func:`model_strands` of the ``.hair`` file at ``path``, loaded once per path and modification time."""
    path = Path(path).resolve()
    stat = path.stat()
    return _cached_model(str(path), stat.st_mtime_ns, stat.st_size, int(n_strands), int(seed), float(radius))
