"""The bench camera's tables, rendered once and shipped: any swatch region's response curves and shine tables
as sums of cells, with no render at capture time.

A response curve (``inference.refine``) or a shine table (``inference.shine``) is the mean colour of one
region of the rig frame over a ladder of ``sigma_a`` levels. A mean over a region is the mean of the means of
the cells that tile it, so rendering the whole swatch area once, as a grid of cells (box-filtered pixels: each
pixel is its cell's area mean), answers every region on that grid. The atlas holds, for the bench camera on
the canonical frame (``FRAME``, 4:3; other frames are scaled to its width and centred on its height, as the
camera's horizontal field of view is fixed):

- every family member's response curve in each of its layouts (``inference.structure.LAYOUTS``), per
  ``CURVE_CELL`` pixels;
- every read member's shine tables (``inference.structure.READ_MEMBERS``), per ``SHINE_CELL`` pixels
  (a shine reading is a ratio of the lights' shares, which hardly moves across the swatch).

A region is snapped to the nearest lines of the atlas's cells. Where the view is not the bench camera's, falls outside
the atlas, or the renderer is not the atlas's kind, the callers render as before.

Away from the rig (an all-hair crop, ``hairdigi estimate photo.png --camera POLAR,AZIMUTH``) the view is a camera
pose. The pose tables (``PoseAtlas``, ``POSES_PATH``) hold the family's curves over a grid of poses (``POSE_POLARS``
by ``POSE_AZIMUTHS``); a pose between them reads its curves interpolated (bilinearly in the logs of the means).

``inference.atlas_build`` makes both (resumable); ``hairdigi bench atlas`` measures what they cost in error
against rendering each region or pose.
"""
from __future__ import annotations

import functools
import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hairdigi.render.domain.rig_geometry import RIG_HALF_WIDTH, RIG_TARGET, CameraPose, Framing, RigRegion
from hairdigi.render.swatch_family import REVISIONS
from hairdigi.resources import ROOT

#: Where the shipped atlas lies.
ATLAS_PATH = ROOT / "tables" / "rig_atlas.npz"
#: The canonical frame (pixels): the family's canonical width (``inference.structure.FAMILY_FRAME``), 4:3.
FRAME = (400, 300)
#: Rendered pixels per canonical pixel: one film pixel covers ``PIXEL`` x ``PIXEL`` canonical pixels.
PIXEL = 4
#: The curves' and the shine tables' cells (canonical pixels; multiples of ``PIXEL``).
CURVE_CELL = 8
SHINE_CELL = 16
#: The area rendered (x, y, w, h canonical pixels, on the ``SHINE_CELL`` grid): the swatch's visible area on the
#: holder (``rig_geometry.swatch_roi``, (30, 56, 130, 189) inset 0.05) grown by 0.1 scene units each side.
BOX = (0, 16, 192, 256)


def cells(image: np.ndarray, cell: int) -> np.ndarray:
    """(H, W) film pixels pooled into (H / c, W / c) cell means (c = cell / PIXEL film pixels)."""
    c = cell // PIXEL
    h, w = image.shape[-2] // c, image.shape[-1] // c
    return image[..., :h * c, :w * c].reshape(*image.shape[:-2], h, c, w, c).mean(axis=(-3, -1))


@dataclass(frozen=True)
class Atlas:
    """The shipped tables: per-cell means over ``BOX`` and what they were rendered with."""

    levels: np.ndarray                      # (K,) sigma ladder (``RefineSettings.levels``)
    betas: np.ndarray                       # (B,) shine grid (``inference.shine.BETA_GRID``)
    curves: dict[tuple[str, int], np.ndarray]   # (member, layout) -> (K, H, W) per CURVE_CELL
    shine: dict[str, np.ndarray]            # member -> (L, B, K, h, w) per SHINE_CELL
    meta: dict                              # spp, seed, variant, strands, depth, revisions, seconds

    def cells(self, view, cell: int) -> tuple[slice, slice] | None:
        """The cells (rows, columns) of ``view``'s region snapped to the nearest ``cell`` lines; None where the
        view is not the bench camera's or its region leaves the atlas."""
        if not isinstance(view, RigRegion) or not _bench(view):
            return None
        scale = FRAME[0] / view.frame_size[0]
        offset = (FRAME[1] - view.frame_size[1] * scale) / 2.0
        x, y, w, h = view.roi
        x0, x1 = x * scale - BOX[0], (x + w) * scale - BOX[0]
        y0, y1 = y * scale + offset - BOX[1], (y + h) * scale + offset - BOX[1]
        c0, c1 = int(np.floor(x0 / cell + 0.5)), int(np.floor(x1 / cell + 0.5))
        r0, r1 = int(np.floor(y0 / cell + 0.5)), int(np.floor(y1 / cell + 0.5))
        if c0 < 0 or r0 < 0 or c1 > BOX[2] // cell or r1 > BOX[3] // cell or c1 <= c0 or r1 <= r0:
            return None
        return slice(r0, r1), slice(c0, c1)

    def curve(self, view, member: str, layout: int) -> np.ndarray | None:
        """(K,) mean of ``member``'s curve in ``layout`` over ``view``'s region; None where the atlas lacks it."""
        cells, table = self.cells(view, CURVE_CELL), self.curves.get((member, int(layout)))
        return None if cells is None or table is None else table[:, cells[0], cells[1]].mean(axis=(-2, -1))

    def shine_means(self, view, member: str) -> np.ndarray | None:
        """(L, B, K) shine tables of ``member`` over ``view``'s region; None where the atlas lacks them."""
        cells, table = self.cells(view, SHINE_CELL), self.shine.get(member)
        if cells is None or table is None:
            return None
        return table[..., cells[0], cells[1]].astype(np.float64).mean(axis=(-2, -1))


