"""What the command line and the renderer accept, without Mitsuba: render bounds and defaults and their checks, scene and
environment names, Mitsuba variant names. numpy and the standard library only, so that ``hairdigi --help`` and
every usage error load neither Mitsuba nor colour-science (``render.renderer``, ``render.scenes``,
``render.strands`` and ``render.variant`` take these from here)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hairdigi.render.domain import rig_geometry
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.text_enum import TextEnum


class BoundsError(HairdigiError, ValueError):
    """A render setting (size, spp, camera) outside what a render can finish or show; the message names
    the setting and its range."""


class SceneKind(TextEnum):
    """What a scene shows: the rig's swatch, a built-in hairstyle on the head, or a ``.hair`` model on it."""

    SWATCH = "swatch"
    HAIRSTYLE = "hairstyle"
    HAIR_FILE = "hairfile"

    @classmethod
    def of(cls, name: str) -> SceneKind:
        """The kind of the scene named ``name``: the swatch, a hair model (or a ``.hair`` file's path), else a
        hairstyle."""
        if isinstance(name, cls):
            return name
        if isinstance(name, str) and name.lower().endswith(".hair"):
            return cls.HAIR_FILE
        return cls(name) if name in (cls.SWATCH.value, cls.HAIR_FILE.value) else cls.HAIRSTYLE

    @property
    def on_head(self) -> bool:
        """Hair on the head (a hairstyle or a hair model): its defaults, camera and lighting are the portrait's."""
        return self is not SceneKind.SWATCH


class Environment(TextEnum):
    """A scene's lighting: the hairstyles' "studio" or "soft" (``render.scenes.portrait_lights``); a swatch's
    "studio" (the rig's three lights) or "key-sky" (a key light and a grey sky, away from the rig)."""

    STUDIO = "studio"
    SOFT = "soft"
    KEY_SKY = "key-sky"


class SwatchModel(TextEnum):
    """The swatch's strand models (``render.scene_kinds.SwatchScene.swatch_model``): "layered",
    ``layered_swatch_strands`` (no fibre meets another, optically thick: the default); "today",
    ``swatch_strands`` (the first swatch: a few layers whose fibres pass through one another, 1.4-1.8 ΔE2000
    lighter at equal sigma_a).
    resources/models/swatch-structure.md measures both. The others are ``render.swatch_family``'s
    physical structures (deposited, tilted layers, ...), which ``hairdigi evaluate --structures`` hides."""

    LAYERED = "layered"
    TODAY = "today"
    DEPOSITED = "deposited"
    DEPOSITED_COARSE = "deposited-coarse"
    SPREAD = "spread"
    WAVY = "wavy"
    TILTED = "tilted"
    LOOSE = "loose"
    THIN = "thin"
    CLUMPED = "clumped"


# Bounds on what a render may ask for: outside them the image is black, or the job cannot finish.
MIN_SIZE = 8                 #: pixels a side; smaller holds too few strands to see
MAX_SIZE = 4096              #: pixels a side; 4096² linear RGB is already 200 MB, and the film more
MAX_SPP = 65536              #: samples per pixel
MAX_SAMPLES = 2 ** 31        #: pixels x spp in one render (Mitsuba's JIT variants stop at 2^32)
MIN_DEPTH = 2                #: path depth; depth 1 shows only the lights themselves (black for the rig)
MAX_DEPTH = 1024
MAX_STRANDS = 200_000
#: Camera distance from the target in scene units: nearer is inside or against the hair (the
#: swatch's strands stand 0.04 above the holder; the head's radius is about 1), farther is a speck.
MIN_CAMERA_DISTANCE = {SceneKind.SWATCH: 0.5, SceneKind.HAIRSTYLE: 2.5}
MAX_CAMERA_DISTANCE = 100.0

#: The built-in hairstyles (``render.strands``) and the scenes: the swatch rig, then the hairstyles.
HAIRSTYLES = ("straight", "wavy", "curly", "bob", "ponytail", "afro")


class StructureMode(TextEnum):
    """How an estimate treats the swatch's structure (``inference.structure``): "assumed" (hairdigi's layered
    swatch), "family" (mapped to the mean of ``render.swatch_family``'s structures), "read" (from the
    single-light frames)."""

    ASSUMED = "assumed"
    FAMILY = "family"
    READ = "read"


