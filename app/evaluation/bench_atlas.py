"""``hairdigi bench atlas``: the shipped atlas (``inference.atlas``) against rendering each region's tables.

For regions a lab's captures give (the simulated rig's live region and its RAW still, a thick swatch's core,
an off-centre swatch, a short one), each region's tables from the atlas and rendered now: what each costs,
and how far apart they put hairs of the hard cases (black, platinum, copper, saturated red and blue), as
ΔE2000 of the colour each predicts for the hair and as the relative sigma_a each reads from one colour.
With ``end_to_end``, a fresh session's first capture of a deposited swatch, estimated with the atlas and
without it (every table rendered in a fresh cache): the time to the estimate and the two answers' distance.

Away from the rig, the pose tables (``inference.atlas.PoseAtlas``): at all-hair camera poses between the grid's
nodes (and one mirrored), the interpolated curves and family map against rendering them at the pose; and with
``end_to_end``, an image file of a deposited swatch seen from such a pose estimated in a fresh session, with the
pose tables and without them, against the truth.
"""
from __future__ import annotations

import contextlib
import json
import os
import tempfile
import time
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from hairdigi.app.evaluation.rig import HARD_CASES
from hairdigi.app.session.rig_session import RigSession
from hairdigi.inference.atlas import load_poses
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.estimate import estimate_image
from hairdigi.inference.refine import RefineSettings, ResponseCurve, response_curve
from hairdigi.inference.shine import shine_tables
from hairdigi.inference.structure import (FAMILY, LAYOUTS, READ_MEMBERS, FamilyCurves, _averaged, family_curves,
                                          family_view, to_family)
from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic
from hairdigi.render.domain.rig_geometry import CameraPose, RigRegion
from hairdigi.render.judge import judge
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.renderer import SceneSpec, render

#: The regions (frame size, x, y, w, h): the simulated rig's own, its RAW still, a thick swatch's core (the
#: finder's ``hair_core``), an off-centre swatch and a short one, and a 16:9 camera's frame of the rig's.
REGIONS = {
    "rig live": ((400, 300), (30, 56, 130, 189)),
    "rig RAW still": ((800, 600), (61, 113, 259, 377)),
    "thick swatch's core": ((400, 300), (38, 70, 112, 150)),
    "off-centre": ((400, 300), (12, 40, 110, 170)),
    "short": ((400, 300), (40, 110, 110, 90)),
    "16:9 frame": ((1600, 900), (120, 74, 520, 756)),
}
#: The hard cases' sigma_a (per fibre radius): black, platinum, copper, saturated red and blue.
HAIRS = {"black": (4.5, 6.0, 8.2), "platinum": (0.02, 0.03, 0.06), "copper": (0.25, 0.6, 1.3),
         "saturated red": (0.05, 1.8, 2.5), "saturated blue": (2.0, 0.9, 0.12)}


@contextlib.contextmanager
def fresh_session(cache: Path, atlas: str):
    """Within it the process renders as a fresh session would: an empty cache at ``cache`` and ``HAIRDIGI_ATLAS`` set
    to ``atlas`` ("": the shipped atlas; "off": none); the environment as it was after."""
    before = dict(os.environ)
    os.environ["HAIRDIGI_CACHE"], os.environ["HAIRDIGI_ATLAS"] = str(cache), atlas
    try:
        yield
    finally:
        os.environ.clear()
        os.environ.update(before)


def _compare(atlas_curve, rendered) -> dict:
    row = {}
    for name, sigma in HAIRS.items():
        sigma = np.asarray(sigma, float)
        a, r = np.clip(atlas_curve(sigma), 1e-9, None), np.clip(rendered(sigma), 1e-9, None)
        back, _ = atlas_curve.inverse(r)
        row[f"{name}_de2000"] = round(float(delta_e2000(a, r)), 3)
        row[f"{name}_sigma_rel"] = round(float(np.max(np.abs(back - sigma) / np.maximum(sigma, 0.05))), 3)
    return row


