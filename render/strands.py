"""Strand geometry as ``bsplinecurve`` control points with radii, deterministic from a seed.

Units: the swatch holder is 1 unit wide (a 5 cm swatch, so 1 unit = 5 cm); the head (``head.py``,
a bust whose skull is about 2 units tall) has 1 unit ≈ 9 cm. Strands are far thicker than real
hair (tens of µm) so that a few thousand of them cover the surface: the ``hair`` BSDF's absorption
is per fibre radius, so the radius changes the texture scale but not the colour.

Hairstyles grow in three steps (``grow``): guide strands drape from the scalp under gravity and
collide with the bust; every strand follows its nearest guide (a clump), converging on it towards
the tip; then waves, curls, frizz, a cut and a last collision. ``STYLES`` holds each style's
parameters; strand counts and point counts are chosen in ``render/README.md``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from hairdigi.render import head
from hairdigi.render.domain.rig_geometry import SWATCH_HALF
from hairdigi.render.domain.text_enum import TextEnum


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
        memory (``render/README.md``; ``tests/test_render.py`` renders the case that crashed).
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
        rows = np.column_stack([self.points, self.radii]).astype(np.float64)   # 9 digits: exact float32
        template = "".join("%.9g %.9g %.9g %.9g\n" * int(k) + "\n" for k in self.counts)
        return (template % tuple(rows.ravel().tolist()))[:-1]   # one C-level format: 10x a loop

    def polylines(self) -> list[np.ndarray]:
        """The strands as a list of (K, 3) arrays."""
        return np.split(self.points, np.cumsum(self.counts)[:-1])

    def starts(self) -> np.ndarray:
        """Index of every strand's first control point."""
        return np.concatenate([[0], np.cumsum(self.counts)[:-1]]).astype(np.int64)

    def subset(self, strands: np.ndarray) -> "Strands":
        """The strands numbered ``strands`` (indices, in the order given)."""
        strands = np.asarray(strands, dtype=np.int64)
        starts, counts = self.starts()[strands], self.counts[strands]
        index = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(counts.sum())
        return Strands(self.points[index], self.radii[index], counts.copy())

    def through_ends(self) -> "Strands":
        """Polylines as B-spline control points that pass through each strand's first and last points.

        A uniform cubic B-spline starts at (p0 + 4 p1 + p2) / 6; a mirrored point 2 p0 - p1 before p0
        (and 2 pn - pn-1 after pn) makes it start (and end) on the polyline's ends, with 2 points or more.
        """
        starts, ends = self.starts(), self.starts() + self.counts - 1
        second = np.minimum(starts + 1, ends)
        before = 2 * self.points[starts] - self.points[second]
        after = 2 * self.points[ends] - self.points[np.maximum(ends - 1, starts)]
        index = np.insert(np.arange(len(self.points)), np.concatenate([starts, ends + 1]), -1)
        points = self.points[np.maximum(index, 0)].copy()
        radii = self.radii[np.maximum(index, 0)].copy()
        out_starts = starts + 2 * np.arange(self.n_strands)
        out_ends = out_starts + self.counts + 1
        points[out_starts], points[out_ends] = before, after
        radii[out_starts], radii[out_ends] = self.radii[starts], self.radii[ends]
        return Strands(points.astype(np.float32), radii.astype(np.float32), self.counts + 2)

    def curves(self, per_segment: int = 4) -> "Strands":
        """The cubic B-splines Mitsuba draws, sampled ``per_segment`` times a segment, as polylines."""
        seg = self.segment_indices().astype(np.int64)
        u = np.arange(per_segment) / per_segment
        basis = np.stack([(1 - u) ** 3, 3 * u ** 3 - 6 * u ** 2 + 4, -3 * u ** 3 + 3 * u ** 2 + 3 * u + 1, u ** 3], 1) / 6
        end = np.array([0.0, 1.0, 4.0, 1.0]) / 6
        rows = np.column_stack([self.points, self.radii]).astype(np.float64)
        quads = rows[seg[:, None] + np.arange(4)]                       # (segments, 4, 4)
        samples = np.einsum("uk,skc->suc", basis, quads).reshape(-1, 4)
        n_seg = self.counts - 3
        last = np.cumsum(n_seg) - 1
        ends = np.einsum("k,skc->sc", end, quads[last])
        out = np.insert(samples, np.cumsum(n_seg) * per_segment, ends, axis=0)
        return Strands(out[:, :3].astype(np.float32), out[:, 3].astype(np.float32),
                       (n_seg * per_segment + 1).astype(np.int64))


