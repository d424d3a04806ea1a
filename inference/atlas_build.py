"""Build the shipped atlas (``inference.atlas``): every family member's response curves in each layout and every
read member's shine tables, rendered once over the atlas's area at the bench camera, as cells; and the family's
curves at the rig's swatch pose (an all-hair crop's view), as cache entries (``ship_pose``).

``python -m hairdigi.inference.atlas_build`` (resumable: each table waits in ``--work`` once done); about
20 minutes on 2 cores (curves at 192 spp, shine tables at 48)."""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from hairdigi.inference.atlas import (ATLAS_PATH, BOX, CURVE_CELL, FRAME, PIXEL, POSE_AZIMUTHS, POSE_POLARS, POSES_PATH,
                                     SHINE_CELL, cells, fingerprint)
from hairdigi.inference.refine import SHIPPED_TABLES, RefineSettings, grid_settings, response_curve, view_key
from hairdigi.inference.shine import BETA_GRID
from hairdigi.inference.structure import FAMILY, LAYOUTS, READ_MEMBERS, family_curves
from hairdigi.render.domain.appearance import Appearance
from hairdigi.render.domain.files import atomic_path, cache_dir
from hairdigi.render.domain.rig_geometry import CAMERA_DISTANCE, N_LIGHTS, RIG_SWATCH_POSE, CameraPose, Framing, RigRegion
from hairdigi.render.renderer import SceneSpec, default_renderer


@contextlib.contextmanager
def atlases_off():
    """Within it every table is rendered at its own view (or read from the cache of renders), never read back from
    a shipped atlas: what a build ships must be renders."""
    before = os.environ.get("HAIRDIGI_ATLAS")
    os.environ["HAIRDIGI_ATLAS"] = "off"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("HAIRDIGI_ATLAS", None)
        else:
            os.environ["HAIRDIGI_ATLAS"] = before