def tables_bench(regions: dict = REGIONS) -> list[dict]:
    """Per region: the atlas's curve and shine tables (layered) against rendering them now, and their costs."""
    rows = []
    for name, (frame, roi) in regions.items():
        view = RigRegion(frame, roi)
        start = time.perf_counter()
        shipped = response_curve(view, RefineSettings())
        for member in FAMILY:
            for layout in range(1, LAYOUTS):
                response_curve(view, RefineSettings(strand_seed=layout), swatch_model=member)
        for member in READ_MEMBERS:
            shine_tables(view, RefineSettings(), swatch_model=member)
        atlas_s = time.perf_counter() - start
        if not shipped.cached:
            rows.append({"region": name, "frame": f"{frame[0]}x{frame[1]}", "roi": list(roi), "atlas": False})
            continue
        start = time.perf_counter()
        rendered = response_curve(view, RefineSettings(), cache=False)
        curve_s = time.perf_counter() - start
        start = time.perf_counter()
        shine = shine_tables(view, RefineSettings(), cache=False, swatch_model="layered")
        shine_s = time.perf_counter() - start
        atlas_shine = shine_tables(view, RefineSettings(), swatch_model="layered")
        light_share = atlas_shine.means[0].sum() / atlas_shine.means.sum()
        rendered_share = shine.means[0].sum() / shine.means.sum()
        row = {"region": name, "frame": f"{frame[0]}x{frame[1]}", "roi": list(roi), "atlas": True,
               "atlas_ms_all_tables": round(atlas_s * 1000, 1),
               "render_s_one_curve": round(curve_s, 2), "render_s_one_shine_table": round(shine_s, 2),
               "render_s_all_tables_est": round(curve_s * len(FAMILY) * LAYOUTS + shine_s * len(READ_MEMBERS), 1),
               "light0_share_atlas": round(float(light_share), 4),
               "light0_share_render": round(float(rendered_share), 4),
               **_compare(shipped, rendered)}
        if name == "rig live":      # the renders' own noise: the same region rendered with another sampler seed
            other = response_curve(view, RefineSettings(seed=11), cache=False)
            rows.append({"region": "rig live: a render against another seed's", "frame": row["frame"],
                         "roi": list(roi), "atlas": False, **_compare(other, rendered)})
        compared = _compare(atlas_shine.all_lights_curve(0.3), shine.all_lights_curve(0.3))
        row.update({f"shine_{k}": v for k, v in compared.items() if k.endswith("de2000")})
        rows.append(row)
    # the family map at the rig's own region: the atlas's members against the members rendered now
    view = RigRegion(*regions["rig live"])
    canonical = family_view(view)
    shipped = family_curves(canonical, RefineSettings())
    fresh = family_curves(canonical, RefineSettings(), cache=False)
    mapped = {}
    for hair, sigma in HAIRS.items():
        a = to_family(np.asarray(sigma), shipped)
        b = to_family(np.asarray(sigma), fresh)
        apart = delta_e2000(np.clip(fresh.mean(a), 1e-9, None), np.clip(fresh.mean(b), 1e-9, None))
        mapped[hair] = round(float(apart), 3)
    rows.append({"region": "rig live: the family map", "frame": "400x300", "roi": list(canonical.roi), "atlas": True,
                 "render_s_all_tables_est": round(fresh.seconds, 1),
                 **{f"{h}_de2000": v for h, v in mapped.items()}})
    return rows


def end_to_end(out: Path, without: int = 1, atlas_path: str = "") -> list[dict]:
    """Each hard case's (``app.evaluation.rig.HARD_CASES``) first capture in a fresh session (a fresh cache: nothing
    rendered before), a deposited swatch, estimated with the atlas (``atlas_path``; "": the shipped one); the first
    ``without`` of them also without it (every table rendered)."""
    rows = []
    for k, (hair, hidden) in enumerate(HARD_CASES.items()):
        answers = {}
        for atlas in ("on", "off") if k < without else ("on",):
            with fresh_session(out / f"cache-{k}-{atlas}", atlas_path if atlas == "on" else "off"):
                session = RigSession.simulated_rig(out / f"session-{k}-{atlas}", hidden=hidden, spp=16,
                                                   swatch_model="deposited")
                try:
                    session.calibrate()
                    result = session.capture()
                finally:
                    session.close()
            record = result.record
            if record is None:
                rows.append({"hair": hair, "atlas": atlas, "blocked": "; ".join(str(b) for b in result.blocked)})
                continue
            answers[atlas] = np.asarray(record.refinement.sigma_a)
            verdict = judge(hidden, record.refinement.sigma_a, looks=(None, record.appearance.value))
            rows.append({"hair": hair, "atlas": atlas, "estimate_s": record.provenance.seconds,
                         "truth_de2000": round(float(verdict.de2000), 3),
                         "structure": (record.refinement.region.structure or "")[:60]})
        if len(answers) == 2:
            rows.append({"hair": hair, "atlas": "on vs off", "sigma_rel": round(float(
                np.max(np.abs(answers["on"] - answers["off"]) / answers["off"])), 3)})
    return rows


#: All-hair crops' camera poses (polar°, azimuth°) off the pose tables' grid: between its nodes, grazing, mirrored.
POSES = {"pose 37.5°, 22.5° (between)": (37.5, 22.5), "pose 52.5°, -67.5° (between)": (52.5, -67.5),
         "pose 67.5°, 67.5° (grazing, between)": (67.5, 67.5), "pose 30°, 135° (mirrored)": (30.0, 135.0)}


def _pose_family(pose, settings):
    """The family's curves at ``pose`` as the pose tables give them (interpolated)."""
    tables, levels = load_poses(), np.asarray(settings.levels, float)
    members = {m: _averaged([ResponseCurve(levels.copy(), tables.curve(pose, m, s)) for s in range(LAYOUTS)])
               for m in FAMILY}
    return FamilyCurves(ResponseCurve(levels.copy(), tables.curve(pose, "layered", 0)), members)


