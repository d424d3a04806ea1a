"""``hairdigi bench refine``: the refinement's speed against its error, to choose its defaults.

For each render size and spp of the refinement, and each number of check-and-polish iterations,
the first held-out swatches (clean 64-spp inputs) are estimated by the encoder, refined at their
camera pose, and judged as ``evaluate`` judges (common-seed renders against the truth). A new pose
pays for its response curve (``curve_s``); the rig's fixed pose pays once (``polish_s`` is then the
whole cost). Writes ``refine_bench.csv`` and ``refine_bench.png``.
"""
from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.inference.preprocess import Roi
from hairdigi.inference.refine import RefineSettings, mean_linear, refine, response_curve, scene_for
from hairdigi.inference.training.dataset import DatasetConfig, load, sample_spec
from hairdigi.inference.training.evaluate import JUDGE, Judge, capture, judge_file, judge_render
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.files import write_csv_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import RigRegion, swatch_roi
from hairdigi.render.io.figures import save_figure, save_table
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.renderer import default_renderer


def bench_refine(encoder, data_root: str | os.PathLike, out_dir: str | os.PathLike,
                 sizes=(32, 48, 64), spps=(8, 16, 32), iterations=(0, 1, 2), count: int = 10,
                 judge: Judge = JUDGE, progress: bool = True) -> list[dict]:
    images, vectors, _, manifest = load(data_root)
    config = DatasetConfig(**manifest["config"])
    cached = judge_file(data_root, judge)
    truths = dict(np.load(cached)) if cached.exists() else {}
    indices = list(range(min(count, len(images))))
    frames = {i: capture(images[i], i) for i in indices}
    priors = {i: encoder.estimate(frames[i], roi=Roi(0, 0, frames[i].shape[1], frames[i].shape[0])).params
              for i in indices}
    truth_mean = {}
    for i in indices:
        t = truths.get(f"truth_{i}")
        t = judge_render(config, i, HairParams.from_vector(vectors[i]), judge).linear if t is None else t
        truth_mean[i] = np.asarray(t, np.float32).reshape(-1, 3).mean(0)
    rows = []
    grid = [(size, spp) for size in sizes for spp in spps]
    for size, spp in tqdm(grid, desc="refine bench", unit="setting", disable=not progress):
        for k in iterations:
            settings = replace(RefineSettings(), size=size, spp=spp, check_spp=spp, iterations=k, tolerance_de=0.0)
            de, residual, curve_s, polish_s = [], [], [], []
            for i in indices:
                r = refine(priors[i], mean_linear(frames[i]), sample_spec(config, i).camera, settings)
                judged = judge_render(config, i, r.params, judge).linear.reshape(-1, 3).mean(0)
                de.append(float(delta_e2000(judged, truth_mean[i])))
                residual.append(r.residual_de2000)
                curve_s.append(r.curve_seconds)
                polish_s.append(r.polish_seconds)
            rows.append({"size": size, "spp": spp, "iterations": k, "swatches": len(indices),
                         "de_median": float(np.median(de)), "de_p95": float(np.quantile(de, 0.95)),
                         "de_max": float(np.max(de)), "residual_median": float(np.median(residual)),
                         "curve_s": float(np.median(curve_s)), "polish_s": float(np.median(polish_s))})
    save_table(out_dir, "refine_bench", rows, _plot)
    return rows


