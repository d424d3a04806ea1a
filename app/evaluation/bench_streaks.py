"""``hairdigi bench streaks``: what the swatch area's texture says of how its fibres lie.

Family members (``render.swatch_family.FAMILY``) hide hairs under the simulated rig: the rig
evaluation's 10 hidden hairs (``app.evaluation.rig.hidden_set``: black, platinum, saturated dyes, the
demo's copper, 5 random) in layout 0, each in the two structures ``hairdigi evaluate --rig`` hides it in
(layered, and ``DRAWN``'s turn), and ``--n`` other Table 1 draws in layout 1 in every member. Each is captured
as ``hairdigi evaluate --rig`` captures it: a live frame through the camera model's noise (two noise
seeds); every other evaluation hair also from its tilted camera; and a RAW still of twice the feed's
resolution (a 12-bit Bayer DNG read back through rawpy, its swatch area scaled to the feed's width).
``inference.texture.streaks`` is read on each swatch area, and ``inference.structure.read_texture``'s
thresholds classify it. The table gives each capture's statistics and class; the summary, per member
and per source, the share read streak-free, streaked and undecided: the weights of
``structure.TEXTURE_MEMBERS`` (streak-free). The light images are the rig's own, cached (a later ``evaluate --rig``
of the same hairs renders nothing new).
"""
from __future__ import annotations

import tempfile
from collections import Counter, defaultdict
from pathlib import Path

import cv2
import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.app.evaluation.rig import POSE_HALF_WIDTH, POSES, RigSet, hidden_set, hidden_structure
from hairdigi.hardware.cameras import read_raw
from hairdigi.hardware.sim_rig import render_light_images
from hairdigi.hardware.sim_still import write_raw_still
from hairdigi.inference.preprocess import to_linear
from hairdigi.inference.refine import fitted_pixels
from hairdigi.inference.structure import STREAK_FREE_ORDER, STREAKED, read_texture
from hairdigi.render.camera_model import NOMINAL_EXPOSURE, CameraModel, sensor_response
from hairdigi.render.domain.params import sample_params
from hairdigi.render.domain.rig_geometry import CameraPose, RigRegion, swatch_roi
from hairdigi.render.io.figures import save_table
from hairdigi.render.swatch_family import FAMILY

SEED = 2026_1127
NOISE_SEEDS = (0, 1)
#: The structures ``hairdigi evaluate --rig --hidden-structures`` hides the evaluation's hairs in, in turn.
DRAWN = ("deposited", "tilted", "spread", "wavy", "loose", "deposited-coarse")


def _hairs(n: int) -> list[tuple[str, object, int, bool]]:
    """(name, Table 1 parameters, layout, an evaluation hair) of every hidden hair."""
    rng = np.random.default_rng(SEED)
    return ([(name, p, 0, True) for name, p in hidden_set(RigSet())]
            + [(f"draw {i}", sample_params(rng), 1, False) for i in range(n)])