# --- the swatch -------------------------------------------------------------------------------

SWATCH_WIDTH = 2 * SWATCH_HALF[0]
SWATCH_LENGTH = 2 * SWATCH_HALF[1]


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


#: Clearance between neighbouring fibre surfaces in ``layered_swatch_strands``, in radii.
LAYER_CLEARANCE = 0.02
#: Layers of the layered swatch: within its thick limit (10-40 layers agree within noise) whatever its
#: strand count, which sets how fine its fibres are (``layered_radius``).
SWATCH_LAYERS = 20


def layered_radius(n_strands: int, layers: int = SWATCH_LAYERS, fill: float = 0.8, most: float = 0.004) -> float:
    """The fibre radius at which ``n_strands`` fill ``layers`` layers of the holder's width, at most
    ``most`` (fewer strands, as small test renders use, make fewer layers rather than a block).

    sigma_a is per fibre radius, so the colour does not depend on it (measured at the rig's swatch
    area: 2000 fibres of radius 0.004, 4000 of 0.002 and 8000 of 0.001 agree within 0.04-0.77
    ΔE2000, render noise); a finer fibre makes a thinner stack, as a real swatch is, and no shadow
    of its own edge on the holder."""
    return min(most, fill * SWATCH_WIDTH * layers / (2.0 * n_strands))


def layered_swatch_strands(n_strands: int = 2000, seed: int = 0, radius: float = 0.004,
                           layers: int | None = None, points_per_strand: int = 12, fill: float = 0.8,
                           wobble: float = 0.1) -> Strands:
    """A physical swatch: fibres side by side in irregular layers stacked in z, none intersecting.

    Each layer holds about ``fill * SWATCH_WIDTH / (2 radius)`` fibres (or ``n_strands / layers``
    when ``layers`` is given) across the holder's width, with random gaps of at least 2 radii
    between neighbouring centres (the slack is spread at random: irregular holes that the layers
    above cover). A layer drifts as a whole in x (waves like ``swatch_strands``'s) and in z (by
    ``wobble`` radii); each fibre wavers by up to ``wobble`` radii inside its slot. Layers are
    stacked with at least 2 radii plus their wobble between centres, so no two fibres meet: every
    fibre's control points keep their clearance from its neighbours' at the same y, and a B-spline
    point is a positive blend of them (``through_ends`` included), so the curves keep it too.
    The fibres run the full ``SWATCH_LENGTH``, their ends honoured through ``Strands.through_ends``.
    """
    if n_strands < 1:
        raise ValueError(f"a swatch needs at least 1 strand, got {n_strands}")
    if not 0 < fill <= 1 or not 0 <= wobble <= 0.5 or radius <= 0 or points_per_strand < 2:
        raise ValueError(f"fill in (0, 1], wobble in [0, 0.5], radius > 0 and 2+ points, got "
                         f"{fill}, {wobble}, {radius}, {points_per_strand}")
    rng = np.random.default_rng(seed)
    gap = radius * (2.0 + LAYER_CLEARANCE + 2 * wobble)          # least centre distance in a layer
    most = int(np.floor(SWATCH_WIDTH / gap)) + 1                 # fibres a layer can hold at that gap
    if layers is None:
        per = int(np.clip(round(fill * SWATCH_WIDTH / (2 * radius)), 1, most))
        layers = int(np.ceil(n_strands / per))
    if layers < 1 or int(np.ceil(n_strands / layers)) > most:
        raise ValueError(f"{n_strands} strands of radius {radius} need at least "
                         f"{int(np.ceil(n_strands / most))} layers, got {layers}")
    counts = np.full(layers, n_strands // layers) + (np.arange(layers) < n_strands % layers)
    counts = counts[counts > 0]
    layers = len(counts)
    layer = np.repeat(np.arange(layers), counts)                 # (n,) each fibre's layer
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.arange(n_strands) - first[layer]                   # index within its layer
    # the slack of each layer (its width less the least gaps), split at random before each fibre and after the last
    slack = SWATCH_WIDTH - (counts - 1) * gap
    share = rng.exponential(1.0, n_strands + layers)
    owner = np.concatenate([layer, np.arange(layers)])
    share /= np.bincount(owner, weights=share, minlength=layers)[owner]
    before = share[:n_strands] * slack[layer] + gap * (slot > 0)
    run = np.cumsum(before)
    x0 = -SWATCH_WIDTH / 2 + run - (run - before)[first][layer]   # cumulative sum within each layer
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points_per_strand)
    # whole layers drift: x waves as today's swatch, small z waves; each fibre wavers inside its slot
    phase = rng.uniform(0, 2 * np.pi, (layers, 1))
    x_wave = rng.uniform(0.002, 0.008, (layers, 1)) * np.sin(2 * np.pi * y / rng.uniform(0.3, 0.7, (layers, 1)) + phase)
    z_wave = wobble * radius * np.sin(2 * np.pi * y / rng.uniform(0.5, 1.5, (layers, 1)) + phase[::-1])
    own = (wobble * radius * rng.uniform(0, 1, (n_strands, 1))
           * np.sin(2 * np.pi * y / rng.uniform(0.2, 0.6, (n_strands, 1)) + rng.uniform(0, 2 * np.pi, (n_strands, 1))))
    spacing = radius * (2.0 + LAYER_CLEARANCE + 2 * wobble + rng.uniform(0, 0.3, layers))
    z0 = radius * (1.0 + LAYER_CLEARANCE / 2 + wobble) + np.concatenate([[0.0], np.cumsum(spacing[:-1])])
    x = x0[:, None] + x_wave[layer] + own
    z = np.broadcast_to(z0[layer, None] + z_wave[layer], x.shape)
    pts = np.stack([x, np.broadcast_to(y, x.shape), z], axis=-1)
    return Strands.from_grid(pts, radius).through_ends()


