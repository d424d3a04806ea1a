"""The estimate's error against the input's convergence: does the encoder read hair, or render noise?

``convergence_sweep`` re-renders the first held-out swatches as inputs at several spp (the sample's
own camera, strand layout and seed), shoots each through the camera model, estimates it (encoder
alone, and refined), and judges each estimate as ``evaluate`` does (common-seed renders against the
truth). Flat rows mean the estimate does not depend on render noise. Writes ``convergence.csv``
and ``convergence.png``: input spp against the mean-colour ΔE2000.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.inference.training.dataset import DatasetConfig, load, sample_spec, scene_of
from hairdigi.inference.training.evaluate import JUDGE, Judge, capture, judge_file, judge_render
from hairdigi.inference.refine import RefineSettings, mean_linear, refine
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.domain.params import HairParams
from hairdigi.render.io.figures import save_figure, save_table


def convergence_sweep(encoder, data_root: str | os.PathLike, out_dir: str | os.PathLike,
                      spps=(4, 16, 64, 256), count: int = 20, settings: RefineSettings = RefineSettings(),
                      judge: Judge = JUDGE, progress: bool = True) -> list[dict]:
    """One row per input spp: median, p95 and worst mean-colour ΔE2000 of the encoder and the refinement."""
    # deferred: loads OpenCV and Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.inference.preprocess import Roi
    from hairdigi.render.renderer import default_renderer

    images, vectors, _, manifest = load(data_root)
    config = DatasetConfig(**manifest["config"])
    truths = dict(np.load(judge_file(data_root, judge)))
    indices = range(min(count, len(images)))
    rows = []
    for spp in tqdm(spps, desc="input convergence", unit="spp", disable=not progress):
        enc_de, ref_de, seconds = [], [], []
        for i in indices:
            s = sample_spec(config, i)
            t0 = time.perf_counter()
            linear = default_renderer().render(HairParams.from_vector(vectors[i]), scene_of(config, i),
                                               config.size, spp, s.render_seed).linear
            seconds.append(time.perf_counter() - t0)
            frame = capture(linear, i)
            truth = truths[f"truth_{i}"].astype(np.float32).reshape(-1, 3).mean(0)
            est = encoder.estimate(frame, roi=Roi(0, 0, frame.shape[1], frame.shape[0]))
            judged = lambda hair: judge_render(config, i, hair, judge).linear.reshape(-1, 3).mean(0)  # noqa: E731
            enc_de.append(float(delta_e2000(judged(est.params), truth)))
            r = refine(est.params, mean_linear(frame), s.camera, settings)
            ref_de.append(float(delta_e2000(judged(r.params), truth)))
        rows.append({"spp": spp, "swatches": len(enc_de), "render_s": float(np.median(seconds)),
                     "encoder_de_median": float(np.median(enc_de)), "encoder_de_p95": float(np.quantile(enc_de, .95)),
                     "encoder_de_max": float(np.max(enc_de)), "refined_de_median": float(np.median(ref_de)),
                     "refined_de_p95": float(np.quantile(ref_de, .95)), "refined_de_max": float(np.max(ref_de))})
    save_table(out_dir, "convergence", rows, _plot)
    return rows


def _plot(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6, 4))
    spp = [r["spp"] for r in rows]
    for who, style in (("encoder", "o-"), ("refined", "s-")):
        ax.plot(spp, [r[f"{who}_de_median"] for r in rows], style, label=f"{who}, median")
        ax.plot(spp, [r[f"{who}_de_p95"] for r in rows], style, alpha=0.4, label=f"{who}, p95")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("input samples per pixel (64² swatch)")
    ax.set_ylabel("mean-colour ΔE2000 against the truth")
    ax.grid(True, alpha=0.3)
    ax.legend()
    save_figure(fig, path)
