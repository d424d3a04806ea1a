"""``hairdigi evaluate --cycles``: the estimate judged in another renderer, on swatches it never modelled.

hairdigi's estimate inverts its own world: Mitsuba's ``hair`` BSDF on the project's layered swatch.
A real swatch is neither, so the question is whether the σa it returns is the hair's, or only what
makes the project's swatch look like the photograph. This evaluation answers it with Blender Cycles
(its own path tracer and its own Chiang hair BSDF, through ``render.blender_run``) and a swatch that
hairdigi's generator never draws (``other_swatch``: fibres crossing at small angles, layer by layer,
of other thicknesses, fills and depths):

1. each hidden swatch (Table 1 hard cases and random draws, uniform fibres, each with its own shine)
   is rendered in Cycles at the rig's swatch pose, all hair in view, and shot through the camera model
   (``evaluate.capture``: noise, 12-bit ADC, 8-bit sRGB), as ``hairdigi estimate`` would be given it;
   so is each light alone, 1.5 EV longer, as the rig takes its single-light frames;
2. ``estimate_image`` estimates it (the encoder, the shine read from the three single-light frames,
   then refinement by synthesis in Mitsuba), and again without the single-light frames (the shine
   held at the default, as for an old capture);
3. each estimate (σa and shine) is rendered **back in Cycles** on the hidden swatch's own strands
   with the truth's sampler seed, and compared with the truth: at the rig's pose (**fit**), and in a
   scene neither saw (**transfer**: another camera, one key light across the fibres and a grey sky,
   as ``evaluate --appearance``'s). Mean-colour ΔE2000; also the σa's relative error per channel
   and the shine's absolute error.

``CyclesSet(shine=False)`` (``--default-shine``) keeps every swatch at the default shine and reads no
single-light frames: the renderer and the swatch's structure alone.

Blender runs in its own Python (``HAIRDIGI_BLENDER``; see ``render.blender_run``). The first study of
this kind (``shared/reference/inverse-notes.md``, 16 swatches, the project's first, interpenetrating
swatch) found the twin matched the input (0.40) while the σa rendered back in Cycles was 3.0 away.
"""
from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.inference.encoder import Encoder
from hairdigi.inference.estimate import estimate_image
from hairdigi.inference.preprocess import to_linear
from hairdigi.inference.training.evaluate import capture
from hairdigi.render.blender_run import render_cycles, rig_for_blender
from hairdigi.render.domain.absorption import LONGITUDINAL_ROUGHNESS, hair_sigma_a
from hairdigi.render.domain.appearance import APPEARANCE_DRAW, DEFAULT_SHINE
from hairdigi.render.domain.bounds import Environment
from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic
from hairdigi.render.domain.params import HairParams, sample_params
from hairdigi.render.domain.rig_geometry import N_LIGHTS, RIG_SWATCH_POSE, TRANSFER_POSE
from hairdigi.render.interchange import HairLook
from hairdigi.render.io.figures import save_figure
from hairdigi.render.metrics import delta_e2000, error_stats
from hairdigi.render.strands import SWATCH_LENGTH, SWATCH_WIDTH, Strands

SEED = 2_026_125
#: Named hard cases beside the random draws: Table 1 and the shine (Mitsuba's and Cycles' roughness).
CASES = {
    "black": (HairParams((20, 20, 20), 0.2, 0.97, 0.95), 0.3),
    "platinum, glossy": (HairParams((245, 240, 225), 0.15, 0.04, 0.2), 0.15),
    "saturated red, rough": (HairParams((230, 20, 30), 1.0, 0.08, 0.3), 0.45),
    "saturated blue": (HairParams((30, 60, 230), 0.9, 0.1, 0.5), 0.3),
    "copper": (HairParams((190, 80, 40), 0.5, 0.5, 0.6), 0.25),
}
#: The single-light frames' exposure over the all-lights frame (as the rig takes them, ``RigSession``).
LIGHT_EV = 1.5


@dataclass(frozen=True)
class CyclesSet:
    random: int = 7          # random draws (Table 1, shine over APPEARANCE_DRAW) beside the named cases
    size: int = 64           # the input's and the judge's side in pixels
    spp: int = 128           # Cycles samples per pixel, input and judge
    threads: int = 2
    shine: bool = True       # hidden shines vary, and the single-light frames are rendered and read


