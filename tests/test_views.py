"""An estimate reads its pixels through a view: an all-hair crop's or a rig frame's swatch region."""
from __future__ import annotations

import numpy as np

from hairdigi.inference.preprocess import Roi
from hairdigi.inference.refine import fitted_pixels
from hairdigi.inference.views import CropView, RigView, swatch_view
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, CameraPose, RigRegion


def _frame(w: int = 320, h: int = 240) -> np.ndarray:
    return np.random.default_rng(0).integers(20, 230, (h, w, 3)).astype(np.uint8)


def test_a_camera_pose_is_a_crop_view() -> None:
    pose = CameraPose(20.0, 40.0)
    seen = swatch_view(pose)
    assert isinstance(seen, CropView) and seen.pose == pose and not seen.rig
    image, roi = _frame(), Roi(40, 30, 200, 160)
    assert seen.roi(roi) == roi and seen.roi(None) is None
    pixels = seen.pixels(image, roi)
    assert pixels.shape[0] == pixels.shape[1] <= 160            # the swatch crop's central square
    assert seen.texture(pixels) is None and seen.frame_levels([image]) is None
    assert seen.recorded() == "crop"


def test_a_rig_region_is_a_rig_view_with_its_own_roi_and_levels() -> None:
    image = _frame()
    region = RigRegion((320, 240), (100, 60, 120, 120))
    seen = swatch_view(region)
    assert isinstance(seen, RigView) and seen.rig and seen.pose == region.pose
    assert seen.roi(Roi(0, 0, 10, 10)) == Roi(100, 60, 120, 120)   # the region's, whatever was given
    assert np.array_equal(seen.pixels(image, Roi(0, 0, 10, 10)), fitted_pixels(image, region))
    texture = seen.texture(seen.pixels(image, None))
    assert texture.dtype.kind == "f" and texture.max() <= 1.0
    levels = seen.frame_levels([image, image // 2])
    assert levels.shape == (2, 3) and np.all(levels[0] > levels[1])
    assert seen.recorded() is region
    assert swatch_view(RIG_SWATCH_POSE).pose == RIG_SWATCH_POSE
