"""The interactive strand view: a pyvistaqt ``QtInteractor`` showing a hairstyle's strands on the head.

It draws what the renderer draws: the strands' B-spline curves (not their control points), as lines
shaded like tubes, in the estimated hair colour with a slight per-strand variation and darker roots,
on ``render.head``'s bust, from the portrait camera.
"""
from __future__ import annotations

import functools

import numpy as np
import pyvista as pv
from PySide6.QtWidgets import QVBoxLayout, QWidget

from hairdigi.render.head import HeadMesh, head_mesh, split_scalp
from hairdigi.render.scenes import PORTRAIT_CAMERA, PORTRAIT_FOV, PORTRAIT_TARGET, SCALP_SHADE, SKIN_ALBEDO
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear
from hairdigi.render.strands import Strands

#: Per-strand brightness spread and how much darker a root is than its tip (a view-only touch).
SHADE_SPREAD = 0.12
ROOT_SHADE = 0.75


def strand_polydata(strands: Strands, max_strands: int = 3000, seed: int = 0,
                    colour_rgb8=None, per_segment: int = 2) -> pv.PolyData:
    """Polylines of the curves of (at most ``max_strands`` of) the strands, for display.

    With ``colour_rgb8`` the points carry an ``"rgb"`` array: that colour, varied per strand and
    darker towards the roots.
    """
    rng = np.random.default_rng(seed)
    if strands.n_strands > max_strands:
        strands = strands.subset(np.sort(rng.choice(strands.n_strands, max_strands, replace=False)))
    curves = strands.curves(per_segment) if strands.counts.min() >= 4 else strands
    counts = curves.counts
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    cells = np.insert(np.arange(len(curves.points)), starts, counts)
    data = pv.PolyData(curves.points.astype(np.float32), lines=cells)
    if colour_rgb8 is not None:
        along = np.concatenate([np.linspace(0.0, 1.0, k) for k in counts])
        strand = np.repeat(1.0 + SHADE_SPREAD * rng.uniform(-1, 1, len(counts)), counts)
        shade = strand * (ROOT_SHADE + (1 - ROOT_SHADE) * np.sqrt(along))
        rgb = np.clip(np.asarray(colour_rgb8, float)[None, :] * shade[:, None], 0, 255)
        data.point_data["rgb"] = rgb.astype(np.uint8)
    return data


def head_polydata(mesh: HeadMesh | None = None) -> pv.PolyData:
    """``render.head``'s bust (or ``mesh``) as pyvista PolyData, with its smooth normals."""
    mesh = mesh or head_mesh()
    data = pv.PolyData(np.asarray(mesh.vertices), mesh.pyvista_faces())
    data.point_data["Normals"] = np.asarray(mesh.normals)
    return data


def _display(linear) -> np.ndarray:
    """A linear RGB colour as the [0, 1] sRGB triple VTK takes."""
    return linear_to_srgb8(np.asarray(linear, np.float32).reshape(1, 1, 3))[0, 0] / 255


@functools.lru_cache(maxsize=4)
def _head_parts(part_x: float | None) -> tuple[pv.PolyData, pv.PolyData]:
    """Skin and scalp PolyData of the bust for a parting at ``part_x`` (built once each)."""
    return tuple(head_polydata(part) for part in split_scalp(head_mesh(), part_x))


class StrandView(QWidget):
    """A rotatable 3-D view of the strands, coloured with the estimated hair colour, on the head."""

    def __init__(self, parent: QWidget | None = None) -> None:
        # deferred: pyvista and VTK take ~1 s; they load when the 3-D view first opens
        from pyvistaqt import QtInteractor

        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.plotter = QtInteractor(self)
        layout.addWidget(self.plotter.interactor)
        self.plotter.set_background("#2b2b30")

    def show_strands(self, strands: Strands, colour_rgb8, head: bool = True, part_x: float | None = None,
                     scalp_linear=None) -> None:
        """Show ``strands`` in ``colour_rgb8`` (sRGB 0–255) on the head. The scalp takes the renderer's
        colour, ``scalp_linear`` (linear RGB, ``scenes.scalp_albedo``), or else the strands' colour
        darkened by ``scenes.SCALP_SHADE`` in linear light; a parting at ``part_x`` shows skin."""
        self.plotter.clear()
        self.plotter.enable_lightkit()   # clear() removes the lights too
        colour = np.asarray(colour_rgb8, float)
        if head:   # no render per mesh: one at the end (software GL takes ~0.2 s a frame)
            skin, scalp = _head_parts(part_x)
            if scalp_linear is None:
                scalp_linear = SCALP_SHADE * srgb8_to_linear(np.asarray(colour_rgb8, np.uint8))
            self.plotter.add_mesh(skin, color=_display(SKIN_ALBEDO), smooth_shading=True, render=False)
            self.plotter.add_mesh(scalp, color=_display(scalp_linear), smooth_shading=True, render=False)
        self.plotter.add_mesh(strand_polydata(strands, colour_rgb8=colour), scalars="rgb", rgb=True,
                              line_width=2.0, render_lines_as_tubes=True, render=False)
        position = np.asarray(PORTRAIT_TARGET) + PORTRAIT_CAMERA.distance * np.array([0.0, 0.0, 1.0])
        self.plotter.camera_position = [tuple(position), PORTRAIT_TARGET, (0.0, 1.0, 0.0)]
        self.plotter.camera.view_angle = PORTRAIT_FOV
        self.plotter.render()

    def close_view(self) -> None:
        self.plotter.close()