def _captures(params, member: str, layout: int, k: int, evaluated: bool, folder: Path, tilted: bool = True):
    """(source, RigRegion, linear swatch frame) of one hidden swatch, as the rig evaluation captures it."""
    model = None if member == "layered" else member
    images, _ = render_light_images(params, strand_seed=layout, swatch_model=model)
    radiance = images.sum(0) * NOMINAL_EXPOSURE
    size = (radiance.shape[1], radiance.shape[0])
    for seed in NOISE_SEEDS:
        srgb = sensor_response(radiance, CameraModel(), np.random.default_rng(seed))
        yield "live", RigRegion(size, swatch_roi(size)), to_linear(srgb)
    if not evaluated:
        return
    still = write_raw_still(folder / "still.dng", np.clip(cv2.resize(radiance, None, fx=2, fy=2,
                                                                     interpolation=cv2.INTER_NEAREST) * 0.8, 0, 1))
    big = (2 * size[0], 2 * size[1])
    yield "raw still", RigRegion(big, swatch_roi(big)), read_raw(still).linear
    if tilted and k % 2 == 0:
        pose = CameraPose(*POSES[(k // 2) % len(POSES)])
        images, _ = render_light_images(params, strand_seed=layout, swatch_model=model, pose=pose,
                                        half_width=POSE_HALF_WIDTH)
        srgb = sensor_response(images.sum(0) * NOMINAL_EXPOSURE, CameraModel(), np.random.default_rng(0))
        yield "tilted camera", RigRegion(size, swatch_roi(size, pose=pose, half_width=POSE_HALF_WIDTH), pose), \
            to_linear(srgb)


def streaks_bench(out: str | Path, n: int = 8, members: tuple[str, ...] | None = None, tilted: bool = True,
                  hairs: int | None = None, progress: bool = True) -> dict:
    """Every member's streak statistics over the hidden hairs (``tilted``: with the tilted cameras' captures;
    ``hairs``: only the first so many); writes streaks.csv/.json/.png."""
    members = members or FAMILY
    drawn = RigSet(hidden_structures=DRAWN)
    jobs = [(k, hair, member) for k, hair in enumerate(_hairs(n)[:hairs]) for member in members
            if not hair[3] or member in ("layered", hidden_structure(drawn, k))]   # an evaluation hair: its two
    rows = []
    with tempfile.TemporaryDirectory(prefix="hairdigi-streaks-") as tmp:
        for k, (name, params, layout, evaluated), member in tqdm(jobs, desc="streaks", unit="swatch",
                                                                 disable=not progress):
            for source, region, frame in _captures(params, member, layout, k, evaluated, Path(tmp), tilted):
                reading = read_texture(fitted_pixels(frame, region), region)
                rows.append({"hair": name, "member": member, "layout": layout, "source": source,
                             "along": reading.along, "order": reading.order, "kind": reading.kind or "undecided"})
    summary = {"shares": _shares(rows), "n": len(rows),
               "settings": {"draws": n, "members": list(members), "tilted": tilted}}
    save_table(out, "streaks", rows, _plot, summary)
    return summary


def _shares(rows: list[dict]) -> dict:
    """Per member (and per member and source): the share of captures read as each texture class."""
    groups: dict[str, list[str]] = defaultdict(list)
    for r in rows:
        groups[r["member"]].append(r["kind"])
        groups[f"{r['member']} / {r['source']}"].append(r["kind"])
    return {g: {kind: round(c / len(kinds), 3) for kind, c in Counter(kinds).items()} | {"n": len(kinds)}
            for g, kinds in sorted(groups.items())}


def _plot(rows: list[dict], path: Path) -> None:
    matplotlib.use("Agg")

    fig, ax = plt.subplots(figsize=(8, 6))
    marks = {"live": "o", "raw still": "s", "tilted camera": "^"}
    members = sorted({r["member"] for r in rows})
    for i, member in enumerate(members):
        for source, mark in marks.items():
            pts = [(r["along"], r["order"]) for r in rows if r["member"] == member and r["source"] == source]
            if pts:
                x, y = zip(*pts)
                ax.scatter(x, y, marker=mark, color=f"C{i}", s=22, alpha=0.8,
                           label=member if source == "live" else None)
    ax.set_xscale("symlog", linthresh=0.01)
    ax.axhline(STREAK_FREE_ORDER, color="0.5", lw=0.8, ls="--")          # under it: streak-free
    right = ax.get_xlim()[1]                                              # streaked: the corner above and right
    ax.plot([STREAKED[0], STREAKED[0], right], [1.02, STREAKED[1], STREAKED[1]], color="0.3", lw=0.8, ls=":")
    ax.set_xlim(right=right)
    ax.set_xlabel("streaks along the fibres (autocorrelation, lags 4-16 px)")
    ax.set_ylabel("orientation order (0: none, 1: one direction)")
    ax.set_title("the swatch area's texture by structure (o live, □ RAW still, △ tilted camera)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
