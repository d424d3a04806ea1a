"""The synthetic swatch dataset: uniform Table 1 parameters, random cameras, rendered in shards.

Sample ``i`` of a dataset with seed ``s`` is drawn from ``np.random.default_rng([s, i])`` alone, so a
sample is the same whatever the worker count, the shard size, or how often the run was resumed.
Each shard is one ``.npz`` (images, normalised parameters, cameras, seeds) written atomically when
complete; a restarted run renders only the shards that are missing. Shards are rendered by local
worker processes or by Ray tasks on a cluster (``inference.training.cluster``), through one function,
``render_shard``, so a dataset is bitwise the same on either backend.

Images are stored as ``linear16``: linear HDR radiance in float16, as the renderer computes it, so
that training can apply the capture chain (exposure, colour error, sensor noise, 8-bit sRGB) the
way a camera does (``render.camera_model``). The older ``srgb8`` store (8-bit sRGB, clipped before
averaging, and so darker than the scene at low spp) is still read.
"""
from __future__ import annotations

import ctypes
import json
import multiprocessing as mp
import os
import signal
import sys
import time
import zipfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from hairdigi.inference.training.cluster import check_address, render_shards, require_ray
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance, sample_appearance
from hairdigi.render.domain.bounds import SwatchModel
from hairdigi.render.domain.appearance import FIELDS as APPEARANCE_FIELDS
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import atomic_path, read_json, write_json_atomic
from hairdigi.render.domain.interrupt import sigint_held

from hairdigi.render.domain.params import HairParams, sample_params
from hairdigi.render.domain.rig_geometry import (CAMERA_DISTANCE, FRAMING_HALF_WIDTH, CameraPose, Framing,
                                                 light_blocks_view)

MANIFEST = "manifest.json"
STORES = ("linear16", "srgb8")
#: Settings added after datasets were made, with the value those older datasets implicitly used.
LEGACY_DEFAULTS = {"store": "srgb8", "swatch_model": "today", "appearance": "fixed"}
#: How a sample's appearance (shine, fibre spread, greys) is drawn: ``fixed`` is the default uniform
#: hair (datasets made before appearance was drawn); ``random`` draws ``render.domain.appearance.APPEARANCE_DRAW``.
APPEARANCES = ("random", "fixed")


