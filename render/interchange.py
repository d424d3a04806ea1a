"""A hair colour for other renderers: MaterialX 1.39 ``chiang_hair_bsdf`` and a Blender script.

Both carry what hairdigi renders with Mitsuba's ``hair`` BSDF (Chiang et al. 2016): the absorption
``sigma_a`` per fibre radius in linear Rec.709 (hairdigi's rendering space), the longitudinal and
azimuthal roughness, the cuticle tilt and the fibre's IOR. The mappings, each checked where it could be:

- **MaterialX**: ``absorption_coefficient`` is ``sigma_a`` as is (per radius, as pbrt and Mitsuba);
  the roughness goes through MaterialX's own ``chiang_hair_roughness`` node (its inputs are the user
  roughnesses Mitsuba takes; its R / TT / TRT outputs are the variances the BSDF wants, with the
  Marschner scales 1, 0.5 and 2 of Mitsuba and pbrt); ``cuticle_angle`` remaps [0, 1] to
  [-90°, 90°], so Mitsuba's ``scale_tilt`` 2° is 0.5 + 2 / 180.
- **Blender** (Principled Hair BSDF, Chiang, "Absorption coefficient"): Roughness and Radial
  Roughness are Mitsuba's longitudinal and azimuthal roughness; Coat 0; IOR as is; Offset is
  **minus** Mitsuba's tilt for curves drawn root to tip (measured: Cycles -2° matches Mitsuba +2°
  within ΔE2000 0.05, +2° is 2.0 away).

numpy and the standard library only (``records`` and ``absorption`` are).
"""
from __future__ import annotations

import math
import pprint
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from hairdigi.render.domain.absorption import AZIMUTHAL_ROUGHNESS, LONGITUDINAL_ROUGHNESS
from hairdigi.render.domain.files import write_text_atomic
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import EstimateRecord

#: Mitsuba's ``hair`` defaults, which hairdigi renders with (render/scenes.py sets neither).
SCALE_TILT_DEG = 2.0
FIBRE_IOR = 1.55
COLOUR_SPACE = "lin_rec709"
#: The sign that turns Mitsuba's ``scale_tilt`` into Cycles' Offset for root-to-tip curves.
CYCLES_OFFSET_SIGN = -1.0
FORMATS = ("materialx", "blender")


@dataclass(frozen=True)
class HairLook:
    """Everything a Chiang hair BSDF needs to render an estimate as hairdigi renders it."""

    name: str
    sigma_a: tuple[float, float, float]          # per fibre radius, linear Rec.709
    longitudinal_roughness: float = LONGITUDINAL_ROUGHNESS
    azimuthal_roughness: float = AZIMUTHAL_ROUGHNESS
    tilt_deg: float = SCALE_TILT_DEG              # Mitsuba's scale_tilt (pbrt's alpha)
    ior: float = FIBRE_IOR
    shine_measured: bool = False                  # the longitudinal roughness came from the record
    source: str = ""                              # what it was made from (a record's path)

    @property
    def cuticle_angle(self) -> float:
        """MaterialX's ``cuticle_angle``: [0, 1] for [-90°, 90°]."""
        return 0.5 + self.tilt_deg / 180.0

    @property
    def cycles_offset_deg(self) -> float:
        return CYCLES_OFFSET_SIGN * self.tilt_deg


def look_from_record(record: EstimateRecord, name: str = "hairdigi_hair", source: str = "") -> HairLook:
    """The look of an estimate (or dye prediction): refinement's ``sigma_a``, else Table 1's mapping."""
    if record.sigma_a is None:
        why = "; ".join(record.blocked) or "it holds no hair parameters"
        raise RecordError(f"the record has no estimate to export ({why})")
    sigma = np.asarray(record.sigma_a, float)
    appearance = record.appearance
    measured = appearance is not None and appearance.shine_measured
    return HairLook(name=safe_name(name), sigma_a=tuple(float(s) for s in sigma),
                    longitudinal_roughness=(appearance.value.longitudinal_roughness if measured
                                            else LONGITUDINAL_ROUGHNESS),
                    shine_measured=measured, source=source)


