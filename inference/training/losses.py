"""The training loss: L2 in parameter space plus an appearance term (PyTorch; training only).

The renderer sees the six Table 1 parameters only through the 3-vector ``sigma_a``
(``render.domain.absorption.hair_sigma_a``): a three-dimensional family of parameter vectors renders
identically (a dye ``c`` at concentration ``k`` is the dye ``c**sqrt(k)`` at concentration 1).
An L2 loss in parameter space alone learns the conditional mean over that family, which need not
lie on it, and re-renders to another colour (measured: median mean-colour ΔE2000 2.8). The
appearance term compares the fibre colours the two vectors give instead: Chiang 2016's
multiple-scattering albedo of ``sigma_a``, cube-rooted as CIELAB's lightness is, so that equal
steps weigh about equally dark or light. The parameter term stays, lightly weighted, to pick one
member of the family the way the training draws do.
"""
from __future__ import annotations

import torch

from hairdigi.render.domain.absorption import (AZIMUTHAL_ROUGHNESS, EUMELANIN_SIGMA_A, MELANIN_REMAP, MIN_DYE_ALBEDO,
                                               PHEOMELANIN_SIGMA_A, chiang_denominator)


def _interp(x: torch.Tensor, xp: tuple, fp: tuple) -> torch.Tensor:
    """``np.interp`` for increasing ``xp``, differentiable in ``x``."""
    xp_t = torch.tensor(xp, dtype=x.dtype)
    fp_t = torch.tensor(fp, dtype=x.dtype)
    x = x.clamp(xp_t[0], xp_t[-1])
    i = torch.bucketize(x, xp_t[1:-1])        # segment index, 0 .. len(xp) - 2
    x0, x1, f0, f1 = xp_t[i], xp_t[i + 1], fp_t[i], fp_t[i + 1]
    return f0 + (f1 - f0) * (x - x0) / (x1 - x0)


def sigma_a(vector: torch.Tensor, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> torch.Tensor:
    """``hair_sigma_a`` of (N, 6) normalised parameter vectors, in torch: (N, 3)."""
    dye = vector[:, 0:3].clamp(MIN_DYE_ALBEDO, 1.0)
    dye_conc, melanin, ratio = vector[:, 3:4], vector[:, 4:5], vector[:, 5:6]
    denom = chiang_denominator(azimuthal_roughness)
    dye_sigma = dye_conc * (torch.log(dye) / denom) ** 2
    m, q = zip(*MELANIN_REMAP)
    quantity = _interp(melanin, m, q)
    eu = torch.tensor(EUMELANIN_SIGMA_A, dtype=vector.dtype)
    pheo = torch.tensor(PHEOMELANIN_SIGMA_A, dtype=vector.dtype)
    return quantity * (ratio * eu + (1.0 - ratio) * pheo) + dye_sigma


def appearance(vector: torch.Tensor) -> torch.Tensor:
    """Cube root of the fibre albedo (Chiang 2016 eq. 9 inverted) of (N, 6) vectors: (N, 3) in (0, 1]."""
    denom = chiang_denominator(AZIMUTHAL_ROUGHNESS)
    return torch.exp(-torch.sqrt(sigma_a(vector) + 1e-8) * denom / 3.0)


def encoder_loss(pred: torch.Tensor, target: torch.Tensor, appearance_weight: float) -> torch.Tensor:
    """Mean squared error of the parameters plus ``appearance_weight`` times that of the appearance."""
    loss = torch.mean((pred - target) ** 2)
    if appearance_weight:
        loss = loss + appearance_weight * torch.mean((appearance(pred) - appearance(target)) ** 2)
    return loss