@dataclass(frozen=True)
class DatasetConfig:
    """How a dataset is drawn and rendered; stored in its manifest and checked on resume."""

    n: int
    size: int = 128
    spp: int = 8
    seed: int = 0
    polar_max_deg: float = 45.0
    distance_jitter: float = 0.1
    strands: int | None = None
    max_depth: int | None = None
    framing: Framing = Framing.CROP
    shard_size: int = 100
    store: str = "linear16"   # "linear16": linear float16 radiance; "srgb8": 8-bit sRGB (older datasets)
    swatch_model: SwatchModel = SwatchModel.LAYERED
    appearance: str = "random"      # APPEARANCES

    def __post_init__(self) -> None:
        if self.store not in STORES:
            raise DatasetError(f"dataset store {self.store!r} is not one of {', '.join(STORES)}")
        if not SwatchModel.knows(self.swatch_model):
            raise DatasetError(f"dataset swatch_model {self.swatch_model!r} is not one of "
                               f"{', '.join(SwatchModel.names())}")
        if not Framing.knows(self.framing):
            raise DatasetError(f"dataset framing {self.framing!r} is not one of {', '.join(Framing.names())}")
        object.__setattr__(self, "swatch_model", SwatchModel(self.swatch_model))
        object.__setattr__(self, "framing", Framing(self.framing))
        if self.appearance not in APPEARANCES:
            raise DatasetError(f"dataset appearance {self.appearance!r} is not one of {', '.join(APPEARANCES)}")
        for name, low in (("size", 8), ("spp", 1), ("n", 1), ("shard_size", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise DatasetError(f"dataset {name} must be a whole number >= {low}, got {value!r}")

    @property
    def n_shards(self) -> int:
        return (self.n + self.shard_size - 1) // self.shard_size


@dataclass(frozen=True)
class SampleSpec:
    index: int
    params: HairParams
    camera: CameraPose
    strand_seed: int
    render_seed: int
    look: Appearance = DEFAULT_APPEARANCE


def sample_spec(config: DatasetConfig, index: int) -> SampleSpec:
    """The parameters, camera and seeds of sample ``index``: uniform parameters, camera uniform on the cap.

    A camera drawn behind one of the rig lights (about 3% of a 45° cap) would see the light's dark
    back; it is drawn again from a generator of its own, so every other sample is unchanged.
    """
    rng = np.random.default_rng([config.seed, index])
    params = sample_params(rng)
    camera = _draw_camera(config, rng)
    strand_seed, render_seed = (int(v) for v in rng.integers(0, 2**31 - 1, size=2))
    retry = 0
    while not camera_is_clear(camera, config.framing):
        retry += 1
        if retry > 100:
            raise ValueError(f"polar_max_deg {config.polar_max_deg} leaves almost no camera clear of the "
                             "rig lights; use a smaller cap (45° is the default)")
        camera = _draw_camera(config, np.random.default_rng([config.seed, index, retry]))
    # drawn last, so a dataset of fixed appearance keeps the samples it had before appearances were drawn
    look = sample_appearance(rng) if config.appearance == "random" else DEFAULT_APPEARANCE
    return SampleSpec(index, params, camera, strand_seed, render_seed, look)


def camera_is_clear(camera: CameraPose, framing: Framing = Framing.CROP) -> bool:
    """Whether the camera sees the framed swatch rather than the back of a rig light."""
    return not light_blocks_view(camera, FRAMING_HALF_WIDTH[Framing(framing)])


def usable(cameras: np.ndarray, framing: Framing = Framing.CROP) -> np.ndarray:
    """Mask of stored samples (rows of polar°, azimuth°, distance) whose camera is clear of the lights.

    Datasets drawn before ``sample_spec`` redrew blocked cameras hold about 3% of them (black or part
    black images with arbitrary labels); training skips them.
    """
    return np.array([camera_is_clear(CameraPose(*c), framing) for c in cameras], dtype=bool)


def _draw_camera(config: DatasetConfig, rng: np.random.Generator) -> CameraPose:
    cos_max = np.cos(np.radians(config.polar_max_deg))
    polar = float(np.degrees(np.arccos(rng.uniform(cos_max, 1.0))))  # uniform over the cap's area
    azimuth = float(rng.uniform(0.0, 360.0))
    distance = CAMERA_DISTANCE * float(rng.uniform(1 - config.distance_jitter, 1 + config.distance_jitter))
    return CameraPose(polar, azimuth, distance)


def shard_path(root: Path, shard: int) -> Path:
    return root / f"shard-{shard:05d}.npz"


def _die_with_parent() -> None:
    """Pool initializer: on Linux, end this worker when the parent dies, even by SIGKILL, so no
    orphan keeps rendering for a stopped run."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


#: The arrays of a shard file, in the order they are written.
#: ``nonfinite``: per sample, the NaN or Inf values the path tracer returned (replaced by 0 in ``images``).
SHARD_FIELDS = ("images", "params", "cameras", "seeds", "indices", "nonfinite")
#: Arrays written since appearance was drawn and absent from older shards: ``appearance`` (N, 3), the sample's
#: shine, fibre spread and grey share (``render.domain.appearance.FIELDS``).
OPTIONAL_FIELDS = ("appearance",)
#: Where shards are rendered: ``local`` processes, or ``ray`` tasks (``inference.training.cluster``).
BACKENDS = ("local", "ray")


def shard_indices(config: DatasetConfig, shard: int) -> range:
    """The sample indices of shard ``shard``."""
    return range(shard * config.shard_size, min(config.n, (shard + 1) * config.shard_size))


_RENDERERS: dict = {}


def _renderer():
    """This process's renderer for the current Mitsuba variant; its loaded scene is reused by every
    sample of a shard and by the next shard."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import Renderer, default_renderer
    from hairdigi.render.variant import mi

    renderer = default_renderer()
    if renderer.variant != mi.variant():   # the variant was switched after the default one was made
        if mi.variant() not in _RENDERERS:
            _RENDERERS[mi.variant()] = Renderer()
        renderer = _RENDERERS[mi.variant()]
    return renderer


def scene_of(config: DatasetConfig, index: int):
    """Sample ``index``'s scene (camera, strand layout, framing): the one way from a sample to a scene."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec

    s = sample_spec(config, index)
    return SceneSpec("swatch", camera=s.camera, framing=config.framing, strands=config.strands,
                     strand_seed=s.strand_seed, max_depth=config.max_depth, swatch_model=config.swatch_model,
                     appearance=None if s.look == DEFAULT_APPEARANCE else s.look)


def render_shard(config: DatasetConfig, shard: int, variant: str | None = None,
                 threads: int = 0) -> dict[str, np.ndarray]:
    """Render shard ``shard`` in this process and return its arrays (``SHARD_FIELDS``).

    The one rendering core of every backend: the local pool writes what it returns with
    ``write_shard`` in the worker, Ray tasks return it to the driver, which writes it. ``variant``
    sets Mitsuba's variant first (None: the one set); ``threads`` > 0 sets drjit's thread count.
    """
    if threads:
        # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
        import drjit as dr

        with sigint_held():   # new pool threads never take Ctrl-C (render.domain.interrupt)
            dr.set_thread_count(threads)
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.variant import select_variant

    if variant is not None:
        select_variant(variant)
    indices = shard_indices(config, shard)
    images, vectors, cameras, seeds, nonfinite, looks = [], [], [], [], [], []
    renderer = _renderer()
    for i in indices:
        s = sample_spec(config, i)
        result = renderer.render(s.params, scene_of(config, i), config.size, config.spp, s.render_seed)
        images.append(result.linear.astype(np.float16) if config.store == "linear16" else result.srgb)
        vectors.append(s.params.to_vector())
        cameras.append([s.camera.polar_deg, s.camera.azimuth_deg, s.camera.distance])
        seeds.append([s.strand_seed, s.render_seed])
        nonfinite.append(result.nonfinite)
        looks.append([getattr(s.look, f) for f in APPEARANCE_FIELDS])
    return {"images": np.stack(images), "params": np.stack(vectors), "cameras": np.array(cameras),
            "seeds": np.array(seeds, dtype=np.int64), "indices": np.array(list(indices)),
            "nonfinite": np.array(nonfinite, dtype=np.int64), "appearance": np.array(looks, dtype=np.float32)}


def write_shard(root: str | os.PathLike, shard: int, arrays: dict[str, np.ndarray]) -> Path:
    """Write a shard's arrays to ``shard-NNNNN.npz`` in ``root`` atomically (a temporary file, renamed)."""
    path = shard_path(Path(root), shard)
    with atomic_path(path, ".npz") as tmp:
        np.savez(tmp, **{name: arrays[name] for name in SHARD_FIELDS + OPTIONAL_FIELDS if name in arrays})
    return path


class DatasetError(HairdigiError, ValueError):
    """A dataset's file is damaged or not what it should be; the message names the file and the fix."""


def read_shard(path: Path, expected: range | None = None) -> dict[str, np.ndarray]:
    """A shard's arrays (``SHARD_FIELDS``); a truncated, garbage or mismatched file raises DatasetError
    naming it. ``expected``: the sample indices it must hold."""
    fix = "delete it and run hairdigi dataset again with the same settings to render it again"
    try:
        with np.load(path, allow_pickle=False) as npz:
            missing = [name for name in SHARD_FIELDS if name not in npz.files]
            if missing:
                raise DatasetError(f"{path}: damaged dataset shard (no {', '.join(missing)} array); {fix}")
            names = ("indices",) if expected is not None else \
                SHARD_FIELDS + tuple(n for n in OPTIONAL_FIELDS if n in npz.files)
            arrays = {name: npz[name] for name in names}
    except DatasetError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, KeyError, TypeError) as exc:
        why = " ".join(str(exc).split())[:100] or type(exc).__name__
        raise DatasetError(f"{path}: damaged dataset shard ({why}); {fix}") from None
    if expected is not None and not np.array_equal(arrays["indices"], np.asarray(list(expected))):
        raise DatasetError(f"{path}: the shard holds other samples than its name says; {fix}")
    return arrays


def _damaged_shards(root: Path, config: DatasetConfig) -> list[int]:
    """Shards on disk that cannot be read back (truncated, garbage, other samples): rendered again."""
    damaged = []
    for s in range(config.n_shards):
        path = shard_path(root, s)
        if path.exists():
            try:
                read_shard(path, shard_indices(config, s))
            except DatasetError as exc:
                print(f"dataset: {str(exc).split('; delete')[0]}; rendering it again", file=sys.stderr)
                damaged.append(s)
    return damaged


def _render_shard(args: tuple) -> tuple[int, int, float]:
    """Render one shard in a worker process and write it atomically; returns (shard, count, seconds).

    ``args``: (config as a dict, root, shard, threads[, variant]).
    """
    config_dict, root, shard, threads, *rest = args
    start = time.perf_counter()
    arrays = render_shard(DatasetConfig(**config_dict), shard, rest[0] if rest else None, threads)
    write_shard(root, shard, arrays)
    return shard, len(arrays["indices"]), time.perf_counter() - start


def _check_manifest(root: Path, config: DatasetConfig, variant: str | None = None) -> None:
    path = root / MANIFEST
    if path.exists():
        stored = {**LEGACY_DEFAULTS, **json.loads(path.read_text())["config"]}
        asked = json.loads(json.dumps(asdict(config)))     # as the manifest holds it: enums as their text
        if stored != asked:
            diff = {k: (stored.get(k), v) for k, v in asked.items() if stored.get(k) != v}
            raise DatasetError(f"{root} holds a dataset made with other settings {diff} (stored, asked); "
                               f"use another --out or the same settings to resume")
    else:
        # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
        from hairdigi.render.variant import mi
        write_json_atomic(path, {"config": asdict(config), "format": "shard-NNNNN.npz: images (N,S,S,3) "
                                 "linear float16 radiance (store linear16) or uint8 sRGB (srgb8); params (N,6) normalised Table 1 vector; cameras (N,3) "
                                 "polar°, azimuth°, distance; seeds (N,2) strand, render; indices (N,); "
                                 "appearance (N,3) shine, fibre spread, grey share",
                                 "mitsuba_variant": variant or mi.variant(),
                                 "created": time.strftime("%Y-%m-%dT%H:%M:%S")})


def _check_variant(root: Path, variant: str, has_shards: bool) -> None:
    """Refuse to add shards rendered with another Mitsuba variant than the dataset's (a sample's
    pixels depend on the variant, so the dataset would no longer be one function of (seed, i)).
    A dataset with no shard yet takes the new variant."""
    manifest = json.loads((root / MANIFEST).read_text())
    stored = manifest.get("mitsuba_variant")
    if not stored or stored == variant:
        return
    if has_shards:
        raise DatasetError(f"{root} was rendered with Mitsuba variant {stored}, not {variant}; resume it with "
                           f"--variant {stored}, or use another --out")
    write_json_atomic(root / MANIFEST, {**manifest, "mitsuba_variant": variant})


def _resolve_variant(variant: str | None, set_here: bool) -> str:
    """The variant to render with, by name: None is this process's, ``auto`` is resolved here. A
    named variant is also set here when this process renders (``set_here``); for Ray it is checked
    where the tasks run, since the driver may have no GPU."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.variant import select_variant

    if variant is None or variant == "auto" or set_here:
        return select_variant(variant)
    return variant


def shard_task(config: dict, shard: int, variant: str, threads: int) -> dict:
    """One Ray task (``inference.training.cluster.render_shards``): render shard ``shard`` of the dataset
    ``config`` (its fields as a dict) with ``variant`` and return its arrays."""
    return render_shard(DatasetConfig(**config), shard, variant, threads)


def generate(config: DatasetConfig, root: str | os.PathLike, workers: int = 1, progress: bool = True,
             backend: str = "local", address: str | None = None, variant: str | None = None) -> Path:
    """Render every missing shard of the dataset into ``root``; resumable and deterministic.

    ``backend="local"``: ``workers`` processes on this machine, each writing the shards it renders.
    ``backend="ray"``: one Ray task per shard (``inference.training.cluster``) on the cluster at ``address``,
    or on a local Ray instance with ``workers`` CPUs started for the run; each task returns its
    shard's arrays and this process writes them, so only this machine needs the dataset folder.
    Either way a sample is the same (bitwise), as the shards share one core, ``render_shard``.
    ``variant``: Mitsuba's variant for every shard (None: this process's; ``auto``: resolved here);
    the manifest records it, and adding shards with another one is refused.
    """
    from tqdm import tqdm   # deferred: tqdm only for a local run's progress bar

    if backend not in BACKENDS:
        raise ValueError(f"unknown dataset backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    if backend == "ray":
        require_ray()   # before anything is written: without Ray, one line saying how to install it
        check_address(address)   # an unreachable cluster fails now, in seconds, leaving no manifest
    variant = _resolve_variant(variant, set_here=backend == "local")
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    _check_manifest(root, config, variant)
    for stray in root.glob(".shard-*.npz"):   # half-written by a killed run
        stray.unlink(missing_ok=True)
    damaged = set(_damaged_shards(root, config))
    todo = [s for s in range(config.n_shards) if s in damaged or not shard_path(root, s).exists()]
    if todo:
        _check_variant(root, variant, has_shards=len(todo) < config.n_shards)
    done = config.n - sum(len(shard_indices(config, s)) for s in todo)
    bar = tqdm(total=config.n, initial=done, unit="swatch", desc="dataset", disable=not progress,
               smoothing=0.1, dynamic_ncols=True)
    jobs = [(asdict(config), str(root), s, 1 if workers > 1 else 0, variant) for s in todo]
    try:
        if backend == "local" and workers <= 1:
            for job in jobs:
                _, count, _ = _render_shard(job)
                bar.update(count)
        elif todo:
            # SIGTERM (kill, a session ending) unwinds through the pool's exit, which ends the workers
            # (for Ray: cancels the tasks, and stops the instance this run started)
            previous = signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
            try:
                if backend == "ray":
                    def arrived(shard: int, arrays: dict) -> None:
                        write_shard(root, shard, arrays)
                        bar.update(len(arrays["indices"]))

                    render_shards(shard_task, asdict(config), todo, variant, arrived, address=address,
                                  num_cpus=workers)
                else:
                    with mp.get_context("spawn").Pool(workers, initializer=_die_with_parent) as pool:
                        for _, count, _ in pool.imap_unordered(_render_shard, jobs):
                            bar.update(count)
            finally:
                signal.signal(signal.SIGTERM, previous)
    finally:
        bar.close()
    return root


def load(root: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """All complete shards: images (N,S,S,3), params (N,6), cameras (N,3), and the manifest.

    Images are float16 linear radiance for ``linear16`` datasets and uint8 sRGB for ``srgb8`` ones;
    ``manifest["config"]["store"]`` says which (older manifests lack it: ``srgb8``).
    """
    root = Path(root)
    if not (root / MANIFEST).exists():
        raise FileNotFoundError(f"{root} is not a hairdigi dataset (no {MANIFEST}); make one with hairdigi dataset")
    manifest = read_json(root / MANIFEST, DatasetError, "no manifest", "not a hairdigi dataset manifest ({exc})")
    if not isinstance(manifest, dict) or not isinstance(manifest.get("config"), dict):
        raise DatasetError(f"{root / MANIFEST}: not a hairdigi dataset manifest (no \"config\" object)")
    manifest["config"] = {**LEGACY_DEFAULTS, **manifest["config"]}
    shards = sorted(root.glob("shard-*.npz"))
    if not shards:
        raise FileNotFoundError(f"{root} has no finished shards yet")
    parts = [read_shard(p) for p in shards]
    return (np.concatenate([p["images"] for p in parts]), np.concatenate([p["params"] for p in parts]),
            np.concatenate([p["cameras"] for p in parts]), manifest)
