"""``render(params, scene, size, spp, seed)``: hair parameters and a scene in, a path-traced image out.

Loaded scenes are cached. When only the hair parameters, the camera, the light intensities or (in
the JIT variants) the strand layout change, the cached scene is updated through ``mi.traverse``
instead of being rebuilt, which is what makes rendering thousands of dataset swatches cheap.
"""
from __future__ import annotations

import contextlib
import gc
import os
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np

from hairdigi.render.domain import rig_geometry
# Bounds, defaults and their checks: in render.domain.bounds, so the command line reads them without Mitsuba.
from hairdigi.render.domain.bounds import (MAX_DEPTH, MAX_STRANDS, MIN_DEPTH, SCENE_NAMES, check_camera,
                                           check_size_spp, defaults_for, is_whole)
from hairdigi.render import scenes
from hairdigi.render.chart import colorchecker_spectra, is_colorchecker
from hairdigi.render.domain.absorption import hair_bsdf, hair_sigma_a
from hairdigi.render.hairfile import hair_model_strands
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance
from hairdigi.render.domain.bounds import (ENVIRONMENTS, SWATCH_ENVIRONMENTS, Environment, SceneKind,
                                           SwatchModel)
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.interrupt import sigint_held
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.text_enum import text_of
from hairdigi.render.fibres import FIBRE_GROUPS, group_keys, group_sigma_a, split_strands
from hairdigi.render.srgb import linear_to_srgb8
from hairdigi.render.strands import (STYLES, Strands, hairstyle_strands, layered_radius,
                                     layered_swatch_strands, swatch_strands)
from hairdigi.render.swatch_family import structure_strands
from hairdigi.render.variant import is_jit, load_scene, mi, select_variant, spectral_variant

#: The swatch's strand model when none is named (``render.domain.bounds.SwatchModel`` has them all).
DEFAULT_SWATCH_MODEL = SwatchModel.LAYERED


class SceneError(HairdigiError, ValueError):
    """A scene cannot be built as asked (an unknown name, environment or framing, a missing .hair file, a
    setting out of its range); the message names it and what would work."""


