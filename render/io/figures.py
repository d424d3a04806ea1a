"""One way to save a matplotlib figure (headless, atomically, closed afterwards) and a benchmark's table."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib

from hairdigi.render.domain.files import atomic_path, write_csv_atomic, write_json_atomic

matplotlib.use("Agg")


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Write ``fig`` as PNG atomically, then close it."""
    import matplotlib.pyplot as plt   # deferred: pyplot costs 0.25 s; the tables' writers here need none

    try:
        with atomic_path(path, ".png") as tmp:
            fig.savefig(tmp, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    return Path(path)


def save_table(out_dir: str | os.PathLike, stem: str, rows: list[dict], plot, summary: dict | None = None) -> Path:
    """A benchmark's or an evaluation's results: ``stem.csv``, ``stem.png`` drawn by ``plot(rows, path)``
    and, with a ``summary``, ``stem.json`` holding it and the rows."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / f"{stem}.csv", rows)
    if summary is not None:
        write_json_atomic(out / f"{stem}.json", {"summary": summary, "rows": rows})
    plot(rows, out / f"{stem}.png")
    return out
