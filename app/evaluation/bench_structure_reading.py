"""``hairdigi bench structure-reading``: can the structure be read as a continuous quantity?

The family mode maps an undecided swatch to its members' mean curve (``inference.structure.to_family``). This
bench replays, from the swatch region's tables at the bench camera, what three other readings would have
answered, on structures the reading does not know: each read member left out in turn (estimated with the
others only), and structures outside the family (``OUTSIDERS``, their tables rendered here over the atlas's
cells). The single-light means of a hair are its structure's own tables at shine 0.3; the answer is judged as
the layered swatch's colour of it against the truth's (ΔE2000). Readings:

- ``family``: the family's mean (what the estimate does);
- ``best``: the member whose tables fit the single-light means best (``inference.shine.estimate_shine``);
- ``mixture``: a geometric mixture of the members' tables fitted to the single-light means (simplex weights);
- ``soft``: the members weighted by their misfits, exp(-(m / m_best)^2).
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import minimize

from hairdigi.app.evaluation.bench_atlas import HAIRS
from hairdigi.app.evaluation.registry import BENCH_OUT
from hairdigi.app.evaluation.results import Result
from hairdigi.inference.atlas import CURVE_CELL, SHINE_CELL, cells
from hairdigi.inference.atlas import load as load_atlas
from hairdigi.inference.atlas_build import _render_ladder, box_view
from hairdigi.inference.refine import RefineSettings, ResponseCurve
from hairdigi.inference.shine import ShineTables, estimate_shine
from hairdigi.inference.structure import READ_MEMBERS, _averaged
from hairdigi.render.domain.appearance import Appearance
from hairdigi.render.domain.rig_geometry import N_LIGHTS, Framing
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.renderer import SceneSpec, default_renderer
from hairdigi.render.swatch_family import FAMILY

#: Structures outside the family the readings are tried on (``render.swatch_family.STRUCTURES``).
OUTSIDERS = ("clumped", "thin", "wavy")
#: The rig's swatch region in the atlas's cells: curves' (8 px) rows and columns, shine tables' (16 px).
CURVE_CELLS = (slice(5, 28), slice(4, 20))
SHINE_CELLS = (slice(3, 13), slice(2, 10))
SHINE = 0.3
READINGS = ("family", "best", "mixture", "soft")


def _outsider_tables(member: str, levels: np.ndarray, betas: np.ndarray, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """(K,) curve and (L, B, K) shine tables of ``member`` over the swatch region, rendered over the atlas's cells."""
    renderer, (region, film, crop) = default_renderer(), box_view()
    spec = SceneSpec("swatch", camera=region.pose, framing=Framing.RIG, target=region.target,
                     half_width=region.half_width, crop=crop, strand_seed=0, swatch_model=member)
    curve = cells(_render_ladder(renderer, spec, film, levels, spp, 7), CURVE_CELL)[:, CURVE_CELLS[0], CURVE_CELLS[1]]
    shine = np.empty((N_LIGHTS, len(betas), len(levels)))
    for light in range(N_LIGHTS):
        lights = tuple(1.0 if j == light else 0.0 for j in range(N_LIGHTS))
        for b, beta in enumerate(betas):
            one = replace(spec, lights=lights, appearance=Appearance(float(beta)))
            table = cells(_render_ladder(renderer, one, film, levels, spp, 7), SHINE_CELL)
            shine[light, b] = table[:, SHINE_CELLS[0], SHINE_CELLS[1]].mean(axis=(-2, -1))
    return curve.mean(axis=(-2, -1)), shine


def _fit_mixture(single: np.ndarray, members: list[str], shine: dict, betas: np.ndarray, levels: np.ndarray):
    """Simplex weights of ``members`` whose geometric mixture of tables fits ``single`` best, and its misfit."""
    logs = [np.log(np.clip(shine[m].means, 1e-12, None)) for m in members]

    def weights(z):
        w = np.exp(z - z.max())
        return w / w.sum()

    def loss(z):
        tables = ShineTables(betas, levels.copy(), np.exp(sum(wi * lg for wi, lg in zip(weights(z), logs))))
        return estimate_shine(single, tables, steps=15).residual

    starts = [np.zeros(len(members))] + [3.0 * row for row in np.eye(len(members))]
    best = min((minimize(loss, s, method="Nelder-Mead", options={"maxiter": 300, "xatol": 1e-3, "fatol": 1e-6})
                for s in starts), key=lambda r: r.fun)
    return weights(best.x), float(best.fun)