@dataclass(frozen=True)
class SceneSpec:
    """What to render, apart from the hair colour.

    ``name`` is ``"swatch"``, a hairstyle, or ``"hairfile"`` with ``hair_file`` the path of a Cem
    Yuksel ``.hair`` model (a ``name`` ending in ``.hair`` is taken as that path: ``SceneSpec("x.hair")``
    is ``SceneSpec("hairfile", hair_file="/abs/x.hair")``); the model is fitted to the head and cut to
    ``strands`` strands (``hairfile.hair_model_strands``). ``kind`` is what ``name`` names (a
    ``SceneKind``, parsed once: test it, not the name). ``framing`` (swatch only) is ``"crop"``, all hair, as in
    the training set, or ``"rig"``, the whole swatch on its holder. ``env`` lights hairstyles.
    ``strands``, ``max_depth`` None take the scene's defaults. ``lights`` scales the three rig lights.
    ``chart`` adds a colour chart of (24, 3) linear reflectances beside the swatch (swatch only), at
    ``chart_center`` on the holder (x, y; default ``rig_geometry.CHART_CENTER``). ``crop`` (swatch
    only) renders just that x, y, w, h window of the film (``rig_geometry.RigRegion.render_plan``).
    ``swatch_model`` (swatch only) picks its strands (a ``SwatchModel``).
    ``env``, ``framing`` and ``swatch_model`` are given as their enums or their text, and held as the enums. ``appearance``
    (``render.domain.appearance.Appearance``) is the hair's shine, fibre spread and grey share; a varied
    one is drawn as ``fibre_groups`` pigment groups and a grey group (``render.fibres``). A swatch's
    ``env`` ``"key-sky"`` adds a key light and a grey sky (the rig's lights set to 0: away from the rig).
    ``illuminant`` None renders in RGB with white lights; a name of ``render.spectra.ILLUMINANTS`` or a
    CSV of wavelength, power renders the scene spectrally, every light emitting that SPD, seen by the
    CIE 1931 observer as linear sRGB (D65 white: under tungsten a white holder is orange); a ColorChecker
    ``chart`` is drawn with its measured spectral reflectances (``render.chart.colorchecker_spectra``).
    ``sensitivities`` (spectral renders only) sees it through a camera's R, G, B sensitivities instead
    (``render.spectra.CAMERAS`` or a CSV; Mitsuba's ``specfilm``): the camera's raw linear RGB, each
    band of unit area (``render.spectra.camera_bands``), neither white-balanced nor colour-corrected.
    """

    name: str = SceneKind.SWATCH.value
    camera: rig_geometry.CameraPose | None = None
    env: Environment = Environment.STUDIO
    framing: rig_geometry.Framing = rig_geometry.Framing.CROP
    strands: int | None = None
    strand_seed: int = 0
    max_depth: int | None = None
    lights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    chart: tuple | None = None
    target: tuple[float, float, float] = (0.0, 0.0, 0.0)
    half_width: float | None = None
    chart_center: tuple[float, float] | None = None
    hair_file: str | None = None
    crop: tuple[int, int, int, int] | None = None   # swatch: render only this x, y, w, h of the film
    appearance: Appearance | None = None            # shine, fibre spread, greys; None: the default (uniform)
    fibre_groups: int | None = None                  # pigment groups of a varied appearance; None: FIBRE_GROUPS
    swatch_model: SwatchModel | None = None          # swatch strands; None: the default
    illuminant: str | None = None                    # None: RGB; a light (render.spectra): rendered spectrally
    sensitivities: str | None = None                 # spectral: None, the CIE observer; a camera (render.spectra)
    kind: SceneKind = field(init=False, repr=False, compare=False)   # what ``name`` names, parsed once

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", text_of(self.name))   # SceneKind.SWATCH and "swatch" make one spec
        if isinstance(self.name, str) and self.name.lower().endswith(".hair") and self.hair_file is None:
            object.__setattr__(self, "hair_file", self.name)
            object.__setattr__(self, "name", SceneKind.HAIR_FILE.value)
        object.__setattr__(self, "kind", SceneKind.of(self.name))
        swatch = self.kind is SceneKind.SWATCH
        if self.kind is SceneKind.HAIR_FILE:
            path = Path(self.hair_file or "")
            if not self.hair_file or not path.is_file():
                raise SceneError(f"hair model {self.hair_file!r}: no such file; give the path of a .hair file")
            object.__setattr__(self, "hair_file", str(path.resolve()))
        elif self.hair_file is not None:
            raise SceneError(f"hair_file applies to the {SceneKind.HAIR_FILE.value!r} scene, not {self.name!r}")
        elif text_of(self.name) not in SCENE_NAMES:
            raise SceneError(f"unknown scene {self.name!r}; choose one of {', '.join(SCENE_NAMES)} "
                             f"or the path of a .hair file")
        if not swatch and text_of(self.env) not in ENVIRONMENTS:
            raise SceneError(f"unknown environment {self.env!r}; choose one of {', '.join(ENVIRONMENTS)}")
        if swatch and text_of(self.env) not in SWATCH_ENVIRONMENTS:
            raise SceneError(f"unknown swatch environment {self.env!r}; choose 'studio' (the rig) or "
                             f"{Environment.KEY_SKY.value!r} (a key light and a grey sky)")
        object.__setattr__(self, "env", Environment(self.env))
        if rig_geometry.Framing.knows(self.framing):
            object.__setattr__(self, "framing", rig_geometry.Framing(self.framing))
        elif swatch:
            raise SceneError(f"unknown framing {self.framing!r}; choose one of "
                             f"{', '.join(rig_geometry.Framing.names())}")
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
        if swatch and self.swatch_model is None:
            object.__setattr__(self, "swatch_model", DEFAULT_SWATCH_MODEL)
        if self.swatch_model is not None:
            if not SwatchModel.knows(self.swatch_model) or not swatch:
                raise SceneError(f"swatch_model {self.swatch_model!r}: choose one of "
                                 f"{', '.join(SwatchModel.names())} (it applies to the swatch scene only)")
            object.__setattr__(self, "swatch_model", SwatchModel(self.swatch_model))
        if self.camera is not None:
            check_camera(self.camera, self.kind)
        if self.illuminant is not None:
            from hairdigi.render.spectra import illuminant_spd

            illuminant_spd(self.illuminant)   # an unknown name or a bad CSV fails here, in one line
        if self.sensitivities is not None:
            if self.illuminant is None:
                raise SceneError("a camera's sensitivities need a spectral render: give an illuminant too")
            from hairdigi.render.spectra import camera_sensitivities

            camera_sensitivities(self.sensitivities)

    @property
    def n_strands(self) -> int:
        return self.strands if self.strands is not None else defaults_for(self.kind).strands

    @property
    def depth(self) -> int:
        return self.max_depth if self.max_depth is not None else defaults_for(self.kind).max_depth

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
        if self.camera is not None:
            return self.camera
        return rig_geometry.CameraPose() if self.kind is SceneKind.SWATCH else scenes.PORTRAIT_CAMERA


