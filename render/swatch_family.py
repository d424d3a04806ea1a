"""A family of physical swatches: the ways a lab's fibres may lie on the holder.

hairdigi estimates a fibre property, ``sigma_a`` (per fibre radius), through one model of how the
fibres lie. At equal ``sigma_a`` another physical structure renders another colour at the rig (two
physical swatches differ by about 1.9 ΔE2000), so an estimate read through one structure inherits it.
This module draws the structures a lab's swatch may have, each a function ``(n_strands, seed) ->
Strands`` in ``STRUCTURES`` (a registry, as colour-science's method registries):

- ``layered``: ``strands.layered_swatch_strands``, fibres side by side in 20 irregular layers;
- ``deposited``: fibres dropped one by one onto the holder at small random angles (1°), each resting on
  what lies below it, none inside another (``deposit``): irregular layers and voids, as a combed
  swatch is;
- ``deposited-coarse``: the same with a quarter of the fibres, each twice as thick;
- ``spread``: deposited with a fibre alignment spread of 8°;
- ``wavy``: deposited fibres that wave along their length (amplitude 2-5 fibre diameters);
- ``tilted``: layers of parallel fibres, each layer tilted a few degrees (``tilted_layers``);
- ``loose``: layered at a low volume fraction (half the fibres a layer, layers further apart);
- ``thin``: too few fibres to cover the holder (about 4 deposited layers): the holder shows through;
- ``clumped``: fibres in flat clumps of 40 that sway as one, gaps between them (``clumps``): a structure drawn
  to evaluate one that no estimate was made robust over, before its figures were seen.

``FAMILY`` names the members a lab's full swatch may have (``thin`` is a capture to flag, not a
structure to average over; ``clumped`` is held out of it, for evaluations). The swatch spans ``rig_geometry.SWATCH_HALF``; every member takes its
fibre radius from its count so that it fills about the same thickness (``strands.layered_radius``).
"""
from __future__ import annotations

import functools
from typing import Callable

import numpy as np

from hairdigi.render.domain.files import atomic_path, cache_dir
from hairdigi.render.domain.text_enum import text_of
from hairdigi.render.strands import (SWATCH_LENGTH, SWATCH_WIDTH, Strands, layered_radius,
                                     layered_swatch_strands)

#: Points along each fibre (polyline; B-spline control points after ``Strands.through_ends``).
POINTS = 24
#: Height-map cells per fibre radius across the holder (the deposit's contact resolution).
CELLS_PER_RADIUS = 4
#: Gap (radii) a fibre keeps above what it rests on, as ``tilted_layers`` keeps 2.04 radii between
#: neighbours: renderers offset a ray leaving a fibre by their own epsilon, and fibres exactly in contact
#: render apart in Mitsuba and Cycles.
CLEARANCE = 0.03
#: How far (radii) a dropped fibre may roll sideways into a hollow before it rests: combing settles a
#: swatch (without it, fibres stick where they first touch and stack at a volume fraction of 0.13).
SETTLE_RADII = 3


