"""The kinds of scene the renderer draws, one type each: the rig's swatch (:class:`SwatchScene`), a built-in
hairstyle (:class:`HairstyleScene`) and a Cem Yuksel ``.hair`` model on the head (:class:`HairFileScene`).

As a Mitsuba plugin owns its parameters, a kind owns its fields and their checks (``_settle``), its strands
(``make_strands``), what of it makes a loaded scene's structure (``shape_key``), its Mitsuba scene dictionary
(``scene_dict``), its in-place update of a loaded scene through ``mi.traverse`` (``update``) and its spectral
parts (``spectralise``). The fields every kind has (camera, strands, depth, lights, appearance, colour) are
:class:`Scene`'s, which checks them once for all. ``render.renderer.Renderer`` calls these methods and never
asks which kind it holds: a new kind of scene is one new subclass of :class:`Scene` (the manual's page
"Extending" works one through).

``SceneSpec(name, **fields)`` builds the kind that ``name`` names from the fields of every kind, as callers
write it: ``SceneSpec("swatch", framing="rig")``, ``SceneSpec("bob", env="soft")``, ``SceneSpec("x.hair")``.
"""
from __future__ import annotations

import dataclasses
import os
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from hairdigi.render import scenes
from hairdigi.render.chart import colorchecker_spectra, is_colorchecker
from hairdigi.render.domain import rig_geometry
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance
from hairdigi.render.domain.bounds import (ENVIRONMENTS, HAIRSTYLES, MAX_DEPTH, MAX_STRANDS, MIN_DEPTH, SCENE_NAMES,
                                           SWATCH_ENVIRONMENTS, Environment, SceneDefaults, SceneKind, SwatchModel,
                                           check_camera, defaults_for, is_whole)
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.text_enum import text_of
from hairdigi.render.fibres import FIBRE_GROUPS
from hairdigi.render.hairfile import hair_model_strands
from hairdigi.render.spectra import camera_sensitivities, illuminant_spd, rgb_projection
from hairdigi.render.strands import (STYLES, Strands, hairstyle_strands, layered_radius, layered_swatch_strands,
                                     swatch_strands)
from hairdigi.render.swatch_family import structure_strands
from hairdigi.render.variant import mi

#: The swatch's strand model when none is named (``render.domain.bounds.SwatchModel`` has them all).
DEFAULT_SWATCH_MODEL = SwatchModel.LAYERED


class SceneError(HairdigiError, ValueError):
    """A scene cannot be built as asked (an unknown name, environment or framing, a missing .hair file, a
    setting out of its range); the message names it and what would work."""


def _set(scene: Scene, name: str, value) -> None:
    """Settle a field of a frozen scene while it is built (its parsed or resolved value)."""
    object.__setattr__(scene, name, value)


