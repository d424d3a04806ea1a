"""``hairdigi bench NAME``'s benchmarks (``registry.BENCHES`` names them): each runs its work, which
writes its table and plot, and returns a ``results.Result`` that the registry prints: the summary lines,
then the files written. The work is in ``app/evaluation/bench_*.py``; it may use every layer below.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hairdigi.app.evaluation.bench_atlas import HAIRS as ATLAS_HAIRS
from hairdigi.app.evaluation.bench_atlas import atlas_bench
from hairdigi.app.evaluation.bench_dataset import run_dataset_bench
from hairdigi.app.evaluation.bench_fibres import run as run_fibres
from hairdigi.app.evaluation.bench_previews import CLEAN_DE, cheapest_clean, run_previews_bench
from hairdigi.app.evaluation.bench_refine import CHECK_SETTINGS
from hairdigi.app.evaluation.bench_refine import bench_check_spp as run_check_spp
from hairdigi.app.evaluation.bench_refine import bench_layouts as run_layouts
from hairdigi.app.evaluation.bench_refine import bench_refine as run_refine
from hairdigi.app.evaluation.bench_render import run_render_bench
from hairdigi.app.evaluation.bench_rig import detection_sweep
from hairdigi.app.evaluation.bench_shine import run_shine_bench, run_spread_bench
from hairdigi.app.evaluation.bench_spectral import run as run_spectral
from hairdigi.app.evaluation.bench_streaks import streaks_bench
from hairdigi.app.evaluation.bench_structure import FAMILY_HAIRS, family, renderers
from hairdigi.app.evaluation.bench_structure import run as run_structure
from hairdigi.app.evaluation.registry import BENCH_OUT
from hairdigi.app.evaluation.results import Result
from hairdigi.app.review.previews import PreviewSettings, twin_view
from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN, SIM_SIZE
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.training.report import bench_encoders
from hairdigi.render.blender_run import BlenderError, probe_blender
from hairdigi.render.domain.errors import EvaluationError
from hairdigi.render.domain.files import cache_dir
from hairdigi.render.domain.rig_geometry import swatch_roi


def _files(out: Path, *names: str) -> list[Path]:
    return [out / name for name in names]


def bench_render(args: argparse.Namespace) -> Result:
    """Renderer defaults: strands, spp and depth against error and time."""
    out = Path(args.out)
    rows = run_render_bench(out, quick=args.quick)
    return Result("render_bench", rows, files=_files(out, "render_bench.csv", "render_bench.png"),
                  note=f"{len(rows)} cases")


def bench_rig(args: argparse.Namespace) -> Result:
    """Chart detection and ΔE2000 over simulated poses, noise and casts."""
    out = Path(args.out)
    rows = detection_sweep(out)
    found = [r for r in rows if r["detected"]]
    return Result("rig_bench", rows, files=_files(out, "rig_bench.csv"), text=[
        f"chart detected in {len(found)}/{len(rows)} simulated frames; ΔE2000 mean before "
        f"{np.mean([r['de_before'] for r in found]):.2f}, after {np.mean([r['de_after'] for r in found]):.2f}"])


def bench_encoder(args: argparse.Namespace) -> Result:
    """ONNX encoders side by side: latency and error on held-out swatches."""
    if not args.models:
        raise EvaluationError("bench encoder needs --models A.onnx B.onnx ...")
    out = Path(args.out)
    rows = bench_encoders(args.models, out, n=args.n or 300, data_root=args.data)
    return Result("encoder_bench", rows, files=_files(out, "encoder_bench.csv", "encoder_bench.png"), text=[
        f"{r['model']}: {r['latency_ms']:.3f} ms, L1 {r['l1']:.2f} (floor {r['l1_floor']:.2f}), "
        f"ΔE2000 median {r['mean_colour_de2000_median']:.2f}" for r in rows])


def bench_refine(args: argparse.Namespace) -> Result:
    """Refinement by synthesis: render size, spp and iterations against error and time."""
    out = Path(args.out)
    data = Path(args.data) if args.data else cache_dir() / "datasets" / "heldout-s1000003-64px-64spp-linear16"
    rows = run_refine(Encoder(args.model), data, out, count=args.n or 10)
    return Result("refine_bench", rows, files=_files(out, "refine_bench.csv", "refine_bench.png"), text=[
        f"{r['size']:3d}² {r['spp']:3d} spp, {r['iterations']} iteration(s): ΔE2000 median "
        f"{r['de_median']:.2f} (p95 {r['de_p95']:.2f}); curve {r['curve_s']:.2f} s + {r['polish_s']:.2f} s"
        for r in rows])


def bench_layouts(args: argparse.Namespace) -> Result:
    """The refinement's check renders averaged over strand layouts: how far a new layout moves the answer."""
    out = Path("packaging/bench/layouts") if args.out == BENCH_OUT else Path(args.out)
    rows = run_layouts(out)
    return Result("layouts_bench", rows, files=_files(out, "layouts_bench.csv", "layouts_bench.png"), text=[
        f"{r['hair']:15s} {r['check_layouts']} layouts: two layouts' answers {r['nuisance_de2000']:.2f} "
        f"apart (the truth's own colour {r['truth_spread_de2000']:.2f}, "
        f"{r['truth_spread_fine_de2000']:.2f} of finer fibres); error median {r['error_median_de2000']:.2f}, "
        f"worst {r['error_worst_de2000']:.2f}; polish {r['polish_s']:.2f} s" for r in rows])