def box_view() -> tuple[RigRegion, tuple[int, int], tuple[int, int, int, int]]:
    """The atlas's area as a rig region of the canonical frame, its film size and its crop (film pixels)."""
    film = (FRAME[0] // PIXEL, FRAME[1] // PIXEL)
    return RigRegion(FRAME, BOX), film, tuple(v // PIXEL for v in BOX)


def _render_ladder(renderer, spec, film, levels: np.ndarray, spp: int, seed: int) -> np.ndarray:
    """(K, H, W) film-pixel means of one channel per level: three levels per render, one per channel."""
    order = levels.reshape(3, -1).T
    out = np.empty((len(levels), spec.crop[3], spec.crop[2]))
    for t, triple in enumerate(order):
        image = renderer.render(triple, spec, film, spp, seed).linear
        for channel in range(3):
            out[t + channel * len(order)] = image[..., channel]
    return out


def build(out: str | os.PathLike = ATLAS_PATH, spp: int = 192, seed: int = 7, renderer=None,
          work: str | os.PathLike | None = None, say=print, shine_spp: int = 48) -> Path:
    """Render the atlas (every family member's curves in each layout, every read member's shine tables) and
    write it to ``out``; each table is kept in ``work`` as it is done, so a stopped build resumes there. The curves
    are rendered at ``spp``, the shine tables (24 times as many renders, read as ratios) at ``shine_spp``: the
    family's map is a ratio of one curve to the mean of 14, and the one curve's noise is most of its noise."""
    renderer = renderer or default_renderer()
    work = Path(work or cache_dir() / "atlas-work")
    work.mkdir(parents=True, exist_ok=True)
    levels, betas = np.asarray(RefineSettings().levels, float), np.asarray(BETA_GRID, float)
    region, film, crop = box_view()
    jobs = [("curve", m, s) for m in FAMILY for s in range(LAYOUTS)] + [("shine", m, 0) for m in READ_MEMBERS]
    arrays, seconds = {}, {}
    for i, (kind, member, layout) in enumerate(jobs, 1):
        name = f"{kind}__{member}__{layout}" if kind == "curve" else f"{kind}__{member}"
        samples = spp if kind == "curve" else shine_spp
        part = work / f"{name}-{samples}-{seed}.npy"
        if part.exists():
            arrays[name] = np.load(part)
            say(f"[{i}/{len(jobs)}] {name}: done before")
            continue
        start = time.perf_counter()
        spec = SceneSpec("swatch", camera=region.pose, framing=Framing.RIG, target=region.target,
                         half_width=region.half_width, crop=crop, strand_seed=layout, swatch_model=member)
        if kind == "curve":
            table = cells(_render_ladder(renderer, spec, film, levels, samples, seed), CURVE_CELL).astype(np.float32)
        else:
            table = np.empty((N_LIGHTS, len(betas), len(levels), BOX[3] // SHINE_CELL, BOX[2] // SHINE_CELL))
            for light in range(N_LIGHTS):
                lights = tuple(1.0 if j == light else 0.0 for j in range(N_LIGHTS))
                for b, beta in enumerate(betas):
                    one = replace(spec, lights=lights, appearance=Appearance(float(beta)))
                    table[light, b] = cells(_render_ladder(renderer, one, film, levels, samples, seed), SHINE_CELL)
            table = table.astype(np.float32)
        with atomic_path(part, ".npy") as tmp:
            np.save(tmp, table)
        arrays[name] = table
        seconds[name] = round(time.perf_counter() - start, 1)
        say(f"[{i}/{len(jobs)}] {name}: {seconds[name]:.0f} s")
    meta = {"curves": [[m, s] for _, m, s in jobs if _ == "curve"], "shine": list(READ_MEMBERS),
            "spp": spp, "shine_spp": shine_spp, "seed": seed, "variant": renderer.variant,
            "fingerprint": fingerprint(renderer.variant),
            "frame": list(FRAME), "box": list(BOX), "pixel": PIXEL, "curve_cell": CURVE_CELL,
            "shine_cell": SHINE_CELL, "seconds": seconds, "built": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out, ".npz") as tmp:
        np.savez_compressed(tmp, levels=levels, betas=betas, meta=np.array(json.dumps(meta)), **arrays)
    say(f"atlas: {out} ({out.stat().st_size / 1e6:.2f} MB)")
    return out


def ship_pose(pose: CameraPose = RIG_SWATCH_POSE, out: str | os.PathLike = SHIPPED_TABLES, say=print) -> list[Path]:
    """Render (or take from the cache) the family's response curves at ``pose`` (an all-hair crop's view: what an
    image file away from the rig is estimated at) and copy their cache entries into ``out``, where
    ``inference.refine.response_curve`` reads them when the cache has none."""
    start = time.perf_counter()
    with atlases_off():
        family_curves(pose, RefineSettings())
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    copied = []
    for path in sorted((cache_dir() / "response").glob("curve-*.json")):
        if json.loads(path.read_text()).get("view") == view_key(pose):
            copied.append(Path(shutil.copy2(path, out / path.name)))
    say(f"pose {pose}: {len(copied)} curves in {out} ({time.perf_counter() - start:.0f} s)")
    return copied


def build_poses(out: str | os.PathLike = POSES_PATH, settings: RefineSettings = RefineSettings(), renderer=None,
                say=print) -> Path:
    """Render (or take from the cache) the family's curves at every pose of the pose tables' grid (``POSE_POLARS`` by
    ``POSE_AZIMUTHS``, all-hair crops at ``CAMERA_DISTANCE``) and write them to ``out``; resumable through the
    cache (about 1 minute a pose on 2 cores)."""
    renderer = renderer or default_renderer()
    with atlases_off():
        tables, seconds = _pose_tables(settings, renderer, say)
    keys = list(tables)
    meta = {"curves": [list(k) for k in keys], "settings": json.loads(json.dumps(grid_settings(settings), default=str)),
            "distance": CAMERA_DISTANCE, "variant": renderer.variant, "fingerprint": fingerprint(renderer.variant),
            "seconds": round(seconds, 1), "built": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out, ".npz") as tmp:
        np.savez_compressed(tmp, levels=np.asarray(settings.levels, float), polars=np.asarray(POSE_POLARS),
                            azimuths=np.asarray(POSE_AZIMUTHS), meta=np.array(json.dumps(meta)),
                            **{f"curve__{m}__{s}": t.astype(np.float32) for (m, s), t in tables.items()})
    say(f"pose tables: {out} ({out.stat().st_size / 1e3:.0f} kB)")
    return out


def _pose_tables(settings: RefineSettings, renderer, say) -> tuple[dict, float]:
    """Every family member's curve in each layout at every grid pose: (member, layout) -> (P, A, K), and seconds."""
    keys = [(m, s) for m in FAMILY for s in range(LAYOUTS)]
    tables = {k: np.empty((len(POSE_POLARS), len(POSE_AZIMUTHS), len(settings.levels))) for k in keys}
    seconds = 0.0
    for i, polar in enumerate(POSE_POLARS):
        for j, azimuth in enumerate(POSE_AZIMUTHS):
            if polar == 0.0 and j:                 # straight down: every azimuth is one pose
                for k in keys:
                    tables[k][i, j] = tables[k][i, 0]
                continue
            start = time.perf_counter()
            pose = CameraPose(polar, azimuth, CAMERA_DISTANCE)
            for member, layout in keys:
                curve = response_curve(pose, replace(settings, strand_seed=layout), renderer, swatch_model=member)
                tables[member, layout][i, j] = curve.mean
            seconds += time.perf_counter() - start
            say(f"pose {polar:g}°, {azimuth:g}°: {time.perf_counter() - start:.0f} s")
    return tables, seconds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hairdigi.inference.atlas_build", description=build.__doc__)
    parser.add_argument("--out", default=str(ATLAS_PATH))
    parser.add_argument("--spp", type=int, default=192, help="the curves' samples per pixel")
    parser.add_argument("--shine-spp", type=int, default=48, help="the shine tables' samples per pixel")
    parser.add_argument("--work", default=None, help="where finished tables wait (default: the cache's atlas-work)")
    parser.add_argument("--pose-only", action="store_true", help="only the rig's swatch pose's curves (ship_pose)")
    parser.add_argument("--poses-only", action="store_true", help="only the pose tables of all-hair crops (build_poses)")
    args = parser.parse_args(argv)
    if not (args.pose_only or args.poses_only):
        build(args.out, args.spp, work=args.work, shine_spp=args.shine_spp)
    if not args.poses_only:
        ship_pose()
    if not args.pose_only:
        build_poses()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
