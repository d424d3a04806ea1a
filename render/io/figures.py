"""One way to save a matplotlib figure: headless (Agg), atomically, closed afterwards."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

matplotlib.use("Agg")


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Write ``fig`` as PNG through a temporary file and a rename, then close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return path


def save_table(out_dir: str | os.PathLike, stem: str, rows: list[dict], plot) -> Path:
    """A benchmark's results: ``stem.csv`` (atomic) and ``stem.png`` drawn by ``plot(rows, path)``."""
    from hairdigi.render.bench import write_csv_atomic

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / f"{stem}.csv", rows)
    plot(rows, out / f"{stem}.png")
    return out