#: Where the shipped pose tables lie (``inference.atlas_build.build_poses``).
POSES_PATH = ROOT / "tables" / "pose_atlas.npz"
#: The pose tables' grid (degrees). The rig is symmetric across the holder's x = 0 plane (the lights at 90°, 210° and
#: 330°, the swatch's fibres along y), so a camera at azimuth φ sees what one at 180° − φ does (renders the same
#: means), and the azimuths run over one side: -90° to 90°. The spacing is measured (the layered swatch, whose
#: aligned fibres' highlight moves fastest, at 30°): a pose halfway between two 15° polar steps is read within 0.3-0.7
#: ΔE2000 of its render (a sampler seed's own noise 0.1-0.9), halfway between two 45° azimuth steps 1.7-2.3 off, so the
#: azimuths step by 15°.
POSE_POLARS = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0)
POSE_AZIMUTHS = tuple(float(a) for a in range(-90, 91, 15))
#: How far a pose's distance may be from the grid's (``CAMERA_DISTANCE``) and still read it (a crop's field of view
#: is fixed at the swatch, so the distance moves only the perspective).
POSE_DISTANCE_TOLERANCE = 0.05


def mirrored_azimuth(azimuth_deg: float) -> float:
    """The azimuth in [-90°, 90°] that sees what ``azimuth_deg`` does (the rig's mirror plane, ``POSE_AZIMUTHS``)."""
    a = (float(azimuth_deg) + 180.0) % 360.0 - 180.0          # (-180, 180]
    return 180.0 - a if a > 90.0 else (-180.0 - a if a < -90.0 else a)


