"""Judging an estimate against the truth: both rendered in one scene with one sampler seed.

The truth and the estimate are rendered with the same camera, strands and sampler seed (common
random numbers), so most render noise cancels in their difference; the verdict is the CIEDE2000
difference of their mean linear colours. The default scene is the rig's swatch pose in the crop
framing (all hair, as the bench camera sees the swatch's centre); ``scene`` and ``size`` judge it
anywhere else (another camera, another light: the transfer).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hairdigi.render.base.params import HairParams
from hairdigi.render.base.rig_geometry import RIG_SWATCH_POSE
from hairdigi.render.metrics import delta_e2000

#: Judge renders: 64² at 64 spp (the mean colour of the swatch's centre to about 0.1 ΔE).
JUDGE_SIZE, JUDGE_SPP, JUDGE_SEED = 64, 64, 424_242


@dataclass(frozen=True)
class Verdict:
    de2000: float
    truth_linear: tuple[float, float, float]
    estimate_linear: tuple[float, float, float]
    spp: int
    nonfinite: int


def judge(truth: HairParams | np.ndarray, estimate: HairParams | np.ndarray, scene=None,
          size: int | tuple[int, int] = JUDGE_SIZE, spp: int = JUDGE_SPP, seed: int = JUDGE_SEED,
          renderer=None) -> Verdict:
    """Mean-colour ΔE2000 between ``truth`` and ``estimate`` (Table 1 parameters or ``sigma_a``)."""
    from hairdigi.render.renderer import SceneSpec, default_renderer

    renderer = renderer or default_renderer()
    scene = scene or SceneSpec("swatch", camera=RIG_SWATCH_POSE, framing="crop")
    a = renderer.render(truth if isinstance(truth, HairParams) else np.asarray(truth, float), scene, size, spp, seed)
    b = renderer.render(estimate if isinstance(estimate, HairParams) else np.asarray(estimate, float), scene, size,
                        spp, seed)
    ta, tb = a.linear.reshape(-1, 3).mean(0), b.linear.reshape(-1, 3).mean(0)
    return Verdict(float(delta_e2000(np.clip(tb, 1e-9, None), np.clip(ta, 1e-9, None))),
                   tuple(float(v) for v in ta), tuple(float(v) for v in tb), spp, a.nonfinite + b.nonfinite)
