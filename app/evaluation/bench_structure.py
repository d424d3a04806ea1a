"""``hairdigi bench structure``: how the swatch's fibre structure sets its rig colour.

Today's swatch (``swatch_strands``) packs its fibres into a few layers that pass through one
another; ``layered_swatch_strands`` stacks them in irregular layers where none meets another. This
bench renders both at the rig's swatch area as the refinement renders it (``inference.refine.
scene_for`` on the bench camera's swatch region) for three hairs, under all lights and each light
alone, with two strand seeds, and the layered swatch at several fibre counts; it reports the mean
colour in CIELAB, ΔE2000 against today's swatch, against the thickest layered swatch and between
seeds, how much holder is uncovered or shows with black hair, and the render time.
"""
from __future__ import annotations

import dataclasses
import json
import os
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.app.evaluation.structures_evaluation import StructureSet, _Cycles, _Mitsuba
from hairdigi.inference.refine import RefineSettings, response_curve, scene_for
from hairdigi.render.domain.bounds import defaults_for
from hairdigi.render.domain.files import write_csv_atomic
from hairdigi.render.domain.rig_geometry import RigRegion, swatch_roi
from hairdigi.render.io.figures import save_figure, save_table
from hairdigi.render.metrics import delta_e2000, linear_rgb_to_lab
from hairdigi.render.renderer import Renderer, SceneSpec, strands_for
from hairdigi.render.strands import Strands
from hairdigi.render.swatch_family import FAMILY, STRUCTURES, inside_share, structure_strands

#: The hairs measured: sigma_a per fibre radius.
HAIRS = {"platinum": (0.05, 0.08, 0.15), "brown": (0.35, 0.6, 1.2), "dark": (2.0, 3.0, 5.0)}
#: Black hair: what is left of the mean is the fibres' surface reflection and the holder between them.
BLACK = (50.0, 50.0, 50.0)
LIGHTS = {"all": (1.0, 1.0, 1.0), "0": (1.0, 0.0, 0.0), "1": (0.0, 1.0, 0.0), "2": (0.0, 0.0, 1.0)}
#: The rig frame the region is taken from, and the refinement's render size (pixels of its side) and spp.
FRAME = (400, 300)
SIZE, SPP = 48, 64
SEEDS = (0, 1)
RENDER_SEED = 11   # a strand seed s renders with RENDER_SEED + s: seed-to-seed includes the noise


def rig_spec(size: int = SIZE) -> tuple[SceneSpec, tuple[int, int]]:
    """The scene and film size of the refinement at the bench camera's swatch region."""
    return scene_for(RigRegion(FRAME, swatch_roi(FRAME)), RefineSettings(size=size, spp=SPP))


def uncovered_fraction(strands: Strands, half_w: float = 0.45, half_l: float = 0.53, rows: int = 64) -> float:
    """Share of the holder's area (|x| < half_w, |y| < half_l) that no fibre covers seen straight down.

    The curves are sampled as Mitsuba draws them; every fibre is taken as a band 2 radii wide along
    x at each of ``rows`` heights y (the swatch's fibres run along y)."""
    curves = strands.curves(per_segment=8)
    pts, rad = curves.points.astype(float), curves.radii.astype(float)
    owner = np.repeat(np.arange(curves.n_strands), curves.counts)
    same = owner[:-1] == owner[1:]                 # segments of one strand's polyline
    uncovered = []
    for y in np.linspace(-half_l, half_l, rows):
        lo = np.nonzero(same & ((pts[:-1, 1] - y) * (pts[1:, 1] - y) <= 0) & (pts[:-1, 1] != pts[1:, 1]))[0]
        t = (y - pts[lo, 1]) / (pts[lo + 1, 1] - pts[lo, 1])
        uncovered.append(_uncovered_1d(pts[lo, 0] + t * (pts[lo + 1, 0] - pts[lo, 0]), rad[lo], half_w))
    return float(np.mean(uncovered))