@dataclass(frozen=True)
class Scene(ABC):
    """What to render, apart from the hair colour: the fields every kind of scene has, checked once here.

    ``name`` names the scene (``"swatch"``, a hairstyle, ``"hairfile"``); ``kind`` (a class attribute, a
    ``SceneKind``) is what the type shows: test it, not the name. ``camera`` None takes the kind's
    ``default_camera`` (``pose`` is the camera used). ``strands``, ``max_depth`` None take the kind's defaults
    (``n_strands``, ``depth``; ``render.domain.bounds.defaults_for``). ``lights`` scales the rig's three
    lights (a swatch's). ``appearance`` (``render.domain.appearance.Appearance``; None, the default uniform
    hair) is the hair's shine, fibre spread and grey share; a varied one is drawn as ``fibre_groups`` pigment
    groups and a grey group (``render.fibres``). ``illuminant`` None renders in RGB with white lights; a name
    of ``render.spectra.ILLUMINANTS`` or a CSV of wavelength, power renders the scene spectrally, every light
    emitting that SPD, seen by the CIE 1931 observer as linear sRGB (D65 white: under tungsten a white holder
    is orange). ``sensitivities`` (spectral renders only) sees it through a camera's R, G, B sensitivities
    instead (``render.spectra.CAMERAS`` or a CSV; Mitsuba's ``specfilm``): the camera's raw linear RGB, each
    band of unit area (``render.spectra.camera_bands``), neither white-balanced nor colour-corrected.

    A kind is a frozen dataclass subclass: its own fields after these (its lighting ``env`` among them), a
    ``kind``, a ``default_camera``, and the methods marked abstract. ``dataclasses.replace`` keeps the kind;
    ``SceneSpec`` builds a scene by name. ``swatch_model`` and ``hair_file`` are read on any scene: None
    where the kind has none.
    """

    name: str
    camera: rig_geometry.CameraPose | None = None
    strands: int | None = None
    strand_seed: int = 0
    max_depth: int | None = None
    lights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    appearance: Appearance | None = None   # shine, fibre spread, greys; None: the default (uniform)
    fibre_groups: int | None = None        # pigment groups of a varied appearance; None: FIBRE_GROUPS
    illuminant: str | None = None          # None: RGB; a light (render.spectra): rendered spectrally
    sensitivities: str | None = None       # spectral: None, the CIE observer; a camera (render.spectra)

    kind: ClassVar[SceneKind]                          # what the type shows
    default_camera: ClassVar[rig_geometry.CameraPose]  # the camera when ``camera`` is None
    swatch_model = None                                # kinds other than the swatch have no swatch model
    hair_file = None                                   # and no .hair file but the hair model's

    def __post_init__(self) -> None:
        _set(self, "name", text_of(self.name))   # SceneKind.SWATCH and "swatch" make one scene
        self._settle()
        if self.max_depth is not None and (not is_whole(self.max_depth)
                                           or not MIN_DEPTH <= self.max_depth <= MAX_DEPTH):
            raise SceneError(f"max_depth must be a whole number between {MIN_DEPTH} and {MAX_DEPTH} (depth 1 "
                             f"shows only the lights, 0 nothing), got {self.max_depth!r}")
        if self.strands is not None and (not is_whole(self.strands) or not 1 <= self.strands <= MAX_STRANDS):
            raise SceneError(f"strands must be a whole number between 1 and {MAX_STRANDS}, got {self.strands!r}")
        if self.appearance is not None and not isinstance(self.appearance, Appearance):
            raise ValueError(f"appearance must be an Appearance (render.domain.appearance), got {self.appearance!r}")
        if self.fibre_groups is not None and (not is_whole(self.fibre_groups) or not 1 <= self.fibre_groups <= 64):
            raise SceneError(f"fibre_groups must be a whole number between 1 and 64, got {self.fibre_groups!r}")
        if not all(np.isfinite(float(v)) and v >= 0 for v in self.lights):
            raise ValueError(f"lights {self.lights} must be finite scales >= 0")
        if self.camera is not None:
            check_camera(self.camera, self.kind)
        if self.illuminant is not None:
            illuminant_spd(self.illuminant)   # an unknown name or a bad CSV fails here, in one line
        if self.sensitivities is not None:
            if self.illuminant is None:
                raise SceneError("a camera's sensitivities need a spectral render: give an illuminant too")
            camera_sensitivities(self.sensitivities)

    # -- what a kind owns --------------------------------------------------------------------
    @abstractmethod
    def _settle(self) -> None:
        """Check the kind's own fields (its name first, then its ``env``) and settle them to their parsed
        values (``_set``); raise SceneError naming what is wrong. Runs before the shared checks."""

    @abstractmethod
    def make_strands(self) -> Strands:
        """The hair's strands: ``n_strands`` of them, laid out by ``strand_seed``."""

    @abstractmethod
    def scene_dict(self, curve_file: str, bsdf: dict, size: int | tuple[int, int]) -> dict:
        """The Mitsuba scene dictionary at film ``size``, its hair (key ``"hair"``) read from ``curve_file``
        with ``bsdf``. The renderer splits the hair into fibre groups where the appearance asks."""

    @abstractmethod
    def view(self) -> tuple[np.ndarray, tuple, float]:
        """The camera at ``pose``: its position, the point it looks at, and its horizontal field of view."""

    def shape_key(self) -> tuple:
        """What of the scene makes a loaded scene's structure (a change means a new scene, not an update).
        A kind adds its own fields to these."""
        return type(self), self.name, self.n_strands, self.depth, self.groups

    def update(self, params, sigma_a: np.ndarray, moved: bool) -> None:
        """Update a loaded scene of this kind in place: ``params`` is its ``mi.traverse``, ``sigma_a`` the hair's
        RGB absorption (the renderer has set the hair's), ``moved`` that the camera is not the loaded one's.
        A kind adds its own parameters (its lights, the scalp) to the camera's."""
        if moved:
            position, target, fov = self.view()
            params["sensor.to_world"] = mi.AffineTransform4f(scenes.look_at(position, np.asarray(target)).matrix)
            params["sensor.x_fov"] = fov   # the field of view follows the distance

    def spectralise(self, scene_dict: dict, sigma_a: np.ndarray, hair: dict[str, np.ndarray],
                    spd: np.ndarray) -> None:
        """Turn the kind's scene dict spectral (``render.scenes.spectralise``): every light emits ``spd``; each
        hair shape (``hair``: key, absorption spectrum) takes its ``sigma_a(λ)``; ``sigma_a`` is the hair's."""
        scenes.spectralise(scene_dict, hair, spd, None)

    # -- read by every kind ------------------------------------------------------------------
    @property
    def defaults(self) -> SceneDefaults:
        """The kind's strands, depth, size and spp when none is given (``render.domain.bounds``)."""
        return defaults_for(self.kind)

    @property
    def n_strands(self) -> int:
        return self.strands if self.strands is not None else self.defaults.strands

    @property
    def depth(self) -> int:
        return self.max_depth if self.max_depth is not None else self.defaults.max_depth

    @property
    def look(self) -> Appearance:
        return self.appearance if self.appearance is not None else DEFAULT_APPEARANCE

    @property
    def groups(self) -> int:
        """Pigment groups drawn: 0 for uniform hair (one shape), else ``fibre_groups`` or ``FIBRE_GROUPS``."""
        if self.fibre_groups is not None:
            return int(self.fibre_groups)
        return FIBRE_GROUPS if self.look.varied else 0

    @property
    def pose(self) -> rig_geometry.CameraPose:
        return self.camera if self.camera is not None else self.default_camera


