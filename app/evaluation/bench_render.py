"""``hairdigi bench render``: render time against error, to choose strands, spp and depth per scene.

Each case is rendered after a warm-up render of the same scene, so its time is the steady-state
time of a reused scene (what dataset generation pays); ``first_s`` is the time with the scene
load and kernel compile. The error is measured against a reference of the same scene at high spp
and depth: RMSE of linear RGB, and ΔE2000 of the mean colour. In the strand sweep the geometry
differs from the reference, so RMSE there mixes noise with layout; its ΔE is the figure to read.
"""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.render.domain.bounds import defaults_for
from hairdigi.render.domain.files import write_csv_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.io.figures import save_figure
from hairdigi.render.metrics import mean_colour_delta_e, rmse
from hairdigi.render.renderer import Renderer, SceneSpec


@dataclass(frozen=True)
class BenchCase:
    scene: str
    size: int
    strands: int
    spp: int
    depth: int
    sweep: str


#: Hair colours to average over: a mid brown, a light blond (many bounces) and a dyed red.
BENCH_HAIR = (
    HairParams((255, 255, 255), 0.0, 0.5, 0.8),
    HairParams((255, 255, 255), 0.0, 0.08, 0.3),
    HairParams((200, 40, 60), 0.8, 0.2, 0.5),
)


def bench_cases(quick: bool = False) -> tuple[list[BenchCase], dict[tuple, tuple[int, int]]]:
    """The cases, and the reference (spp, depth) for each (scene, size, strands).

    Each sweep varies one setting around the scene's defaults (``render.domain.bounds.DEFAULTS``): spp and
    strands at the default depth, depth at the default spp.
    """
    cases: list[BenchCase] = []
    refs: dict[tuple, tuple[int, int]] = {}
    sw_depth, hs_depth = defaults_for("swatch").max_depth, defaults_for("straight").max_depth
    sw = [("swatch", 128, 2000), ("swatch", 256, 2000)] if not quick else [("swatch", 64, 500)]
    for scene, size, strands in sw:
        refs[(scene, size, strands)] = ((256 if size <= 128 else 128) if not quick else 64, 64)
        spps = (2, 4, 8, 16, 32, 64) if size <= 128 else (4, 16, 32)
        for spp in (spps if not quick else (2, 8)):
            cases.append(BenchCase(scene, size, strands, spp, sw_depth, "spp"))
        for depth in (((4, 8, 16) if size <= 128 else (16,)) if not quick else (4,)):
            cases.append(BenchCase(scene, size, strands, 16 if not quick else 8, depth, "depth"))
        for n in ((250, 500, 1000, 4000) if not quick else (250,)):
            if size == 128 or quick:
                cases.append(BenchCase(scene, size, n, 16 if not quick else 8, sw_depth, "strands"))
    hs = ("straight", 512, 4000) if not quick else ("straight", 64, 300)
    refs[hs] = (48 if not quick else 16, 48)
    for spp in ((1, 2, 4, 16) if not quick else (1,)):
        cases.append(BenchCase(hs[0], hs[1], hs[2], spp, hs_depth, "spp"))
    for depth in ((4, 8, 12) if not quick else (4,)):
        cases.append(BenchCase(hs[0], hs[1], hs[2], 4 if not quick else 1, depth, "depth"))
    for n in ((1000, 2000, 8000) if not quick else (150,)):
        cases.append(BenchCase(hs[0], hs[1], n, 4 if not quick else 1, hs_depth, "strands"))
    return cases, refs


def _spec(scene: str, strands: int, depth: int) -> SceneSpec:
    return SceneSpec(name=scene, strands=strands, max_depth=depth)


def run_render_bench(out_dir: str | os.PathLike, quick: bool = False, repeats: int = 1) -> list[dict]:
    """Render every case, write ``render_bench.csv`` and ``render_bench.png``; return the rows."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cases, refs = bench_cases(quick)
    renderer = Renderer(max_cached=2)
    references: dict[tuple, list[np.ndarray]] = {}
    for key, (spp, depth) in tqdm(refs.items(), desc="references", unit="scene"):
        spec = _spec(key[0], key[2], depth)
        references[key] = [renderer.render(h, spec, key[1], spp, seed=9999).linear for h in BENCH_HAIR]
    rows = []
    for case in tqdm(cases, desc="bench render", unit="case"):
        spec = _spec(case.scene, case.strands, case.depth)
        first = renderer.render(BENCH_HAIR[0], spec, case.size, case.spp, seed=1).seconds
        ref_key = next(k for k in refs if k[:2] == (case.scene, case.size))
        times, cpus, errs, des, nonfinite = [], [], [], [], 0
        for i, hair in enumerate(BENCH_HAIR):
            for r in range(repeats):
                res = renderer.render(hair, spec, case.size, case.spp, seed=100 + r)
                times.append(res.seconds)
                cpus.append(res.cpu_seconds)
                nonfinite += res.nonfinite
            errs.append(rmse(res.linear, references[ref_key][i]))
            des.append(mean_colour_delta_e(res.linear, references[ref_key][i]))
        rows.append({**asdict(case), "seconds": float(np.median(times)), "cpu_s": float(np.median(cpus)),
                     "first_s": first,
                     "rmse": float(np.mean(errs)), "mean_delta_e2000": float(np.mean(des)),
                     "max_delta_e2000": float(np.max(des)), "nonfinite": nonfinite, "variant": renderer.variant})
    write_csv_atomic(out / "render_bench.csv", rows)
    bad = sum(r["nonfinite"] for r in rows)
    print(f"non-finite values returned by the path tracer over all cases: {bad}"
          + ("" if not bad else " (written as 0; see the CSV's nonfinite column)"))
    plot_speed_vs_error(rows, out / "render_bench.png")
    return rows


def plot_speed_vs_error(rows: list[dict], path: Path) -> Path:
    """Two panels, seconds against RMSE and against mean-colour ΔE2000, one series per sweep."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["scene"], r["size"], r["sweep"]), []).append(r)
    for (scene, size, sweep), rs in groups.items():
        label = f"{scene} {size}² — {sweep}"
        for ax, metric in zip(axes, ("rmse", "mean_delta_e2000")):
            ax.plot([r["seconds"] for r in rs], [r[metric] for r in rs], "o-", label=label)
            for r in rs:
                ax.annotate(str(r[sweep if sweep != "depth" else "depth"]), (r["seconds"], r[metric]),
                            fontsize=7, xytext=(3, 3), textcoords="offset points")
    for ax, name in zip(axes, ("RMSE (linear RGB)", "mean-colour ΔE2000")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("render time per image (s, reused scene)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
    axes[1].axhline(1.0, color="grey", ls="--", lw=0.8)
    axes[0].legend(fontsize=7)
    fig.suptitle("hairdigi bench render: speed against error (labels: the swept value)")
    fig.tight_layout()
    return save_figure(fig, path)