@dataclass
class RenderResult:
    linear: np.ndarray  # (H, W, 3) float32, linear RGB
    srgb: np.ndarray    # (H, W, 3) uint8, sRGB-encoded
    seconds: float
    spp: int
    cpu_seconds: float = 0.0   # core-seconds of this process: robust to other load; ~2x wall on 2 idle cores
    nonfinite: int = 0         # NaN or Inf values the path tracer returned, replaced by 0 in ``linear``


def absorption_of(hair: HairParams | np.ndarray) -> np.ndarray:
    """The RGB ``sigma_a`` to render: mapped from Table 1 parameters, or given directly (3 values >= 0)."""
    if isinstance(hair, HairParams):
        return hair_sigma_a(hair)
    sigma = np.asarray(hair, dtype=float).ravel()
    if sigma.shape != (3,) or not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
        raise ValueError(f"sigma_a must be 3 finite values >= 0, got {hair!r}")
    return sigma


def spectral_absorption_of(hair: HairParams | np.ndarray) -> np.ndarray:
    """The ``sigma_a(λ)`` to render spectrally: mapped from Table 1 parameters (``render.spectra``), or
    given directly (finite values >= 0 on ``render.spectra.WAVELENGTHS``)."""
    from hairdigi.render.spectra import WAVELENGTHS, hair_sigma_a_spectrum

    if isinstance(hair, HairParams):
        return hair_sigma_a_spectrum(hair)
    sigma = np.asarray(hair, dtype=float).ravel()
    if sigma.shape != WAVELENGTHS.shape or not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
        raise ValueError(f"a spectral render takes Table 1 parameters or sigma_a as {len(WAVELENGTHS)} finite "
                         f"values >= 0 on render.spectra.WAVELENGTHS (360-830 nm every 5 nm), got shape {sigma.shape}")
    return sigma


def strands_for(spec: SceneSpec) -> Strands:
    if spec.kind is SceneKind.SWATCH:
        if spec.swatch_model is SwatchModel.LAYERED:
            return layered_swatch_strands(spec.n_strands, seed=spec.strand_seed, radius=layered_radius(spec.n_strands))
        if spec.swatch_model is SwatchModel.TODAY:
            return swatch_strands(spec.n_strands, seed=spec.strand_seed)
        return structure_strands(spec.swatch_model, spec.n_strands, seed=spec.strand_seed)
    if spec.kind is SceneKind.HAIR_FILE:
        return hair_model_strands(spec.hair_file, spec.n_strands, seed=spec.strand_seed)
    return hairstyle_strands(spec.name, spec.n_strands, seed=spec.strand_seed)


@dataclass
class _Loaded:
    scene: object
    params: object
    strand_seed: int
    camera: rig_geometry.CameraPose
    keys: dict = field(default_factory=dict)


#: One render at a time in the whole process, whatever the ``Renderer``: two renders at once, even on
#: separate Renderers and scenes, crash Dr.Jit's LLVM backend (measured: "jit_llvm_compile(): module
#: could not be verified", then a segmentation fault, within 3 rounds of a twin, a hairstyle and
#: refinement rendered side by side). Re-entrant: a render may build a scene under it.
RENDER_LOCK = threading.RLock()