def _plot(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for k in sorted({r["iterations"] for r in rows}):
        rs = [r for r in rows if r["iterations"] == k]
        ax.scatter([r["curve_s"] + r["polish_s"] for r in rs], [r["de_median"] for r in rs],
                   label=f"{k} iteration(s)")
        for r in rs:
            ax.annotate(f"{r['size']}²/{r['spp']}", (r["curve_s"] + r["polish_s"], r["de_median"]), fontsize=7)
    ax.set_xlabel("seconds per refinement at a new pose (response curve + polish)")
    ax.set_ylabel("median mean-colour ΔE2000 against the truth")
    ax.grid(True, alpha=0.3)
    ax.legend()
    save_figure(fig, path)


#: The check-spp bench's hairs (Table 1) at the bench camera's swatch area, and the settings it compares.
CHECK_HAIRS = {"copper": HairParams((190, 80, 40), 0.5, 0.5, 0.6), "platinum": HairParams((245, 240, 225), 0.15, 0.04, 0.2),
               "dark brown": HairParams((60, 40, 30), 0.2, 0.8, 0.9), "saturated blue": HairParams((30, 60, 230), 0.9, 0.1, 0.5)}
CHECK_SETTINGS = (("check 32 spp", {"check_spp": 32}),
                  ("check 64 spp, the corrected answer rendered too (before 0.15)", {"check_spp": 64, "check_last": True}),
                  ("check 64 spp (the default)", {"check_spp": 64}),
                  ("check 128 spp", {"check_spp": 128}),
                  ("no check: the curve at 256 spp", {"spp": 256, "iterations": 0}))
CHECK_JUDGE_SPP, CHECK_JUDGE_SEED = 384, 11
#: The swatch structures the check-spp bench hides its hairs in: hairdigi's layered swatch (None) and the family
#: member whose check renders cost the most (``render.swatch_family``: its crossing fibres).
CHECK_MEMBERS = (None, "spread")


def bench_check_spp(out_dir: str | os.PathLike, progress: bool = True) -> list[dict]:
    """The refinement's check renders at the rig's swatch area: its result is the sigma_a whose fixed-seed
    check render matches the capture, so it inherits that render's noise. Each hair's truth, rendered at
    ``CHECK_JUDGE_SPP`` with another seed on each of ``CHECK_MEMBERS``, is the capture; each setting's answer,
    refined on that structure, is rendered the same way and judged against it (mean-colour ΔE2000). Writes
    ``check_spp_bench.csv``."""
    renderer = default_renderer()
    frame = (400, 300)
    view = RigRegion(frame, swatch_roi(frame))
    rows = []
    cases = [(name, hair, member) for member in CHECK_MEMBERS for name, hair in CHECK_HAIRS.items()]
    for name, hair, member in tqdm(cases, desc="check spp", unit="hair", disable=not progress):
        spec, film = scene_for(view, RefineSettings(), swatch_model=member)

        def judged(sigma) -> np.ndarray:
            return renderer.render(np.asarray(sigma, float), spec, film, CHECK_JUDGE_SPP,
                                   CHECK_JUDGE_SEED).linear.reshape(-1, 3).mean(0)

        target = judged(hair_sigma_a(hair))
        for label, change in CHECK_SETTINGS:
            settings = replace(RefineSettings(), **change)
            curve = response_curve(view, settings, renderer, swatch_model=member)   # rendered once, cached
            start = time.perf_counter()
            r = refine(hair, target, view, settings, renderer, curve=curve, swatch_model=member)
            seconds = time.perf_counter() - start
            rows.append({"hair": name, "structure": member or "layered", "setting": label,
                         "de2000": round(float(delta_e2000(judged(r.sigma_a), target)), 3),
                         "residual_de2000": round(r.residual_de2000, 3), "check_renders": len(r.history),
                         "polish_s": round(seconds, 2)})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / "check_spp_bench.csv", rows)
    _plot_check(rows, out / "check_spp_bench.png")
    return rows