def _bracket(grid: np.ndarray, value: float) -> tuple[int, float]:
    """The grid cell holding ``value`` (its lower index) and the fraction across it."""
    i = int(np.clip(np.searchsorted(grid, value, side="right") - 1, 0, len(grid) - 2))
    return i, float(np.clip((value - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0))


@dataclass(frozen=True)
class PoseAtlas:
    """The shipped family curves over a grid of all-hair camera poses, interpolated between them."""

    levels: np.ndarray                      # (K,)
    polars: np.ndarray                      # (P,) degrees, increasing from 0
    azimuths: np.ndarray                    # (A,) degrees, -90 to 90
    curves: dict[tuple[str, int], np.ndarray]   # (member, layout) -> (P, A, K) means
    meta: dict                              # settings, distance, spp, fingerprint, seconds

    def curve(self, pose: CameraPose, member: str, layout: int) -> np.ndarray | None:
        """(K,) ``member``'s curve in ``layout`` at ``pose``, interpolated; None off the grid (steeper than its
        last polar angle, another distance) or for a curve it lacks."""
        table = self.curves.get((member, int(layout)))
        distance = float(self.meta["distance"])
        if table is None or pose.polar_deg > self.polars[-1] + 1e-9 \
                or abs(pose.distance - distance) > POSE_DISTANCE_TOLERANCE * distance:
            return None
        i, s = _bracket(self.polars, pose.polar_deg)
        j, t = _bracket(self.azimuths, mirrored_azimuth(pose.azimuth_deg))
        logs = np.log(np.clip(table, 1e-12, None))
        row = lambda k: (1 - t) * logs[k, j] + t * logs[k, j + 1]
        return np.exp((1 - s) * row(i) + s * row(i + 1))


def _bench(view: RigRegion) -> bool:
    """The bench camera (the pose, target and field of view the atlas was rendered from)."""
    return (view.pose == CameraPose() and tuple(view.target) == tuple(RIG_TARGET)
            and abs(view.half_width - RIG_HALF_WIDTH) < 1e-9)


def fingerprint(renderer_variant: str) -> dict:
    """What the atlas's renders depend on beyond the view: the swatch geometry's revisions, strands, depth and
    the renderer's colour mode (an rgb atlas answers every rgb variant)."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec

    spec = SceneSpec("swatch", framing=Framing.RIG)
    return {"revisions": dict(sorted(REVISIONS.items())), "strands": spec.n_strands, "depth": spec.depth,
            "colour": "spectral" if "spectral" in renderer_variant else "rgb"}


@functools.lru_cache(maxsize=4)
def _load(path: str, mtime: float) -> Atlas | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            curves = {(m, int(s)): np.asarray(data[f"curve__{m}__{s}"], np.float64)
                      for m, s in meta["curves"]}
            shine = {m: np.asarray(data[f"shine__{m}"]) for m in meta["shine"]}
            return Atlas(np.asarray(data["levels"], float), np.asarray(data["betas"], float), curves, shine, meta)
    except (OSError, ValueError, KeyError):   # a damaged atlas answers nothing: the callers render
        return None


@functools.lru_cache(maxsize=2)
def _load_poses(path: str, mtime: float) -> PoseAtlas | None:
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            curves = {(m, int(s)): np.asarray(data[f"curve__{m}__{s}"], np.float64) for m, s in meta["curves"]}
            return PoseAtlas(np.asarray(data["levels"], float), np.asarray(data["polars"], float),
                             np.asarray(data["azimuths"], float), curves, meta)
    except (OSError, ValueError, KeyError):   # damaged: the callers render
        return None


def load_poses(path: str | os.PathLike | None = None) -> PoseAtlas | None:
    """The pose tables at ``path`` (None: the shipped ones; ``HAIRDIGI_ATLAS=off``: none); missing or damaged, said
    once, they answer nothing."""
    if os.environ.get("HAIRDIGI_ATLAS") == "off":
        return None
    chosen = path or POSES_PATH
    atlas = _load_poses(str(chosen), Path(chosen).stat().st_mtime) if Path(chosen).is_file() else None
    if atlas is None:
        _say_missing(str(chosen))
    return atlas


def load(path: str | os.PathLike | None = None) -> Atlas | None:
    """The atlas at ``path`` (None: ``HAIRDIGI_ATLAS``, else the shipped one; ``HAIRDIGI_ATLAS=off``: none). One
    that is missing or damaged answers nothing (the tables are rendered), and is said once."""
    chosen = path or os.environ.get("HAIRDIGI_ATLAS") or ATLAS_PATH
    if str(chosen) == "off":
        return None
    atlas = _load(str(chosen), Path(chosen).stat().st_mtime) if Path(chosen).is_file() else None
    if atlas is None:
        _say_missing(str(chosen))
    return atlas


@functools.lru_cache(maxsize=None)
def _say_missing(path: str) -> None:
    warnings.warn(f"atlas {path}: missing or damaged, so every new region's tables are rendered (minutes on 2 cores); "
                  f"reinstall hairdigi, rebuild it (python -m hairdigi.inference.atlas_build), or set HAIRDIGI_ATLAS to "
                  f"a good one", stacklevel=3)


def _usable(atlas: Atlas | PoseAtlas | None, levels, renderer_variant: str) -> bool:
    return (atlas is not None and len(atlas.levels) == len(levels) and np.allclose(atlas.levels, levels)
            and atlas.meta.get("fingerprint") == fingerprint(renderer_variant))


def curve_means(view, levels, layout: int, member: str, renderer_variant: str,
                settings: dict | None = None) -> np.ndarray | None:
    """(K,) the atlas's mean colour of ``member`` in ``layout`` over ``view``'s region at the ``levels`` ladder
    (one channel per level), or None where the shipped atlas does not answer (``Atlas.cells``). A camera pose (an
    all-hair crop) is read from the pose tables where they were rendered with ``settings``
    (``inference.refine.curve_settings`` without the layout)."""
    if isinstance(view, CameraPose):
        poses = load_poses()
        if not _usable(poses, levels, renderer_variant) or settings is None \
                or json.dumps(poses.meta.get("settings"), sort_keys=True) != json.dumps(settings, sort_keys=True, default=str):
            return None
        return poses.curve(view, str(member), layout)
    atlas = load()
    if not _usable(atlas, levels, renderer_variant):
        return None
    return atlas.curve(view, str(member), layout)


def shine_means(view, levels, betas, layout: int, member: str, renderer_variant: str) -> np.ndarray | None:
    """(L, B, K) the atlas's single-light tables of ``member`` in ``layout`` over ``view``'s region, or None (the
    atlas holds layout 0's)."""
    atlas = load()
    if layout != 0 or not _usable(atlas, levels, renderer_variant) or len(betas) != len(atlas.betas) \
            or not np.allclose(betas, atlas.betas):
        return None
    return atlas.shine_means(view, str(member))
