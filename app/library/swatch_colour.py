"""A swatch's digitized colour, as the library stores and searches it: CIELAB under two lights.

The colour is the swatch's **rendered mean colour** in the rig at the bench camera's pose: each RGB
channel of the mean depends on that channel's ``sigma_a`` alone through the rig's response curve
(``inference.refine.response_curve``, rendered once per pose and cached), so it costs no render at import.

- ``daylight``: the rig's white lights, which in hairdigi's linear Rec.709 are D65; CIELAB against D65.
- ``studio``: the same swatch under 3200 K tungsten studio lamps (a Planckian radiator), seen without
  chromatic adaptation, as a daylight-balanced photograph shows it (CIELAB against D65). Where the
  record holds Table 1 parameters, the change from daylight is the spectral hair's
  (``inference.spectral_reading.colour_under``: the rig's response curve read per wavelength, under each SPD),
  applied per channel to the measured daylight colour, so a dye's absorption band moves as it does
  under a real lamp; the parameters of a declared rig's camera answer (``record.spectral``) are used
  where the record has them. Without parameters, as an RGB renderer lights it: the per-channel product
  of the lamp's linear Rec.709 colour, scaled to luminance 1, and the daylight colour.
"""
from __future__ import annotations

import functools
import re

import numpy as np

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE

ILLUMINANTS = ("daylight", "studio")
#: The instrument geometries a record's readings are stored under (``inference.instrument_reading``; D65, 10°), beside the lights.
INSTRUMENT = ("d/8 SCI", "d/8 SCE", "45/0")
#: Every colour a swatch is stored and searched by.
COLOURS = ILLUMINANTS + INSTRUMENT
STUDIO_CCT = 3200.0
#: The studio lamps as a spectrum (``render.spectra.illuminant_spd``).
STUDIO_LIGHT = f"{STUDIO_CCT:.0f}K"
_HEX = re.compile(r"^#?([0-9a-fA-F]{6})$")


class ColourError(HairdigiError, ValueError):
    """A colour given as text is not ``#RRGGBB``; the message shows the text."""


@functools.lru_cache(maxsize=1)
def studio_light_rgb() -> np.ndarray:
    """A 3200 K lamp in linear Rec.709, luminance 1."""
    import colour   # deferred: the CLI parser imports this module; colour-science takes ~1 s

    xy = colour.CCT_to_xy(STUDIO_CCT, method="Kang 2002")   # the Planckian locus, 1667-25000 K
    xyz = colour.xy_to_XYZ(xy)
    rgb = colour.XYZ_to_RGB(xyz, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)
    return rgb / (rgb @ np.array([0.2126, 0.7152, 0.0722]))


@functools.lru_cache(maxsize=1)
def _curve():
    # deferred: the CLI parser imports this module; colour-science takes ~1 s
    from hairdigi.inference.refine import RefineSettings, response_curve

    return response_curve(RIG_SWATCH_POSE, RefineSettings())


def rendered_linear(sigma_a: np.ndarray) -> np.ndarray:
    """(..., 3) mean linear Rec.709 colour of the rig's swatch for (..., 3) ``sigma_a`` (daylight)."""
    return _curve()(np.asarray(sigma_a, float))


def studio_change(hair) -> np.ndarray:
    """Per channel, the spectral swatch of ``hair`` (``HairParams``) under the studio lamps over under
    daylight (linear sRGB, unadapted; both lights at luminance 1)."""
    # deferred: the CLI parser imports this module; the inference tables load on use
    from hairdigi.inference.spectral_reading import colour_under

    curve = _curve()
    daylight = colour_under(curve, hair, "D65")
    return colour_under(curve, hair, STUDIO_LIGHT) / np.maximum(daylight, 1e-9)


def lab_under(linear_daylight: np.ndarray, hairs: list | None = None) -> dict[str, np.ndarray]:
    """CIELAB of the rendered colour under each illuminant (see the module's docstring); ``hairs``: each
    swatch's Table 1 parameters or None (then the studio colour is the RGB renderer's)."""
    # deferred: the CLI parser imports this module; colour-science takes ~1 s
    from hairdigi.render.metrics import linear_rgb_to_lab

    rgb = np.asarray(linear_daylight, float)
    change = np.broadcast_to(studio_light_rgb(), rgb.shape).copy()
    for i, hair in enumerate(hairs or ()):
        if hair is not None:
            change[i] = studio_change(hair)
    return {"daylight": linear_rgb_to_lab(rgb), "studio": linear_rgb_to_lab(rgb * change)}


def swatch_labs(sigma_a: np.ndarray, hairs: list | None = None) -> dict[str, np.ndarray]:
    """CIELAB under each illuminant of swatches of these ``sigma_a`` (any shape ending in 3); ``hairs``:
    their Table 1 parameters where known (one per swatch, or None), for the spectral studio colour."""
    return lab_under(rendered_linear(sigma_a), hairs)


def hex_lab(text: str) -> np.ndarray:
    """CIELAB (D65) of an sRGB colour written ``#RRGGBB``."""
    # deferred: the CLI parser imports this module; colour-science takes ~1 s
    from hairdigi.render.metrics import linear_rgb_to_lab
    from hairdigi.render.srgb import srgb8_to_linear

    match = _HEX.match(text.strip())
    if not match:
        raise ColourError(f"colour {text!r} is not #RRGGBB (six hexadecimal digits)")
    value = int(match.group(1), 16)
    srgb = np.array([(value >> 16) & 255, (value >> 8) & 255, value & 255], float)
    return linear_rgb_to_lab(srgb8_to_linear(srgb))


def lab_hex(lab: np.ndarray) -> str:
    """``#RRGGBB`` of a CIELAB (D65) colour, clipped to sRGB."""
    # deferred: the CLI parser imports this module; colour-science takes ~1 s
    import colour

    from hairdigi.render.srgb import linear_to_srgb8

    rgb = colour.XYZ_to_RGB(colour.Lab_to_XYZ(np.asarray(lab, float), colour.RGB_COLOURSPACES["sRGB"].whitepoint),
                            colour.RGB_COLOURSPACES["sRGB"], apply_cctf_encoding=False)
    r, g, b = (int(v) for v in linear_to_srgb8(rgb))
    return f"#{r:02x}{g:02x}{b:02x}"


def delta_e(lab_a: np.ndarray, lab_b: np.ndarray) -> np.ndarray:
    """CIEDE2000 between CIELAB colours (broadcasting)."""
    import colour   # deferred: the CLI parser imports this module; colour-science takes ~1 s

    return colour.delta_E(np.asarray(lab_a, float), np.asarray(lab_b, float), method="CIE 2000")