def other_swatch(seed: int) -> tuple[Strands, dict]:
    """A physical swatch drawn unlike ``strands.layered_swatch_strands``: each layer's fibres share a
    small random angle to the swatch's axis (layers cross one another), fibres are placed by random
    sequential gaps of another law, and the fibre radius, fill and layer count vary per swatch. No
    two fibres meet: a layer's fibres are translates of one another at least 2.04 radii apart across
    the layer's direction (angles of a few degrees: cos > 0.99), and layers are at least 2.04 radii
    apart in z. Returned as polylines (24 points a fibre; Cycles draws them as they are) and the
    drawn settings."""
    rng = np.random.default_rng(seed)
    radius = float(rng.uniform(0.0015, 0.003))
    layers = int(rng.integers(12, 25))
    fill = float(rng.uniform(0.55, 0.9))                       # share of a layer's width that fibres cover
    y = np.linspace(-SWATCH_LENGTH / 2, SWATCH_LENGTH / 2, 24)
    fibres, z = [], radius * 1.02
    for _ in range(layers):
        angle = float(rng.normal(0.0, np.radians(2.0)))         # the layer's tilt off the swatch's axis
        span = SWATCH_WIDTH + abs(np.tan(angle)) * SWATCH_LENGTH
        mean_gap = 2 * radius / fill
        gaps = 2.04 * radius + rng.gamma(2.0, max(mean_gap - 2.04 * radius, 1e-6) / 2.0, int(span / (2 * radius)) + 2)
        x0 = -span / 2 + np.cumsum(gaps)
        x0 = x0[x0 < span / 2]
        sway = 0.004 * np.sin(2 * np.pi * y / rng.uniform(0.4, 0.9) + rng.uniform(0, 2 * np.pi))  # the layer's wave
        xs = x0[:, None] + np.tan(angle) * y[None, :] + sway[None, :]
        keep = np.any(np.abs(xs) <= SWATCH_WIDTH / 2, axis=1)
        for x in xs[keep]:          # a tilted layer's fibres may run past the swatch's sides, as on a holder
            fibres.append(np.stack([x, y, np.full_like(y, z)], 1))
        z += radius * float(rng.uniform(2.04, 2.4))
    points = np.array(fibres)
    return Strands.from_grid(points, radius), {"radius": round(radius, 5), "layers": layers,
                                                 "fill": round(fill, 3), "fibres": len(fibres),
                                                 "height": round(float(z), 4)}


def hidden_set(config: CyclesSet) -> list[tuple[str, HairParams, float, int]]:
    """(name, Table 1, shine, strand layout) of each hidden swatch; without ``config.shine`` every shine is
    the default."""
    rng = np.random.default_rng(SEED)
    named = [(n, h, b, 301 + i) for i, (n, (h, b)) in enumerate(CASES.items())]
    drawn = [(f"random {i}", sample_params(rng), round(float(rng.uniform(*APPEARANCE_DRAW["longitudinal_roughness"])), 3),
              401 + i) for i in range(config.random)]
    if not config.shine:   # every swatch at the default shine: its name no longer says glossy or rough
        return [(n.split(",")[0], h, DEFAULT_SHINE, k) for n, h, _, k in named + drawn]
    return named + drawn