@dataclass(frozen=True)
class SwatchScene(Scene):
    """The rig's swatch on its holder. ``framing`` is ``"crop"``, all hair, as in the training set, or
    ``"rig"``, the whole swatch on its holder; the camera at ``pose`` looks at ``target`` and its field of view
    shows ``half_width`` there (None: the framing's). ``chart`` adds a colour chart of (24, 3) linear
    reflectances beside the swatch, at ``chart_center`` on the holder (x, y; default
    ``rig_geometry.CHART_CENTER``); a ColorChecker is drawn with its measured spectral reflectances in a spectral
    render (``render.chart.colorchecker_spectra``). ``crop`` renders just that x, y, w, h window of the film
    (``rig_geometry.RigRegion.render_plan``). ``swatch_model`` picks its strands (a ``SwatchModel``, or its
    text; None: ``DEFAULT_SWATCH_MODEL``). ``env`` (its enum or its text, held as the enum) is ``"studio"``, the
    rig's three lights, or ``"key-sky"``, which adds a key light and a grey sky (the rig's lights set to 0:
    away from the rig). ``framing`` and ``swatch_model`` too are given as their enums or their text."""

    name: str = SceneKind.SWATCH.value
    env: Environment = Environment.STUDIO
    framing: rig_geometry.Framing = rig_geometry.Framing.CROP
    chart: tuple | None = None
    chart_center: tuple[float, float] | None = None
    crop: tuple[int, int, int, int] | None = None   # render only this x, y, w, h of the film
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    half_width: float | None = None
    swatch_model: SwatchModel | None = None          # the swatch's strands; None: the default

    kind: ClassVar[SceneKind] = SceneKind.SWATCH
    default_camera: ClassVar[rig_geometry.CameraPose] = rig_geometry.CameraPose()

    def _settle(self) -> None:
        if self.name != SceneKind.SWATCH.value:
            raise SceneError(f"the swatch scene is named {SceneKind.SWATCH.value!r}, not {self.name!r}: "
                             f"SceneSpec({self.name!r}, ...) builds the scene that name names")
        if text_of(self.env) not in SWATCH_ENVIRONMENTS:
            raise SceneError(f"unknown swatch environment {self.env!r}; choose 'studio' (the rig) or "
                             f"{Environment.KEY_SKY.value!r} (a key light and a grey sky)")
        _set(self, "env", Environment(self.env))
        if not rig_geometry.Framing.knows(self.framing):
            raise SceneError(f"unknown framing {self.framing!r}; choose one of "
                             f"{', '.join(rig_geometry.Framing.names())}")
        _set(self, "framing", rig_geometry.Framing(self.framing))
        if self.swatch_model is None:
            _set(self, "swatch_model", DEFAULT_SWATCH_MODEL)
        if not SwatchModel.knows(self.swatch_model):
            raise SceneError(f"swatch_model {self.swatch_model!r}: choose one of "
                             f"{', '.join(SwatchModel.names())} (it applies to the swatch scene only)")
        _set(self, "swatch_model", SwatchModel(self.swatch_model))

    def make_strands(self) -> Strands:
        n, seed = self.n_strands, self.strand_seed
        if self.swatch_model is SwatchModel.LAYERED:
            return layered_swatch_strands(n, seed=seed, radius=layered_radius(n))
        if self.swatch_model is SwatchModel.TODAY:
            return swatch_strands(n, seed=seed)
        return structure_strands(self.swatch_model, n, seed=seed)

    def shape_key(self) -> tuple:
        return super().shape_key() + (self.env, self.framing, self.chart, self.target, self.half_width,
                                      self.chart_center, self.crop, self.swatch_model)

    def scene_dict(self, curve_file: str, bsdf: dict, size: int | tuple[int, int]) -> dict:
        chart = None if self.chart is None else np.asarray(self.chart)
        moved = chart is not None and self.chart_center is not None
        scene_dict = scenes.swatch_scene(curve_file, bsdf, self.pose, size, self.framing, self.depth, self.lights,
                                         None if moved else chart, self.target, self.half_width, self.crop, self.env)
        if moved:
            scene_dict.update(scenes.chart_patches(chart, center=tuple(self.chart_center)))
        return scene_dict

    def view(self) -> tuple[np.ndarray, tuple, float]:
        # the field of view follows the distance (the framing is fixed at the holder)
        return (self.pose.position(self.target), self.target,
                rig_geometry.framing_fov(self.framing, self.pose.distance, self.half_width))

    def update(self, params, sigma_a: np.ndarray, moved: bool) -> None:
        super().update(params, sigma_a, moved)
        for i, scale in enumerate(self.lights):
            params[f"light{i}.emitter.radiance.value"] = mi.Color3f([scenes.LIGHT_RADIANCE * float(scale)] * 3)

    def spectralise(self, scene_dict: dict, sigma_a: np.ndarray, hair: dict[str, np.ndarray],
                    spd: np.ndarray) -> None:
        chart = colorchecker_spectra() if is_colorchecker(self.chart) else None   # its measured spectra
        scenes.spectralise(scene_dict, hair, spd, chart)


