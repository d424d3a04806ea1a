"""The portrait's head: a procedural bust (skull, face, ears, neck, shoulders) as a signed distance.

One smooth signed distance function (``sdf``) defines the bust; hair collides against it and
:func:`head_mesh` meshes its zero set once per process (surface nets on a 0.04-unit grid, vertices
projected onto the surface, normals from the gradient). Units as in ``strands``: 1 unit is about
9 cm, y is up, the face looks along +z, the skull's crown is at y ≈ 1 and the shoulders' top at
y ≈ -2.3, inside the portrait camera's view (``scenes.PORTRAIT_*``).

The scalp is the skull above ``HAIRLINE``; a parting (``in_parting``) is a bare line on it.
Mitsuba reads the bust as two PLYs, skin and scalp (:func:`head_plys`, the ``ply`` shape); pyvista
reads ``HeadMesh.vertices`` / ``pyvista_faces()``. numpy only.
"""
from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.render.domain.files import write_bytes_atomic

#: Centre of the skull's ellipsoid: scalp roots are found on rays from here.
SKULL_CENTER = np.array([0.0, 0.02, -0.08])
SKULL_RADII = np.array([0.80, 0.97, 1.0])
GRID_STEP = 0.04
#: The bust's bounding box (min, max) for meshing; the torso is cut flat at its bottom.
BOUNDS = (np.array([-2.25, -3.5, -1.25]), np.array([2.25, 1.1, 1.3]))
BOTTOM_Y = -3.4
#: Bump when the shape changes, so a PLY written by an older build is never reused.
SHAPE_VERSION = 2


def _rotation(axis: str, degrees: float) -> np.ndarray:
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m = np.eye(3)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def _norm(a: np.ndarray) -> np.ndarray:
    """Row lengths of an (N, 3) array (faster than ``np.linalg.norm`` for this shape)."""
    return np.sqrt(np.einsum("ij,ij->i", a, a))


def _ellipsoid(p: np.ndarray, center, radii, rotation: np.ndarray | None = None) -> np.ndarray:
    """Approximate signed distance from (N, 3) points to an ellipsoid (exact on the surface, close near it)."""
    q = p - np.asarray(center, float)
    if rotation is not None:
        q = q @ rotation   # world to local: rows times R is R^T applied
    r = np.asarray(radii, float)
    q /= r
    k0 = _norm(q)
    q /= r
    k1 = _norm(q)
    return k0 * (k0 - 1.0) / np.maximum(k1, 1e-12)


def _capsule(p: np.ndarray, a, b, radius: float) -> np.ndarray:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return _norm(p - (a + t[:, None] * ab)) - radius