# --- hairstyles on the head -------------------------------------------------------------------

from hairdigi.render.domain.bounds import HAIRSTYLES  # noqa: E402  (the names, for the command line without Mitsuba)
DOWN = np.array([0.0, -1.0, 0.0])
MIN_GUIDES = 120
#: Fibre radius of the hairstyles (0.6 mm: far thicker than hair, so that ~6000 strands cover a head;
#: the absorption is per radius, so this sets the texture, not the colour; see render/README.md).
HAIR_RADIUS = 0.007
CROWN = head.CROWN


class Growth(TextEnum):
    """How a hairstyle's strands grow from the scalp."""

    DRAPE = "drape"           # fall under gravity
    PONYTAIL = "ponytail"     # gathered at the back of the head
    AFRO = "afro"             # grow outward


@dataclass(frozen=True)
class Style:
    """How one hairstyle grows. Lengths are in scene units (1 unit ≈ 9 cm)."""

    length: float                 #: guide length from the scalp
    points: int                   #: control points per strand
    kind: Growth = Growth.DRAPE   #: how its strands grow
    length_jitter: float = 0.1    #: each strand is up to this fraction shorter than its guide
    part_x: float | None = None   #: a parting at this x, from the front hairline to the crown; None: none
    bend: float = 0.5             #: arc length over which a strand turns from its growth direction to gravity
    lift: float = 0.3             #: how far strands rise off the scalp along its normal before combing
    layer: float = 0.08           #: thickness of the hair over the scalp: crown strands lie on top
    strands_per_clump: int = 16
    clump: float = 0.4            #: 0: strands keep their offset from the guide; 1: their tips meet it; < 0: fan out
    wave: tuple[float, float] = (0.0, 0.5)   #: amplitude, wavelength of planar waves
    curl: tuple[float, float] = (0.0, 0.2)   #: amplitude, wavelength of helical curls (ringlets, coils)
    curl_jitter: float = 0.15     #: per-strand variation of the curls' amplitude and wavelength
    frizz: float = 0.01           #: per-strand random wander, growing to the tip
    cut_y: float | None = None    #: a blunt cut: tips end at this height in front, 0.25 higher at the back
    curl_under: float = 0.0       #: ends turned under towards the neck (a bob)
    thickness: float = 1.0        #: radius multiplier (coils need thicker strands to fill their volume)