def _uncovered_1d(x: np.ndarray, r: np.ndarray, half_w: float) -> float:
    """Share of [-half_w, half_w] outside every interval [x - r, x + r]."""
    if len(x) == 0:
        return 1.0
    order = np.argsort(x - r)
    lo, hi = np.clip((x - r)[order], -half_w, half_w), np.clip((x + r)[order], -half_w, half_w)
    reach = np.maximum.accumulate(hi)
    gaps = np.maximum(lo[1:] - reach[:-1], 0).sum() + (lo[0] + half_w) + (half_w - reach[-1])
    return float(gaps / (2 * half_w))


def _lab(rgb: np.ndarray) -> np.ndarray:
    return np.asarray(linear_rgb_to_lab(np.asarray(rgb, float)), float)


def run(out_dir: str | os.PathLike, quick: bool = False) -> list[dict]:
    """Render the cases, write ``structure.csv``, ``structure.json`` and ``structure.png``; return the rows.

    One row per (model, strands, hair, lights): the mean linear colour over the two strand seeds,
    its L*a*b*, and ΔE2000 against today's swatch, against the thickest layered swatch and between
    the seeds (structure and render noise together)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    configs = ([("today", 2000), ("layered", 1000), ("layered", 2000)] if quick else
               [("today", 2000)] + [("layered", n) for n in (500, 1000, 2000, 4000, 8000)])
    lights = {k: LIGHTS[k] for k in (("all", "0") if quick else LIGHTS)}
    base, film = rig_spec()
    renderer = Renderer(max_cached=2)
    renders: dict[tuple, np.ndarray] = {}
    extra: dict[str, dict] = {"configs": {}}
    for model, n in configs:
        spec0 = dataclasses.replace(base, swatch_model=model, strands=n)
        strands = strands_for(spec0)
        geometry = {"uncovered": uncovered_fraction(strands),
                    "height": float(strands.points[:, 2].max() + strands.radii.max()),
                    "layers": _layer_count(strands) if model == "layered" else None,
                    "stack_diameters": float((strands.points[:, 2].max() - strands.points[:, 2].min())
                                             / (2 * strands.radii.max()) + 1)}
        black = []
        for seed in SEEDS:
            for hair, sigma in {**HAIRS, "black": BLACK}.items():
                for light, scale in (lights.items() if hair != "black" else [("all", LIGHTS["all"])]):
                    spec = dataclasses.replace(spec0, strand_seed=seed, lights=scale)
                    res = renderer.render(np.array(sigma), spec, film, SPP, seed=RENDER_SEED + seed)
                    renders[(model, n, hair, light, seed)] = res.linear.reshape(-1, 3).mean(0)
                    if hair == "black":
                        black.append(float(_lab(renders[(model, n, hair, light, seed)])[0]))
        geometry["black_L"] = float(np.mean(black))
        for hair in ("platinum", "brown"):
            geometry[f"holder_dL_{hair}"] = holder_lightness(renderer, spec0, film, HAIRS[hair])
        geometry.update(_timing(renderer, model, n))
        extra["configs"][f"{model}-{n}"] = geometry
    # the noise floor: one layout, two render seeds
    spec = dataclasses.replace(base, swatch_model="layered", strands=2000)
    noise = {}
    for hair, sigma in HAIRS.items():
        a, b = (renderer.render(np.array(sigma), spec, film, SPP, seed=s).linear.reshape(-1, 3).mean(0)
                for s in (RENDER_SEED, RENDER_SEED + 100))
        noise[hair] = float(delta_e2000(a, b))
    extra["noise_de2000"] = noise
    if not quick:   # does the path depth cut the thick swatch's light short?
        deep = dataclasses.replace(spec, max_depth=64)
        a = renderer.render(np.array(HAIRS["platinum"]), deep, film, SPP, seed=RENDER_SEED).linear.reshape(-1, 3).mean(0)
        extra["depth64_vs_32_platinum_de2000"] = float(delta_e2000(a, renders[("layered", 2000, "platinum", "all", 0)]))
    thickest = max(n for m, n in configs if m == "layered")
    rows = []
    for model, n in configs:
        g = extra["configs"][f"{model}-{n}"]
        for hair in HAIRS:
            for light in lights:
                per_seed = [renders[(model, n, hair, light, s)] for s in SEEDS]
                mean = np.mean(per_seed, axis=0)
                today = np.mean([renders[("today", 2000, hair, light, s)] for s in SEEDS], axis=0)
                thick = np.mean([renders[("layered", thickest, hair, light, s)] for s in SEEDS], axis=0)
                lab, lab_today = _lab(mean), _lab(today)
                rows.append({"model": model, "strands": n, "layers": g["layers"],
                             "stack_diameters": round(g["stack_diameters"], 1), "hair": hair, "lights": light,
                             "L": round(float(lab[0]), 3), "a": round(float(lab[1]), 3), "b": round(float(lab[2]), 3),
                             "r": float(mean[0]), "g": float(mean[1]), "b_lin": float(mean[2]),
                             "de2000_vs_today": round(float(delta_e2000(mean, today)), 3),
                             "dL_vs_today": round(float(lab[0] - lab_today[0]), 3),
                             f"de2000_vs_layered_{thickest}": round(float(delta_e2000(mean, thick)), 3),
                             "de2000_seeds": round(float(delta_e2000(*per_seed)), 3),
                             "uncovered": round(g["uncovered"], 6), "black_L": round(g["black_L"], 3),
                             "holder_dL": round(g.get(f"holder_dL_{hair}", float("nan")), 3),
                             "render_s_64": round(g["render_s"], 3), "build_s": round(g["build_s"], 3)})
    write_csv_atomic(out / "structure.csv", rows)
    (out / "structure.json").write_text(json.dumps({"settings": {"frame": FRAME, "size": SIZE, "spp": SPP,
                                                                 "seeds": SEEDS, "hairs": HAIRS},
                                                    **extra, "rows": rows}, indent=1))
    plot_structure(rows, out / "structure.png")
    return rows


def holder_lightness(renderer: Renderer, spec: SceneSpec, film, sigma_a) -> float:
    """L* the holder adds to the region's mean: rendered with its albedo (0.18) less rendered black.

    The holder is not a scene parameter of ``Renderer``; this reaches into the renderer's loaded
    scene for it (a measurement only) and puts the albedo back."""
    sigma = np.asarray(sigma_a, float)
    with_holder = renderer.render(sigma, spec, film, SPP, seed=RENDER_SEED).linear.reshape(-1, 3).mean(0)
    params = renderer._cache[renderer._structure_key(spec, film)].params
    key = "holder.bsdf.reflectance.value"
    albedo = params[key]
    params[key] = type(albedo)(0.0, 0.0, 0.0)
    params.update()
    try:
        without = renderer.render(sigma, spec, film, SPP, seed=RENDER_SEED).linear.reshape(-1, 3).mean(0)
    finally:
        params[key] = albedo
        params.update()
    return float(_lab(with_holder)[0] - _lab(without)[0])


def _layer_count(strands: Strands) -> int:
    """Fibre layers at the swatch's middle: the fibres' heights split wherever two neighbours (in z)
    are more than half a radius apart (a layered swatch's layers; today's drifts: about 1)."""
    z = np.sort(strands.points[strands.starts() + strands.counts // 2, 2])
    return int(np.count_nonzero(np.diff(z) > 0.5 * float(strands.radii.max()))) + 1


def _timing(renderer: Renderer, model: str, n: int, size: int = 64, spp: int = 64) -> dict:
    """Build (first render less a warm one) and warm render seconds of the swatch crop, 64² at 64 spp."""
    spec = SceneSpec("swatch", strands=n, swatch_model=model)
    first = renderer.render(np.array(HAIRS["brown"]), spec, size, spp, seed=1).seconds
    warm = min(renderer.render(np.array(HAIRS["brown"]), spec, size, spp, seed=s).seconds for s in (2, 3))
    return {"render_s": warm, "build_s": max(first - warm, 0.0)}


def plot_structure(rows: list[dict], path: Path) -> Path:
    """L* against fibre count (all lights) per hair, today's as lines; ΔE2000 to today's; render time."""
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    colours = {"platinum": "goldenrod", "brown": "saddlebrown", "dark": "black"}
    for hair, colour in colours.items():
        lay = sorted((r["strands"], r["L"]) for r in rows
                     if r["model"] == "layered" and r["hair"] == hair and r["lights"] == "all")
        today = [r["L"] for r in rows if r["model"] == "today" and r["hair"] == hair and r["lights"] == "all"]
        if lay:
            axes[0].plot(*zip(*lay), "o-", color=colour, label=f"{hair} layered")
        if today:
            axes[0].axhline(today[0], color=colour, ls="--", lw=1, label=f"{hair} today (2000)")
        for light, marker in (("all", "o"), ("0", "s"), ("1", "^"), ("2", "v")):
            pts = sorted((r["strands"], r["de2000_vs_today"]) for r in rows
                         if r["model"] == "layered" and r["hair"] == hair and r["lights"] == light)
            if pts:
                axes[1].plot(*zip(*pts), marker=marker, color=colour, ls="-" if light == "all" else ":",
                             label=f"{hair}, lights {light}")
    axes[0].set(xscale="log", xlabel="layered swatch: strands", ylabel="L* (rig region, all lights)")
    axes[0].legend(fontsize=6)
    axes[1].set(xscale="log", xlabel="layered swatch: strands", ylabel="ΔE2000 to today's swatch")
    axes[1].legend(fontsize=5, ncol=2)
    times = sorted({(r["model"], r["strands"], r["render_s_64"]) for r in rows})
    for model, marker in (("today", "s"), ("layered", "o")):
        pts = [(n, s) for m, n, s in times if m == model]
        if pts:
            axes[2].plot(*zip(*pts), marker, ls="-", label=model)
    axes[2].set(xscale="log", xlabel="strands", ylabel="s per render (64², 64 spp, warm)")
    axes[2].legend()
    counts = sorted({r["strands"] for r in rows})
    for ax in axes:
        ax.set_xticks(counts, [str(n) for n in counts], fontsize=7)
        ax.minorticks_off()
    fig.suptitle("Swatch structure: rig colour of the layered (non-intersecting) swatch against today's")
    fig.tight_layout()
    return save_figure(fig, path)


#: ``hairdigi bench family``: the hairs (sigma_a per fibre radius) and the strand layouts.
FAMILY_HAIRS = {**HAIRS, "red": (0.05, 2.5, 3.0), "blue": (2.5, 1.0, 0.1)}
FAMILY_LAYOUTS = (0, 1)


def family(out_dir: str | os.PathLike) -> list[dict]:
    """Every structure of ``render.swatch_family`` at equal sigma_a: its response curve at the rig's swatch
    area (the refinement's default settings: 48², 32 spp, 12 levels; cached), per layout, and each hair's
    ΔE2000 against the layered swatch's layout 0. Writes ``family.csv`` and ``family.png``."""
    view = RigRegion(FRAME, swatch_roi(FRAME))
    settings = RefineSettings()
    curves = {(m, s): response_curve(view, dataclasses.replace(settings, strand_seed=s), swatch_model=m)
              for m in STRUCTURES for s in FAMILY_LAYOUTS}
    ref = curves[("layered", 0)]
    rows = []
    for (model, layout), curve in curves.items():
        row = {"structure": model, "layout": layout, "curve_s": round(curve.seconds, 2)}
        for hair, sigma in FAMILY_HAIRS.items():
            s = np.asarray(sigma, float)
            row[f"{hair}_de2000"] = round(float(delta_e2000(curve(s), ref(s))), 3)
            row[f"{hair}_dL"] = round(float(_lab(curve(s))[0] - _lab(ref(s))[0]), 3)
        rows.append(row)
    save_table(out_dir, "family", rows, _plot_family)
    return rows


def _plot_family(rows: list[dict], path: Path) -> None:
    models = list(dict.fromkeys(r["structure"] for r in rows))
    _grouped_bars(path, models, list(FAMILY_HAIRS),
                  lambda m, h: np.mean([r[f"{h}_de2000"] for r in rows if r["structure"] == m]),
                  "ΔE2000 vs layered, equal σa",
                  "the swatch's structure at equal σa, rig's swatch area (mean of 2 layouts)")


def _grouped_bars(path: Path, models: list[str], groups: list[str], value, ylabel: str, title: str,
                  labels: list[str] | None = None) -> None:
    """A bar per (model, group): ``value(model, group)``, the groups side by side over each model."""
    fig, ax = plt.subplots(figsize=(8, 3.5))
    x = np.arange(len(models))
    width = 0.8 / max(1, len(groups))
    for k, group in enumerate(groups):
        ax.bar(x + (k - (len(groups) - 1) / 2) * width, [value(m, group) for m in models], width, label=group)
    ax.set_xticks(x, labels or models, rotation=0 if labels else 20, ha="center" if labels else "right", fontsize=7)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=len(groups))
    fig.tight_layout()
    save_figure(fig, path)


