"""Render the rig's ColorChecker under the three lights: the targets calibration maps a capture onto
(``render.chart.rig_chart_targets`` reads them from ``resources/charts/rig_chart_targets.json``)."""
from __future__ import annotations

import numpy as np

from hairdigi.render.chart import colorchecker_reflectances, patch_means
from hairdigi.render.domain import rig_geometry
from hairdigi.render.domain.params import HairParams
from hairdigi.render.renderer import Renderer, SceneSpec


def render_chart_targets(size: tuple[int, int] = (400, 300), spp: int = 256) -> np.ndarray:
    """Render the rig with the chart under all three lights at full power; (24, 3) linear patch values
    (ValueError when the render had NaN or Inf samples)."""
    spec = SceneSpec("swatch", framing="rig", chart=tuple(map(tuple, colorchecker_reflectances())),
                     target=rig_geometry.RIG_TARGET, half_width=rig_geometry.RIG_HALF_WIDTH, strands=200)
    result = Renderer(max_cached=1).render(HairParams(), spec, size, spp, seed=0)
    if result.nonfinite:    # a zeroed sample would darken a patch: targets must not be made from it
        raise ValueError(f"the chart render returned {result.nonfinite} NaN or Inf values; targets not made")
    return patch_means(result.linear, size)