STRUCTURE_MODES = StructureMode.names()
#: The mode an estimate uses when none is named (``--structure``, the app's settings, the rig profile). "family":
#: a lab's swatch is built another way than hairdigi's, and on swatches of other structures "family" was right
#: where "assumed" was not (Blender Cycles, hidden structures: 0.37 against 1.61 median ΔE2000; a structure no
#: family member resembles, 1.08 against 2.53); the model card's figures measure every mode. "assumed" stays for
#: hairdigi's own synthetic swatch and its evaluations.
DEFAULT_STRUCTURE = StructureMode.FAMILY
#: Named cameras of the spectral world (``render.spectra``): name -> colour-science's ``MSDS_CAMERA_SENSITIVITIES`` key.
CAMERAS = {"nikon-5100": "Nikon 5100 (NPL)", "sigma-sdmerill": "Sigma SDMerill (NPL)"}
#: Named lights of the spectral world (``render.spectra``): name -> colour-science's ``SDS_ILLUMINANTS`` key.
ILLUMINANTS = {
    "D65": "D65", "daylight": "D65", "D50": "D50", "A": "A", "tungsten": "A",
    "FL2": "FL2", "FL11": "FL11", "shop-led": "LED-B3",
    **{f"LED-{k}": f"LED-{k}" for k in ("B1", "B2", "B3", "B4", "B5", "BH1", "RGB1", "V1", "V2")},
}
SCENE_NAMES = (SceneKind.SWATCH.value,) + HAIRSTYLES
#: The hairstyles' lighting (``render.scenes``); a swatch's is ``SWATCH_ENVIRONMENTS``.
ENVIRONMENTS = (Environment.STUDIO.value, Environment.SOFT.value)
SWATCH_ENVIRONMENTS = (Environment.STUDIO.value, Environment.KEY_SKY.value)

#: Mitsuba variants (``render.variant``): the ones that work without a GPU, in order of preference;
#: what ``"auto"`` tries (the GPU when Mitsuba finds one first); the choices of ``--variant``.
PREFERRED_VARIANTS = ("llvm_ad_rgb", "scalar_rgb")
AUTO_VARIANTS = ("cuda_ad_rgb",) + PREFERRED_VARIANTS
VARIANT_CHOICES = ("auto",) + AUTO_VARIANTS


@dataclass(frozen=True)
class SceneDefaults:
    """Per-scene defaults, chosen from ``hairdigi bench render`` (see render/README.md)."""

    strands: int
    spp: int
    max_depth: int
    size: int


#: Chosen from the benchmark in render/README.md: the cheapest setting whose error is under the
#: noise that matters.
DEFAULTS = {
    # swatch: 8000 fibres in 20 layers, 2.3 mm thick at 5 cm a unit (resources/models/swatch-structure.md)
    SceneKind.SWATCH: SceneDefaults(strands=8000, spp=16, max_depth=32, size=128),
    SceneKind.HAIRSTYLE: SceneDefaults(strands=6000, spp=16, max_depth=24, size=512),   # strands: render/README.md
}


def defaults_for(name: str) -> SceneDefaults:
    """The defaults of the swatch, or of every hairstyle and hair model."""
    return DEFAULTS[SceneKind.HAIRSTYLE if SceneKind.of(name).on_head else SceneKind.SWATCH]


def is_whole(value: object) -> bool:
    """A whole number (Python or numpy), not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def check_size_spp(size: int | tuple[int, int], spp: int) -> None:
    """Raise BoundsError naming ``size`` or ``spp`` when a render could not finish or show anything."""
    sides = tuple(size) if isinstance(size, (tuple, list)) else (size,)
    if not all(is_whole(s) for s in sides) or not MIN_SIZE <= min(sides) <= max(sides) <= MAX_SIZE:
        raise BoundsError(f"size must be whole pixels between {MIN_SIZE} and {MAX_SIZE}, got {size!r}")
    if not is_whole(spp) or not 1 <= spp <= MAX_SPP:
        raise BoundsError(f"spp must be a whole number between 1 and {MAX_SPP}, got {spp!r}")
    pixels = int(sides[0]) * int(sides[-1])
    if pixels * int(spp) > MAX_SAMPLES:
        raise BoundsError(f"size {size} at {spp} spp is {pixels * int(spp):.3g} samples, over the limit of "
                          f"{MAX_SAMPLES:.3g} for one render; lower the size or the spp")


def check_camera(pose: rig_geometry.CameraPose, scene: str = "swatch") -> None:
    """Raise BoundsError naming the camera when its angles or distance are not finite, or its distance
    puts it inside the geometry or absurdly far (both give a black image)."""
    values = (pose.polar_deg, pose.azimuth_deg, pose.distance)
    if not all(np.isfinite(float(v)) for v in values):
        raise BoundsError(f"camera {values} must be finite numbers (polar, azimuth, distance)")
    low = MIN_CAMERA_DISTANCE[SceneKind.HAIRSTYLE if SceneKind.of(scene).on_head else SceneKind.SWATCH]
    if not low <= pose.distance <= MAX_CAMERA_DISTANCE:
        raise BoundsError(f"camera distance {pose.distance:g} must be between {low:g} (nearer is inside or "
                          f"against the hair) and {MAX_CAMERA_DISTANCE:g} scene units")
