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
- ``thin``: too few fibres to cover the holder (about 4 deposited layers): the holder shows through.

``FAMILY`` names the members a lab's full swatch may have (``thin`` is a capture to flag, not a
structure to average over). The swatch spans ``rig_geometry.SWATCH_HALF``; every member takes its
fibre radius from its count so that it fills about the same thickness (``strands.layered_radius``).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from hairdigi.render.strands import (SWATCH_LENGTH, SWATCH_WIDTH, Strands, layered_radius,
                                     layered_swatch_strands)

#: Points along each fibre (polyline; B-spline control points after ``Strands.through_ends``).
POINTS = 24
#: Height-map cells per fibre radius across the holder (the deposit's contact resolution).
CELLS_PER_RADIUS = 2
#: How far (cells) a dropped fibre may roll sideways into a hollow before it rests: combing settles a
#: swatch (without it, fibres stick where they first touch and stack at a volume fraction of 0.13).
SETTLE_CELLS = 6


def deposit(n_strands: int, seed: int, radius: float, angle_sd_deg: float = 1.0, wave: float = 0.0,
            points: int = POINTS) -> Strands:
    """Fibres dropped one by one on the holder, each resting on the fibres below it.

    Each fibre is a line across the swatch's length at a random offset and a small random angle
    (normal, ``angle_sd_deg``), waving across by ``wave`` diameters. Along its length (``points`` rows)
    it rests where its circular section first touches the height map of the fibres already laid
    (``z = max(H + sqrt(r^2 - dx^2))`` over the cells under it: a combed fibre under tension follows
    what it lies on, row by row), and then raises the map. It first rolls
    sideways by up to ``SETTLE_CELLS`` cells to where it lies lowest, as combing settles a swatch. Fibres that run
    off the holder's sides are kept, as on a real holder.
    """
    rng = np.random.default_rng(seed)
    cell = radius / CELLS_PER_RADIUS
    margin = 0.1 * SWATCH_WIDTH
    n_cells = int(np.ceil((SWATCH_WIDTH + 2 * margin) / cell))
    height = np.zeros((points, n_cells))                       # top surface per row and cell
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, points)
    reach = np.arange(-CELLS_PER_RADIUS, CELLS_PER_RADIUS + 1)   # the cells under a fibre's section
    rows = np.arange(points)[:, None]
    out = np.empty((n_strands, points, 3))
    x0 = rng.uniform(-SWATCH_WIDTH / 2, SWATCH_WIDTH / 2, n_strands)
    angle = np.tan(np.radians(rng.normal(0.0, angle_sd_deg, n_strands)))
    amp = wave * 2 * radius * rng.uniform(1.0, 2.5, n_strands)
    length = rng.uniform(0.25, 0.6, n_strands)
    phase = rng.uniform(0, 2 * np.pi, n_strands)
    shifts = np.arange(-SETTLE_CELLS, SETTLE_CELLS + 1)            # where it may roll to, in cells
    for i in range(n_strands):
        x = x0[i] + angle[i] * y + amp[i] * np.sin(2 * np.pi * y / length[i] + phase[i])
        centre = (x + SWATCH_WIDTH / 2 + margin) / cell
        base = np.round(centre).astype(int)
        idx = np.clip(base[None, :, None] + shifts[:, None, None] + reach, 0, n_cells - 1)   # (shift, row, cell)
        dx = np.clip((idx - (centre[None, :, None] + shifts[:, None, None])) * cell, -radius, radius)
        lift = np.sqrt(np.maximum(radius ** 2 - dx ** 2, 0.0))
        z = np.max(height[rows[None], idx] + lift, axis=2)             # (shift, row)
        best = int(np.argmin(z.mean(axis=1)))                          # it settles where it lies lowest
        idx, lift, z = idx[best], lift[best], np.maximum(z[best], radius * 1.01)
        height[rows, idx] = np.maximum(height[rows, idx], z[:, None] + lift)
        out[i] = np.stack([x + shifts[best] * cell, y, z], 1)
    return Strands.from_grid(out, radius).through_ends()


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


def _radius(n_strands: int, scale: float = 1.0) -> float:
    return layered_radius(n_strands) * scale


Builder = Callable[[int, int], Strands]

#: Every structure by name: ``(n_strands, seed) -> Strands``. The fibre count sets the radius so that
#: each fills the default swatch's thickness (20 layers' worth), except where a member varies just that.
STRUCTURES: dict[str, Builder] = {
    "layered": lambda n, s: layered_swatch_strands(n, seed=s, radius=layered_radius(n)),
    "deposited": lambda n, s: deposit(n, s, _radius(n)),
    "deposited-coarse": lambda n, s: deposit(max(1, n // 4), s, _radius(n, 4.0)),
    "spread": lambda n, s: deposit(n, s, _radius(n), angle_sd_deg=8.0),
    "wavy": lambda n, s: deposit(n, s, _radius(n), wave=1.0),
    "tilted": lambda n, s: tilted_layers(n, s, _radius(n)),
    "loose": lambda n, s: layered_swatch_strands(n, seed=s, radius=layered_radius(n), fill=0.4),
    "thin": lambda n, s: deposit(max(1, n // 5), s, _radius(n)),
}
#: The structures a lab's full swatch may have: what an estimate is made robust over.
FAMILY = ("layered", "deposited", "deposited-coarse", "spread", "wavy", "tilted", "loose")


def structure_strands(name: str, n_strands: int, seed: int = 0) -> Strands:
    """The strands of structure ``name`` (one of ``STRUCTURES``)."""
    try:
        build = STRUCTURES[name]
    except KeyError:
        raise ValueError(f"unknown swatch structure {name!r}; choose one of {', '.join(STRUCTURES)}") from None
    if n_strands < 1:
        raise ValueError(f"a swatch needs at least 1 strand, got {n_strands}")
    return build(int(n_strands), int(seed))
