"""``hairdigi bench dataset``: swatches per second of dataset rendering, local pool against Ray.

Four cases render the same small dataset into fresh folders: the local backend with 1 and 2 worker
processes, and the Ray backend on a local Ray instance with 1 and 2 CPUs (one CPU per task). Each
time is the whole ``generate`` call as a user waits for it: process or Ray start, scene load and
kernel compile included, so on a small dataset it favours the backends that start fastest (the
local backend with one worker renders in this process, which has Mitsuba loaded already). Every
case must give the same arrays as the first (``identical``): the backends share one core.

The machine's 1-minute load average is recorded beside each case (``load_1min``): figures taken
while other jobs run measure those jobs too; quote only figures from an idle machine.
"""
from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hairdigi.inference.training.cluster import ClusterError, require_ray
from hairdigi.inference.training.dataset import DatasetConfig, generate, shard_path
from hairdigi.render.domain.bounds import defaults_for
from hairdigi.render.domain.files import write_csv_atomic
from hairdigi.render.io.figures import save_figure
from hairdigi.render.variant import select_variant

#: (backend, workers): workers are pool processes (local) or the local Ray instance's CPUs (ray).
CASES = (("local", 1), ("local", 2), ("ray", 1), ("ray", 2))


def bench_config(quick: bool = False, n: int | None = None) -> DatasetConfig:
    """The benchmark's dataset: 16 swatches of 64² at 4 spp (quick: 4 of 16² at 1 spp, 150 strands),
    in about 8 shards so that two workers share the work."""
    n = n if n is not None else (4 if quick else 16)
    if n < 1:
        raise ValueError(f"bench dataset --n must be at least 1, got {n}")

    return DatasetConfig(n=n, size=16 if quick else 64, spp=1 if quick else 4, seed=7,
                         strands=150 if quick else defaults_for("swatch").strands,
                         max_depth=defaults_for("swatch").max_depth, shard_size=max(1, n // 8))


def _arrays(root: Path, config: DatasetConfig) -> list[dict]:
    return [dict(np.load(shard_path(root, s))) for s in range(config.n_shards)]


def _same(a: list[dict], b: list[dict]) -> bool:
    return len(a) == len(b) and all(x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)
                                    for x, y in zip(a, b))


def run_dataset_bench(out_dir: str | os.PathLike, quick: bool = False, n: int | None = None) -> list[dict]:
    """Time every case, write ``dataset_bench.csv`` and ``dataset_bench.png``; return the rows.

    Without Ray installed, the Ray cases are left out (with a note on stderr).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    config = bench_config(quick, n)
    variant = select_variant()

    try:
        require_ray()
        cases = CASES
    except ClusterError:
        print("bench dataset: Ray is not installed (pip install 'hairdigi[cluster]'); timing the local "
              "backend only", file=sys.stderr)
        cases = tuple(c for c in CASES if c[0] != "ray")
    scratch = out / ".dataset-bench"
    shutil.rmtree(scratch, ignore_errors=True)
    rows, first = [], None
    try:
        for backend, workers in cases:
            root = scratch / f"{backend}-{workers}"
            load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
            start = time.perf_counter()
            generate(config, root, workers=workers, progress=False, backend=backend, variant=variant)
            seconds = time.perf_counter() - start
            arrays = _arrays(root, config)
            first = arrays if first is None else first
            rows.append({"backend": backend, "workers": workers, "n": config.n, "size": config.size,
                         "spp": config.spp, "strands": config.strands, "shards": config.n_shards,
                         "seconds": seconds, "swatches_per_s": config.n / seconds,
                         "identical": _same(arrays, first), "variant": variant, "load_1min": load})
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    write_csv_atomic(out / "dataset_bench.csv", rows)
    plot_dataset_bench(rows, out / "dataset_bench.png")
    return rows


def plot_dataset_bench(rows: list[dict], path: Path) -> Path:
    """Bars of swatches per second, one per case."""
    fig, ax = plt.subplots(figsize=(6, 4))
    labels = [f"{r['backend']}\n{r['workers']} {'worker' if r['backend'] == 'local' else 'CPU'}"
              f"{'s' if r['workers'] > 1 else ''}" for r in rows]
    rates = [r["swatches_per_s"] for r in rows]
    bars = ax.bar(labels, rates, color=["tab:blue" if r["backend"] == "local" else "tab:orange" for r in rows])
    for bar, r in zip(bars, rows):
        ax.annotate(f"{r['swatches_per_s']:.2f}", (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                    ha="center", va="bottom", fontsize=8)
    r0 = rows[0]
    ax.set_ylabel("swatches per second (start-up included)")
    ax.set_title(f"hairdigi bench dataset: {r0['n']} swatches, {r0['size']}², {r0['spp']} spp, "
                 f"{r0['strands']} strands, {r0['variant']}\nload average at start: "
                 + ", ".join(f"{r['load_1min']:.1f}" for r in rows), fontsize=9)
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)
