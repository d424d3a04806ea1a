"""``render(params, scene, size, spp, seed)``: hair parameters and a scene in, a path-traced image out.

Loaded scenes are cached. When only the hair parameters, the camera, the light intensities or (in
the JIT variants) the strand layout change, the cached scene is updated through ``mi.traverse``
instead of being rebuilt, which is what makes rendering thousands of dataset swatches cheap.

A scene is one of ``render.scene_kinds``'s types (the swatch, a hairstyle, a ``.hair`` model; ``SceneSpec``
builds one by name), which makes its own Mitsuba scene dict and updates its own parameters: the renderer
draws any kind alike, holding only what every kind shares (the hair's absorption, its fibre groups, the
strand layout, the cache).
"""
from __future__ import annotations

import contextlib
import gc
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np

from hairdigi.render.domain import rig_geometry
# Bounds, defaults and their checks: in render.domain.bounds, so the command line reads them without Mitsuba.
from hairdigi.render.domain.bounds import check_size_spp, defaults_for  # noqa: F401  (defaults_for: read from here)
from hairdigi.render import scenes
from hairdigi.render.domain.absorption import hair_bsdf, hair_sigma_a
from hairdigi.render.domain.interrupt import sigint_held
from hairdigi.render.domain.params import HairParams
from hairdigi.render.fibres import group_keys, group_sigma_a, split_strands
# The kinds of scene, each a type owning its fields, its scene dict and its update (render.scene_kinds).
from hairdigi.render.scene_kinds import (DEFAULT_SWATCH_MODEL, SCENE_TYPES, HairFileScene,  # noqa: F401
                                         HairstyleScene, Scene, SceneError, SceneSpec, SwatchScene)
from hairdigi.render.spectra import WAVELENGTHS, camera_bands, hair_sigma_a_spectrum, illuminant_spd
from hairdigi.render.srgb import linear_to_srgb8
from hairdigi.render.strands import Strands
from hairdigi.render.variant import is_jit, load_scene, mi, select_variant, spectral_variant


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
    if isinstance(hair, HairParams):
        return hair_sigma_a_spectrum(hair)
    sigma = np.asarray(hair, dtype=float).ravel()
    if sigma.shape != WAVELENGTHS.shape or not np.all(np.isfinite(sigma)) or np.any(sigma < 0):
        raise ValueError(f"a spectral render takes Table 1 parameters or sigma_a as {len(WAVELENGTHS)} finite "
                         f"values >= 0 on render.spectra.WAVELENGTHS (360-830 nm every 5 nm), got shape {sigma.shape}")
    return sigma


def strands_for(spec: Scene) -> Strands:
    """The strands of ``spec``: its kind's (``Scene.make_strands``)."""
    return spec.make_strands()


