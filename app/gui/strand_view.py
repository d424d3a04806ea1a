"""The interactive strand view: a pyvistaqt ``QtInteractor`` showing a hairstyle's strands as lines."""
from __future__ import annotations

import numpy as np
import pyvista as pv
from PySide6.QtWidgets import QVBoxLayout, QWidget

from hairdigi.render.strands import Strands


def strand_polydata(strands: Strands, max_strands: int = 3000, seed: int = 0) -> pv.PolyData:
    """Polylines of (at most ``max_strands`` of) the strands, for display."""
    lines = strands.polylines()
    if len(lines) > max_strands:
        keep = np.random.default_rng(seed).choice(len(lines), max_strands, replace=False)
        lines = [lines[i] for i in sorted(keep)]
    points = np.concatenate(lines)
    cells, start = [], 0
    for line in lines:
        cells.append(np.concatenate([[len(line)], np.arange(start, start + len(line))]))
        start += len(line)
    return pv.PolyData(points, lines=np.concatenate(cells))


class StrandView(QWidget):
    """A rotatable 3-D view of the strands, coloured with the estimated hair colour, and the head proxy."""

    def __init__(self, parent: QWidget | None = None) -> None:
        from pyvistaqt import QtInteractor

        super().__init__(parent)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.plotter = QtInteractor(self)
        layout.addWidget(self.plotter.interactor)
        self.plotter.set_background("#2b2b30")

    def show_strands(self, strands: Strands, colour_rgb8, head: bool = True) -> None:
        self.plotter.clear()
        if head:
            self.plotter.add_mesh(pv.Sphere(radius=0.98, theta_resolution=32, phi_resolution=32),
                                  color=(0.55, 0.38, 0.30), smooth_shading=True)
        self.plotter.add_mesh(strand_polydata(strands), color=[c / 255 for c in colour_rgb8], line_width=1.5)
        self.plotter.camera_position = [(0, -0.5, 7.5), (0, -0.55, 0), (0, 1, 0)]
        self.plotter.render()

    def close_view(self) -> None:
        self.plotter.close()
