"""The ten standard natural bases (hair-colour "levels" 1 black to 10 lightest blonde) as Table 1 parameters.

Colourists grade natural hair by level, 1 (black) to 10 (lightest blonde). No colorimetric standard
fixes a level's colour, so hairdigi defines them once, here, as undyed Table 1 hair (Kips et al. 2022):

- **melanin concentration** falls in equal steps from 1.0 (level 1) to 0.1 (level 10). The rig's
  melanin remap (``render.domain.absorption.MELANIN_REMAP``) was measured so that equal steps of
  concentration give equal steps of the swatch's L*, so the levels are evenly spaced in lightness,
  as a colourist's level chart is meant to be. Level 10 keeps 0.1, not 0: a natural blonde still
  has melanin, and concentration 0 is platinum-white fibre.
- **melanin ratio** (eumelanin share) goes from 0.9 (level 1) to 0.5 (level 10): dark hair is
  mostly eumelanin, light blonde carries relatively more pheomelanin (the warm cast of natural
  blondes; d'Eon et al. 2011 and pbrt's coefficients turn the two into ``sigma_a``).
- no dye: ``dye_concentration`` 0.

These are the bases of the shade card (``hairdigi dye card``) and of ``hairdigi evaluate --dye``.
"""
from __future__ import annotations

from hairdigi.render.domain.params import HairParams

LEVELS = tuple(range(1, 11))
LEVEL_NAMES = {1: "black", 2: "darkest brown", 3: "dark brown", 4: "medium brown", 5: "light brown",
               6: "dark blonde", 7: "medium blonde", 8: "light blonde", 9: "very light blonde",
               10: "lightest blonde"}


def natural_base(level: int) -> HairParams:
    """The undyed Table 1 hair of a natural level, 1 (black) to 10 (lightest blonde)."""
    if level not in LEVELS:
        raise ValueError(f"a natural level is a whole number from 1 to 10, got {level!r}")
    t = (level - 1) / 9.0
    return HairParams(dye_rgb=(255.0, 255.0, 255.0), dye_concentration=0.0,
                      melanin_concentration=round(1.0 - 0.9 * t, 6), melanin_ratio=round(0.9 - 0.4 * t, 6))


#: The held-out bases of ``hairdigi evaluate --dye``: light, medium, dark.
EVALUATION_LEVELS = {"light": 8, "medium": 5, "dark": 3}