@dataclass(frozen=True)
class HeadScene(Scene):
    """Hair on the head, seen by the portrait camera around ``scenes.PORTRAIT_TARGET`` under the portrait
    lights of ``env`` (``render.scenes.portrait_lights``); the scalp under the hair takes the hair's colour.
    ``env`` (its enum or its text, held as the enum) is ``"studio"`` or ``"soft"``. Its kinds differ in the
    strands they grow (``make_strands``) and the parting they show (``part_x``)."""

    env: Environment = Environment.STUDIO
    default_camera: ClassVar[rig_geometry.CameraPose] = scenes.PORTRAIT_CAMERA

    def shape_key(self) -> tuple:
        return super().shape_key() + (self.env,)

    def _settle_env(self) -> None:
        if text_of(self.env) not in ENVIRONMENTS:
            raise SceneError(f"unknown environment {self.env!r}; choose one of {', '.join(ENVIRONMENTS)}")
        _set(self, "env", Environment(self.env))

    @property
    def part_x(self) -> float | None:
        """The parting's x on the scalp (``render.head``), or None for none."""
        return None

    def scene_dict(self, curve_file: str, bsdf: dict, size: int | tuple[int, int]) -> dict:
        return scenes.portrait_scene(curve_file, bsdf, size, self.env, self.pose, self.depth, part_x=self.part_x)

    def view(self) -> tuple[np.ndarray, tuple, float]:
        return scenes.portrait_camera_position(self.pose), scenes.PORTRAIT_TARGET, scenes.PORTRAIT_FOV

    def update(self, params, sigma_a: np.ndarray, moved: bool) -> None:
        super().update(params, sigma_a, moved)
        if "scalp.bsdf.reflectance.value" in params:   # the scalp under the hair takes its colour
            params["scalp.bsdf.reflectance.value"] = mi.Color3f(*scenes.scalp_albedo(sigma_a))

    def spectralise(self, scene_dict: dict, sigma_a: np.ndarray, hair: dict[str, np.ndarray],
                    spd: np.ndarray) -> None:
        if "scalp" in scene_dict:   # the scalp under the hair takes its colour
            scene_dict["scalp"]["bsdf"]["reflectance"]["value"] = scenes.scalp_albedo(rgb_projection(sigma_a))
        super().spectralise(scene_dict, sigma_a, hair, spd)


