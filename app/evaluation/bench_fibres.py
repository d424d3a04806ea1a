"""``hairdigi bench fibres``: how many fibre groups a varied swatch needs.

A varied appearance is drawn as pigment groups (``render.fibres``). More groups sample the
log-normal spread of sigma_a more finely but add shapes to the scene. For group counts 2-32 this
measures the render time and the mean colour against the finest split (32 groups), at the rig's
swatch area, for a strong spread (0.5) with greys (0.2) on three hairs, with a common sampler seed.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hairdigi.app.evaluation.results import Result
from hairdigi.render.domain.appearance import Appearance
from hairdigi.render.domain.rig_geometry import RigRegion, swatch_roi
from hairdigi.render.io.figures import save_figure
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.renderer import Renderer, SceneSpec

HAIRS = {"platinum": (0.05, 0.08, 0.15), "brown": (0.35, 0.6, 1.2), "dark": (2.0, 3.0, 5.0)}
GROUPS = (1, 2, 4, 6, 8, 12, 16, 32)
LOOK = Appearance(0.3, 0.5, 0.2)


def run(out: Path, quick: bool = False) -> Result:
    """Render each hair at each group count; save ``fibres_bench.csv`` and ``.png``; return the result."""
    frame = (400, 300)
    region = RigRegion(frame, swatch_roi(frame))
    film, crop, _ = region.render_plan(64 * 64)
    base = SceneSpec("swatch", camera=region.pose, framing="rig", target=region.target,
                     half_width=region.half_width, crop=crop, appearance=LOOK)
    spp = 16 if quick else 64
    groups = (1, 4, 32) if quick else GROUPS
    renderer = Renderer(max_cached=2)
    rows = []
    for hair, sigma in HAIRS.items():
        means = {}
        for g in groups:
            spec = replace(base, fibre_groups=g)
            renderer.render(np.asarray(sigma), spec, film, 1, seed=0)    # build and compile first
            start = time.perf_counter()
            means[g] = renderer.render(np.asarray(sigma), spec, film, spp, seed=11).linear.reshape(-1, 3).mean(0)
            rows.append({"hair": hair, "groups": g, "seconds": round(time.perf_counter() - start, 3), "spp": spp})
        finest = means[max(groups)]
        for row in rows:
            if row["hair"] == hair:
                row["de2000_vs_finest"] = round(float(delta_e2000(means[row["groups"]], finest)), 3)
    return Result("fibres_bench", rows, plot=_plot).save(out)


def _plot(rows: list[dict], path: Path) -> None:
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3.2))
    for hair in HAIRS:
        r = [x for x in rows if x["hair"] == hair]
        a.plot([x["groups"] for x in r], [x["de2000_vs_finest"] for x in r], "o-", label=hair)
        b.plot([x["groups"] for x in r], [x["seconds"] for x in r], "o-", label=hair)
    a.set_xscale("log", base=2)
    b.set_xscale("log", base=2)
    a.set_xlabel("pigment groups")
    b.set_xlabel("pigment groups")
    a.set_ylabel("ΔE2000 against 32 groups")
    b.set_ylabel("render seconds (64², 64 spp)")
    a.legend(fontsize=8)
    fig.suptitle(f"fibre groups: spread {LOOK.fibre_spread}, greys {LOOK.grey_fraction}")
    fig.tight_layout()
    save_figure(fig, path)