def poses_bench(poses: dict = POSES) -> list[dict]:
    """Per pose off the grid: the pose tables' curve and family map against rendering them there, and their costs."""
    rows = []
    for name, (polar, azimuth) in poses.items():
        pose, settings = CameraPose(polar, azimuth), RefineSettings()
        start = time.perf_counter()
        shipped = _pose_family(pose, settings)
        tables_ms = (time.perf_counter() - start) * 1000
        start = time.perf_counter()
        rendered = response_curve(pose, settings, cache=False)
        curve_s = time.perf_counter() - start
        fresh = family_curves(pose, settings, cache=False)
        mapped = {}
        for hair, sigma in HAIRS.items():
            a, b = to_family(np.asarray(sigma), shipped), to_family(np.asarray(sigma), fresh)
            mapped[f"{hair}_family_de2000"] = round(float(delta_e2000(np.clip(fresh.mean(a), 1e-9, None),
                                                                      np.clip(fresh.mean(b), 1e-9, None))), 3)
        rows.append({"region": name, "frame": "crop", "roi": [polar, azimuth], "atlas": True,
                     "atlas_ms_all_tables": round(tables_ms, 1), "render_s_one_curve": round(curve_s, 2),
                     "render_s_all_tables_est": round(curve_s * (1 + len(fresh.members) * 2), 1),
                     **_compare(shipped.default, rendered), **mapped})
    return rows


#: The poses an image file is estimated from end to end: halfway between the tables' nodes in both angles (their
#: worst), and the transfer check's camera (``rig_geometry.TRANSFER_POSE``: between polar nodes, on an azimuth one).
POSES_END_TO_END = ((37.5, 22.5), (40.0, 30.0))


def poses_end_to_end(out: Path, pose: tuple[float, float] = POSES_END_TO_END[0], without: int = 1) -> list[dict]:
    """Each hard case's all-hair crop of a deposited swatch seen from ``pose``, estimated in a fresh session (a fresh
    cache) with the pose tables; the first ``without`` also without them (every curve rendered): time and truth."""
    camera, encoder, rows = CameraPose(*pose), Encoder(), []
    for k, (hair, hidden) in enumerate(HARD_CASES.items()):
        image = render(hidden, SceneSpec("swatch", camera=camera, framing="crop", swatch_model="deposited"),
                       96, 128, seed=3).linear
        answers = {}
        for tables in ("on", "off") if k < without else ("on",):
            with fresh_session(out / f"pose-cache-{k}-{tables}", "" if tables == "on" else "off"):
                start = time.perf_counter()
                result = estimate_image(image, encoder, view=camera)
                seconds = time.perf_counter() - start
            answers[tables] = np.asarray(result.refinement.sigma_a)
            verdict = judge(hidden, result.refinement.sigma_a)
            rows.append({"hair": hair, "pose": list(pose), "pose_tables": tables, "estimate_s": round(seconds, 2),
                         "truth_de2000": round(float(verdict.de2000), 3)})
        if len(answers) == 2:
            rows.append({"hair": hair, "pose": list(pose), "pose_tables": "on vs off", "sigma_rel": round(float(
                np.max(np.abs(answers["on"] - answers["off"]) / answers["off"])), 3)})
    return rows


def plot(rows: list[dict], path: Path) -> None:
    matplotlib.use("Agg")

    table = [r for r in rows if r.get("render_s_one_curve")]
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for hair in HAIRS:
        ax.scatter([r["render_s_all_tables_est"] for r in table], [r[f"{hair}_de2000"] for r in table], label=hair)
    for r in table:
        ax.annotate(r["region"], (r["render_s_all_tables_est"], max(r[f"{h}_de2000"] for h in HAIRS)), fontsize=7)
    ax.set_xlabel("rendering the region's tables now (s, 2 cores; the atlas: under 0.1 s)")
    ax.set_ylabel("ΔE2000, the atlas's colour against the render's")
    ax.set_title("hairdigi bench atlas: the shipped atlas against rendering each region")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def atlas_bench(out: Path, end_to_end_too: bool = False) -> dict:
    """Run the bench; write ``atlas.csv``, ``atlas.json`` and ``atlas.png`` under ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    rows = tables_bench() + poses_bench()
    write_csv_atomic(out / "atlas.csv", rows)
    summary = {"tables": rows}
    if not end_to_end_too and (out / "atlas.json").exists():   # --quick: the last full run's end to end is kept
        last = json.loads((out / "atlas.json").read_text())
        summary.update({k: last[k] for k in ("end_to_end", "poses_end_to_end") if k in last})
    if end_to_end_too:      # its sessions and fresh caches go to a temporary folder, not beside the table
        with tempfile.TemporaryDirectory(prefix="hairdigi-bench-atlas-") as work:
            summary["end_to_end"] = end_to_end(Path(work))
            summary["poses_end_to_end"] = [row for pose in POSES_END_TO_END
                                           for row in poses_end_to_end(Path(work), pose)]
    write_json_atomic(out / "atlas.json", summary)
    plot(rows, out / "atlas.png")
    return summary
