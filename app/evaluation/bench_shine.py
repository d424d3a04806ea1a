"""``hairdigi bench shine``: can the rig's three lights, one at a time, read the shine?

Held-out swatches of known shine (longitudinal roughness beta_m) and colour are rendered in the rig's
swatch area under each light alone, with another strand layout and sampler seed than the tables'.
``inference.shine.estimate_shine`` reads beta_m and sigma_a from the three means. Each answer, and
today's answer (sigma_a fitted to the all-lights colour with beta_m held at 0.3), is then judged
against the truth where neither was fitted: another camera (35° / 120°) in the crop framing under
the same rig (the transfer), and under each light alone.
"""
from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import least_squares

from hairdigi.inference.refine import RefineSettings, response_curve, scene_for
from hairdigi.inference.shine import estimate_shine, shine_tables
from hairdigi.render.domain.absorption import LONGITUDINAL_ROUGHNESS, hair_sigma_a
from hairdigi.render.domain.appearance import Appearance
from hairdigi.render.domain.files import write_csv_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import N_LIGHTS, CameraPose, RigRegion, swatch_roi
from hairdigi.render.fibres import FIBRE_GROUPS, group_z
from hairdigi.render.io.figures import save_figure
from hairdigi.render.judge import judge_mean
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.renderer import SceneSpec, default_renderer

#: Held-out shine values (the tables' grid is 0.1-0.6) and colours (copper, platinum, dark brown).
BETAS = (0.12, 0.22, 0.35, 0.5)
HAIRS = {"copper": HairParams((190, 80, 40), 0.5, 0.5, 0.6), "platinum": HairParams((245, 240, 225), 0.15, 0.04, 0.2),
         "dark brown": HairParams((60, 40, 30), 0.2, 0.8, 0.9)}
CAPTURE_SPP, CAPTURE_SEED, CAPTURE_STRANDS = 64, 99, 3


def run_shine_bench(out_dir: str | os.PathLike, quick: bool = False) -> list[dict]:
    size = (400, 300)
    view = RigRegion(size, swatch_roi(size))
    settings = RefineSettings()
    renderer = default_renderer()
    tables = shine_tables(view, settings)
    tables_s = tables.seconds          # what rendering them cost (once per view; cached on disk)
    today = response_curve(view, settings)            # the all-lights curve at beta_m 0.3, as refinement uses
    spec, film = scene_for(view, settings)
    capture = replace(spec, strand_seed=CAPTURE_STRANDS)
    transfer = SceneSpec("swatch", camera=CameraPose(35.0, 120.0), framing="crop")
    betas, hairs = (BETAS[::3], dict(list(HAIRS.items())[:1])) if quick else (BETAS, HAIRS)
    rows = []
    for name, hair in hairs.items():
        sigma = hair_sigma_a(hair)
        for beta in betas:
            single = np.array([renderer.render(sigma, replace(capture, lights=tuple(float(i == light) for i in
                                                                                     range(N_LIGHTS)),
                                                              appearance=Appearance(beta)), film, CAPTURE_SPP,
                                               CAPTURE_SEED).linear.reshape(-1, 3).mean(0)
                               for light in range(N_LIGHTS)])
            t0 = time.perf_counter()
            est = estimate_shine(single, tables)
            estimate_s = time.perf_counter() - t0
            fixed_sigma, _ = today.inverse(single.sum(0))

            def de(scene, s, b):
                truth, _ = judge_mean(sigma, replace(scene, appearance=Appearance(beta)))
                mine, _ = judge_mean(np.asarray(s), replace(scene, appearance=Appearance(b)))
                return float(delta_e2000(np.clip(mine, 1e-9, None), np.clip(truth, 1e-9, None)))

            row = {"hair": name, "beta": beta, "beta_estimate": round(est.longitudinal_roughness, 4),
                   "beta_error": round(abs(est.longitudinal_roughness - beta), 4), "misfit": est.residual,
                   "light0_share": round(float(single[0].sum() / single.sum()), 4), "estimate_s": round(estimate_s, 4),
                   "transfer_de2000": de(transfer, est.sigma_a, est.longitudinal_roughness),
                   "transfer_de2000_fixed_shine": de(transfer, fixed_sigma, LONGITUDINAL_ROUGHNESS)}
            rows.append(row)
            print(f"{name:10s} beta {beta:.2f}: read {est.longitudinal_roughness:.3f}; transfer ΔE2000 "
                  f"{row['transfer_de2000']:.2f} (shine held at 0.3: {row['transfer_de2000_fixed_shine']:.2f})",
                  flush=True)
    for r in rows:
        r["tables_s"] = round(tables_s, 2)
    out = Path(out_dir)
    write_csv_atomic(out / "shine_bench.csv", rows)
    _plot(rows, out / "shine_bench.png")
    return rows