def _smin(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth union of two distances, blending over ``k``."""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


def _smax(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    return -_smin(-a, -b, k)


_EAR_ROT = {side: _rotation("y", side * 18.0) @ _rotation("z", -side * 8.0) for side in (-1, 1)}
_NOSE_ROT = _rotation("x", -22.0)


def skull_sdf(p: np.ndarray) -> np.ndarray:
    """The cranium alone, for (N, 3) points: the scalp is the part of it above the hairline."""
    return _ellipsoid(p, SKULL_CENTER, SKULL_RADII)


def _near(p: np.ndarray, lo, hi) -> np.ndarray:
    """Indices of the (N, 3) points inside the box [lo, hi]."""
    near = np.flatnonzero((p[:, 1] >= lo[1]) & (p[:, 1] <= hi[1]))
    for axis in (0, 2):
        c = p[near, axis]
        near = near[(c >= lo[axis]) & (c <= hi[axis])]
    return near


def _blend(d: np.ndarray, p: np.ndarray, part, k: float, lo, hi, subtract: bool = False) -> np.ndarray:
    """Smoothly add (or carve) ``part`` where it can matter: within its box grown by 2k, elsewhere
    the smooth union equals ``d`` already (the part is farther than ``k``)."""
    near = _near(p, np.asarray(lo) - 2 * k, np.asarray(hi) + 2 * k)
    if len(near):
        e = part(p[near])
        d[near] = _smax(d[near], -e, k) if subtract else _smin(d[near], e, k)
    return d


def _box(center, radii) -> tuple[np.ndarray, np.ndarray]:
    c, r = np.asarray(center, float), np.max(radii) * np.ones(3)
    return c - r, c + r


def _face(p: np.ndarray) -> np.ndarray:
    """Face and jaw: an ellipsoid narrowing towards the chin."""
    face_c, face_r = np.array([0.0, -0.6, 0.26]), np.array([0.64, 0.84, 0.76])
    t = np.clip((p[:, 1] - face_c[1]) / face_r[1], -1.0, 1.0)
    warped = p.copy()
    warped[:, 0] = p[:, 0] / (1.0 + 0.22 * t)
    return _ellipsoid(warped, face_c, face_r)


#: (part, blend radius, box, carve) in the order they are combined; the skull comes first.
_PARTS = [
    (_face, 0.18, ((-0.7, -1.5, -0.55), (0.7, 0.3, 1.05)), False),
    (lambda p: _ellipsoid(p, (0.0, -1.3, 0.62), (0.22, 0.15, 0.2)), 0.12, _box((0.0, -1.3, 0.62), (0.22,)), False),
    (lambda p: _ellipsoid(p, (0.0, -0.93, 0.96), (0.2, 0.045, 0.07)), 0.04, _box((0.0, -0.93, 0.96), (0.2,)), True),
    (lambda p: _ellipsoid(p, (0.0, -0.1, 0.8), (0.55, 0.13, 0.2)), 0.1, ((-0.55, -0.23, 0.6), (0.55, 0.03, 1.0)), False),
    (lambda p: _ellipsoid(p, (0.0, -0.42, 1.0), (0.1, 0.26, 0.14), _NOSE_ROT), 0.08, _box((0.0, -0.42, 1.0), (0.26,)), False),
]
for _side in (-1, 1):
    _PARTS += [
        (functools.partial(_ellipsoid, center=(_side * 0.29, -0.24, 1.04), radii=(0.16, 0.1, 0.12)), 0.1,
         _box((_side * 0.29, -0.24, 1.04), (0.16,)), True),                                          # eye socket
        (functools.partial(_ellipsoid, center=(_side * 0.29, -0.25, 0.84), radii=(0.12, 0.08, 0.1)), 0.03,
         _box((_side * 0.29, -0.25, 0.84), (0.12,)), False),                                         # eye
    ]
for _side in (-1, 1):
    _PARTS.append((functools.partial(_ellipsoid, center=(_side * 0.80, -0.3, -0.06), radii=(0.09, 0.28, 0.18),
                                     rotation=_EAR_ROT[_side]), 0.05, _box((_side * 0.80, -0.3, -0.06), (0.28,)), False))
_PARTS.append((lambda p: _capsule(p, (0.0, -0.7, -0.22), (0.0, -2.5, -0.18), 0.5), 0.25,
               ((-0.5, -3.0, -0.72), (0.5, -0.2, 0.32)), False))                                      # neck
for _side in (-1, 1):                                                                                  # shoulders
    _PARTS.append((functools.partial(_capsule, a=(0.0, -2.2, -0.22), b=(_side * 1.45, -2.62, -0.2), radius=0.36),
                   0.35, ((min(0.0, _side * 1.81), -2.98, -0.58), (max(0.0, _side * 1.81), -1.84, 0.16)), False))
_PARTS.append((lambda p: _ellipsoid(p, (0.0, -3.45, -0.15), (1.95, 1.05, 0.8)), 0.35,
               ((-1.95, -4.5, -0.95), (1.95, -2.4, 0.65)), False))                                    # torso


def _group(parts: list) -> tuple[tuple[np.ndarray, np.ndarray], list]:
    """The parts with the box that holds all their (grown) boxes."""
    lo = np.min([np.asarray(box[0]) - 2 * k for _, k, box, _ in parts], axis=0)
    hi = np.max([np.asarray(box[1]) + 2 * k for _, k, box, _ in parts], axis=0)
    return (lo, hi), parts


_GROUPS = [_group(_PARTS[:9]), _group(_PARTS[9:11]), _group(_PARTS[11:])]   # face, ears, neck and body


def sdf(points: np.ndarray) -> np.ndarray:
    """Signed distance (approximate, negative inside) from ``points`` (..., 3) to the bust."""
    p = np.asarray(points, float)
    shape = p.shape[:-1]
    p = p.reshape(-1, 3)
    d = skull_sdf(p)
    for (lo, hi), parts in _GROUPS:   # a box per group first: most points are near few parts
        near = _near(p, lo, hi)
        if len(near):
            q, e = p[near], d[near]
            for part, k, (part_lo, part_hi), carve in parts:
                e = _blend(e, q, part, k, part_lo, part_hi, carve)
            d[near] = e
    return np.maximum(d, BOTTOM_Y - p[:, 1]).reshape(shape)


def gradient(points: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """Unit gradient of :func:`sdf` (the outward normal near the surface), by central differences."""
    p = np.asarray(points, float)
    g = np.stack([sdf(p + h * e) - sdf(p - h * e) for e in np.eye(3)], axis=-1)
    return g / np.maximum(np.linalg.norm(g, axis=-1, keepdims=True), 1e-12)


def push_out(points: np.ndarray, margin: np.ndarray | float, iterations: int = 4) -> np.ndarray:
    """Move points closer than ``margin`` to the bust (or inside it) out to ``margin`` along the normal."""
    p = np.array(points, float).reshape(-1, 3)
    margin = np.broadcast_to(np.asarray(margin, float), np.shape(points)[:-1]).reshape(-1)
    active = np.arange(len(p))
    for _ in range(iterations):   # only points that moved are checked again
        d = sdf(p[active])
        bad = d < margin[active]
        if not bad.any():
            break
        active, d = active[bad], d[bad]
        p[active] += (margin[active] - d)[:, None] * _forward_gradient(p[active], d)
    return p.reshape(np.shape(points))


def _forward_gradient(p: np.ndarray, d: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """Unit gradient of :func:`sdf` at ``p`` whose distances ``d`` are known (forward differences)."""
    g = np.stack([sdf(p + h * e) - d for e in np.eye(3)], axis=-1)
    return g / np.maximum(_norm(g), 1e-12)[:, None]


def surface_along(directions: np.ndarray, center: np.ndarray = SKULL_CENTER, far: float = 2.5,
                  iterations: int = 30) -> np.ndarray:
    """Where rays from ``center`` along unit ``directions`` leave the bust (bisection; the skull is star-shaped)."""
    d = np.asarray(directions, float)
    lo, hi = np.zeros(len(d)), np.full(len(d), far)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        inside = sdf(center + mid[:, None] * d) < 0
        lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
    return center + hi[:, None] * d


@dataclass(frozen=True)
class HeadMesh:
    """A triangle mesh of the bust: float32 vertices and unit normals (V, 3), int32 faces (F, 3)."""

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray

    def pyvista_faces(self) -> np.ndarray:
        """Faces in VTK's flat layout ``[3, a, b, c, 3, ...]`` (for ``pyvista.PolyData``)."""
        return np.column_stack([np.full(len(self.faces), 3, np.int32), self.faces]).ravel()


def _surface_nets(values: np.ndarray, origin: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Naive surface nets on a grid of signed values: one vertex per sign-changing cell, a quad per crossing edge."""
    inside = values < 0
    nx, ny, nz = values.shape
    sums = np.zeros((nx - 1, ny - 1, nz - 1, 3))
    counts = np.zeros((nx - 1, ny - 1, nz - 1))
    edges = []
    for axis in range(3):
        a = [slice(None)] * 3
        b = [slice(None)] * 3
        a[axis], b[axis] = slice(0, -1), slice(1, None)
        va, vb = values[tuple(a)], values[tuple(b)]
        cross = inside[tuple(a)] != inside[tuple(b)]
        idx = np.argwhere(cross)
        t = va[cross] / (va[cross] - vb[cross])
        pos = idx.astype(float)
        pos[:, axis] += t
        # each crossing edge touches up to 4 cells: shift by 0/-1 along the two other axes
        others = [ax for ax in range(3) if ax != axis]
        for du in (0, -1):
            for dv in (0, -1):
                cell = idx.copy()
                cell[:, others[0]] += du
                cell[:, others[1]] += dv
                ok = np.all((cell >= 0) & (cell < np.array(counts.shape)), axis=1)
                np.add.at(sums, tuple(cell[ok].T), pos[ok])
                np.add.at(counts, tuple(cell[ok].T), 1)
        edges.append((axis, idx, inside[tuple(a)][cross]))
    active = counts > 0
    index = np.full(counts.shape, -1, dtype=np.int64)
    index[active] = np.arange(int(active.sum()))
    vertices = origin + step * (sums[active] / counts[active][:, None])
    quads = []
    for axis, idx, starts_inside in edges:
        u, v = (axis + 1) % 3, (axis + 2) % 3   # cyclic, so every axis winds the same way
        interior = (idx[:, u] > 0) & (idx[:, v] > 0) & (idx[:, u] < counts.shape[u]) & (idx[:, v] < counts.shape[v])
        idx, starts_inside = idx[interior], starts_inside[interior]
        corners = []
        for du, dv in ((-1, -1), (0, -1), (0, 0), (-1, 0)):
            c = idx.copy()
            c[:, u] += du
            c[:, v] += dv
            corners.append(index[tuple(c.T)])
        q = np.stack(corners, axis=1)
        q[~starts_inside] = q[~starts_inside][:, ::-1]   # wind so the normal points out
        quads.append(q)
    quads = np.concatenate(quads)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return vertices, tris


def _grid_values(lo: np.ndarray, hi: np.ndarray, step: float, coarse: int = 4) -> np.ndarray:
    """:func:`sdf` on a grid, evaluated exactly only near the surface (a coarse pass finds where)."""
    shape = tuple(int(round((hi[i] - lo[i]) / step)) + 1 for i in range(3))
    axes = [lo[i] + step * np.arange(shape[i]) for i in range(3)]
    coarse_axes = [a[::coarse] for a in axes]
    rough = sdf(np.stack(np.meshgrid(*coarse_axes, indexing="ij"), axis=-1))
    for axis in range(3):   # each fine node takes its nearest coarse node's value
        index = np.minimum((np.arange(shape[axis]) + coarse // 2) // coarse, rough.shape[axis] - 1)
        rough = np.take(rough, index, axis=axis)
    band = np.abs(rough) < 1.5 * coarse * step
    idx = np.nonzero(band)
    values = np.where(rough < 0, -1.0, 1.0)
    values[idx] = sdf(np.column_stack([axes[i][idx[i]] for i in range(3)]))
    return values


@functools.lru_cache(maxsize=1)
def head_mesh() -> HeadMesh:
    """The bust as a triangle mesh (built once per process, about 0.5 s)."""
    lo, hi = BOUNDS
    values = _grid_values(lo, hi, GRID_STEP)
    vertices, faces = _surface_nets(values, lo, GRID_STEP)
    for _ in range(2):   # project the averaged crossings onto the surface
        vertices = vertices - sdf(vertices)[:, None] * gradient(vertices)
    normals = gradient(vertices)
    # the winding must agree with the outward normals (the mesh's face normals drive shading near edges)
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if np.sum(face_n * normals[faces].mean(axis=1)) < 0:
        faces = faces[:, ::-1]
    mesh = HeadMesh(vertices.astype(np.float32), normals.astype(np.float32), faces.astype(np.int32))
    for a in (mesh.vertices, mesh.normals, mesh.faces):
        a.setflags(write=False)
    return mesh


def ply_bytes(mesh: HeadMesh) -> bytes:
    """A binary little-endian PLY with positions, normals and triangles (Mitsuba's ``ply`` shape reads it)."""
    header = ("ply\nformat binary_little_endian 1.0\ncomment hairdigi head, shape version "
              f"{SHAPE_VERSION}\nelement vertex {len(mesh.vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              f"element face {len(mesh.faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    verts = np.column_stack([mesh.vertices, mesh.normals]).astype("<f4")
    faces = np.zeros(len(mesh.faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, mesh.faces
    return header.encode("ascii") + verts.tobytes() + faces.tobytes()


def write_ply(path: str | os.PathLike, mesh: HeadMesh | None = None) -> Path:
    """Write the bust (or ``mesh``) as a PLY, atomically."""
    return write_bytes_atomic(path, ply_bytes(mesh or head_mesh()))


# --- the scalp --------------------------------------------------------------------------------

#: The hairline as the lowest elevation (degrees, seen from ``SKULL_CENTER``) at which hair grows,
#: against the azimuth from the face (0°) round to the nape (180°): forehead, temples, sideburns in
#: front of the ear, above the ear, behind it, the nape.
HAIRLINE = ((0.0, 38.0), (25.0, 36.0), (45.0, 27.0), (60.0, 12.0), (70.0, -4.0), (78.0, -14.0),
            (84.0, -6.0), (92.0, 12.0), (104.0, 10.0), (118.0, -6.0), (135.0, -26.0), (155.0, -40.0),
            (180.0, -46.0))


def elevation_azimuth(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elevation and |azimuth from the face| in degrees of ``points`` seen from ``SKULL_CENTER``."""
    d = np.asarray(points, float) - SKULL_CENTER
    d = d / np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-12)
    return (np.degrees(np.arcsin(np.clip(d[..., 1], -1, 1))),
            np.degrees(np.abs(np.arctan2(d[..., 0], d[..., 2]))))


def hairline_margin(points: np.ndarray) -> np.ndarray:
    """Degrees above the hairline (negative: below it, on the face, ears or neck)."""
    elevation, azimuth = elevation_azimuth(points)
    a, e = np.array(HAIRLINE).T
    return elevation - np.interp(azimuth, a, e)


#: The crown's whorl: behind the parting, hair radiates from here.
CROWN = np.array([0.0, 0.8, -0.5])
PART_HALF_GAP = 0.022


def in_parting(points: np.ndarray, part_x: float | None, half_gap: float = PART_HALF_GAP) -> np.ndarray:
    """Whether scalp ``points`` lie on a parting's bare line at ``part_x`` (front hairline to the crown)."""
    p = np.atleast_2d(np.asarray(points, float))
    if part_x is None:
        return np.zeros(len(p), dtype=bool)
    return (np.abs(p[:, 0] - part_x) < half_gap) & (p[:, 2] > CROWN[2] + 0.05) & (p[:, 1] > 0.2)


def _submesh(mesh: HeadMesh, keep: np.ndarray) -> HeadMesh:
    faces = mesh.faces[keep]
    used = np.unique(faces)
    remap = np.full(len(mesh.vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return HeadMesh(mesh.vertices[used], mesh.normals[used], remap[faces].astype(np.int32))


def split_scalp(mesh: HeadMesh, part_x: float | None = None, inset_deg: float = 5.0) -> tuple[HeadMesh, HeadMesh]:
    """The bust as (skin, scalp): the scalp is the part ``inset_deg`` inside the hairline, minus the
    parting. The renderer paints it in the hair's colour, so that it never shows as skin between strands."""
    centres = mesh.vertices[mesh.faces].mean(axis=1)
    scalp = (hairline_margin(centres) > inset_deg) & ~in_parting(centres, part_x, 1.6 * PART_HALF_GAP)
    return _submesh(mesh, ~scalp), _submesh(mesh, scalp)


def head_plys(directory: str | os.PathLike, part_x: float | None = None) -> tuple[Path, Path]:
    """PLYs of the skin and the scalp (for a parting at ``part_x``) in ``directory``, written on first use."""
    tag = "none" if part_x is None else f"{part_x:+.4f}"
    paths = (Path(directory) / f"head-v{SHAPE_VERSION}-skin-{tag}.ply",
             Path(directory) / f"head-v{SHAPE_VERSION}-scalp-{tag}.ply")
    if not all(p.is_file() for p in paths):
        for path, part in zip(paths, split_scalp(head_mesh(), part_x)):
            write_ply(path, part)
    return paths