def deposit(n_strands: int, seed: int, radius: float, angle_sd_deg: float = 1.0, wave: float = 0.0,
            points: int = POINTS) -> Strands:
    """Fibres dropped one by one on the holder, each resting on the fibres below it, none inside another.

    Each fibre is a line across the swatch's length at a random offset and a small random angle
    (normal, ``angle_sd_deg``), waving across by ``wave`` diameters. It is drawn as the B-spline
    Mitsuba and Cycles draw (``points`` control points, ``Strands.through_ends``), and checked on
    ``rows_between(radius, angle_sd_deg)`` rows a segment, close enough that it moves under half a radius
    sideways from row to row: on each row its circular section must clear the height map of the fibres
    already laid (``z >= max(H + sqrt(r^2 - dx^2))`` over the cells under it). Its control points are
    raised until the drawn curve clears every row (``_clear``), and the map is then raised by the drawn
    curve. It first rolls sideways by up to ``SETTLE_RADII`` radii to where it lies lowest, as combing
    settles a swatch. Fibres that run off the holder's sides are kept, as on a real holder.

    Checked on the control points alone (the former deposit), fibres of 100 µm crossed between rows and
    the B-spline sagged into what they lay on: 68% of the drawn curve lay inside another fibre, and
    Mitsuba and Cycles, which treat fibres inside fibres differently, rendered it 10% apart.
    """
    rng = np.random.default_rng(seed)
    cell = radius / CELLS_PER_RADIUS
    margin = 0.1 * SWATCH_WIDTH
    n_cells = int(np.ceil((SWATCH_WIDTH + 2 * margin) / cell))
    per = rows_between(radius, angle_sd_deg, wave, points)
    draw = drawn_rows_matrix(points, per)                          # (rows, points): control -> drawn
    height = np.zeros((len(draw), n_cells))                      # top surface per drawn row and cell
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points)
    reach = np.arange(-CELLS_PER_RADIUS, CELLS_PER_RADIUS + 1)   # the cells under a fibre's section
    rows = np.arange(len(draw))[:, None]
    out = np.empty((n_strands, points, 3))
    x0 = rng.uniform(-SWATCH_WIDTH / 2, SWATCH_WIDTH / 2, n_strands)
    angle = np.tan(np.radians(rng.normal(0.0, angle_sd_deg, n_strands)))
    amp = wave * 2 * radius * rng.uniform(1.0, 2.5, n_strands)
    length = rng.uniform(0.25, 0.6, n_strands)
    phase = rng.uniform(0, 2 * np.pi, n_strands)
    settle = SETTLE_RADII * CELLS_PER_RADIUS
    shifts = np.arange(-settle, settle + 1)                        # where it may roll to, in cells
    per_control = np.arange(points) * per                             # the drawn rows at the control points
    for i in range(n_strands):
        x = x0[i] + angle[i] * y + amp[i] * np.sin(2 * np.pi * y / length[i] + phase[i])
        centre = (draw @ x + SWATCH_WIDTH / 2 + margin) / cell      # the drawn curve's, row by row
        # where it settles, judged on the control points' rows; then every drawn row under it
        best = shifts[int(np.argmin(_need(height[per_control], centre[per_control, None] + shifts, reach, cell,
                                          radius).mean(axis=0)))]
        need, idx, lift = _need(height, centre[:, None] + best, reach, cell, radius, keep=True)
        z = _clear(draw, np.maximum(need[:, 0] + CLEARANCE * radius, radius * 1.01), radius)
        height[rows, idx] = np.maximum(height[rows, idx], (draw @ z)[:, None] + lift)
        out[i] = np.stack([x + best * cell, y, z], 1)
    return Strands.from_grid(out, radius).through_ends()


def _need(height: np.ndarray, centres: np.ndarray, reach: np.ndarray, cell: float, radius: float,
          keep: bool = False):
    """How high a fibre's axis must be, row by row, at ``centres`` (rows, shifts; in cells) to clear the
    map ``height`` (rows, cells); with ``keep`` also the cells under it and its section's height there
    (-inf off the map, so that a fibre running off the holder's side raises nothing)."""
    cells = np.round(centres).astype(int)[:, :, None] + reach         # (row, shift, cell)
    dx = np.clip((cells - centres[:, :, None]) * cell, -radius, radius)
    lift = np.sqrt(np.maximum(radius ** 2 - dx ** 2, 0.0))
    idx = np.clip(cells, 0, height.shape[1] - 1)
    outside = (cells < 0) | (cells >= height.shape[1])                # off the map: nothing under it
    below = np.where(outside, 0.0, height[np.arange(len(height))[:, None, None], idx])
    need = np.max(below + lift, axis=2)                                # (row, shift)
    return (need, idx[:, 0], np.where(outside, -np.inf, lift)[:, 0]) if keep else need


def rows_between(radius: float, angle_sd_deg: float = 1.0, wave: float = 0.0, points: int = POINTS) -> int:
    """Drawn rows a segment at which ``deposit`` checks a fibre: enough that a fibre at 3 standard
    deviations of the angle (or waving) moves at most half a radius sideways from one to the next."""
    step = SWATCH_LENGTH / (points - 1)
    slope = np.tan(np.radians(3 * angle_sd_deg)) + wave * 2 * radius * 2.5 * 2 * np.pi / 0.25
    return int(np.clip(np.ceil(step * slope / (0.5 * radius)), 1, 64))


def drawn_rows_matrix(points: int, per_segment: int) -> np.ndarray:
    """(rows, points): the drawn B-spline (``Strands.through_ends`` then ``Strands.curves``) at its rows, as
    weights on the control points, so that ``matrix @ z`` is the curve's height row by row."""
    grid = np.zeros((points, points, 3))
    grid[np.arange(points), np.arange(points), 0] = 1.0            # strand j: control point j at 1
    drawn = Strands.from_grid(grid, 1.0).through_ends().curves(per_segment)
    return drawn.points[:, 0].astype(np.float64).reshape(points, -1).T