@dataclass
class RenderTally:
    """What the process's Mitsuba renders did, all of them (``trace`` counts under :data:`RENDER_LOCK`)."""

    renders: int = 0     # calls of ``trace``: a render split in passes is one
    nonfinite: int = 0   # NaN or Inf values they returned, each replaced by 0


#: Every render of the process goes through ``trace``, which adds itself here: whatever drops a result's
#: ``nonfinite`` (a table's mean, a light image), the process's count of NaN and Inf values keeps it.
TALLY = RenderTally()


class Renderer:
    """Holds loaded Mitsuba scenes and re-renders them with new hair parameters, cameras and lights.

    Thread-safe: every render in the process, on any ``Renderer``, takes :data:`RENDER_LOCK` (scenes
    are updated in place, and Dr.Jit's LLVM backend runs one render at a time); a progressive render
    lets others in between its passes. ``builds`` counts the scenes built (an update is not a build).
    """

    def __init__(self, max_cached: int = 4) -> None:
        self.variant = select_variant()   # the entry point's choice, or the first that works
        self.builds = 0
        self._cache: dict[tuple, _Loaded] = {}
        self._max_cached = max_cached
        self._tmp = tempfile.TemporaryDirectory(prefix="hairdigi-curves-")

    # -- scene cache -------------------------------------------------------------------------
    def _structure_key(self, spec: SceneSpec, size: int) -> tuple:
        key = (spec.name, spec.env, spec.framing, spec.n_strands, spec.depth, size, spec.chart,
               spec.target, spec.half_width, spec.chart_center, spec.crop, spec.groups, spec.swatch_model)
        if spec.groups:   # which strands are grey or in which group is structure: a new share is a new scene
            key += (round(spec.look.grey_fraction, 4), spec.strand_seed)
        if spec.hair_file is not None:   # a model saved again is loaded again
            stat = os.stat(spec.hair_file)
            key += (spec.hair_file, stat.st_mtime_ns, stat.st_size)
        if not is_jit():  # scalar_rgb cannot swap curves in memory: a new layout means a new scene
            key += (spec.strand_seed,)
        return key

    def _scene_dict(self, spec: SceneSpec, size: int, bsdf: dict) -> tuple[dict, list[Path]]:
        """The scene dict of ``spec`` and the curve files it reads (delete them once it is loaded)."""
        curve_file = Path(self._tmp.name) / f"curves-{len(self._cache)}-{time.monotonic_ns()}.txt"
        curve_file.write_text(strands_for(spec).with_dummy().to_curve_text())
        if spec.kind is SceneKind.SWATCH:
            chart = None if spec.chart is None else np.asarray(spec.chart)
            moved = chart is not None and spec.chart_center is not None
            scene_dict = scenes.swatch_scene(str(curve_file), bsdf, spec.pose, size, spec.framing, spec.depth,
                                             spec.lights, None if moved else chart, spec.target, spec.half_width,
                                             spec.crop, spec.env)
            if moved:
                scene_dict.update(scenes.chart_patches(chart, center=tuple(spec.chart_center)))
        else:
            scene_dict = scenes.portrait_scene(str(curve_file), bsdf, size, spec.env, spec.pose, spec.depth,
                                               part_x=STYLES[spec.name].part_x if spec.name in STYLES else None)
        files = [curve_file]
        if spec.groups:   # fibre groups: one curve shape and BSDF each, keyed by render.fibres.group_keys
            del scene_dict["hair"]
            parts = split_strands(strands_for(spec), spec.groups, spec.look.grey_fraction, spec.strand_seed)
            for key, part in zip(group_keys(spec.groups), parts):
                path = curve_file.with_name(f"{curve_file.stem}-{key}.txt")
                path.write_text(part.with_dummy().to_curve_text())
                scene_dict[key] = scenes.hair_shape(str(path), dict(bsdf))
                files.append(path)
        return scene_dict, files

    def _build(self, spec: SceneSpec, size: int, params: HairParams) -> _Loaded:
        self.builds += 1
        bsdf = hair_bsdf(params if isinstance(params, HairParams) else HairParams())  # sigma_a set on update
        scene_dict, files = self._scene_dict(spec, size, bsdf)
        scene = load_scene(scene_dict)
        for path in files:
            path.unlink(missing_ok=True)
        return _Loaded(scene, mi.traverse(scene), spec.strand_seed, spec.pose)

    def _scene_for(self, spec: SceneSpec, size: int, params: HairParams):
        key = self._structure_key(spec, size)
        loaded = self._cache.get(key)
        if loaded is None:
            if len(self._cache) >= self._max_cached:
                self._cache.pop(next(iter(self._cache)))
            loaded = self._cache[key] = self._build(spec, size, params)
        self._update(loaded, spec, params)
        return loaded.scene

    def _update(self, loaded: _Loaded, spec: SceneSpec, params: HairParams) -> None:
        p = loaded.params
        look = spec.look
        sigma = absorption_of(params)
        keys = group_keys(spec.groups) if spec.groups else ("hair",)
        for key, value in zip(keys, group_sigma_a(sigma, spec.groups, look.fibre_spread) if spec.groups else [sigma]):
            p[f"{key}.bsdf.sigma_a.value"] = mi.Color3f(*np.asarray(value, float).tolist())
            p[f"{key}.bsdf.longitudinal_roughness"] = float(look.longitudinal_roughness)
        if "scalp.bsdf.reflectance.value" in p:   # portraits: the scalp under the hair takes its colour
            p["scalp.bsdf.reflectance.value"] = mi.Color3f(*scenes.scalp_albedo(absorption_of(params)))
        swatch = spec.kind is SceneKind.SWATCH
        if swatch:
            for i, scale in enumerate(spec.lights):
                p[f"light{i}.emitter.radiance.value"] = mi.Color3f([scenes.LIGHT_RADIANCE * float(scale)] * 3)
        if spec.pose != loaded.camera:
            target = spec.target if swatch else scenes.PORTRAIT_TARGET
            position = spec.pose.position(target) if swatch else scenes.portrait_camera_position(spec.pose)
            p["sensor.to_world"] = mi.AffineTransform4f(scenes.look_at(position, np.asarray(target)).matrix)
            # the field of view follows the distance (the framing is fixed at the holder)
            p["sensor.x_fov"] = (rig_geometry.framing_fov(spec.framing, spec.pose.distance, spec.half_width)
                                 if swatch else scenes.PORTRAIT_FOV)
            loaded.camera = spec.pose
        if spec.strand_seed != loaded.strand_seed and not spec.groups:   # groups: a new layout is a new scene
            strands = strands_for(spec).with_dummy()
            p["hair.control_point_count"] = int(len(strands.points))
            p["hair.control_points"] = mi.Float(strands.control_points())
            p["hair.segment_indices"] = mi.UInt32(strands.segment_indices())
            loaded.strand_seed = spec.strand_seed
        p.update()

    # -- rendering ---------------------------------------------------------------------------
    def render(self, params: HairParams, spec: SceneSpec | str = "swatch",
               size: int | tuple[int, int] | None = None, spp: int | None = None, seed: int = 0) -> RenderResult:
        """Path-trace ``params`` in ``spec``; returns linear float32 RGB and an sRGB 8-bit image.

        ``params`` is ``HairParams`` or, for refinement by synthesis, an RGB ``sigma_a`` array.

        ``size`` is the side of a square image, or (width, height).
        """
        spec, size, spp = self._request(spec, size, spp)
        with RENDER_LOCK:
            start, cpu = time.perf_counter(), time.process_time()
            if spec.illuminant is None:
                scene = self._scene_for(spec, size, params)
                linear, nonfinite = trace(scene, size, spp, int(seed))
            else:
                linear, nonfinite = self._render_spectral(params, spec, size, spp, int(seed))
            seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        return RenderResult(linear, linear_to_srgb8(linear), seconds, spp, cpu, nonfinite)

    def _render_spectral(self, params: HairParams | np.ndarray, spec: SceneSpec, size, spp: int,
                         seed: int) -> tuple[np.ndarray, int]:
        """``spec`` rendered by the spectral twin of the variant under ``spec.illuminant``, seen by the CIE
        1931 observer (linear sRGB). Built for each call: a spectral scene is not cached."""
        from hairdigi.render.spectra import camera_bands, illuminant_spd, rgb_projection

        sigma = spectral_absorption_of(params)
        keys = group_keys(spec.groups) if spec.groups else ("hair",)
        values = group_sigma_a(sigma, spec.groups, spec.look.fibre_spread) if spec.groups else [sigma]
        bsdf = hair_bsdf(HairParams(), spec.look.longitudinal_roughness)
        with mi.variant_context(spectral_variant()):
            scene_dict, files = self._scene_dict(spec, size, bsdf)
            if "scalp" in scene_dict:   # portraits: the scalp under the hair takes its colour
                scene_dict["scalp"]["bsdf"]["reflectance"]["value"] = scenes.scalp_albedo(rgb_projection(sigma))
            chart = colorchecker_spectra() if is_colorchecker(spec.chart) else None   # its measured spectra
            scenes.spectralise(scene_dict, dict(zip(keys, values)), illuminant_spd(spec.illuminant), chart)
            if spec.sensitivities is not None:
                scenes.camera_film(scene_dict["sensor"], camera_bands(spec.sensitivities))
            try:
                scene = load_scene(scene_dict)
            finally:
                for path in files:
                    path.unlink(missing_ok=True)
            return trace(scene, size, spp, seed)

    def render_aov(self, params: HairParams, spec: SceneSpec | str, aovs: str,
                   size: int | tuple[int, int] | None = None, spp: int = 1, seed: int = 3) -> RenderResult:
        """Mitsuba's ``aov`` integrator (``aovs`` as it takes them, e.g. ``"albedo:albedo,nn:sh_normal"``)
        on the cached scene of ``spec``: the channels of each AOV side by side in ``linear``."""
        spec, size, spp = self._request(spec, size, spp)
        with RENDER_LOCK:
            start, cpu = time.perf_counter(), time.process_time()
            scene = self._scene_for(spec, size, params)
            linear, nonfinite = trace(scene, size, spp, int(seed), mi.load_dict({"type": "aov", "aovs": aovs}))
            seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
        return RenderResult(linear, linear_to_srgb8(linear[..., :3]), seconds, spp, cpu, nonfinite)

    @staticmethod
    def _request(spec: SceneSpec | str, size, spp) -> tuple[SceneSpec, int | tuple[int, int], int]:
        if isinstance(spec, str):
            spec = SceneSpec(name=spec)
        size = defaults_for(spec.name).size if size is None else size
        spp = defaults_for(spec.name).spp if spp is None else spp
        check_size_spp(size, spp)
        size = (int(size[0]), int(size[1])) if isinstance(size, (tuple, list)) else int(size)
        return spec, size, int(spp)

    def render_progressive(self, params: HairParams, spec: SceneSpec | str, size: int | tuple[int, int] | None = None,
                           spp_per_pass: int | Sequence[int] = 2, passes: int = 8, seed: int = 0,
                           cancelled: Callable[[], bool] = lambda: False,
                           gate: Callable[[], None] | None = None) -> Iterator[RenderResult]:
        """Render in passes with new seeds, yielding the running mean (weighted by spp) after each.

        ``spp_per_pass``: the spp of every pass (``passes`` of them), or one spp per pass. ``gate()``
        runs before each pass and may wait (a hairstyle lets the twin go first); ``cancelled()`` is
        checked after it: a cancelled render stops before its next pass. ``nonfinite`` adds up.
        """
        schedule = [int(spp_per_pass)] * passes if isinstance(spp_per_pass, (int, np.integer)) else list(spp_per_pass)
        total, spp, nonfinite, cpu = None, 0, 0, 0.0
        start = time.perf_counter()
        for i, n in enumerate(schedule):
            if gate is not None:
                gate()
            if cancelled():
                return
            result = self.render(params, spec, size, n, seed=seed * 1_000_003 + i)
            total = result.linear * n if total is None else total + result.linear * n
            spp, nonfinite, cpu = spp + n, nonfinite + result.nonfinite, cpu + result.cpu_seconds
            mean = (total / spp).astype(np.float32)
            yield RenderResult(mean, linear_to_srgb8(mean), time.perf_counter() - start, spp, cpu, nonfinite)


