"""Strand geometry as ``bsplinecurve`` control points with radii, deterministic from a seed.

Units: the swatch holder is 1 unit wide (a 5 cm swatch, so 1 unit = 5 cm); the head proxy is a
sphere of radius 1 (about 9 cm). Strands are far thicker than real hair (tens of µm) so that a
few thousand of them cover the surface: the ``hair`` BSDF's absorption is per fibre radius, so
the radius changes the texture scale but not the colour.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HEAD_RADIUS = 1.0
HAIRSTYLES = ("straight", "wavy", "curly", "bob", "ponytail")


@dataclass(frozen=True)
class Strands:
    """Strands stored flat, as in Cem Yuksel's format: all points, their radii, and points per strand."""

    points: np.ndarray  # (P, 3) float32
    radii: np.ndarray   # (P,) float32
    counts: np.ndarray  # (S,) int64, every count >= 4 for a cubic B-spline

    @property
    def n_strands(self) -> int:
        return int(len(self.counts))

    @classmethod
    def from_grid(cls, points: np.ndarray, radius: float | np.ndarray) -> "Strands":
        """From a (S, K, 3) array of S strands of K points each."""
        s, k, _ = points.shape
        radii = np.broadcast_to(np.asarray(radius, dtype=np.float32), (s, k)).reshape(-1)
        return cls(points.reshape(-1, 3).astype(np.float32), radii.astype(np.float32),
                   np.full(s, k, dtype=np.int64))

    def with_dummy(self, where: tuple[float, float, float] = (0.0, 0.0, -1.0e4)) -> "Strands":
        """Append a tiny strand far out of view.

        Mitsuba 3.9.1's ``bsplinecurve`` reads one segment past its array on some rays under
        ``llvm_ad_rgb`` and segfaults; an extra strand at the end makes that read land in valid
        memory (see shared/reference/mitsuba-hair-notes.md).
        """
        dummy = np.asarray(where, dtype=np.float32) + np.array(
            [[0, 0, 0], [0, 0, 1e-3], [0, 0, 2e-3], [0, 0, 3e-3]], dtype=np.float32)
        return Strands(np.vstack([self.points, dummy]),
                       np.concatenate([self.radii, np.full(4, 1e-5, np.float32)]),
                       np.concatenate([self.counts, [4]]))

    def control_points(self) -> np.ndarray:
        """Flat ``x, y, z, r`` array, the layout of Mitsuba's ``control_points`` parameter."""
        return np.column_stack([self.points, self.radii]).astype(np.float32).ravel()

    def segment_indices(self) -> np.ndarray:
        """Index of the first control point of every cubic segment (K - 3 per strand of K points)."""
        starts = np.concatenate([[0], np.cumsum(self.counts)[:-1]])
        return np.concatenate([s + np.arange(k - 3) for s, k in zip(starts, self.counts)]).astype(np.uint32)

    def to_curve_text(self) -> str:
        """Mitsuba's curve file: one ``x y z r`` line per control point, a blank line between strands."""
        rows = np.column_stack([self.points, self.radii])
        lines: list[str] = []
        start = 0
        for k in self.counts:
            lines.extend(" ".join(f"{v:.9g}" for v in row) for row in rows[start:start + k])  # exact float32
            lines.append("")
            start += k
        return "\n".join(lines)

    def polylines(self) -> list[np.ndarray]:
        """The strands as a list of (K, 3) arrays."""
        return np.split(self.points, np.cumsum(self.counts)[:-1])


# --- the swatch -------------------------------------------------------------------------------

SWATCH_WIDTH = 1.0
SWATCH_LENGTH = 1.4


