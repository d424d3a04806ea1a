"""Fibre-to-fibre variation as groups of strands, each with its own ``hair`` BSDF.

A varied appearance (``render.domain.appearance.Appearance``: ``fibre_spread`` > 0 or
``grey_fraction`` > 0) is drawn by splitting the strands at random into ``groups`` pigmented groups
of equal size and one grey group. Pigmented group k takes sigma_a_median * exp(spread * z_k), with
z_k the normal quantiles at (k + 0.5) / groups scaled to unit standard deviation (so the groups'
ln sigma_a has exactly the stated spread); the grey group takes ``GREY_SIGMA_A``. Each group is a
curve shape of its own in the scene, keyed ``group_keys(groups)``; the renderer sets their sigma_a
and shine through ``mi.traverse`` as it does for uniform hair.

How many groups: ``hairdigi bench fibres`` measures the render cost and the mean colour against
finer splits (``FIBRE_GROUPS`` is chosen from it; see the model card).
"""
from __future__ import annotations

from statistics import NormalDist

import numpy as np

from hairdigi.render.domain.appearance import GREY_SIGMA_A
from hairdigi.render.strands import Strands

#: Pigment groups of a varied appearance (``hairdigi bench fibres``).
FIBRE_GROUPS = 6
GREY_KEY = "hair_grey"


def group_keys(groups: int) -> tuple[str, ...]:
    """Scene keys of the pigmented groups (the first is ``"hair"``, as uniform hair's) and the grey one."""
    return ("hair",) + tuple(f"hair_{k}" for k in range(1, groups)) + (GREY_KEY,)


def group_z(groups: int) -> np.ndarray:
    """Normal quantiles at (k + 0.5) / groups, scaled to unit standard deviation (0 for one group)."""
    z = np.array([NormalDist().inv_cdf((k + 0.5) / groups) for k in range(groups)])
    rms = float(np.sqrt(np.mean(z ** 2)))
    return z / rms if rms > 0 else z


def group_sigma_a(sigma_median: np.ndarray, groups: int, spread: float) -> list[np.ndarray]:
    """sigma_a of each group in ``group_keys`` order: the pigmented groups, then the grey group."""
    sigma_median = np.asarray(sigma_median, float)
    out = [sigma_median * np.exp(spread * z) for z in group_z(groups)]
    return out + [np.full(sigma_median.shape, GREY_SIGMA_A)]   # RGB, or a spectrum (render.spectra)


def split_strands(strands: Strands, groups: int, grey_fraction: float, seed: int = 0) -> list[Strands]:
    """The strands split at random into ``groups`` pigmented groups of equal size and a grey group of
    ``round(grey_fraction * n)`` strands (``group_keys`` order); the same seed gives the same split."""
    n = strands.n_strands
    order = np.random.default_rng([int(seed), 1815]).permutation(n)
    n_grey = int(round(float(grey_fraction) * n))
    grey, pigmented = order[:n_grey], order[n_grey:]
    return [strands.subset(np.sort(pigmented[k::groups])) for k in range(groups)] + [strands.subset(np.sort(grey))]

