"""``hairdigi evaluate --readings``: the lab's instrument readings against hairdigi's, tress by tress.

For every tress the lab read (``hairdigi library readings``) and hairdigi captured (a swatch whose id,
capture id or tag is the tress's id), in each geometry: the mean of the lab's readings against the mean
of hairdigi's readings of that tress's swatches (``EstimateRecord.instrument``, D65/10°). The table
gives each tress's ΔE2000 and differences; the summary the median and p95 ΔE2000, the bias in L*, a*,
b*, and Bland & Altman's limits of agreement; the plot is their Bland-Altman plot: for each of L*, a*, b*,
the difference (hairdigi − instrument) against the mean of the two, the bias and its 95% limits drawn.
"""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from hairdigi.app.library.store import Library
from hairdigi.render.io.figures import save_table
from hairdigi.render.metrics import bland_altman, delta_e2000_lab, quantiles


def paired(library: Library, observer: str = "10", illuminant: str = "D65") -> list[dict]:
    """One row per tress and geometry that both the lab and hairdigi read (the lab's in ``observer``/``illuminant``)."""
    lab_means: dict[tuple[str, str], list] = {}
    for tress, geom, obs, ill, L, a, b, _source, _line in library.readings():
        if obs == observer and ill == illuminant:
            lab_means.setdefault((tress, geom), []).append((L, a, b))
    rows = []
    for (tress, geom), values in sorted(lab_means.items()):
        ours = [s.labs[geom] for s in library.swatches_of(tress) if geom in s.labs]
        if not ours:
            continue
        theirs, mine = np.mean(values, axis=0), np.mean(ours, axis=0)
        d = mine - theirs
        rows.append({"tress": tress, "geometry": geom, "instrument_readings": len(values), "hairdigi_readings": len(ours),
                     "de2000": round(float(delta_e2000_lab(mine, theirs)), 3),
                     "dL": round(float(d[0]), 3), "da": round(float(d[1]), 3), "db": round(float(d[2]), 3),
                     "instrument_L": round(float(theirs[0]), 2), "instrument_a": round(float(theirs[1]), 2),
                     "instrument_b": round(float(theirs[2]), 2), "hairdigi_L": round(float(mine[0]), 2),
                     "hairdigi_a": round(float(mine[1]), 2), "hairdigi_b": round(float(mine[2]), 2)})
    return rows


def summarise(rows: list[dict]) -> dict:
    out = {"tresses": len({r["tress"] for r in rows}), "by_geometry": {}}
    for geom in dict.fromkeys(r["geometry"] for r in rows):
        mine = [r for r in rows if r["geometry"] == geom]
        out["by_geometry"][geom] = {
            "de2000": quantiles([r["de2000"] for r in mine]),
            **{f"bland_altman_{c}": bland_altman([r[f"hairdigi_{c}"] for r in mine], [r[f"instrument_{c}"] for r in mine])
               for c in ("L", "a", "b")}}
    return out


def compare_readings(library: Library, out_dir: str | os.PathLike) -> dict:
    """Pair, summarise, and write ``readings_comparison.csv``, ``.json`` and the Bland-Altman ``.png``."""
    rows = paired(library)
    summary = summarise(rows)
    save_table(out_dir, "readings_comparison", rows, _plot, summary)
    return summary


def _plot(rows: list[dict], path: Path) -> None:
    matplotlib.use("Agg")
    geometries = list(dict.fromkeys(r["geometry"] for r in rows)) or ["none"]
    fig, axes = plt.subplots(len(geometries), 3, figsize=(12, 3.4 * len(geometries)), squeeze=False)
    for g, geom in enumerate(geometries):
        mine = [r for r in rows if r["geometry"] == geom]
        for c, channel in enumerate(("L", "a", "b")):
            ax = axes[g, c]
            ours = np.array([r[f"hairdigi_{channel}"] for r in mine], float)
            theirs = np.array([r[f"instrument_{channel}"] for r in mine], float)
            ax.scatter((ours + theirs) / 2, ours - theirs, s=16)
            if len(mine) > 1:
                ba = bland_altman(ours, theirs)
                for value, style in ((ba["bias"], "-"), (ba["lower"], "--"), (ba["upper"], "--")):
                    ax.axhline(value, color="tab:red" if style == "-" else "grey", ls=style, lw=1)
                ax.set_title(f"{geom}: {channel}*  bias {ba['bias']:+.2f}, limits {ba['lower']:+.2f} to {ba['upper']:+.2f}",
                             fontsize=9)
            ax.set_xlabel(f"mean of the two {channel}*")
            ax.set_ylabel(f"hairdigi − instrument ({channel}*)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