def _plot(rows: list[dict], path: Path) -> None:
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
    for name in sorted({r["hair"] for r in rows}):
        mine = [r for r in rows if r["hair"] == name]
        a.plot([r["beta"] for r in mine], [r["beta_estimate"] for r in mine], "o-", label=name)
        b.plot([r["beta"] for r in mine], [r["transfer_de2000"] for r in mine], "o-", label=f"{name}, shine read")
        b.plot([r["beta"] for r in mine], [r["transfer_de2000_fixed_shine"] for r in mine], "x--",
               label=f"{name}, shine held at 0.3")
    a.plot([0.1, 0.6], [0.1, 0.6], color="grey", lw=0.8)
    a.set_xlabel("true longitudinal roughness")
    a.set_ylabel("read from the three lights")
    b.set_xlabel("true longitudinal roughness")
    b.set_ylabel("ΔE2000, another camera")
    b.legend(fontsize=6)
    a.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


#: The spread bench's hairs (sigma_a per fibre radius) and shines; spreads up to the draw's top (0.5) and past it.
SPREAD_HAIRS = {"platinum": (0.05, 0.08, 0.15), "brown": (0.35, 0.6, 1.2), "dark": (2.0, 3.0, 5.0)}
SPREAD_BETAS, SPREADS = (0.2, 0.35), (0.0, 0.25, 0.5, 0.75, 1.0)


def spread_from_means(tables) -> list[dict]:
    """Can the three single-light means tell a fibre spread from uniform fibres? For each hair, shine
    and spread, the nine means of the varied swatch (each pigment group on the per-light tables, as
    ``refine.varied_curve`` mixes them) are fitted by uniform fibres (sigma_a and shine free, least
    squares in log, as ``estimate_shine``); the rms log misfit left is what a reading could use.
    Pure arithmetic on ``tables`` (``inference.shine.ShineTables``)."""
    z = group_z(FIBRE_GROUPS)
    rows = []
    for name, sigma in SPREAD_HAIRS.items():
        sigma = np.asarray(sigma, float)
        for beta in SPREAD_BETAS:
            for spread in SPREADS:
                target = np.mean([tables.predict(sigma * np.exp(spread * zz), beta) for zz in z], 0)

                def misfit(p: np.ndarray) -> np.ndarray:
                    return (np.log(tables.predict(np.exp(p[:3]), p[3])) - np.log(target)).ravel()

                fit = least_squares(misfit, np.r_[np.log(sigma), beta],
                                    bounds=([-9.0] * 3 + [tables.betas[0]], [5.0] * 3 + [tables.betas[-1]]))
                rows.append({"hair": name, "beta": beta, "spread": spread,
                             "uniform_misfit_rms_log": round(float(np.sqrt(np.mean(fit.fun ** 2))), 5),
                             "uniform_beta": round(float(fit.x[3]), 4),
                             "uniform_sigma_a": [round(float(v), 4) for v in np.exp(fit.x[:3])]})
    return rows


def run_spread_bench(out_dir: str | os.PathLike, capture_misfit: float | None = None) -> list[dict]:
    """``spread_from_means`` at the bench camera's swatch area (the tables rendered or loaded), written
    with a plot against ``capture_misfit`` (a real capture's shine misfit, for scale)."""
    size = (400, 300)
    rows = spread_from_means(shine_tables(RigRegion(size, swatch_roi(size)), RefineSettings()))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / "spread_bench.csv", rows)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for name in SPREAD_HAIRS:
        for beta, style in zip(SPREAD_BETAS, ("-", "--")):
            sel = [r for r in rows if r["hair"] == name and r["beta"] == beta]
            ax.plot([r["spread"] for r in sel], [r["uniform_misfit_rms_log"] for r in sel], style, marker="o",
                    label=f"{name}, shine {beta:g}")
    if capture_misfit is not None:
        ax.axhline(capture_misfit, color="grey", ls=":", label=f"a rig capture's own misfit ({capture_misfit:g})")
    ax.axvspan(0, 0.5, color="0.92", zorder=0)
    ax.set_xlabel("fibre spread (std of ln σa)")
    ax.set_ylabel("uniform fibres' best misfit (rms log)")
    ax.set_title("the lights' nine means: spread against uniform fibres", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, out / "spread_bench.png")
    return rows