def _plot_check(rows: list[dict], path: Path) -> None:
    """Each setting's median error against its median polish time, one marker per structure."""
    fig, ax = plt.subplots(figsize=(6.5, 4))
    for marker, member in zip("os^", dict.fromkeys(r["structure"] for r in rows)):
        for k, (label, _) in enumerate(CHECK_SETTINGS):
            sel = [r for r in rows if r["setting"] == label and r["structure"] == member]
            if sel:
                ax.plot(np.median([r["polish_s"] for r in sel]), np.median([r["de2000"] for r in sel]), marker,
                        color=f"C{k}", label=label if member == rows[0]["structure"] else None)
        ax.plot([], [], marker, color="grey", label=member)
    ax.set_xlabel("polish seconds (median)")
    ax.set_ylabel("ΔE2000 against the truth (median)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


#: The layouts bench: hidden layouts of one swatch (seeds no refinement renders) and the settings tried.
LAYOUT_SEEDS = (101, 102, 103, 104)
LAYOUT_SETTINGS = (1, 4)
LAYOUT_JUDGE_SPP = 192
LAYOUT_HAIRS = {**CHECK_HAIRS, "saturated red": HairParams((230, 20, 30), 1.0, 0.08, 0.3)}
#: The same swatch of 4x finer fibres (32,000 of radius 0.00025 in place of the default 8,000 of 0.001,
#: ``strands.layered_radius``: 25 µm fibres at 5 cm a unit, finer than hair): is the truth's spread
#: between layouts a property of how many fibres the swatch area holds?
LAYOUT_FINE_STRANDS = 32000


def bench_layouts(out_dir: str | os.PathLike, progress: bool = True) -> list[dict]:
    """How far a new strand layout of one swatch moves the refinement's answer, against the check renders'
    layouts (``RefineSettings.check_layouts``, same samples in all). Each hair is hidden in
    ``LAYOUT_SEEDS`` layouts of the default swatch at the rig's swatch area (the capture: its mean at
    ``LAYOUT_JUDGE_SPP``); every answer is rendered on one judge layout (seed 900, ``LAYOUT_JUDGE_SPP``):
    the **nuisance** is the largest ΔE2000 between two layouts' answers there, the **error** each answer
    against the truth on its own layout, and the **truth's spread** the largest ΔE2000 between the
    truth's own captures (the floor of any answer read from one capture), and again on a swatch of
    ``LAYOUT_FINE_STRANDS`` finer fibres. Writes ``layouts_bench.csv`` and ``layouts_bench.png``."""
    renderer = default_renderer()
    frame = (400, 300)
    view = RigRegion(frame, swatch_roi(frame))
    spec, film = scene_for(view, RefineSettings())
    curve = response_curve(view, RefineSettings(), renderer)

    def mean(sigma, layout: int, strands: int | None = None) -> np.ndarray:
        return renderer.render(np.asarray(sigma, float), replace(spec, strand_seed=layout, strands=strands), film,
                               LAYOUT_JUDGE_SPP, CHECK_JUDGE_SEED).linear.reshape(-1, 3).mean(0)

    def spread(means: list[np.ndarray]) -> float:
        return max(float(delta_e2000(a, b)) for i, a in enumerate(means) for b in means[i + 1:])

    rows = []
    for name, hair in tqdm(LAYOUT_HAIRS.items(), desc="layouts", unit="hair", disable=not progress):
        truth = hair_sigma_a(hair)
        captures = {s: mean(truth, s) for s in LAYOUT_SEEDS}
        # the floor: no answer read from one capture can vary less between layouts than the truth's own colour
        floor = spread(list(captures.values()))
        fine = spread([mean(truth, s, LAYOUT_FINE_STRANDS) for s in LAYOUT_SEEDS])
        for layouts in LAYOUT_SETTINGS:
            settings = replace(RefineSettings(), check_layouts=layouts)
            answers, errors, seconds = [], [], []
            for s in LAYOUT_SEEDS:
                start = time.perf_counter()
                r = refine(hair, captures[s], view, settings, renderer, curve=curve)
                seconds.append(time.perf_counter() - start)
                answers.append(mean(r.sigma_a, 900))
                errors.append(float(delta_e2000(mean(r.sigma_a, s), captures[s])))
            rows.append({"hair": name, "check_layouts": layouts, "nuisance_de2000": round(spread(answers), 3),
                         "truth_spread_de2000": round(floor, 3), "truth_spread_fine_de2000": round(fine, 3),
                         "error_median_de2000": round(float(np.median(errors)), 3),
                         "error_worst_de2000": round(float(np.max(errors)), 3),
                         "polish_s": round(float(np.median(seconds)), 2)})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / "layouts_bench.csv", rows)
    _plot_layouts(rows, out / "layouts_bench.png")
    return rows


def _plot_layouts(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for name in dict.fromkeys(r["hair"] for r in rows):
        sel = [r for r in rows if r["hair"] == name]
        line, = ax.plot([r["check_layouts"] for r in sel], [r["nuisance_de2000"] for r in sel], "o-", label=name)
        ax.plot([r["check_layouts"] for r in sel], [r["truth_spread_de2000"] for r in sel], ":", color=line.get_color())
    ax.axhline(0.3, ls="--", color="grey", lw=0.8)
    ax.set_xscale("log", base=2)
    ax.set_xlabel("layouts the check renders average over (same samples)")
    ax.set_ylabel("ΔE2000 between two layouts' answers\n(dotted: between the truth's own captures)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)