def bench_check_spp(args: argparse.Namespace) -> Result:
    """The refinement's check renders at the rig's swatch area: their spp against the error they leave."""
    out = Path("packaging/bench/check-spp") if args.out == BENCH_OUT else Path(args.out)
    rows = run_check_spp(out)
    result = Result("check_spp_bench", rows, files=_files(out, "check_spp_bench.csv", "check_spp_bench.png"))
    for member in dict.fromkeys(r["structure"] for r in rows):
        for label, _ in CHECK_SETTINGS:
            sel = [r for r in rows if r["setting"] == label and r["structure"] == member]
            result.text.append(f"{member}, {label}: ΔE2000 median {np.median([r['de2000'] for r in sel]):.2f}, "
                               f"worst {max(r['de2000'] for r in sel):.2f}; polish "
                               f"{np.median([r['polish_s'] for r in sel]):.2f} s")
    return result


def bench_dataset(args: argparse.Namespace) -> Result:
    """Dataset rendering: the local pool and a local Ray instance, swatches per second."""
    out = Path(args.out)
    rows = run_dataset_bench(out, quick=args.quick, n=args.n)
    result = Result("dataset_bench", rows, files=_files(out, "dataset_bench.csv", "dataset_bench.png"))
    for r in rows:
        unit = "worker process(es)" if r["backend"] == "local" else "CPU(s) of a local Ray instance"
        result.text.append(f"{r['backend']:5s} {r['workers']} {unit}: {r['swatches_per_s']:.2f} swatches/s "
                           f"({r['n']} in {r['seconds']:.1f} s, {r['size']}² {r['spp']} spp, {r['variant']})")
    return result


def bench_previews(args: argparse.Namespace) -> Result:
    """The app's previews: spp x denoiser x guides x size against error."""
    out = Path(args.out)
    out = out / "previews" if args.out == BENCH_OUT else out
    return Result("previews_bench", text=previews_lines(out, quick=args.quick),
                  files=_files(out, "previews_bench.csv", "previews_bench.png"))


def previews_lines(out_dir: str | Path, quick: bool = False) -> list[str]:
    """``hairdigi bench previews``: app/evaluation/bench_previews.py on the simulated rig's twin view (at the
    scales the app renders it) and the hairstyle; the summary lines say each default's measured error
    and the cheapest clean setting."""
    s = PreviewSettings()
    roi = swatch_roi(SIM_SIZE)
    twins = {scale: twin_view(roi, SIM_SIZE, True, scale) for scale, _ in s.twin_passes}
    rows = run_previews_bench(out_dir, list(twins.values()), DEFAULT_HIDDEN, quick)
    mode = "oidn" if s.denoise and any(r["mode"] == "oidn" for r in rows) else "raw"
    defaults = {("hairstyle", s.hairstyle_size): [("first pass", s.hairstyle_passes[0]),
                                                  ("clean pass", s.hairstyle_clean_spp)]}
    for scale, (_, size) in twins.items():
        firsts = [n for sc, n in s.twin_passes if sc == scale]
        defaults[("twin", size[0])] = [(f"first pass at {scale:g}x resolution", firsts[0]),
                                       ("clean pass", dict(s.twin_clean_spp)[scale])]
    lines = []
    for view, width in sorted({(r["view"], r["width"]) for r in rows}):
        best = cheapest_clean(rows, view, width)
        lines.append(f"{view} {width}px: cheapest clean (per-pixel ΔE2000 <= {CLEAN_DE:g}): "
                     + (f"{best['spp']} spp {best['mode']}, {best['total_s']:.2f} s, ΔE {best['pixel_de2000']:.2f}"
                        if best else "none"))
        for label, spp in defaults.get((view, width), []):
            row = next((r for r in rows if (r["view"], r["width"], r["spp"], r["mode"]) == (view, width, spp, mode)),
                       None)
            if row is not None:
                lines.append(f"  app default {label}: {spp} spp {mode}: per-pixel ΔE2000 {row['pixel_de2000']:.2f}, "
                             f"mean colour {row['mean_colour_de2000']:.2f}, {row['total_s']:.2f} s")
    return lines


