"""What the swatch's physical structure does to an estimate, and the estimate made robust over it.

The refinement (``inference.refine``) finds the ``sigma_a`` whose swatch, drawn as hairdigi draws it
(``render.strands.layered_swatch_strands``, one layout), renders the capture's colour. A lab's swatch
lies another way (``render.swatch_family``): at equal ``sigma_a`` the physical structures of the family
render 0.4-2 ΔE2000 apart at the rig (``hairdigi evaluate --structures``), so the ``sigma_a`` read
through one structure inherits it. Each channel's mean colour is one monotone response curve of its
``sigma_a`` (``refine.ResponseCurve``), for every structure, so the structure acts per channel:

- ``family_curves`` renders (once per view; cached with the curves) every family member's response
  curve, each averaged over ``layouts`` strand layouts;
- ``to_family`` maps the refinement's ``sigma_a`` (the default structure's) to the ``sigma_a`` whose
  family-mean colour is the colour the default structure gives: ``F_family^-1(F_default(sigma))``;
- ``nuisance`` is how far each member's colour of that answer lies from the family mean (ΔE2000):
  what the record's colour interval carries for the structure it does not know.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from hairdigi.inference.refine import RefineSettings, ResponseCurve, View, response_curve
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.swatch_family import FAMILY

#: Strand layouts each member's curve is averaged over (its seeds 0..LAYOUTS-1).
LAYOUTS = 2


@dataclass
class FamilyCurves:
    """Every family member's layout-averaged response curve at one view, and the default's own."""

    default: ResponseCurve                 # the refinement's: default structure, layout settings.strand_seed
    members: dict[str, ResponseCurve]      # member -> its curve, averaged over layouts
    seconds: float = 0.0

    @property
    def mean(self) -> ResponseCurve:
        """The family's response: the geometric mean of its members' curves."""
        logs = np.mean([np.log(np.clip(c.mean, 1e-12, None)) for c in self.members.values()], axis=0)
        return ResponseCurve(self.default.sigma.copy(), np.exp(logs))


def _averaged(curves: list[ResponseCurve]) -> ResponseCurve:
    logs = np.mean([np.log(np.clip(c.mean, 1e-12, None)) for c in curves], axis=0)
    return ResponseCurve(curves[0].sigma.copy(), np.exp(logs), sum(c.seconds for c in curves),
                         all(c.cached for c in curves))


def family_curves(view: View, settings: RefineSettings = RefineSettings(), renderer=None,
                  members: tuple[str, ...] = FAMILY, layouts: int = LAYOUTS) -> FamilyCurves:
    """The family's response curves at ``view`` (``len(members) * layouts`` curves, cached on disk)."""
    default = response_curve(view, settings, renderer)
    curves = {m: _averaged([response_curve(view, replace(settings, strand_seed=s), renderer, swatch_model=m)
                            for s in range(layouts)]) for m in members}
    seconds = sum(c.seconds for c in curves.values() if not c.cached)
    return FamilyCurves(default, curves, seconds)


def to_family(sigma: np.ndarray, family: FamilyCurves) -> np.ndarray:
    """The ``sigma_a`` whose family-mean colour is the default structure's colour of ``sigma``."""
    sigma = np.asarray(sigma, float)
    return family.mean.inverse(family.default(sigma))[0]


def nuisance(sigma: np.ndarray, family: FamilyCurves) -> dict[str, float]:
    """ΔE2000 of each member's colour of ``sigma`` from the family mean's (the structure left unknown)."""
    sigma = np.asarray(sigma, float)
    centre = np.clip(family.mean(sigma), 1e-9, None)
    return {m: round(float(delta_e2000(np.clip(c(sigma), 1e-9, None), centre)), 3)
            for m, c in family.members.items()}
