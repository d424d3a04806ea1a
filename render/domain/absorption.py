"""From ``HairParams`` to the absorption ``sigma_a`` of Mitsuba's ``hair`` BSDF.

The BSDF is Chiang et al. 2016 ("A practical and controllable hair and fur model for production
path tracing"). Its ``sigma_a`` is an absorption coefficient **per fibre radius** (measured in this
project: the same ``sigma_a`` gives the same colour at any strand radius), so nothing here depends
on the scene's units. The mapping is a sum of two absorbers:

1. **Melanin** (d'Eon et al. 2011, "An energy-conserving hair reflectance model"). The
   concentration ``m`` in [0, 1] becomes a melanin quantity ``q`` through a remap **measured in
   the swatch rig** so that equal steps of ``m`` give equal steps of CIELAB lightness L* of the
   swatch, from 64.8 (no melanin, platinum) to 9.3 (black): ``MELANIN_REMAP``, interpolated
   linearly, monotone and finite. Blender's Principled Hair remap ``-ln(1 - m)`` was measured too
   and rejected: its first tenth of ``m`` spends 17.8 of the 55.5 L* range and its last half only
   10.7, so uniformly drawn parameters were nine times in ten brown enough to hide any dye.
   ``q`` is split by ``melanin_ratio`` into eumelanin ``q * r`` and pheomelanin ``q * (1 - r)``,
   each multiplied by its absorption per unit concentration, the coefficients of pbrt-v3 and
   Mitsuba: eumelanin (0.419, 0.697, 1.37), pheomelanin (0.187, 0.4, 1.05).
2. **The dye**. Its colour ``c`` (``dye_rgb / 255``) is read as the multiple-scattering albedo the
   dyed fibre should have, and turned into an absorption with Chiang 2016's fit (their eq. 9):
   ``sigma = (ln c / (5.969 - 0.215 b + 2.532 b^2 - 10.73 b^3 + 5.574 b^4 + 0.245 b^5))^2``, with
   ``b`` the azimuthal roughness. ``c`` is clamped to at least 1e-3 so that a black dye stays
   finite (``sigma`` about 1.4). The result is scaled by ``dye_concentration``: concentration 0
   adds nothing whatever the colour, and a white dye never absorbs.

Mitsuba rejects melanin and ``sigma_a`` given together, so the sum goes in ``sigma_a``. Every term
is finite and non-negative, and the total rises monotonically with melanin concentration (the hair
gets darker) and with dye concentration.
"""
from __future__ import annotations

import numpy as np

from hairdigi.render.domain.appearance import DEFAULT_SHINE
from hairdigi.render.domain.params import HairParams

EUMELANIN_SIGMA_A = np.array([0.419, 0.697, 1.37])
PHEOMELANIN_SIGMA_A = np.array([0.187, 0.4, 1.05])

#: Roughness of the fibres; Table 1 holds colour only, so the roughness is fixed. Roughness 0
#: renders black and 0.01 gives fireflies in Mitsuba 3.9, so values are clamped to this range.
LONGITUDINAL_ROUGHNESS = DEFAULT_SHINE   # the default shine (render.domain.appearance)
AZIMUTHAL_ROUGHNESS = 0.3
ROUGHNESS_RANGE = (0.05, 1.0)

#: (melanin_concentration, melanin quantity q): equal steps of L* in the rig, eumelanin ratio 0.7,
#: measured by rendering the swatch (L*: 64.8 59.3 53.7 48.2 42.6 37.0 31.5 26.0 20.4 14.9 9.3).
MELANIN_REMAP = ((0.0, 0.0), (0.1, 0.03), (0.2, 0.063), (0.3, 0.097), (0.4, 0.14), (0.5, 0.21),
                 (0.6, 0.32), (0.7, 0.45), (0.8, 0.67), (0.9, 1.1), (1.0, 6.0))
MIN_DYE_ALBEDO = 1e-3


def melanin_quantity(concentration: float) -> float:
    """Melanin quantity for a concentration in [0, 1]: the rig-measured perceptual remap."""
    m, q = zip(*MELANIN_REMAP)
    return float(np.interp(float(concentration), m, q))


def melanin_sigma_a(concentration: float, ratio: float) -> np.ndarray:
    """RGB absorption per fibre radius of melanin, split into eumelanin (``ratio``) and pheomelanin."""
    q = melanin_quantity(concentration)
    return q * ratio * EUMELANIN_SIGMA_A + q * (1.0 - ratio) * PHEOMELANIN_SIGMA_A


def chiang_denominator(azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> float:
    """The roughness polynomial of Chiang 2016 eq. 9 (``sigma = (ln c / denominator)^2``)."""
    b = float(np.clip(azimuthal_roughness, *ROUGHNESS_RANGE))
    return 5.969 - 0.215 * b + 2.532 * b**2 - 10.73 * b**3 + 5.574 * b**4 + 0.245 * b**5


def sigma_a_from_albedo(albedo: np.ndarray, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """Chiang 2016 eq. 9: the absorption that gives a fibre this multiple-scattering albedo."""
    denom = chiang_denominator(azimuthal_roughness)
    c = np.clip(np.asarray(albedo, dtype=float), MIN_DYE_ALBEDO, 1.0)
    return (np.log(c) / denom) ** 2


def dye_sigma_a(dye_rgb: tuple[float, float, float], concentration: float,
                azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """RGB absorption of the dye: its colour read as an albedo (Chiang 2016), times its concentration."""
    return float(concentration) * sigma_a_from_albedo(np.asarray(dye_rgb) / 255.0, azimuthal_roughness)


def hair_sigma_a(params: HairParams, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """Total RGB ``sigma_a`` (per fibre radius) of melanin plus dye; finite and non-negative."""
    return (melanin_sigma_a(params.melanin_concentration, params.melanin_ratio)
            + dye_sigma_a(params.dye_rgb, params.dye_concentration, azimuthal_roughness))


def hair_bsdf(params: HairParams, longitudinal_roughness: float = LONGITUDINAL_ROUGHNESS,
              azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> dict:
    """A Mitsuba ``hair`` BSDF dict for these parameters."""
    lo, hi = ROUGHNESS_RANGE
    return {
        "type": "hair",
        "sigma_a": {"type": "rgb", "value": hair_sigma_a(params, azimuthal_roughness).tolist()},
        "longitudinal_roughness": float(np.clip(longitudinal_roughness, lo, hi)),
        "azimuthal_roughness": float(np.clip(azimuthal_roughness, lo, hi)),
    }


def albedo_from_sigma_a(sigma_a: np.ndarray, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """Chiang 2016 eq. 9 inverted: ``c = exp(-sqrt(sigma_a) * denominator)``, the fibre's albedo."""
    return np.exp(-np.sqrt(np.clip(sigma_a, 0.0, None)) * chiang_denominator(azimuthal_roughness))


def approximate_albedo(params: HairParams, azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS) -> np.ndarray:
    """The fibre's multiple-scattering albedo (linear RGB) of these parameters, for previews.

    Exact for a lone dye, approximate for the sum of dye and melanin.
    """
    return albedo_from_sigma_a(hair_sigma_a(params, azimuthal_roughness), azimuthal_roughness)
