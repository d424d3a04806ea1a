"""How the image metrics and their noise floor fall as the renders get more samples per pixel.

The paper's L1 compares single renders pixel by pixel, so at low spp it measures render noise
more than the estimate. ``noise_sweep`` keeps each held-out swatch's estimate (made once, from the
held-out image) and renders, at each spp, the original (true parameters, the sample's seed), the
floor (true parameters, a new seed) and the estimate (estimated parameters, that new seed). It
writes ``noise_sweep.csv`` and ``noise_sweep.png``: render seconds against L1 and mean-colour ΔE2000.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from inference.dataset import DatasetConfig, load, usable
from inference.evaluate import _rerender, _whole, image_metrics
from render.params import HairParams

METRICS = ("l1", "l1_blocks4", "mean_colour_de2000", "pixel_de2000", "ms_ssim")


def noise_sweep(encoder, data_root: str | os.PathLike, out_dir: str | os.PathLike, spps=(4, 16, 64),
                count: int = 10, progress: bool = True) -> list[dict]:
    """One row per spp: the mean of each metric for the estimate and the floor, and the render time."""
    from tqdm import tqdm

    from render.bench import write_csv_atomic

    images, vectors, cameras, manifest = load(data_root)
    config = DatasetConfig(**manifest["config"])   # the held-out set's own scene settings
    indices = np.flatnonzero(usable(cameras))[:count].tolist()
    estimates = {i: encoder.estimate(images[i], roi=_whole(images[i]), views=True).params for i in indices}
    rows = []
    for spp in tqdm(spps, desc="noise sweep", unit="spp", disable=not progress):
        per = {f"{who}_{m}": [] for who in ("est", "floor") for m in METRICS}
        seconds = []
        for i in indices:
            truth = HairParams.from_vector(vectors[i])
            t0 = time.perf_counter()
            original = _rerender(config, i, truth, spp, seed_offset=0)
            seconds.append(time.perf_counter() - t0)
            for who, params in (("floor", truth), ("est", estimates[i])):
                for m, v in image_metrics(original, _rerender(config, i, params, spp)).items():
                    per[f"{who}_{m}"].append(v)
        rows.append({"spp": spp, "swatches": len(indices), "render_s": float(np.median(seconds)),
                     **{k: float(np.mean(v)) for k, v in per.items() if v}})
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / "noise_sweep.csv", rows)
    _plot(rows, out / "noise_sweep.png")
    return rows


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    x = [r["render_s"] for r in rows]
    for ax, metric, name in ((axes[0], "l1", "L1 (0–255) vs original"),
                             (axes[1], "mean_colour_de2000", "mean-colour ΔE2000 (mean)")):
        ax.plot(x, [r[f"est_{metric}"] for r in rows], "o-", label="estimate re-rendered")
        ax.plot(x, [r[f"floor_{metric}"] for r in rows], "s--", label="noise floor (true parameters)")
        for r in rows:
            ax.annotate(f"{r['spp']} spp", (r["render_s"], r[f"est_{metric}"]), fontsize=7, xytext=(4, 4),
                        textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("render time per swatch (s, 2 CPU cores)")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"hairdigi evaluate --noise-sweep: {rows[0]['swatches']} held-out swatches")
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}")
    fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    os.replace(tmp, path)