def cycles_render(sigma_a, strands: Strands, scene: str, config: CyclesSet, seed: int, folder: Path,
                  pixels: bool = False, shine: float | None = None, bspline: bool = False) -> dict:
    """One Cycles render of ``strands`` with absorption ``sigma_a`` and ``shine`` (None: the default):
    ``scene`` "rig" (the rig's swatch pose, its three lights), "light0".."light2" (one light alone) or
    "transfer"; the mean linear colour (and the pixels), the seconds and the NaN/Inf count
    (``blender_run.render_cycles``, the one Cycles path). ``bspline``: ``strands`` are Mitsuba's B-spline
    control points (``render.swatch_family``'s), drawn as Mitsuba draws them; else polylines as they are
    (this evaluation's own generator)."""
    look = HairLook("hidden", tuple(float(v) for v in sigma_a),
                    longitudinal_roughness=LONGITUDINAL_ROUGHNESS if shine is None else float(shine))
    if scene == "rig":
        rig = rig_for_blender(strands, RIG_SWATCH_POSE, "crop", config.size, bspline=bspline)
    elif scene.startswith("light"):
        alone = tuple(1.0 if f"light{i}" == scene else 0.0 for i in range(N_LIGHTS))
        rig = rig_for_blender(strands, RIG_SWATCH_POSE, "crop", config.size, lights=alone, bspline=bspline)
    else:
        rig = rig_for_blender(strands, TRANSFER_POSE, "crop", config.size, lights=(0.0, 0.0, 0.0), env=Environment.KEY_SKY,
                              bspline=bspline)
    out = render_cycles(look, rig, config.spp, seed, config.threads, pixels=pixels, folder=folder)
    return {"mean_linear": list(out.mean_linear), "seconds": out.seconds, "spp": out.spp, "nonfinite": out.nonfinite,
            "blender": out.blender, **({"pixels": out.pixels} if pixels else {})}


def _relative_error(sigma, truth) -> float:
    """The median channel's |sigma / truth - 1|."""
    return round(float(np.median(np.abs(np.asarray(sigma, float) / np.maximum(truth, 1e-6) - 1))), 4)


def _one(name: str, hidden: HairParams, shine: float, layout: int, config: CyclesSet, encoder, folder: Path) -> dict:
    """One hidden swatch: rendered in Cycles, estimated (with and without its single-light frames),
    each estimate rendered back in Cycles and judged against the truth."""
    def de(a, b) -> float:
        return round(float(delta_e2000(np.clip(np.asarray(a), 1e-9, None), np.clip(np.asarray(b), 1e-9, None))), 3)

    strands, drawn = other_swatch(layout)
    truth = hair_sigma_a(hidden)
    row = {"hidden": name, "layout": layout, "true_shine": shine, **{f"swatch_{k}": v for k, v in drawn.items()},
           "true_sigma_a": [round(float(v), 5) for v in truth]}
    start = time.perf_counter()
    shot = cycles_render(truth, strands, "rig", config, layout, folder, pixels=True, shine=shine)
    row["cycles_s"] = round(shot["seconds"], 2)
    frame = capture(np.asarray(shot["pixels"], np.float32), layout)
    lights = None
    if config.shine:   # each light alone, 1.5 EV longer, as the rig takes them; back to the frame's exposure
        lights = [to_linear(capture(np.asarray(cycles_render(truth, strands, f"light{i}", config, layout, folder,
                                                             pixels=True, shine=shine)["pixels"], np.float32)
                                    * np.float32(2.0 ** LIGHT_EV), layout + 7 * (i + 1)))
                  / np.float32(2.0 ** LIGHT_EV) for i in range(N_LIGHTS)]
    truth_away = cycles_render(truth, strands, "transfer", config, layout, folder, shine=shine)["mean_linear"]
    modes = [("read", lights)] + ([("no light frames", None)] if config.shine else [])
    for mode, singles in modes:
        tag = "" if mode == "read" else "nolights_"
        result = estimate_image(frame, encoder, light_images=singles)
        row[f"{tag}estimate_s"] = round(result.seconds, 2)
        if result.refinement is None:
            row["error"] = "no refinement"
            return row
        sigma = np.asarray(result.refinement.sigma_a, float)
        est_shine = result.appearance.value.longitudinal_roughness if result.appearance else None
        back = cycles_render(sigma, strands, "rig", config, layout, folder, shine=est_shine)["mean_linear"]
        away = cycles_render(sigma, strands, "transfer", config, layout, folder, shine=est_shine)["mean_linear"]
        row.update({f"{tag}est_sigma_a": [round(float(v), 5) for v in sigma], f"{tag}est_shine": est_shine,
                    f"{tag}sigma_rel_error": _relative_error(sigma, truth),
                    f"{tag}twin_residual": round(result.refinement.residual_de2000, 3),
                    f"{tag}fit": de(back, shot["mean_linear"]), f"{tag}transfer": de(away, truth_away),
                    f"{tag}warnings": " | ".join(w.kind.value for w in result.warnings)})
        if mode == "read":
            row["encoder_sigma_rel_error"] = _relative_error(hair_sigma_a(result.encoder.params), truth)
            row["shine_abs_error"] = None if est_shine is None or not config.shine else round(abs(est_shine - shine), 4)
    row["seconds"] = round(time.perf_counter() - start, 1)
    return row