def swatch_strands(n_strands: int = 2000, seed: int = 0, radius: float = 0.004,
                   points_per_strand: int = 12, layers: float = 3.0) -> Strands:
    """Parallel strands along y lying on the holder (z = 0), with slight waves and jitter."""
    if n_strands < 1:
        raise ValueError(f"a swatch needs at least 1 strand, got {n_strands}")
    rng = np.random.default_rng(seed)
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points_per_strand)
    x0 = np.sort(rng.uniform(-SWATCH_WIDTH / 2, SWATCH_WIDTH / 2, n_strands))[:, None]
    phase = rng.uniform(0, 2 * np.pi, (n_strands, 1))
    wavelength = rng.uniform(0.3, 0.7, (n_strands, 1))
    amp = rng.uniform(0.002, 0.008, (n_strands, 1))
    x = x0 + amp * np.sin(2 * np.pi * y / wavelength + phase)
    x += rng.normal(0, 0.0015, (n_strands, points_per_strand))
    # each strand floats in a layer above the holder and drifts between layers, so strands cross
    base = radius * (1.0 + 2.0 * layers * rng.uniform(0, 1, (n_strands, 1)))
    z = base + radius * layers * 0.5 * np.sin(2 * np.pi * y / rng.uniform(0.5, 1.5, (n_strands, 1)) + phase)
    z = np.maximum(z, radius * 1.01)
    pts = np.stack([x, np.broadcast_to(y, x.shape), z], axis=-1)
    return Strands.from_grid(pts, radius)


# --- hairstyles on a head proxy ---------------------------------------------------------------

def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def scalp_roots(n: int, rng: np.random.Generator) -> np.ndarray:
    """Unit directions on the scalp: the upper head, minus the face (the face looks along +z)."""
    out = np.empty((0, 3))
    while len(out) < n:
        d = _unit(rng.normal(size=(4 * n, 3)))
        face = (d[:, 2] > 0.45) & (d[:, 1] < 0.55)
        temples = (d[:, 2] > 0.2) & (d[:, 1] < 0.25)
        keep = (d[:, 1] > -0.15) & ~face & ~temples
        out = np.vstack([out, d[keep]])
    return out[:n]


def _drape(roots: np.ndarray, length: np.ndarray, n_pts: int, stiffness: float,
           rng: np.random.Generator) -> np.ndarray:
    """Walk strands from their roots under gravity, pushed out of the head sphere."""
    s = len(roots)
    shell = HEAD_RADIUS * (1.02 + 0.06 * rng.uniform(0, 1, (s, 1)))
    p = roots * HEAD_RADIUS * 1.005
    # start along the normal, combed back and away from the face
    v = _unit(0.6 * roots + np.column_stack([0.3 * roots[:, 0], np.zeros(s),
                                             -0.9 * np.clip(roots[:, 2], 0, None) - 0.3]))
    step = (length / (n_pts - 1))[:, None]
    down = np.array([0.0, -1.0, 0.0])
    out = np.empty((s, n_pts, 3))
    out[:, 0] = p
    for k in range(1, n_pts):
        v = _unit(stiffness * v + (1 - stiffness) * down)
        p = p + step * v
        # in front of the face nothing hangs: push such points behind the jaw plane
        front = (p[:, 2] > 0.35) & (p[:, 1] < 0.4) & (np.abs(p[:, 0]) < 0.9)
        p[front, 2] = 0.35
        p = _push_out(p, shell)
        out[:, k] = p
    return out


def _push_out(points: np.ndarray, radius: np.ndarray | float) -> np.ndarray:
    """Move points that lie inside a sphere of ``radius`` around the origin onto its surface."""
    r = np.linalg.norm(points, axis=-1, keepdims=True)
    return np.where(r < radius, points / np.maximum(r, 1e-9) * radius, points)