#: ``hairdigi bench renderers``: the hairs (sigma_a per fibre radius), the crop's side and samples.
RENDERER_HAIRS = {"copper": (0.07, 0.14, 0.31), "brown": (0.19, 0.30, 0.62), "red": (0.01, 0.20, 0.16)}
RENDERER_SIZE, RENDERER_SPP = 32, 64


def renderers(out_dir: str | os.PathLike, structures: tuple[str, ...] | None = None, size: int = RENDERER_SIZE,
              spp: int = RENDERER_SPP, progress: bool = True) -> list[dict]:
    """Every structure's swatch at equal sigma_a in Mitsuba and in Blender Cycles (``HAIRDIGI_BLENDER``), as
    ``hairdigi evaluate --structures --blender`` renders its hidden swatches (the rig's swatch pose, a crop
    of ``size``², ``spp``, layout 0, one shine): the two mean colours' ΔE2000, their ratio per channel,
    each renderer's seconds, and the share of the drawn fibres inside another fibre
    (``swatch_family.inside_share``). Writes ``renderers.csv`` and ``renderers.png``."""
    names = tuple(structures or FAMILY)
    config = StructureSet(size=size, spp=spp, blender=True)
    mitsuba = _Mitsuba(config)
    rows = []
    with tempfile.TemporaryDirectory(prefix="hairdigi-bench-renderers-") as tmp:
        cycles = _Cycles(config, Path(tmp))
        bar = tqdm(total=len(names) * len(RENDERER_HAIRS), desc="Mitsuba and Cycles", unit="swatch",
                   disable=not progress)
        for name in names:
            inside = round(inside_share(structure_strands(name, defaults_for("swatch").strands, 0)), 4)
            for hair, sigma in RENDERER_HAIRS.items():
                s = np.asarray(sigma, float)
                start = time.perf_counter()
                a = np.asarray(mitsuba.mean(s, name, 0, "rig", 0.25), float)
                mid = time.perf_counter()
                b = np.asarray(cycles.mean(s, name, 0, "rig", 0.25), float)
                rows.append({"structure": name, "hair": hair, "inside_share": inside,
                             "de2000": round(float(delta_e2000(np.clip(a, 1e-9, None), np.clip(b, 1e-9, None))), 3),
                             **{f"ratio_{c}": round(float(b[k] / max(a[k], 1e-12)), 4) for k, c in enumerate("rgb")},
                             "mitsuba_s": round(mid - start, 2), "cycles_s": round(time.perf_counter() - mid, 2)})
                bar.update()
        bar.close()
    save_table(out_dir, "renderers", rows, _plot_renderers)
    return rows


def _plot_renderers(rows: list[dict], path: Path) -> None:
    models = list(dict.fromkeys(r["structure"] for r in rows))
    share = {r["structure"]: r["inside_share"] for r in rows}
    _grouped_bars(path, models, list(dict.fromkeys(r["hair"] for r in rows)),
                  lambda m, h: next(r["de2000"] for r in rows if r["structure"] == m and r["hair"] == h),
                  "ΔE2000, Mitsuba vs Cycles", "one swatch at equal σa in two renderers (rig's swatch pose, crop)",
                  [f"{m}\n{100 * share[m]:.1f}% inside" for m in models])