def _clear(draw: np.ndarray, need: np.ndarray, radius: float, tolerance: float = 0.01) -> np.ndarray:
    """Control heights whose drawn curve clears ``need`` on every row (within ``tolerance`` radii), raised
    little above it: each pass raises every control point by the worst shortfall of the rows it weighs
    on most; a B-spline sags below its control points at a peak, so the points start at the need."""
    weighs = draw >= 0.5 * draw.max(axis=1, keepdims=True)         # (rows, points): the main weights
    per = max(1, (len(draw) - 1) // (draw.shape[1] - 1))
    z = need[::per].copy()
    for _ in range(50):
        short = need - draw @ z
        if short.max() <= tolerance * radius:
            break
        z += np.max(np.where(weighs, np.maximum(short, 0.0)[:, None], 0.0), axis=0)
    return z


def tilted_layers(n_strands: int, seed: int, radius: float, tilt_sd_deg: float = 2.0, fill: float = 0.75,
                  points: int = POINTS) -> Strands:
    """Layers of parallel fibres, each layer at its own small angle to the swatch's axis (normal,
    ``tilt_sd_deg``), fibres at random gaps of at least 2.04 radii, layers 2.04-2.4 radii apart:
    none meets another (angles of a few degrees: cos > 0.99)."""
    rng = np.random.default_rng(seed)
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points)
    fibres: list[np.ndarray] = []
    z = radius * 1.02
    while len(fibres) < n_strands:
        tilt = np.tan(np.radians(rng.normal(0.0, tilt_sd_deg)))
        span = SWATCH_WIDTH + abs(tilt) * SWATCH_LENGTH
        mean_gap = 2 * radius / fill
        gaps = 2.04 * radius + rng.gamma(2.0, max(mean_gap - 2.04 * radius, 1e-9) / 2.0,
                                         int(span / (2 * radius)) + 2)
        x0 = -span / 2 + np.cumsum(gaps)
        x0 = x0[x0 < span / 2]
        sway = 0.004 * np.sin(2 * np.pi * y / rng.uniform(0.4, 0.9) + rng.uniform(0, 2 * np.pi))
        xs = x0[:, None] + tilt * y[None, :] + sway[None, :]
        for x in xs[np.any(np.abs(xs) <= SWATCH_WIDTH / 2, axis=1)]:
            fibres.append(np.stack([x, y, np.full_like(y, z)], 1))
        z += radius * float(rng.uniform(2.04, 2.4))
    return Strands.from_grid(np.array(fibres[:n_strands]), radius).through_ends()


def clumps(n_strands: int, seed: int, radius: float, per_clump: tuple[int, int] = (8, 5), wave: float = 0.012,
           points: int = POINTS) -> Strands:
    """Fibres gathered in clumps, as a combed tress with product dries: each clump a ribbon of ``per_clump``
    (across, rows) fibres packed hexagonally 2.04 radii apart, the whole clump swaying as one (amplitude up to
    ``wave`` units, its slope at most 0.13, so its fibres stay over 2 radii apart), clumps side by side with
    gaps wider than their sways, in layers that do not overlap: none meets another. Drawn for an evaluation of
    a structure no estimate was made robust over, before its figures were seen; not a family member."""
    rng = np.random.default_rng(seed)
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points)
    across, rows = per_clump
    dx = (np.arange(across) - (across - 1) / 2) * 2.04 * radius
    cross = np.array([(x + (r % 2) * 1.02 * radius, r * np.sqrt(3) * 1.02 * radius)
                      for r in range(rows) for x in dx])                       # (across * rows, 2): x, z
    clump_width, clump_height = float(np.ptp(cross[:, 0])) + 2.04 * radius, float(np.ptp(cross[:, 1]))
    fibres: list[np.ndarray] = []
    z = radius * 1.02
    while len(fibres) < n_strands:
        x = -SWATCH_WIDTH / 2 - clump_width / 2
        while x < SWATCH_WIDTH / 2 + clump_width / 2 and len(fibres) < n_strands:
            amplitude = rng.uniform(0.2, 1.0) * wave
            period = rng.uniform(0.6, 1.2)
            sway = amplitude * np.sin(2 * np.pi * y / period + rng.uniform(0, 2 * np.pi))
            for cx, cz in cross:
                fibres.append(np.stack([x + cx + sway, y, np.full_like(y, z + cz)], 1))
            x += clump_width + 2 * wave + rng.uniform(0.1, 0.6) * clump_width
        z += clump_height + 2.04 * radius * rng.uniform(1.0, 1.4)
    kept = [f for f in fibres if np.any(np.abs(f[:, 0]) <= SWATCH_WIDTH / 2)]
    return Strands.from_grid(np.array(kept[:n_strands]), radius).through_ends()


def _radius(n_strands: int, scale: float = 1.0) -> float:
    return layered_radius(n_strands) * scale


Builder = Callable[[int, int], Strands]