def _frame(curves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit normals per point, perpendicular to each strand's tangent."""
    t = _unit(np.gradient(curves, axis=1))
    ref = np.where(np.abs(t[..., 1:2]) < 0.9, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    n1 = _unit(np.cross(t, ref))
    return n1, np.cross(t, n1)


def _displace(curves: np.ndarray, arc: np.ndarray, amplitude: float, wavelength: float,
              helix: bool, rng: np.random.Generator) -> np.ndarray:
    """Waves (planar) or curls (helical) whose amplitude fades in from the root."""
    n1, n2 = _frame(curves)
    phase = rng.uniform(0, 2 * np.pi, (len(curves), 1))
    lam = wavelength * rng.uniform(0.85, 1.15, (len(curves), 1))
    amp = amplitude * rng.uniform(0.7, 1.3, (len(curves), 1)) * np.clip(arc / 0.35, 0, 1)
    ang = 2 * np.pi * arc / lam + phase
    offset = amp[..., None] * np.cos(ang)[..., None] * n1
    if helix:
        offset += amp[..., None] * np.sin(ang)[..., None] * n2
    return curves + offset


def _ponytail(roots: np.ndarray, n_pts: int, rng: np.random.Generator) -> np.ndarray:
    """Hair gathered from the scalp to a tie at the back of the head, then falling as a tail."""
    tie = np.array([0.0, 0.25, -1.08])
    s = len(roots)
    n_gather = n_pts // 3
    t = np.linspace(0, 1, n_gather)[None, :, None]
    start = roots * HEAD_RADIUS * 1.01
    # slerp-like path over the head: blend, then push onto a shell just above the scalp
    path = (1 - t) * start[:, None] + t * tie
    r = np.linalg.norm(path, axis=-1, keepdims=True)
    path = path / r * np.maximum(r, HEAD_RADIUS * 1.02)
    tail_len = rng.uniform(1.3, 1.7, (s, 1))
    u = np.linspace(0, 1, n_pts - n_gather + 1)[1:][None, :]
    spread = rng.normal(0, 0.05, (s, 1, 2)) * (0.3 + u[..., None])
    tail = np.empty((s, n_pts - n_gather, 3))
    tail[..., 0] = tie[0] + spread[..., 0]
    tail[..., 1] = tie[1] - tail_len * u
    tail[..., 2] = tie[2] - 0.15 * np.sin(np.pi * u * 0.6) + spread[..., 1]
    return np.concatenate([path, tail], axis=1)


def hairstyle_strands(style: str, n_strands: int = 4000, seed: int = 0, radius: float = 0.006) -> Strands:
    """One of ``HAIRSTYLES`` on the head proxy (a sphere of radius 1 at the origin, face along +z)."""
    if style not in HAIRSTYLES:
        raise ValueError(f"unknown hairstyle {style!r}; choose one of {', '.join(HAIRSTYLES)}")
    if n_strands < 1:
        raise ValueError(f"a hairstyle needs at least 1 strand, got {n_strands}")
    rng = np.random.default_rng(seed)
    roots = scalp_roots(n_strands, rng)
    if style == "ponytail":
        curves = _ponytail(roots, 36, rng)
        return Strands.from_grid(_push_out(curves, HEAD_RADIUS * 1.005), radius)
    length = {"straight": 2.4, "wavy": 2.2, "curly": 1.7, "bob": 1.15}[style]
    n_pts = {"straight": 32, "wavy": 40, "curly": 72, "bob": 20}[style]
    lengths = length * rng.uniform(0.9, 1.05, n_strands)
    stiffness = 0.75 if style != "curly" else 0.8
    curves = _drape(roots, lengths, n_pts, stiffness, rng)
    arc = np.linspace(0, 1, n_pts)[None, :] * lengths[:, None]
    if style == "wavy":
        curves = _displace(curves, arc, 0.07, 0.45, helix=False, rng=rng)
    elif style == "curly":
        curves = _displace(curves, arc, 0.06, 0.16, helix=True, rng=rng)
    elif style == "bob":
        # ends turn in under the chin line
        curl_in = np.clip((arc - 0.8) / 0.35, 0, 1)[..., None] ** 2
        curves = curves - 0.15 * curl_in * _unit(curves * np.array([1.0, 0.0, 1.0]))
    # waves, curls and the bob's curl-in may dip into the head: collide once more, last
    return Strands.from_grid(_push_out(curves, HEAD_RADIUS * 1.005), radius)