def replay(outsiders: tuple[str, ...] = OUTSIDERS, spp: int = 64, say=print) -> list[dict]:
    """One row per (structure, hair): each reading's error against the truth, and the misfits."""
    atlas, levels = load_atlas(), np.asarray(RefineSettings().levels, float)
    betas = atlas.betas
    curve = {m: _averaged([ResponseCurve(levels.copy(), atlas.curves[(m, s)][:, CURVE_CELLS[0], CURVE_CELLS[1]]
                                         .mean(axis=(1, 2))) for s in (0, 1)]) for m in FAMILY}
    shine = {m: ShineTables(betas, levels.copy(), atlas.shine[m][..., SHINE_CELLS[0], SHINE_CELLS[1]]
                            .astype(float).mean(axis=(-2, -1))) for m in READ_MEMBERS}
    for member in outsiders:
        start = time.perf_counter()
        own_curve, own_shine = _outsider_tables(member, levels, betas, spp)
        curve.setdefault(member, ResponseCurve(levels.copy(), own_curve))
        shine[member] = ShineTables(betas, levels.copy(), own_shine)
        say(f"{member}: its tables rendered in {time.perf_counter() - start:.0f} s")
    layered, rows = curve["layered"], []
    for structure in list(READ_MEMBERS) + list(outsiders):
        members = [m for m in READ_MEMBERS if m != structure]
        family = _averaged([curve[m] for m in FAMILY if m != structure])
        for hair, sigma in HAIRS.items():
            if hair == "black":            # its colour is the fibres' surface: every reading answers alike
                continue
            sigma = np.asarray(sigma, float)
            single, colour = shine[structure].predict(sigma, SHINE), curve[structure](sigma)
            misfits = {m: estimate_shine(single, shine[m]).residual for m in members}
            best = min(misfits, key=misfits.get)
            weights, residual = _fit_mixture(single, members, shine, betas, levels)
            m = np.array([misfits[k] for k in members])
            soft = np.exp(-(m / m.min()) ** 2)
            answers = {"family": family, "best": curve[best], "mixture": _averaged([curve[k] for k in members],
                                                                                    list(weights)),
                       "soft": _averaged([curve[k] for k in members], list(soft / soft.sum()))}
            row = {"structure": structure, "outside": structure in outsiders, "hair": hair, "best_member": best,
                   "best_misfit": round(min(misfits.values()), 4), "mixture_misfit": round(residual, 4),
                   "mixture": " ".join(f"{k} {w:.2f}" for k, w in zip(members, weights) if w >= 0.01)}
            for name, c in answers.items():
                row[f"{name}_de2000"] = round(float(delta_e2000(layered(c.inverse(colour)[0]), layered(sigma))), 3)
            rows.append(row)
    return rows


def summary(rows: list[dict]) -> dict:
    """Median and p90 of each reading, for the members left out and for the outsiders."""
    out = {}
    for group, outside in (("members left out", False), ("outside the family", True)):
        chosen = [r for r in rows if r["outside"] == outside]
        out[group] = {name: {"median": round(float(np.median([r[f"{name}_de2000"] for r in chosen])), 2),
                             "p90": round(float(np.percentile([r[f"{name}_de2000"] for r in chosen], 90)), 2),
                             "n": len(chosen)} for name in READINGS}
    return out


def plot(rows: list[dict], path: Path) -> None:
    matplotlib.use("Agg")

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, outside in zip(axes, (False, True)):
        chosen = [r for r in rows if r["outside"] == outside]
        ax.boxplot([[r[f"{name}_de2000"] for r in chosen] for name in READINGS], tick_labels=READINGS)
        ax.set_title("outside the family" if outside else "each member left out")
    axes[0].set_ylabel("ΔE2000 against the truth")
    fig.suptitle("hairdigi bench structure-reading: continuous readings of the structure")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def bench_structure_reading(args: argparse.Namespace) -> Result:
    """The family's mean against continuous readings of the structure, on structures the reading does not know;
    writes ``structure_reading.csv``, ``.json`` and ``.png``."""
    out = Path("packaging/bench/structure-reading") if args.out == BENCH_OUT else Path(args.out)
    out.mkdir(parents=True, exist_ok=True)     # before the replay's minutes: a folder it cannot write stops it now
    rows = replay(OUTSIDERS[:1] if args.quick else OUTSIDERS, spp=16 if args.quick else 64)
    s = summary(rows)
    return Result("structure_reading", rows, s, plot=plot, text=[
        f"{group}: " + ", ".join(f"{k} {v['median']:.2f} / {v['p90']:.2f}" for k, v in readings.items())
        for group, readings in s.items()]).save(out)