def evaluate_cycles(out_dir: str | os.PathLike, config: CyclesSet = CyclesSet(), progress: bool = True) -> dict:
    """Every hidden swatch rendered in Cycles, estimated, rendered back in Cycles; table, summary, plot."""
    encoder = Encoder()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    hidden = hidden_set(config)
    with tempfile.TemporaryDirectory(prefix="hairdigi-cycles-eval-") as tmp:
        for name, params, shine, layout in tqdm(hidden, desc="cycles swatches", unit="swatch", disable=not progress):
            try:
                rows.append(_one(name, params, shine, layout, config, encoder, Path(tmp)))
            except Exception as exc:   # noqa: BLE001 - a failure is reported in the table, the run goes on
                rows.append({"hidden": name, "layout": layout, "error": f"{type(exc).__name__}: {exc}"})
            write_json_atomic(out / "cycles_evaluation.json", {"summary": summarise(rows, config), "rows": rows})
    summary = summarise(rows, config)
    write_json_atomic(out / "cycles_evaluation.json", {"summary": summary, "rows": rows})
    write_csv_atomic(out / "cycles_evaluation.csv", [{k: (json.dumps(v) if isinstance(v, list) else v)
                                                     for k, v in r.items()} for r in rows])
    _plot(rows, out / "cycles_evaluation.png")
    return summary


def summarise(rows: list[dict], config: CyclesSet) -> dict:
    """Median / p95 / worst of the fit and the transfer in Cycles, the σa's error and the costs."""
    done = [r for r in rows if "transfer" in r]
    out = {"swatches": len(rows), "judged": len(done),
           "errors": [f"{r['hidden']}: {r['error']}" for r in rows if r.get("error")],
           "encoder_sigma_rel_error": error_stats(r["encoder_sigma_rel_error"] for r in done),
           "shine_abs_error": error_stats(r.get("shine_abs_error") for r in done),
           "cycles_s": error_stats(r["cycles_s"] for r in done),
           "by_case": {r["hidden"]: {"fit": r["fit"], "transfer": r["transfer"]} for r in done},
           "settings": {"size": config.size, "spp": config.spp, "shine": config.shine,
                        "transfer_pose": [TRANSFER_POSE.polar_deg, TRANSFER_POSE.azimuth_deg]}}
    for mode, tag in (("read", ""), ("no light frames", "nolights_")):
        if mode == "read" or config.shine:
            out[mode] = {key: error_stats(r.get(f"{tag}{key}") for r in done)
                         for key in ("fit", "transfer", "twin_residual", "sigma_rel_error", "estimate_s")}
    return out


def _plot(rows: list[dict], path: Path) -> None:
    done = [r for r in rows if "transfer" in r]
    fig, ax = plt.subplots(figsize=(8, 4))
    x = np.arange(len(done))
    for k, (key, label) in enumerate((("twin_residual", "hairdigi's Mitsuba twin vs the input"),
                                      ("fit", "σa rendered back in Cycles, rig view"),
                                      ("transfer", "σa rendered back in Cycles, key light + sky, another camera"))):
        ax.bar(x + (k - 1) * 0.27, [r[key] for r in done], 0.27, label=label)
    if any("nolights_transfer" in r for r in done):
        ax.scatter(x + 0.27, [r["nolights_transfer"] for r in done], marker="x", color="k", zorder=3,
                   label="transfer without the single-light frames (shine held at 0.3)")
    ax.axhline(1.0, ls="--", color="grey", lw=0.8)
    ax.set_xticks(x, [r["hidden"] for r in done], rotation=30, ha="right", fontsize=8)
    ax.set_ylabel("mean-colour ΔE2000 vs truth")
    ax.set_title("swatches rendered in Blender Cycles, estimated by hairdigi, judged in Cycles")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