def _set_strands(params, key: str, strands: Strands) -> None:
    """Set the hair shape ``key``'s strands (its dummy strand appended: ``Strands.with_dummy``) through ``mi.traverse``'s
    ``params`` (JIT variants; ``params.update()`` applies them). A scene is loaded from a one-strand curve file and
    its strands set so: writing and parsing the curve text took 0.4-1 s of a build (``shared/reference``'s Mitsuba
    notes: 0.02 s in memory against 0.6 s through a file for 20k strands), and the renders are the same to the bit
    (``tests/test_render.py``)."""
    strands = strands.with_dummy()
    params[f"{key}.control_point_count"] = int(len(strands.points))
    params[f"{key}.control_points"] = mi.Float(strands.control_points())
    params[f"{key}.segment_indices"] = mi.UInt32(strands.segment_indices())


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
    def _structure_key(self, spec: Scene, size: int | tuple[int, int]) -> tuple:
        """What a loaded scene of ``spec`` at ``size`` is cached by: its kind's ``shape_key``, and what else a
        change of would rebuild it rather than update it."""
        key = spec.shape_key() + (size,)
        if spec.groups:   # which strands are grey or in which group is structure: a new share is a new scene
            key += (round(spec.look.grey_fraction, 4), spec.strand_seed)
        if not is_jit():  # scalar_rgb cannot swap curves in memory: a new layout means a new scene
            key += (spec.strand_seed,)
        return key

    def _scene_dict(self, spec: Scene, size: int | tuple[int, int], bsdf: dict, in_memory: bool = False
                    ) -> tuple[dict, list[Path], dict[str, Strands]]:
        """The scene dict of ``spec`` (its kind's ``scene_dict``, its hair split into fibre groups where its
        appearance asks), the curve files it reads (delete them once it is loaded), and each hair shape's strands
        where they are to be set in memory once it is loaded (``in_memory``, a JIT variant: ``_set_strands``);
        without, the curve files hold them."""
        curve_file = Path(self._tmp.name) / f"curves-{len(self._cache)}-{time.monotonic_ns()}.txt"
        strands = strands_for(spec)
        shapes = {"hair": strands} if not spec.groups else dict(zip(
            group_keys(spec.groups), split_strands(strands, spec.groups, spec.look.grey_fraction, spec.strand_seed)))

        def written(key: str, part: Strands) -> str:
            path = curve_file if key == "hair" else curve_file.with_name(f"{curve_file.stem}-{key}.txt")
            path.write_text((part.subset(np.arange(min(1, len(part.counts)))) if in_memory else part)
                            .with_dummy().to_curve_text())
            files.append(path)
            return str(path)

        files: list[Path] = []
        scene_dict = spec.scene_dict(written("hair", strands) if not spec.groups else str(curve_file), bsdf, size)
        if spec.groups:   # fibre groups: one curve shape and BSDF each, keyed by render.fibres.group_keys
            del scene_dict["hair"]
            for key, part in shapes.items():
                scene_dict[key] = scenes.hair_shape(written(key, part), dict(bsdf))
        return scene_dict, files, shapes if in_memory else {}

    def _build(self, spec: Scene, size: int | tuple[int, int], params: HairParams) -> _Loaded:
        self.builds += 1
        bsdf = hair_bsdf(params if isinstance(params, HairParams) else HairParams())  # sigma_a set on update
        scene_dict, files, shapes = self._scene_dict(spec, size, bsdf, in_memory=is_jit())
        try:
            scene = load_scene(scene_dict)
        finally:
            for path in files:
                path.unlink(missing_ok=True)
        loaded = _Loaded(scene, mi.traverse(scene), spec.strand_seed, spec.pose)
        if shapes:
            for key, part in shapes.items():
                _set_strands(loaded.params, key, part)
            loaded.params.update()
        return loaded

    def _scene_for(self, spec: Scene, size: int | tuple[int, int], params: HairParams):
        key = self._structure_key(spec, size)
        loaded = self._cache.get(key)
        if loaded is None:
            if len(self._cache) >= self._max_cached:
                self._cache.pop(next(iter(self._cache)))
            loaded = self._cache[key] = self._build(spec, size, params)
        self._update(loaded, spec, params)
        return loaded.scene

    def _update(self, loaded: _Loaded, spec: Scene, params: HairParams) -> None:
        """The hair's absorption and shine, the strand layout, and (``Scene.update``) what the kind owns:
        the camera, its lights, the scalp."""
        p = loaded.params
        look = spec.look
        sigma = absorption_of(params)
        keys = group_keys(spec.groups) if spec.groups else ("hair",)
        for key, value in zip(keys, group_sigma_a(sigma, spec.groups, look.fibre_spread) if spec.groups else [sigma]):
            p[f"{key}.bsdf.sigma_a.value"] = mi.Color3f(*np.asarray(value, float).tolist())
            p[f"{key}.bsdf.longitudinal_roughness"] = float(look.longitudinal_roughness)
        moved = spec.pose != loaded.camera
        spec.update(p, sigma, moved)
        if moved:
            loaded.camera = spec.pose
        if spec.strand_seed != loaded.strand_seed and not spec.groups:   # groups: a new layout is a new scene
            _set_strands(p, "hair", strands_for(spec))
            loaded.strand_seed = spec.strand_seed
        p.update()

    # -- rendering ---------------------------------------------------------------------------
    def render(self, params: HairParams, spec: Scene | str = "swatch",
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

    def _render_spectral(self, params: HairParams | np.ndarray, spec: Scene, size, spp: int,
                         seed: int) -> tuple[np.ndarray, int]:
        """``spec`` rendered by the spectral twin of the variant under ``spec.illuminant``, seen by the CIE
        1931 observer (linear sRGB). Built for each call: a spectral scene is not cached."""
        sigma = spectral_absorption_of(params)
        keys = group_keys(spec.groups) if spec.groups else ("hair",)
        values = group_sigma_a(sigma, spec.groups, spec.look.fibre_spread) if spec.groups else [sigma]
        bsdf = hair_bsdf(HairParams(), spec.look.longitudinal_roughness)
        with mi.variant_context(spectral_variant()):
            scene_dict, files, _ = self._scene_dict(spec, size, bsdf)
            spec.spectralise(scene_dict, sigma, dict(zip(keys, values)), illuminant_spd(spec.illuminant))
            if spec.sensitivities is not None:
                scenes.camera_film(scene_dict["sensor"], camera_bands(spec.sensitivities))
            try:
                scene = load_scene(scene_dict)
            finally:
                for path in files:
                    path.unlink(missing_ok=True)
            return trace(scene, size, spp, seed)

    def render_aov(self, params: HairParams, spec: Scene | str, aovs: str,
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
    def _request(spec: Scene | str, size, spp) -> tuple[Scene, int | tuple[int, int], int]:
        if isinstance(spec, str):
            spec = SceneSpec(name=spec)
        elif not isinstance(spec, Scene):
            raise SceneError(f"a scene is a render.scene_kinds.Scene (SceneSpec builds one) or a scene's name, "
                             f"not a {type(spec).__name__}")
        size = spec.defaults.size if size is None else size
        spp = spec.defaults.spp if spp is None else spp
        check_size_spp(size, spp)
        size = (int(size[0]), int(size[1])) if isinstance(size, (tuple, list)) else int(size)
        return spec, size, int(spp)

    def render_progressive(self, params: HairParams, spec: Scene | str, size: int | tuple[int, int] | None = None,
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


def render(params: HairParams, scene: Scene | str = "swatch", size: int | None = None,
           spp: int | None = None, seed: int = 0) -> RenderResult:
    """Render with the process-wide :class:`Renderer`, reusing its loaded scenes."""
    return default_renderer().render(params, scene, size, spp, seed)