STYLES = {
    "straight": Style(length=2.5, points=32, part_x=0.3, bend=0.18, lift=0.15, layer=0.05,
                      strands_per_clump=14, clump=0.35, wave=(0.012, 0.8), frizz=0.006, length_jitter=0.12),
    "wavy": Style(length=2.4, points=44, part_x=0.0, bend=0.35, lift=0.3, layer=0.09,
                  strands_per_clump=16, clump=0.5, wave=(0.07, 0.42), frizz=0.01, length_jitter=0.12),
    "curly": Style(length=1.9, points=72, part_x=-0.22, bend=0.45, lift=0.3, layer=0.1,
                   strands_per_clump=18, clump=0.65, curl=(0.085, 0.21), frizz=0.014, length_jitter=0.18),
    "bob": Style(length=1.8, points=26, part_x=-0.3, bend=0.3, lift=0.25, layer=0.08,
                 strands_per_clump=14, clump=0.3, wave=(0.006, 0.8), frizz=0.004, length_jitter=0.03,
                 cut_y=-1.3, curl_under=0.12),
    "ponytail": Style(length=1.7, points=40, kind=Growth.PONYTAIL, bend=0.5, layer=0.05,
                      strands_per_clump=16, clump=-1.5, wave=(0.02, 0.6), frizz=0.01, length_jitter=0.15),
    "afro": Style(length=0.8, points=96, kind=Growth.AFRO, lift=1.0, layer=0.02, strands_per_clump=6, clump=0.25,
                  curl=(0.05, 0.08), curl_jitter=0.25, frizz=0.07, length_jitter=0.1, thickness=1.15),
}
assert tuple(STYLES) == HAIRSTYLES


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _smoothstep(lo: float, hi: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def scalp_roots(n: int, rng: np.random.Generator, part_x: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``n`` root points on the scalp (above the hairline, off the parting) and their outward normals."""
    out = np.empty((0, 3))
    while len(out) < n:
        d = _unit(rng.normal(size=(3 * n + 16, 3)))
        d = d[head.hairline_margin(head.SKULL_CENTER + d) > rng.uniform(0.0, 4.0, len(d))]  # a soft hairline
        p = head.surface_along(d)
        out = np.vstack([out, p[~head.in_parting(p, part_x)]])
    out = out[:n]
    return out, head.gradient(out)


def _comb(roots: np.ndarray, normals: np.ndarray, part_x: float | None) -> tuple[np.ndarray, np.ndarray]:
    """Each root's combing direction on the scalp, and its side of the parting (±1)."""
    radial = _unit(roots - CROWN)
    side = np.where(roots[:, 0] >= (0.0 if part_x is None else part_x), 1.0, -1.0)
    if part_x is None:
        comb = radial
    else:   # in front of the crown: away from the parting, a little back; behind it: from the crown
        away = np.column_stack([side, np.full(len(roots), -0.2), np.full(len(roots), -0.45)])
        w = _smoothstep(CROWN[2] - 0.1, CROWN[2] + 0.35, roots[:, 2])[:, None]
        comb = w * _unit(away) + (1 - w) * radial
    comb = comb - np.sum(comb * normals, axis=1, keepdims=True) * normals
    return _unit(comb), side


def _keep_off_face(p: np.ndarray, side: np.ndarray, margin: np.ndarray, active: np.ndarray | bool = True) -> np.ndarray:
    """Hair does not hang in front of the face: points there move sideways to its edge, on the side
    they are on (or their root's, near the middle). ``active`` spares the roots."""
    half = 0.74 + margin
    front = active & (p[:, 2] > 0.05) & (p[:, 1] < 0.45) & (p[:, 1] > -1.6) & (np.abs(p[:, 0]) < half)
    if front.any():
        p = p.copy()
        toward = np.where(np.abs(p[front, 0]) > 0.05, np.sign(p[front, 0]), side[front])
        p[front, 0] = toward * half[front]
        p[front, 2] = np.minimum(p[front, 2], 0.3 + 2 * margin[front])   # beside the cheek, not before it
    return p


def _margins(heights: np.ndarray, radius: float, layer: float, rng: np.random.Generator) -> np.ndarray:
    """Each strand's height over the bust: higher roots lie on top of lower ones."""
    rank = np.argsort(np.argsort(heights)) / max(len(heights) - 1, 1)
    return 1.5 * radius + 0.004 + layer * np.clip(rank + rng.normal(0, 0.12, len(heights)), 0, 1)


def _ramp(margin: np.ndarray, arc: np.ndarray, over: float = 0.25) -> np.ndarray:
    """The margin rises from the scalp to its full height over the first ``over`` units of a strand."""
    base = 1e-3 + 0 * margin
    return base[:, None] + (margin - base)[:, None] * _smoothstep(0.0, over, arc)


def _drape(roots: np.ndarray, normals: np.ndarray, comb: np.ndarray, side: np.ndarray, lengths: np.ndarray,
           n_pts: int, style: Style, margin: np.ndarray) -> np.ndarray:
    """Walk strands from their roots: combed, then turning to gravity, sliding over the bust."""
    s = len(roots)
    step = lengths / (n_pts - 1)
    keep = np.exp(-step / style.bend)[:, None]
    arc = step[:, None] * np.arange(n_pts)[None, :]
    m = _ramp(margin, arc)
    p = roots + normals * m[:, :1]
    v = _unit(style.lift * normals + comb)
    out = np.empty((s, n_pts, 3))
    out[:, 0] = p
    for k in range(1, n_pts):
        v = _unit(keep * v + (1 - keep) * DOWN)
        q = p + step[:, None] * v
        q = _keep_off_face(q, side, m[:, k], arc[:, k] > 0.2)
        q = head.push_out(q, m[:, k], iterations=2)
        v = _unit(q - p)
        p = out[:, k] = q
    return out


def _resample(curves: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Each strand's first ``keep`` fraction of its arc length, resampled to the same point count."""
    s, k, _ = curves.shape
    seg = np.linalg.norm(np.diff(curves, axis=1), axis=-1)
    arc = np.concatenate([np.zeros((s, 1)), np.cumsum(seg, axis=1)], axis=1)
    target = arc[:, -1:] * keep[:, None] * np.linspace(0, 1, k)[None, :]
    idx = np.clip(np.sum(arc[:, None, :] <= target[:, :, None], axis=2) - 1, 0, k - 2)
    a0 = np.take_along_axis(arc, idx, 1)
    a1 = np.take_along_axis(arc, idx + 1, 1)
    w = ((target - a0) / np.maximum(a1 - a0, 1e-12))[..., None]
    p0 = np.take_along_axis(curves, idx[..., None], 1)
    p1 = np.take_along_axis(curves, idx[..., None] + 1, 1)
    return p0 + w * (p1 - p0)


def _frame(curves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit normals per point, perpendicular to each strand's tangent, turning smoothly along it."""
    t = _unit(np.gradient(curves, axis=1))
    ref = np.where(np.abs(t[..., 1:2]) < 0.9, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]))
    n1 = _unit(np.cross(t, ref))
    return n1, np.cross(t, n1)


def _displace(curves: np.ndarray, arc: np.ndarray, amplitude: np.ndarray, wavelength: np.ndarray,
              phase: np.ndarray, helix: bool) -> np.ndarray:
    """Waves (planar) or curls (helical) of ``amplitude`` (per strand and point) and ``wavelength`` and
    ``phase`` (per strand), faded in over the first 0.2 units (curls 0.3: no corkscrews at the part)."""
    n1, n2 = _frame(curves)
    amp = amplitude * _smoothstep(0.0, 0.3 if helix else 0.2, arc)
    ang = 2 * np.pi * arc / wavelength[:, None] + phase[:, None]
    offset = (amp * np.cos(ang))[..., None] * n1
    if helix:
        offset += (amp * np.sin(ang))[..., None] * n2
    return curves + offset


def _nearest(points: np.ndarray, centres: np.ndarray, labels: np.ndarray | None = None,
             centre_labels: np.ndarray | None = None) -> np.ndarray:
    """Index of the nearest centre for every point (only among centres with the same label, if given)."""
    out = np.empty(len(points), dtype=np.int64)
    for start in range(0, len(points), 2048):
        chunk = points[start:start + 2048]
        d = np.sum((chunk[:, None, :] - centres[None, :, :]) ** 2, axis=-1)
        if labels is not None:
            d = d + 1e6 * (labels[start:start + 2048, None] != centre_labels[None, :])
        out[start:start + 2048] = np.argmin(d, axis=1)
    return out


def _afro_guides(roots: np.ndarray, normals: np.ndarray, lengths: np.ndarray, n_pts: int,
                 rng: np.random.Generator) -> np.ndarray:
    """Strands growing outward from the scalp to a rounded silhouette around the head."""
    centre, radii = np.array([0.0, 0.3, -0.14]), np.array([1.55, 1.38, 1.55])
    # front hair rises (seen from the front it stands side-on, as a wall, not end-on)
    rise = 0.5 * _smoothstep(0.0, 0.6, roots[:, 2])[:, None] * np.array([0.0, 1.0, -0.3])
    g = _unit(normals + 0.6 * _unit(roots - centre) + rise + rng.normal(0, 0.3, roots.shape))
    g[:, 1] = np.maximum(g[:, 1], -0.6)
    # distance along g from the root to the silhouette ellipsoid (the root is inside it)
    o, d = (roots - centre) / radii, g / radii
    a, b, c = np.sum(d * d, 1), 2 * np.sum(o * d, 1), np.sum(o * o, 1) - 1
    reach = (-b + np.sqrt(np.maximum(b * b - 4 * a * c, 0))) / (2 * a)
    length = np.clip(reach, 0.25, None) * lengths / lengths.max()
    t = np.linspace(0, 1, n_pts)[None, :, None]
    curves = roots[:, None] + g[:, None] * length[:, None, None] * t
    curves[..., 1] -= 0.08 * (length[:, None] * t[..., 0]) ** 2   # a little weight
    return curves


def _ponytail(roots: np.ndarray, normals: np.ndarray, style: Style, n_strands: int, lengths: np.ndarray,
              margin: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Hair pulled over the scalp to a tie at the back of the head, then a clumped tail falling from it."""
    n_gather = style.points // 3
    tie_dir = _unit(np.array([0.0, 0.4, -1.0]))   # a high tie, at the back of the crown
    tie = head.surface_along(tie_dir[None])[0] + 0.09 * tie_dir
    # the gather: along the skull, from each root's direction to the tie's
    t = np.linspace(0, 1, n_gather)[None, :, None]
    d0 = _unit(roots - head.SKULL_CENTER)[:, None]
    dirs = _unit((1 - t) * d0 + t * tie_dir)
    radius = 1.0 / np.sqrt(np.sum((dirs / head.SKULL_RADII) ** 2, axis=-1, keepdims=True))
    path = head.SKULL_CENTER + dirs * radius
    spread = rng.normal(0, 0.045, (len(roots), 2))
    across = np.stack([np.array([1.0, 0.0, 0.0]), _unit(np.array([0.0, 1.0, 0.05]))])
    tie_points = tie + spread @ across
    pull = _smoothstep(0.55, 1.0, t)
    path = (1 - pull) * path + pull * tie_points[:, None]
    arc = np.linspace(0, 1, n_gather)[None, :] * 1.5
    path = head.push_out(path.reshape(-1, 3), _ramp(margin, arc).reshape(-1)).reshape(path.shape)
    # the tail: guides fall from the tie, every strand follows the nearest one
    n_tail = style.points - n_gather
    n_guides = min(n_strands, max(4, n_strands // style.strands_per_clump))
    guide_spread = rng.normal(0, 0.045, (n_guides, 2))
    guide_roots = tie + guide_spread @ across
    up = _unit(np.array([0.0, 0.7, -1.0]) + rng.normal(0, 0.15, (n_guides, 3)))   # out and up, then falling
    tail_len = style.length * rng.uniform(0.9, 1.0, n_guides)
    guides = _drape(guide_roots, up, np.zeros_like(up), np.ones(n_guides), tail_len, n_tail + 1,
                    replace(style, lift=1.0, bend=0.45), np.full(n_guides, 0.02))
    assign = _nearest(spread, guide_spread)
    tails = _follow(guides, guide_roots, tie_points, assign, style, lengths, rng)
    return np.concatenate([path, tails[:, 1:]], axis=1)


def _follow(guides: np.ndarray, guide_roots: np.ndarray, roots: np.ndarray, assign: np.ndarray, style: Style,
            fraction: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Every strand follows its guide over ``fraction`` of its length, its offset from the guide
    shrinking towards the tip by ``style.clump``, with some frizz of its own."""
    s, (_, k, _) = len(roots), guides.shape
    t = np.linspace(0, 1, k)[None, :]
    pos = t * fraction[:, None] * (k - 1)
    i0 = np.clip(np.floor(pos).astype(np.int64), 0, k - 2)
    w = (pos - i0)[..., None]
    g = guides[assign]
    rows = np.arange(s)[:, None]
    base = g[rows, i0] * (1 - w) + g[rows, i0 + 1] * w
    offset = roots - guide_roots[assign]
    shrink = 1 - style.clump * _smoothstep(0.0, 1.0, t * fraction[:, None]) ** 0.7
    curves = base + offset[:, None, :] * shrink[..., None]
    if style.frizz > 0:
        a = rng.normal(0, 1, (s, 2, 3))
        f = rng.uniform(0.5, 2.0, (s, 2))
        ph = rng.uniform(0, 2 * np.pi, (s, 2))
        wander = np.sin(2 * np.pi * f[:, None, :] * t[..., None] + ph[:, None, :])   # (s, k, 2)
        curves += style.frizz * (t ** 1.5)[..., None] * np.einsum("skj,sjc->skc", wander, a)
    return curves


def grow(style: Style, n_strands: int, seed: int = 0, radius: float = HAIR_RADIUS) -> Strands:
    """Grow ``n_strands`` strands of ``style`` on the head (see the module docstring)."""
    radius = radius * style.thickness
    rng = np.random.default_rng(seed)
    guide_rng = np.random.default_rng([seed, 1])
    k = style.points
    roots, normals = scalp_roots(n_strands, rng, style.part_x)
    # clumps of about ``strands_per_clump`` strands, but never fewer than MIN_GUIDES (so that few
    # strands do not follow guides a head's width away)
    n_guides = min(n_strands, max(MIN_GUIDES, n_strands // max(style.strands_per_clump, 1)))
    g_roots, g_normals = scalp_roots(n_guides, guide_rng, style.part_x)
    margin = _margins(roots[:, 1] + 0.3 * roots[:, 2], radius, style.layer, rng)
    g_margin = _margins(g_roots[:, 1] + 0.3 * g_roots[:, 2], radius, style.layer, guide_rng)
    fraction = 1.0 - style.length_jitter * rng.uniform(0, 1, n_strands) ** 1.5
    comb, side = _comb(roots, normals, style.part_x)
    g_comb, g_side = _comb(g_roots, g_normals, style.part_x)
    g_len = style.length * guide_rng.uniform(0.95, 1.0, n_guides)
    if style.kind is Growth.PONYTAIL:
        curves = _ponytail(roots, normals, style, n_strands, fraction, margin, rng)
    else:
        if style.kind is Growth.AFRO:
            guides = _afro_guides(g_roots, g_normals, g_len, k, guide_rng)
        else:
            guides = _drape(g_roots, g_normals, g_comb, g_side, g_len, k, style, g_margin)
        assign = _nearest(roots, g_roots, side, g_side)
        curves = _follow(guides, g_roots, roots, assign, style, fraction, rng)
        arc = np.concatenate([np.zeros((n_strands, 1)),
                              np.cumsum(np.linalg.norm(np.diff(curves, axis=1), axis=-1), axis=1)], axis=1)
        clump_phase = guide_rng.uniform(0, 2 * np.pi, n_guides)[assign]
        t = arc / np.maximum(arc[:, -1:], 1e-9)
        for (amp, lam), helix in ((style.wave, False), (style.curl, True)):
            if amp > 0:   # coherent in a clump (one phase), varied per strand; curls widen to the tip
                j = style.curl_jitter
                amplitude = amp * (1 + j * rng.uniform(-1, 1, (n_strands, 1))) * (0.6 + 0.4 * t if helix else 1.0)
                clump_lam = lam * (1 + 0.5 * j * guide_rng.uniform(-1, 1, n_guides))[assign]
                curves = _displace(curves, arc, amplitude, clump_lam * (1 + 0.015 * rng.uniform(-1, 1, n_strands)),
                                   clump_phase + rng.normal(0, 0.3, n_strands), helix)
        if style.cut_y is not None:
            curves = _cut(curves, style.cut_y)
        if style.curl_under > 0:
            curves = _curl_under(curves, style.curl_under)
    arc = np.concatenate([np.zeros((n_strands, 1)),
                          np.cumsum(np.linalg.norm(np.diff(curves, axis=1), axis=-1), axis=1)], axis=1)
    m = _ramp(margin, arc).reshape(-1)
    flat = curves.reshape(-1, 3)
    if style.kind is not Growth.AFRO:
        flat = _keep_off_face(flat, np.repeat(side, k), m, arc.reshape(-1) > 0.2)
    curves = head.push_out(flat, m, iterations=8).reshape(curves.shape)
    # a B-spline starts near its second point: mirrored end points make it start at the root
    strands = Strands.from_grid(curves, radius).through_ends()
    grid = _settle(strands.points.reshape(n_strands, k + 2, 3).astype(float), m.reshape(n_strands, k))
    return Strands.from_grid(grid, radius)


def _settle(control: np.ndarray, margin: np.ndarray, rounds: int = 4) -> np.ndarray:
    """Push control points out until the B-spline itself (sampled at its knots and mid-segments),
    not only its control points, clears the bust by ``margin`` (per point, without the mirrored ends).

    Control points straddling a thin part (an ear's rim) otherwise let the curve cut through it.
    """
    s, k, _ = control.shape
    target = np.concatenate([margin[:, :1], margin, margin[:, -1:]], axis=1)
    knot = np.array([1.0, 4.0, 1.0]) / 6
    mid = np.array([1.0, 23.0, 23.0, 1.0]) / 48
    live = np.ones(s, dtype=bool)   # strands still checked: after the first round, those that moved
    for _ in range(rounds):
        moved, touched = False, np.zeros(s, dtype=bool)
        for weights, lift in ((knot, (1,)), (mid, (1, 2))):
            n = len(weights)
            samples = sum(w * control[:, i:k - n + 1 + i] for i, w in enumerate(weights))   # (s, k-n+1, 3)
            first = 1 if n == 3 else 0          # the knot at the root stays on the scalp
            samples = samples[:, first:]
            need = np.min([target[:, first + i:k - n + 1 + i] for i in lift], axis=0)
            d = np.full(samples.shape[:2], np.inf)
            d[live] = head.sdf(samples[live].reshape(-1, 3)).reshape(-1, samples.shape[1])
            bad = d < need - 1e-4
            if not bad.any():
                continue
            moved = True
            rows, cols = np.nonzero(bad)
            touched[rows] = True
            push = ((need - d)[bad] * 1.5)[:, None] * head.gradient(samples[rows, cols])
            for i in lift:
                np.add.at(control, (rows, cols + first + i), push)
        if not moved:
            break
        live = touched
    return control


def _cut(curves: np.ndarray, cut_y: float) -> np.ndarray:
    """A blunt cut: each strand ends where it first goes below the cut line (higher at the back)."""
    level = cut_y + 0.25 * np.clip(-curves[..., 2], 0, 1)
    below = curves[..., 1] < level
    seg = np.linalg.norm(np.diff(curves, axis=1), axis=-1)
    arc = np.concatenate([np.zeros((len(curves), 1)), np.cumsum(seg, axis=1)], axis=1)
    first = np.where(below.any(axis=1), np.argmax(below, axis=1), curves.shape[1] - 1)
    keep = np.take_along_axis(arc, first[:, None], 1)[:, 0] / np.maximum(arc[:, -1], 1e-9)
    return _resample(curves, np.clip(keep, 0.05, 1.0))


def _curl_under(curves: np.ndarray, amount: float) -> np.ndarray:
    """Turn the last quarter of every strand in towards the neck."""
    t = np.linspace(0, 1, curves.shape[1])[None, :, None]
    w = _smoothstep(0.7, 1.0, t) ** 2
    inward = _unit((curves - np.array([0.0, 0.0, -0.2])) * np.array([1.0, 0.0, 1.0]))
    return curves - amount * w * inward + np.array([0.0, 0.5 * amount, 0.0]) * w


def hairstyle_strands(style: str, n_strands: int = 6000, seed: int = 0, radius: float = HAIR_RADIUS) -> Strands:
    """One of ``HAIRSTYLES`` on the head (``head.py``'s bust, face along +z)."""
    if style not in HAIRSTYLES:
        raise ValueError(f"unknown hairstyle {style!r}; choose one of {', '.join(HAIRSTYLES)}")
    if n_strands < 1:
        raise ValueError(f"a hairstyle needs at least 1 strand, got {n_strands}")
    return grow(STYLES[style], n_strands, seed, radius)
