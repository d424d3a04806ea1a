"""What an estimate's pixels show, as one protocol: an all-hair crop seen from a camera pose, or a
rig-view frame's swatch region. ``swatch_view`` turns a refinement ``View`` into one; the estimate
then asks it, instead of testing which it is."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

from hairdigi.inference.preprocess import Roi, swatch_crop, to_linear
from hairdigi.inference.refine import View, fitted_pixels, mean_linear
from hairdigi.render.domain.rig_geometry import CameraPose, RigRegion


class SwatchView(Protocol):
    """How an estimate reads its image: the swatch's pixels, and what else the view shows."""

    view: View                   # what the refinement renders and fits
    rig: ClassVar[bool]          # a rig-view frame: the whole chain's colour interval applies

    @property
    def pose(self) -> CameraPose:
        """The camera's pose."""

    def roi(self, roi: Roi | None) -> Roi | None:
        """The encoder's ROI: the given one (None: found), or the region's own."""

    def pixels(self, image: np.ndarray, roi: Roi) -> np.ndarray:
        """The pixels of ``image`` whose mean colour the refinement fits."""

    def texture(self, fitted: np.ndarray) -> np.ndarray | None:
        """The fitted pixels as linear light where their texture can be read (a rig view's), else None."""

    def frame_levels(self, images: list[np.ndarray]) -> np.ndarray | None:
        """Each single-light frame's mean linear colour where it shows more than hair (the holder, the
        chart: a light dark there is dead), else None."""

    def recorded(self) -> RigRegion | str:
        """What an estimate's record says it saw (``Provenance.view``): the rig region, or "crop"."""


@dataclass(frozen=True)
class CropView:
    """An all-hair crop seen from ``view``, a camera pose: its pixels are the swatch crop."""

    view: CameraPose
    rig: ClassVar[bool] = False

    @property
    def pose(self) -> CameraPose:
        return self.view

    def roi(self, roi: Roi | None) -> Roi | None:
        return roi

    def pixels(self, image: np.ndarray, roi: Roi) -> np.ndarray:
        return swatch_crop(image, roi)[0]

    def texture(self, fitted: np.ndarray) -> None:
        return None

    def frame_levels(self, images: list[np.ndarray]) -> None:
        return None

    def recorded(self) -> str:
        return "crop"


@dataclass(frozen=True)
class RigView:
    """A rig-view frame's swatch region (``view``): fitted and rendered exactly as the rig sees it."""

    view: RigRegion
    rig: ClassVar[bool] = True

    @property
    def pose(self) -> CameraPose:
        return self.view.pose

    def roi(self, roi: Roi | None) -> Roi:
        return Roi(*self.view.roi)

    def pixels(self, image: np.ndarray, roi: Roi) -> np.ndarray:
        return fitted_pixels(image, self.view)

    def texture(self, fitted: np.ndarray) -> np.ndarray:
        return to_linear(fitted)

    def frame_levels(self, images: list[np.ndarray]) -> np.ndarray:
        return np.array([mean_linear(im) for im in images])

    def recorded(self) -> RigRegion:
        return self.view


def swatch_view(view: View) -> SwatchView:
    """``view`` as a :class:`SwatchView`: a ``RigRegion``'s or a camera pose's."""
    return RigView(view) if isinstance(view, RigRegion) else CropView(view)