@dataclass(frozen=True)
class HairstyleScene(HeadScene):
    """A built-in hairstyle (``render.strands.STYLES``; ``name`` is its name) on the head."""

    kind: ClassVar[SceneKind] = SceneKind.HAIRSTYLE

    def _settle(self) -> None:
        if self.name not in HAIRSTYLES:
            raise SceneError(f"unknown scene {self.name!r}; choose one of {', '.join(SCENE_NAMES)} "
                             f"or the path of a .hair file")
        self._settle_env()

    @property
    def part_x(self) -> float | None:
        return STYLES[self.name].part_x if self.name in STYLES else None

    def make_strands(self) -> Strands:
        return hairstyle_strands(self.name, self.n_strands, seed=self.strand_seed)


@dataclass(frozen=True)
class HairFileScene(HeadScene):
    """A Cem Yuksel ``.hair`` model (``hair_file``, held as its absolute path) fitted to the head and cut to
    ``n_strands`` strands (``hairfile.hair_model_strands``). A ``name`` ending in ``.hair`` is taken as that
    path: ``HairFileScene("x.hair")`` is ``HairFileScene("hairfile", hair_file="/abs/x.hair")``."""

    name: str = SceneKind.HAIR_FILE.value
    hair_file: str | None = None

    kind: ClassVar[SceneKind] = SceneKind.HAIR_FILE

    def _settle(self) -> None:
        if isinstance(self.name, str) and self.name.lower().endswith(".hair") and self.hair_file is None:
            _set(self, "hair_file", self.name)
            _set(self, "name", SceneKind.HAIR_FILE.value)
        if SceneKind.of(self.name) is not SceneKind.HAIR_FILE:
            raise SceneError(f"hair_file applies to the {SceneKind.HAIR_FILE.value!r} scene, not {self.name!r}")
        path = Path(self.hair_file or "")
        if not self.hair_file or not path.is_file():
            raise SceneError(f"hair model {self.hair_file!r}: no such file; give the path of a .hair file")
        _set(self, "hair_file", str(path.resolve()))
        self._settle_env()

    def make_strands(self) -> Strands:
        return hair_model_strands(self.hair_file, self.n_strands, seed=self.strand_seed)

    def shape_key(self) -> tuple:
        stat = os.stat(self.hair_file)   # a model saved again is loaded again
        return super().shape_key() + (self.hair_file, stat.st_mtime_ns, stat.st_size)


#: The type of each kind of scene ``SceneSpec`` builds by name (``SceneKind.of`` reads the name).
SCENE_TYPES: dict[SceneKind, type[Scene]] = {SceneKind.SWATCH: SwatchScene, SceneKind.HAIRSTYLE: HairstyleScene,
                                             SceneKind.HAIR_FILE: HairFileScene}

#: The swatch's fields that a scene on the head ignores when ``SceneSpec`` is given them (the command line
#: passes its ``--framing`` whatever the scene).
SWATCH_ONLY = ("framing", "chart", "chart_center", "crop", "target", "half_width")


def SceneSpec(name: str = SceneKind.SWATCH.value, **fields) -> Scene:   # noqa: N802  (it reads as the type it was)
    """The scene ``name`` names, of its kind's type (``SCENE_TYPES``), from the fields of every kind.

    ``name`` is ``"swatch"`` (:class:`SwatchScene`), a hairstyle (:class:`HairstyleScene`), or ``"hairfile"``
    with ``hair_file`` the path of a ``.hair`` model, or that path itself (:class:`HairFileScene`); a
    ``SceneKind`` or its text. A scene on the head ignores the swatch's ``SWATCH_ONLY`` fields; ``hair_file``
    for another kind than the hair model, or ``swatch_model`` for another kind than the swatch, is refused.
    """
    name = text_of(name)
    kind = SceneKind.of(name)
    if kind is not SceneKind.HAIR_FILE and fields.get("hair_file") is not None:
        raise SceneError(f"hair_file applies to the {SceneKind.HAIR_FILE.value!r} scene, not {name!r}")
    scene_type = SCENE_TYPES[kind]
    own = {f.name for f in dataclasses.fields(scene_type) if f.init}
    others = {key: fields.pop(key) for key in (*SWATCH_ONLY, "swatch_model", "hair_file")
              if key in fields and key not in own}   # hair_file is None here: the kind's absent fields
    scene = scene_type(name=name, **fields)
    swatch_model = others.get("swatch_model")
    if swatch_model is not None:
        raise SceneError(f"swatch_model {swatch_model!r}: choose one of "
                         f"{', '.join(SwatchModel.names())} (it applies to the swatch scene only)")
    return scene