def bench_shine(args: argparse.Namespace) -> Result:
    """Shine (longitudinal roughness) read from the rig's lights one at a time, and what it buys elsewhere."""
    out = Path(args.out)
    rows = run_shine_bench(out, quick=args.quick)
    err = np.array([r["beta_error"] for r in rows])
    read = np.array([r["transfer_de2000"] for r in rows])
    held = np.array([r["transfer_de2000_fixed_shine"] for r in rows])
    return Result("shine_bench", rows, files=_files(out, "shine_bench.csv", "shine_bench.png"), text=[
        f"shine read from the three lights: |error| median {np.median(err):.3f}, worst {err.max():.3f}; another "
        f"camera: ΔE2000 median {np.median(read):.2f} (worst {read.max():.2f}) against {np.median(held):.2f} "
        f"(worst {held.max():.2f}) with the shine held at 0.3; tables {rows[0]['tables_s']:.0f} s once per view"])


#: A shine read on the simulated rig's demo capture (copper) leaves this rms log misfit (its record's
#: appearance method): the scale below which a spread cannot be told from uniform fibres.
CAPTURE_SHINE_MISFIT = 0.025


def bench_spread(args: argparse.Namespace) -> Result:
    """Fibre spread against uniform fibres, as the three single-light means see them (no render once the tables exist)."""
    out = Path("packaging/bench/spread") if args.out == BENCH_OUT else Path(args.out)
    rows = run_spread_bench(out, CAPTURE_SHINE_MISFIT)
    top = [r for r in rows if r["spread"] == 0.5]
    return Result("spread_bench", rows, files=_files(out, "spread_bench.csv", "spread_bench.png"), text=[
        "uniform fibres fit the nine means of a swatch of spread 0.5 within rms log "
        + ", ".join(f"{r['hair']} (shine {r['beta']:g}) {r['uniform_misfit_rms_log']:.4f}" for r in top)
        + f"; a rig capture's own shine misfit is {CAPTURE_SHINE_MISFIT}"])


def bench_structure(args: argparse.Namespace) -> Result:
    """The swatch's fibre structure: today's interpenetrating swatch against a layered one, fibre counts, lights."""
    out = Path("packaging/bench/structure") if args.out == BENCH_OUT else Path(args.out)
    rows = run_structure(out, quick=args.quick)
    layered = [r for r in rows if r["model"] == "layered" and r["strands"] == 2000 and r["lights"] == "all"]
    return Result("structure", rows, files=_files(out, "structure.csv", "structure.json", "structure.png"), text=[
        "layered 2000 against today's swatch at equal sigma_a (all lights): "
        + ", ".join(f"{r['hair']} ΔE2000 {r['de2000_vs_today']:.2f} (ΔL* {r['dL_vs_today']:+.2f})" for r in layered)])


def bench_atlas(args: argparse.Namespace) -> Result:
    """The shipped atlas against rendering each region's tables: cost and colour apart, by region and hair."""
    out = Path("packaging/bench/atlas") if args.out == BENCH_OUT else Path(args.out)
    summary = atlas_bench(out, end_to_end_too=not args.quick)
    result = Result("atlas", summary["tables"], summary, files=_files(out, "atlas.csv", "atlas.json", "atlas.png"))
    for r in summary["tables"]:
        result.text.append(f"{r['region']:28s} "
                           + ", ".join(f"{h} {r[f'{h}_de2000']:.2f}" for h in ATLAS_HAIRS if f"{h}_de2000" in r))
    for r in summary.get("end_to_end", []):
        result.text.append("first capture, fresh session: " + ", ".join(f"{k} {v}" for k, v in r.items()))
    for r in summary.get("poses_end_to_end", []):
        result.text.append("image file at a pose, fresh session: " + ", ".join(f"{k} {v}" for k, v in r.items()))
    return result


