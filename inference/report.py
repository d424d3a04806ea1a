"""Reports on trained encoders: the encoder speed-vs-error benchmark and the model card."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from inference.evaluate import SPANS, evaluate
from render.params import VECTOR_FIELDS, write_json_atomic


def bench_encoders(onnx_paths: list[str | os.PathLike], out_dir: str | os.PathLike, n: int = 300,
                   size: int = 176, spp: int = 4, rerender: int = 60, data_root=None, workers: int = 2,
                   progress: bool = True) -> list[dict]:
    """Latency (ONNX, 1 thread, median) against error for several encoders on one held-out set.

    Parameter errors use all ``n`` swatches; image metrics the first ``rerender`` (re-rendering is
    the costly part). Writes ``encoder_bench.csv`` and ``encoder_bench.png``.
    """
    from inference.encoder import Encoder
    from render.bench import write_csv_atomic

    out = Path(out_dir)
    data_root = Path(data_root) if data_root else out / "heldout"   # one held-out set for every variant
    rows = []
    for path in onnx_paths:
        enc = Encoder(path)
        summary = evaluate(enc, out / Path(path).stem, n=n, size=size, spp=spp, data_root=data_root,
                           workers=workers, rerender=rerender, progress=progress)
        a = summary["buckets"]["all"]
        param_rmse = float(np.sqrt(np.mean([(a[f"abs_err_{f[0]}"]["mean"] / s) ** 2
                                            for f, s in zip(VECTOR_FIELDS, SPANS)])))
        rows.append({"model": Path(path).name, "input_size": enc.input_size,
                     "parameters": _parameter_count(path), "latency_ms": summary["latency_ms_median_1_thread"],
                     "latency_ms_8_views": _latency_views(enc), "param_mae_normalised": param_rmse,
                     "l1": a["est_l1"]["mean"], "l1_floor": a["floor_l1"]["mean"],
                     "mean_colour_de2000_median": a["est_mean_colour_de2000"]["median"],
                     "mean_colour_de2000_floor_median": a["floor_mean_colour_de2000"]["median"]})
    write_csv_atomic(out / "encoder_bench.csv", rows)
    _plot(rows, out / "encoder_bench.png")
    return rows


def _parameter_count(path) -> int:
    import onnx
    model = onnx.load(str(path))
    return int(sum(np.prod(t.dims) for t in model.graph.initializer))


def _latency_views(encoder, repeats: int = 100) -> float:
    """Median milliseconds for the 8-view estimate the app uses (batch of 8)."""
    from inference.encoder import median_latency_ms

    return median_latency_ms(encoder, np.zeros((8, 3, encoder.input_size, encoder.input_size), np.float32), repeats)


def _plot(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for ax, key, floor, name in ((axes[0], "l1", "l1_floor", "L1 (0–255) vs original"),
                                 (axes[1], "mean_colour_de2000_median", "mean_colour_de2000_floor_median",
                                  "mean-colour ΔE2000 (median)")):
        for r in rows:
            ax.plot(r["latency_ms"], r[key], "o")
            ax.annotate(f"{r['model']} ({r['parameters'] / 1e3:.0f}k, {r['input_size']}²)",
                        (r["latency_ms"], r[key]), fontsize=7, xytext=(4, 4), textcoords="offset points")
        ax.axhline(np.mean([r[floor] for r in rows]), color="grey", ls="--", lw=0.8, label="render-noise floor")
        ax.set_xlabel("encoder latency, ms (ONNX, 1 thread, median)")
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("hairdigi bench encoder: speed against error")
    fig.tight_layout()
    tmp = path.with_name(f".{path.name}")
    fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    os.replace(tmp, path)


def _loss_text(train: dict) -> str:
    weight = train.get("appearance_weight", 0.0)
    if not weight:
        return "L2 on the normalised Table 1 vector"
    return (f"L2 on the normalised Table 1 vector + {weight:g} x L2 on the fibre colour it renders "
            "(cube-rooted Chiang albedo of sigma_a; inference/losses.py)")


def model_card(onnx_path: str | os.PathLike, run_dir: str | os.PathLike, evaluation: dict,
               out_path: str | os.PathLike, variants: list[dict] | None = None,
               noise_sweep: list[dict] | None = None) -> Path:
    """Write the model card (Markdown) and its JSON twin beside the model.

    A hand-written ``<card>-notes.md`` beside the card (how to read the figures, known limits) is
    appended to it, so regenerating the card keeps them.
    """
    from inference.encoder import sha256_file

    history = json.loads((Path(run_dir) / "history.json").read_text())
    datasets = history.get("datasets") or [history["dataset"]]
    last = history["epochs"][-1]
    a = evaluation["buckets"]["all"]
    card = {
        "model": Path(onnx_path).name, "sha256": sha256_file(onnx_path), "date": time.strftime("%Y-%m-%d"),
        "architecture": {**history["encoder"], "parameters": history["parameters"],
                         "description": "strided conv blocks (conv3x3 s2 + conv3x3, BatchNorm, ReLU), global "
                                        "average pooling, MLP 64, sigmoid over 6 normalised parameters"},
        "training": {**history["train"], "epochs_run": last["epoch"], "final_val_mse": last["val_mse"],
                     "seconds": sum(e["seconds"] for e in history["epochs"])},
        "datasets": datasets,
        "preprocessing": "8-bit sRGB; swatch area found or given; central square (whole image for all-hair "
                         "crops, 70% of the area for rig frames); area-resize to the input size; /255 - 0.5; "
                         "8 flips/quarter turns averaged at inference",
        "evaluation": evaluation, "variants": variants or [], "noise_sweep": noise_sweep or [],
    }
    out_path = Path(out_path)
    write_json_atomic(out_path.with_suffix(".json"), card)

    def m(key, stat="mean"):
        return f"{a[key][stat]:.3f}" if key in a else "n/a"

    lines = [
        f"# Model card: {card['model']}", "",
        f"- sha256 `{card['sha256']}`, made {card['date']}",
        f"- Architecture: {card['architecture']['description']}; width {history['encoder']['width']}, "
        f"{history['encoder']['blocks']} blocks, input {history['encoder']['input_size']}² px, "
        f"{history['parameters']:,} parameters.",
        f"- Training: `hairdigi train`, AdamW (one-cycle, max lr {history['train']['lr']}), batch "
        f"{history['train']['batch_size']}, {_loss_text(history['train'])}, {last['epoch']} epochs "
        f"({card['training']['seconds'] / 60:.0f} min on {history['train']['threads']} CPU thread(s)); final "
        f"validation MSE {last['val_mse']:.5f}. Augmentation: random square crops ({history['train']['crop_min']}"
        f"–1 of the side), flips, quarter turns, a blur of sigma 0–{history['train'].get('blur_max', 0)} px; never colour.",
        "- Datasets: " + "; ".join(
            f"`hairdigi dataset --n {ds['n']} --size {ds['size']} --spp {ds['spp']} --seed {ds['seed']}`"
            for ds in datasets) +
        f": uniform Table 1 parameters, cameras uniform on a {datasets[0]['polar_max_deg']}° cap (distance ±"
        f"{100 * datasets[0]['distance_jitter']:.0f}%) clear of the rig lights, a new strand layout per swatch, "
        f"crop framing (all hair). {sum(ds['n_loaded'] for ds in datasets)} swatches loaded, "
        f"{history.get('n_skipped_behind_light', 0)} skipped (camera behind a light); "
        f"{100 * history['train']['val_fraction']:.0f}% held for validation.",
        f"- Preprocessing: {card['preprocessing']}.", "",
        f"## Evaluation (`hairdigi evaluate`, {evaluation['n']} held-out swatches, seed {evaluation['seed']}, "
        f"{evaluation['size']}² at {evaluation['spp']} spp; image metrics on {evaluation['n_rerendered']})", "",
        "Each swatch is estimated, re-rendered from the estimate with the same camera and strand layout and a "
        "new sampler seed, and compared with the original. The floor re-renders the *true* parameters with "
        "that same new seed: render noise alone.", "",
        "| metric | estimate | noise floor | paper (Table 2) |", "|---|---|---|---|",
        f"| L1 (0–255) | {m('est_l1')} ± {m('est_l1', 'std')} | {m('floor_l1')} | 7.08 ± 11.79 |",
        f"| MS-SSIM | {m('est_ms_ssim')} | {m('floor_ms_ssim')} | 0.20 ± 0.04 (as printed) |",
        f"| ΔE2000 per pixel | {m('est_pixel_de2000')} | {m('floor_pixel_de2000')} | – |",
        f"| ΔE2000 of the mean colour, median | {m('est_mean_colour_de2000', 'median')} | "
        f"{m('floor_mean_colour_de2000', 'median')} | – |",
        "| LPIPS | not computed: no package here ships the pretrained AlexNet/VGG weights | | 0.12 ± 0.19 |", "",
        f"Encoder latency: {evaluation['latency_ms_median_1_thread']:.3f} ms median (ONNX, 1 thread, one view).", "",
        "Mean absolute error per parameter: " + ", ".join(
            f"{f[0]} {a['abs_err_' + f[0]]['mean']:.3f}" for f in VECTOR_FIELDS) + ".", "",
        "Hard cases (mean L1 / floor; median mean-colour ΔE2000 / floor):", "",
    ]
    for name, b in evaluation["buckets"].items():
        if "est_l1" in b:
            lines.append(f"- {name} ({b['count']}): L1 {b['est_l1']['mean']:.2f} / {b['floor_l1']['mean']:.2f}; "
                         f"ΔE {b['est_mean_colour_de2000']['median']:.2f} / "
                         f"{b['floor_mean_colour_de2000']['median']:.2f}")
    if variants:
        lines += ["", "## Variants (`hairdigi bench encoder`)", "",
                  "| model | input | parameters | latency ms | L1 | ΔE2000 median |", "|---|---|---|---|---|---|"]
        lines += [f"| {v['model']} | {int(v['input_size'])}² | {int(v['parameters']):,} | {v['latency_ms']:.3f} | "
                  f"{v['l1']:.2f} | {v['mean_colour_de2000_median']:.2f} |" for v in variants]
    if noise_sweep:
        lines += ["", f"## Noise sweep (`hairdigi evaluate --noise-sweep`, {int(noise_sweep[0]['swatches'])} "
                  "held-out swatches re-rendered at each spp)", "",
                  "| spp | render s | L1 | L1 floor | mean-colour ΔE2000 | floor | MS-SSIM | floor |",
                  "|---|---|---|---|---|---|---|---|"]
        lines += [f"| {int(r['spp'])} | {r['render_s']:.2f} | {r['est_l1']:.2f} | {r['floor_l1']:.2f} | "
                  f"{r['est_mean_colour_de2000']:.2f} | {r['floor_mean_colour_de2000']:.2f} | "
                  f"{r['est_ms_ssim']:.3f} | {r['floor_ms_ssim']:.3f} |" for r in noise_sweep]
    notes = out_path.with_name(f"{out_path.stem}-notes.md")
    if notes.exists():
        lines += ["", notes.read_text().rstrip()]
    tmp = out_path.with_name(f".{out_path.name}")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, out_path)
    return out_path