def safe_name(text: str) -> str:
    """A MaterialX / Blender element name: letters, digits and underscores, not starting with a digit."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", text) or "hair"
    return name if not name[0].isdigit() else f"hair_{name}"


def xml_text(text: str) -> str:
    """Text XML 1.0 can hold anywhere, comments included: no control characters, no ``--``, no final ``-``."""
    text = re.sub(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\ud800-\udfff\ufffe\uffff]", "?", text)
    while "--" in text:
        text = text.replace("--", "-_")
    return text[:-1] + "_" if text.endswith("-") else text


def _f(x: float) -> str:
    return f"{x:.9g}"


def materialx_text(look: HairLook) -> str:
    """A MaterialX 1.39 document: ``chiang_hair_roughness`` -> ``chiang_hair_bsdf`` -> surface -> material."""
    n = look.name
    sigma = ", ".join(_f(s) for s in look.sigma_a)
    shine = ("measured (the record's appearance.longitudinal_roughness)" if look.shine_measured
             else "not measured: hairdigi's fixed longitudinal roughness")
    doc = (f"hairdigi hair colour{f' from {look.source}' if look.source else ''}. absorption_coefficient is "
           f"sigma_a per fibre radius in linear Rec.709 ({COLOUR_SPACE}), as rendered by Mitsuba 3's hair BSDF "
           f"(Chiang 2016); cuticle_angle {_f(look.cuticle_angle)} is a tilt of {_f(look.tilt_deg)} degrees "
           f"towards the root for curves drawn root to tip; shine: {shine}.")
    doc = xml_text(doc)
    return f"""<?xml version="1.0"?>
<materialx version="1.39" colorspace="{COLOUR_SPACE}">
  <!-- {doc} -->
  <chiang_hair_roughness name="{n}_roughness" type="multioutput">
    <input name="longitudinal" type="float" value="{_f(look.longitudinal_roughness)}" />
    <input name="azimuthal" type="float" value="{_f(look.azimuthal_roughness)}" />
    <input name="scale_TT" type="float" value="0.5" />
    <input name="scale_TRT" type="float" value="2" />
  </chiang_hair_roughness>
  <chiang_hair_bsdf name="{n}_bsdf" type="BSDF" doc={quoteattr(doc)}>
    <input name="tint_R" type="color3" value="1, 1, 1" />
    <input name="tint_TT" type="color3" value="1, 1, 1" />
    <input name="tint_TRT" type="color3" value="1, 1, 1" />
    <input name="ior" type="float" value="{_f(look.ior)}" />
    <input name="roughness_R" type="vector2" nodename="{n}_roughness" output="roughness_R" />
    <input name="roughness_TT" type="vector2" nodename="{n}_roughness" output="roughness_TT" />
    <input name="roughness_TRT" type="vector2" nodename="{n}_roughness" output="roughness_TRT" />
    <input name="cuticle_angle" type="float" value="{_f(look.cuticle_angle)}" />
    <input name="absorption_coefficient" type="vector3" value="{sigma}" />
  </chiang_hair_bsdf>
  <surface name="{n}_surface" type="surfaceshader">
    <input name="bsdf" type="BSDF" nodename="{n}_bsdf" />
  </surface>
  <surfacematerial name="{n}" type="material">
    <input name="surfaceshader" type="surfaceshader" nodename="{n}_surface" />
  </surfacematerial>
</materialx>
"""


#: The script Blender runs (bpy and the standard library only); ``LOOK = {}`` is filled in.
BLENDER_TEMPLATE = Path(__file__).with_name("blender_hair.py")


def blender_look(look: HairLook) -> dict:
    """The Principled Hair BSDF's settings for this look (Blender's names and units)."""
    return {"name": look.name, "model": "CHIANG", "parametrization": "ABSORPTION",
            "inputs": {"Absorption Coefficient": list(look.sigma_a),
                       "Roughness": look.longitudinal_roughness, "Radial Roughness": look.azimuthal_roughness,
                       "Coat": 0.0, "IOR": look.ior, "Offset": math.radians(look.cycles_offset_deg),
                       "Random Color": 0.0, "Random Roughness": 0.0, "Color": [1.0, 1.0, 1.0],
                       "Melanin": 0.0, "Melanin Redness": 0.0, "Tint": [1.0, 1.0, 1.0],
                       # the Huang model's inputs, unused by Chiang: a round fibre, every lobe at full weight
                       "Aspect Ratio": 1.0, "Reflection": 1.0, "Transmission": 1.0, "Secondary Reflection": 1.0},
            "colour_space": COLOUR_SPACE, "mitsuba": asdict(look)}


def blender_script_text(look: HairLook) -> str:
    """The Blender script for this look: the template with its ``LOOK`` filled in."""
    template = BLENDER_TEMPLATE.read_text(encoding="utf-8")
    filled = "LOOK = " + pprint.pformat(blender_look(look), sort_dicts=False)
    if "\nLOOK = {}\n" not in template:
        raise RuntimeError(f"{BLENDER_TEMPLATE} lost its 'LOOK = {{}}' line")
    return template.replace("\nLOOK = {}\n", "\n" + filled + "\n", 1)


def write_look(look: HairLook, fmt: str, out: str | Path) -> Path:
    """Write ``look`` as ``materialx`` (.mtlx) or ``blender`` (a .py script), atomically."""
    if fmt == "materialx":
        return write_text_atomic(out, materialx_text(look))
    if fmt == "blender":
        return write_text_atomic(out, blender_script_text(look))
    raise ValueError(f"unknown export format {fmt!r}; choose one of {', '.join(FORMATS)}")