def bench_family(args: argparse.Namespace) -> Result:
    """Every physical swatch structure at equal sigma_a, against the layered swatch."""
    out = Path("packaging/bench/family") if args.out == BENCH_OUT else Path(args.out)
    rows = family(out)
    return Result("family", rows, files=_files(out, "family.csv", "family.png"), text=[
        f"{r['structure']:17s} layout {r['layout']}: " + ", ".join(f"{h} {r[f'{h}_de2000']:.2f}" for h in FAMILY_HAIRS)
        for r in rows])


def bench_streaks(args: argparse.Namespace) -> Result:
    """The swatch area's texture by physical structure: what ``inference.structure.read_texture`` reads."""
    out = Path("packaging/bench/streaks") if args.out == BENCH_OUT else Path(args.out)
    if args.quick:   # the demo's copper, layered and deposited, live and RAW: the rig's own cached renders
        summary = streaks_bench(out, n=0, members=("layered", "deposited"), tilted=False, hairs=1)
    else:
        summary = streaks_bench(out, n=args.n or 8)
    return Result("streaks", summary=summary, files=_files(out, "streaks.csv", "streaks.png"), text=[
        f"{group:17s} " + ", ".join(f"{k} {v:g}" for k, v in shares.items())
        for group, shares in summary["shares"].items() if " / " not in group])


def bench_renderers(args: argparse.Namespace) -> Result | int:
    """Every family structure at equal sigma_a in Mitsuba and in Blender Cycles (HAIRDIGI_BLENDER)."""
    try:
        probe_blender()   # no Blender, or one that does not run, stops here with how to get one
    except BlenderError as exc:
        print(f"hairdigi bench renderers: {exc}", file=sys.stderr)
        return 2
    out = Path("packaging/bench/renderers") if args.out == BENCH_OUT else Path(args.out)
    rows = renderers(out, ("layered", "deposited") if args.quick else None, size=16 if args.quick else 32,
                     spp=8 if args.quick else 64)
    return Result("renderers", rows, files=_files(out, "renderers.csv", "renderers.png"), text=[
        f"{r['structure']:17s} {r['hair']:7s}: ΔE2000 {r['de2000']:.2f}, Cycles / Mitsuba "
        f"{r['ratio_r']:.3f} {r['ratio_g']:.3f} {r['ratio_b']:.3f} ({100 * r['inside_share']:.2f}% of the drawn "
        f"fibres inside another)" for r in rows])


def bench_fibres(args: argparse.Namespace) -> Result:
    """Fibre groups of a varied swatch: render time and colour against the finest split."""
    out = Path("packaging/bench/fibres") if args.out == BENCH_OUT else Path(args.out)
    result = run_fibres(out, quick=args.quick)       # saved: fibres_bench.csv and .png
    result.text = [f"{r['hair']:9s} {r['groups']:2d} groups: {r['seconds']:.2f} s, ΔE2000 {r['de2000_vs_finest']:.2f} "
                   f"against the finest" for r in result.rows]
    return result


def bench_spectral(args: argparse.Namespace) -> Result:
    """The RGB fast path against the spectral render, under daylight, tungsten and shop lights."""
    out = Path("packaging/bench/spectral") if args.out == BENCH_OUT else Path(args.out)
    result = run_spectral(out, quick=args.quick)       # saved: spectral_bench.csv and .png
    for r in result.rows:
        table1 = "  -  " if r["table1_de2000"] is None else f"{r['table1_de2000']:5.2f}"
        result.text.append(f"{r['hair']:10s} {r['light']:8s}: ΔE2000 against spectral, Table 1 RGB {table1}, "
                           f"matched RGB {r['matched_de2000']:5.2f} (spectral noise {r['spectral_noise_de2000']:.2f}); "
                           f"spectral {r['spectral_seconds']:.2f} s, RGB {r['rgb_seconds']:.2f} s")
    return result