#: Every structure by name: ``(n_strands, seed) -> Strands``. The fibre count sets the radius so that
#: each fills the default swatch's thickness (20 layers' worth), except where a member varies just that.
STRUCTURES: dict[str, Builder] = {
    "layered": lambda n, s: layered_swatch_strands(n, seed=s, radius=layered_radius(n)),
    "deposited": lambda n, s: deposit(n, s, _radius(n)),
    "deposited-coarse": lambda n, s: deposit(max(1, n // 4), s, _radius(n, 4.0)),
    "spread": lambda n, s: deposit(n, s, _radius(n), angle_sd_deg=8.0, points=4 * POINTS),
    "wavy": lambda n, s: deposit(n, s, _radius(n), wave=1.0, points=4 * POINTS),
    "tilted": lambda n, s: tilted_layers(n, s, _radius(n)),
    "loose": lambda n, s: layered_swatch_strands(n, seed=s, radius=layered_radius(n), fill=0.4),
    "thin": lambda n, s: deposit(max(1, n // 5), s, _radius(n)),
    "clumped": lambda n, s: clumps(n, s, _radius(n)),
}
#: The structures ``deposit`` draws: a second or more to build at the default swatch (spread 18 s).
DEPOSITS = ("deposited", "deposited-coarse", "spread", "wavy", "thin")
#: Each structure's geometry revision, part of the cache key of every render of it (``inference.refine.cache_key``)
#: and of its kept strands: 2 for the deposits that keep every fibre out of every other (the first let 68%
#: of the drawn curve sink in).
REVISIONS: dict[str, int] = {name: 2 for name in DEPOSITS}
#: The structures a lab's full swatch may have: what an estimate is made robust over.
FAMILY = ("layered", "deposited", "deposited-coarse", "spread", "wavy", "tilted", "loose")


def inside_share(strands: Strands, per_segment: int = 32, sample: int = 100_000, depth: float = 0.025) -> float:
    """The share of the drawn curves' points (a fixed sample of ``sample``) that lie inside another fibre
    by more than ``depth`` radii: another fibre's drawn point closer than ``2 - 2 * depth`` radii. At
    ``per_segment`` 32 the default swatch's points are half a radius apart along a fibre, so a point
    that close is inside it; the share is a floor of the true one."""
    from scipy.spatial import cKDTree   # deferred: scipy.spatial takes ~0.3 s; the CLI parser imports this module

    drawn = strands.curves(per_segment=per_segment)
    radius = float(drawn.radii.max())
    owner = np.repeat(np.arange(drawn.n_strands), drawn.counts)
    query = np.random.default_rng(0).choice(len(drawn.points), min(sample, len(drawn.points)), replace=False)
    d, i = cKDTree(drawn.points).query(drawn.points[query], k=24, distance_upper_bound=(2 - 2 * depth) * radius)
    inside = (owner[np.minimum(i, len(owner) - 1)] != owner[query, None]) & np.isfinite(d)
    return float(inside.any(axis=1).mean())


def structure_strands(name: str, n_strands: int, seed: int = 0) -> Strands:
    """The strands of structure ``name`` (one of ``STRUCTURES``); the last few built are kept (a deposit
    of 8,000 fibres takes 2.6 s, a spread one 18 s, and an evaluation renders each swatch many times)."""
    name = text_of(name)                # a SwatchModel's text, or the text itself
    if name not in STRUCTURES:
        raise ValueError(f"unknown swatch structure {name!r}; choose one of {', '.join(STRUCTURES)}")
    if int(n_strands) < 1:
        raise ValueError(f"a swatch needs at least 1 strand, got {n_strands}")
    return _built(name, int(n_strands), int(seed))


def _from_disk(name: str, n_strands: int, seed: int) -> Strands:
    """Structure ``name``'s strands from the disk cache, built and saved there (atomically) when missing or
    unreadable; the file's name carries the geometry's revision (``REVISIONS``)."""
    path = cache_dir() / "strands" / f"{name}-{n_strands}-{seed}-r{REVISIONS.get(name, 1)}.npz"
    try:
        with np.load(path) as data:
            return Strands(data["points"], data["radii"], data["counts"])
    except (OSError, ValueError, KeyError):
        pass   # not built yet, or a damaged file: built again
    strands = STRUCTURES[name](n_strands, seed)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(path, ".npz") as tmp:
            np.savez(tmp, points=strands.points, radii=strands.radii, counts=strands.counts)
    except OSError:
        pass   # a cache that cannot be written costs time, not the render
    return strands


@functools.lru_cache(maxsize=8)
def _built(name: str, n_strands: int, seed: int) -> Strands:
    # the deposits' strands are kept on disk (``cache_dir() / "strands"``), as the response curves are: an
    # estimate on a spread swatch read from a capture took 25 s, 18 of them building its strands
    strands = _from_disk(name, n_strands, seed) if name in DEPOSITS else STRUCTURES[name](n_strands, seed)
    for array in (strands.points, strands.radii, strands.counts):
        array.flags.writeable = False          # shared between callers: read-only
    return strands