#: Renders over this many samples (pixels x spp) run as passes of at most ``PASS_SAMPLES``: a JIT
#: variant runs one ``mi.render`` as one native kernel that Ctrl-C cannot stop (the LLVM variant
#: replaced scalar_rgb, whose block loop could), and Python raises KeyboardInterrupt between passes.
SPLIT_ABOVE = 1 << 20
PASS_SAMPLES = 1 << 16


def render_in_passes(scene, size: int | tuple[int, int], spp: int, seed: int):
    """``mi.render(scene, spp, seed)``; above ``SPLIT_ABOVE`` samples, passes with derived seeds, averaged
    weighted by their spp (deterministic: the split depends on the size and spp alone)."""
    width, height = (size, size) if isinstance(size, int) else size
    if width * height * spp <= SPLIT_ABOVE:
        with sigint_held():   # Ctrl-C waits for the call, then is a KeyboardInterrupt (render.domain.interrupt)
            return mi.render(scene, spp=spp, seed=seed)   # as before: one call
    per_pass = max(1, PASS_SAMPLES // (width * height))
    total, done, k = None, 0, 0
    while done < spp:
        n = min(per_pass, spp - done)
        with sigint_held():
            image = np.asarray(mi.render(scene, spp=n, seed=(seed * 1_000_003 + 7_919 * k) % (1 << 32)), np.float64)
        total = image * n if total is None else total + image * n
        done, k = done + n, k + 1
    return (total / spp).astype(np.float32)


@contextlib.contextmanager
def _collector_paused():
    """Python's cyclic garbage collector off for the block (on again after, where it was on)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def trace(scene, size: int | tuple[int, int], spp: int, seed: int, integrator=None) -> tuple[np.ndarray, int]:
    """The one call of Mitsuba's path tracer in hairdigi: a loaded ``scene`` rendered under :data:`RENDER_LOCK`
    (``render_in_passes``; with an ``integrator``, such as an AOV one, in one call), its NaN and Inf values
    counted and replaced by 0 (``finite_image``) and added to :data:`TALLY`. The image and that count.
    Python's cyclic garbage collector waits while it renders: run from another thread, it would free an unreachable
    Mitsuba object (a dropped renderer's scene) while Dr.Jit's registry is in use ("jit_registry_id: pointer is not
    registered", then a crash: two threads' renders under the full test suite)."""
    with RENDER_LOCK, _collector_paused():
        if integrator is None:
            image = render_in_passes(scene, size, spp, seed)
        else:
            with sigint_held():
                image = mi.render(scene, integrator=integrator, spp=spp, seed=seed)
        linear, nonfinite = finite_image(image)
        TALLY.renders += 1
        TALLY.nonfinite += nonfinite
    return linear, nonfinite


def render_scene(scene_dict: dict, size: int | tuple[int, int], spp: int, seed: int) -> tuple[np.ndarray, int]:
    """A scene dict that ``SceneSpec`` cannot describe (the Blender check's Mitsuba twin: its own strands and
    BSDF) on the one path: loaded in its dict's order (``variant.load_scene``: one image per seed) and
    rendered by ``trace``, all under :data:`RENDER_LOCK`. The image and its NaN/Inf count."""
    with RENDER_LOCK:
        return trace(load_scene(scene_dict), size, spp, int(seed))


def finite_image(image) -> tuple[np.ndarray, int]:
    """A rendered image as float32 with NaN and Inf replaced by 0, and how many values were replaced."""
    linear = np.array(image, dtype=np.float32)
    nonfinite = int(linear.size - np.count_nonzero(np.isfinite(linear)))
    if nonfinite:   # counted, then replaced, so a NaN never reaches a PNG or a mean unseen
        linear = np.nan_to_num(linear, nan=0.0, posinf=0.0, neginf=0.0)
    return linear, nonfinite


_DEFAULT: Renderer | None = None


def default_renderer() -> Renderer:
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = Renderer()
    return _DEFAULT


def render(params: HairParams, scene: SceneSpec | str = "swatch", size: int | None = None,
           spp: int | None = None, seed: int = 0) -> RenderResult:
    """Render with the process-wide :class:`Renderer`, reusing its loaded scenes."""
    return default_renderer().render(params, scene, size, spp, seed)

