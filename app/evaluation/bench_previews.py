"""``hairdigi bench previews``: the app's preview settings, time against error.

Two views, as the app renders them: the swatch's twin (the rig camera over the swatch area, at each
resolution the app renders it) and a hairstyle portrait. Each case renders ``spp`` samples in a warm
scene (built, and its kernel for that spp compiled, before), optionally denoises (OIDN; with or
without albedo and normal guides, which cost an AOV render), and is compared per pixel with a
1024-spp render of the same view that is not denoised: the mean per-pixel ΔE2000 (the app calls a
pass "clean" at 3 or less) and the ΔE2000 of the mean colour. The references are cached in
``OUT/refs``. ``denoise_mean_shift`` is what OIDN alone moved the mean colour (before
:func:`render.denoise.restore_mean` gives it back).
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.render import denoise as dn
from hairdigi.render import head, scene_kinds, scenes, strands
from hairdigi.render import renderer as renderer_module
from hairdigi.render.domain import absorption
from hairdigi.render.domain.files import atomic_path
from hairdigi.render.domain.params import HairParams
from hairdigi.render.io.figures import save_figure, save_table
from hairdigi.render.metrics import delta_e2000, mean_colour_delta_e, pixel_delta_e
from hairdigi.render.renderer import Renderer, SceneSpec

#: The app's denoise modes: none, colour alone, colour with albedo and normal guides.
MODES = ("raw", "oidn", "oidn+aov")
#: "Clean": mean per-pixel ΔE2000 against the 1024-spp reference at or below this.
CLEAN_DE = 3.0
REFERENCE_SPP = 1024


@dataclass(frozen=True)
class View:
    """One preview view: a scene, its size (pixels, w x h), and the spp values to try."""

    name: str
    spec: SceneSpec
    size: tuple[int, int]
    spps: tuple[int, ...]


def default_views(twins: list[tuple[SceneSpec, tuple[int, int]]], quick: bool = False) -> list[View]:
    """The twin views (given, at each size the app renders: the app knows the rig's swatch area) and
    the hairstyle at 512² and 256²."""
    if quick:
        spec, (w, h) = min(twins, key=lambda t: t[1][0])
        return [View("twin", spec, (max(8, w // 4), max(8, h // 4)), (1, 4)),
                View("hairstyle", SceneSpec("straight", strands=400), (64, 64), (1, 4))]
    return [*(View("twin", spec, tuple(size), (1, 2, 4, 8, 16, 32, 64)) for spec, size in twins),
            View("hairstyle", SceneSpec("straight"), (512, 512), (1, 2, 4, 8, 16)),
            View("hairstyle", SceneSpec("straight"), (256, 256), (1, 2, 4, 8))]


def _aux_images(renderer: Renderer, hair: HairParams, spec: SceneSpec, size, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """OIDN's guides for a view: first-hit albedo in [0, 1] and shading normals in [-1, 1] (Mitsuba's ``aov``)."""
    image = renderer.render_aov(hair, spec, "albedo:albedo,nn:sh_normal", size, spp).linear
    return (np.ascontiguousarray(np.clip(image[..., :3], 0, 1)),
            np.ascontiguousarray(np.clip(image[..., 3:6], -1, 1)))


def _scene_code() -> str:
    """A digest of the modules that make the scenes: a reference is stale once they change."""
    digest = hashlib.sha256()
    for module in (absorption, head, renderer_module, scene_kinds, scenes, strands):
        digest.update(Path(module.__file__).read_bytes())
    return digest.hexdigest()[:16]


def _reference(renderer: Renderer, hair: HairParams, view: View, spp: int, cache: Path, code: str) -> np.ndarray:
    """The view at ``spp`` (not denoised), rendered in chunks of 256 spp and cached on disk."""
    key = hashlib.sha256(json.dumps([2, repr(view.spec), list(view.size), hair.to_dict(), spp, renderer.variant,
                                     code], sort_keys=True, default=str).encode()).hexdigest()[:16]
    path = cache / f"ref-{view.name}-{view.size[0]}x{view.size[1]}-{key}.npy"
    if path.exists():
        return np.load(path)
    chunk = min(spp, 256)
    total = sum(renderer.render(hair, view.spec, view.size, chunk, seed=90_000 + i).linear
                for i in range(spp // chunk))
    image = (total / (spp // chunk)).astype(np.float32)
    with atomic_path(path, ".npy") as tmp:
        np.save(tmp, image)
    return image


def run_previews_bench(out_dir: str | os.PathLike, twins: list[tuple[SceneSpec, tuple[int, int]]],
                       hair: HairParams, quick: bool = False, reference_spp: int = REFERENCE_SPP) -> list[dict]:
    """Every view x spp x denoise mode; writes ``previews_bench.csv`` and ``.png``; returns the rows."""
    out = Path(out_dir)
    cache = out / "refs"
    cache.mkdir(parents=True, exist_ok=True)
    reference_spp = 64 if quick else reference_spp
    modes = MODES if dn.available() else ("raw",)
    renderer = Renderer(max_cached=2)
    code = _scene_code()            # as imported now: references of older scene code are not reused
    rows = []
    for view in default_views(twins, quick):
        ref = _reference(renderer, hair, view, reference_spp, cache, code)
        renderer.render(hair, view.spec, view.size, 1, seed=1)        # warm: build and compile
        if "oidn+aov" in modes:
            _aux_images(renderer, hair, view.spec, view.size, 1)         # warm: the AOV kernel
        for spp in tqdm(view.spps, desc=f"{view.name} {view.size[0]}x{view.size[1]}", unit="spp"):
            renderer.render(hair, view.spec, view.size, spp, seed=3)   # Dr.Jit compiles a kernel per spp: not timed
            result = renderer.render(hair, view.spec, view.size, spp, seed=7 + spp)
            raw = result.linear
            for mode in modes:
                aux_s, denoise_s, shift = 0.0, 0.0, 0.0
                image = raw
                if mode != "raw":
                    guides = (None, None)
                    if mode == "oidn+aov":
                        start = time.perf_counter()
                        guides = _aux_images(renderer, hair, view.spec, view.size, spp)
                        aux_s = time.perf_counter() - start
                    start = time.perf_counter()
                    unscaled = dn.denoise(raw, *guides, keep_mean=False)
                    denoise_s = time.perf_counter() - start
                    shift = mean_colour_delta_e(unscaled, raw)
                    image = dn.restore_mean(unscaled, raw)
                rows.append({"view": view.name, "width": view.size[0], "height": view.size[1], "spp": spp,
                             "mode": mode, "render_s": round(result.seconds, 4), "aux_s": round(aux_s, 4),
                             "denoise_s": round(denoise_s, 4),
                             "total_s": round(result.seconds + aux_s + denoise_s, 4),
                             "pixel_de2000": round(pixel_delta_e(image, ref), 3),
                             "p95_pixel_de2000": round(float(np.percentile(delta_e2000(image, ref), 95)), 3),
                             "mean_colour_de2000": round(mean_colour_delta_e(image, ref), 3),
                             "denoise_mean_shift": round(shift, 3),
                             "clean": pixel_delta_e(image, ref) <= CLEAN_DE,
                             "reference_spp": reference_spp, "variant": renderer.variant})
    save_table(out, "previews_bench", rows, plot_previews)
    return rows


def cheapest_clean(rows: list[dict], view: str, width: int, mode: str | None = None) -> dict | None:
    """The fastest clean case of a view (and denoise mode), or None when none is clean."""
    clean = [r for r in rows if r["view"] == view and r["width"] == width and r["clean"]
             and (mode is None or r["mode"] == mode)]
    return min(clean, key=lambda r: r["total_s"]) if clean else None


def plot_previews(rows: list[dict], path: Path) -> Path:
    """Seconds against mean per-pixel ΔE2000, one panel per view, one line per denoise mode."""
    views = sorted({(r["view"], r["width"], r["height"]) for r in rows})
    fig, axes = plt.subplots(1, len(views), figsize=(5.5 * len(views), 4.6), squeeze=False)
    for ax, (name, w, h) in zip(axes[0], views):
        for mode, style in zip(MODES, ("o-", "s-", "^--")):
            rs = [r for r in rows if (r["view"], r["width"], r["height"], r["mode"]) == (name, w, h, mode)]
            if not rs:
                continue
            ax.plot([r["total_s"] for r in rs], [r["pixel_de2000"] for r in rs], style, label=mode)
            for r in rs:
                ax.annotate(str(r["spp"]), (r["total_s"], r["pixel_de2000"]), fontsize=7, xytext=(3, 3),
                            textcoords="offset points")
        ax.axhline(CLEAN_DE, color="grey", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("seconds per pass (render + guides + denoise, warm scene)")
        ax.set_ylabel(f"mean per-pixel ΔE2000 vs {rows[0]['reference_spp']} spp")
        ax.set_title(f"{name} {w}x{h}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("hairdigi bench previews: time against preview error (labels: spp; dashed: clean)")
    fig.tight_layout()
    return save_figure(fig, path)
