"""Reports on trained encoders: the encoder speed-vs-error benchmark and the model card."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hairdigi.inference.training.evaluate import evaluate
from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic, write_text_atomic
from hairdigi.render.domain.version import version
from hairdigi.render.io.figures import save_figure


def bench_encoders(onnx_paths: list[str | os.PathLike], out_dir: str | os.PathLike, n: int = 300,
                   size: int = 64, spp: int = 64, data_root=None, workers: int = 2, judge=None,
                   progress: bool = True) -> list[dict]:
    """Latency (ONNX, 1 thread, median) against the encoder-alone error of several encoders on one
    clean held-out set. Writes ``encoder_bench.csv`` and ``encoder_bench.png``."""
    from hairdigi.inference.encoder import Encoder   # deferred: loads OpenCV (~0.3 s); only this step needs it

    out = Path(out_dir)
    data_root = Path(data_root) if data_root else out / "heldout"   # one held-out set for every variant
    rows = []
    for path in onnx_paths:
        enc = Encoder(path)
        summary = evaluate(enc, out / Path(path).stem, n=n, size=size, spp=spp, data_root=data_root,
                           workers=workers, refine_colour=False, progress=progress,
                           **({"judge": judge} if judge else {}))
        a = summary["buckets"]["all"]
        rows.append({"model": Path(path).name, "input_size": enc.input_size,
                     "parameters": _parameter_count(path), "latency_ms": summary["latency_ms_median_1_thread"],
                     "latency_ms_8_views": _latency_views(enc),
                     "l1": a["encoder_l1"]["mean"], "l1_floor": a["floor_l1"]["mean"],
                     "mean_colour_de2000_median": a["encoder_mean_colour_de2000"]["median"],
                     "mean_colour_de2000_p95": a["encoder_mean_colour_de2000"]["p95"],
                     "mean_colour_de2000_floor_median": a["floor_mean_colour_de2000"]["median"]})
    write_csv_atomic(out / "encoder_bench.csv", rows)
    _plot(rows, out / "encoder_bench.png")
    return rows


def _parameter_count(path) -> int:
    import onnx   # deferred: torch and onnx are the optional [train] extra
    model = onnx.load(str(path))
    return int(sum(np.prod(t.dims) for t in model.graph.initializer))


def _latency_views(encoder, repeats: int = 100) -> float:
    """Median milliseconds for the 8-view estimate the app uses (batch of 8)."""
    # deferred: loads OpenCV (~0.3 s); only this step needs it
    from hairdigi.inference.encoder import median_latency_ms

    return median_latency_ms(encoder, np.zeros((8, 3, encoder.input_size, encoder.input_size), np.float32), repeats)


def _plot(rows: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for ax, key, floor, name in ((axes[0], "l1", "l1_floor", "L1 (0–255) vs the input"),
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
    fig.suptitle("hairdigi bench encoder: speed against error (clean inputs, encoder alone)")
    fig.tight_layout()
    save_figure(fig, path)


def _loss_text(train: dict) -> str:
    weight = train.get("appearance_weight", 0.0)
    if not weight:
        return "L2 on the normalised Table 1 vector"
    return (f"L2 on the normalised Table 1 vector + {weight:g} x L2 on the fibre colour it renders "
            "(cube-rooted Chiang albedo of sigma_a; inference/training/losses.py)")


def model_card(onnx_path: str | os.PathLike, run_dir: str | os.PathLike, evaluation: dict,
               out_path: str | os.PathLike, variants: list[dict] | None = None,
               convergence: list[dict] | None = None, refine_bench: list[dict] | None = None,
               rig_set: dict | None = None) -> Path:
    """Write the model card (Markdown) and its JSON twin beside the model.

    A hand-written ``<card>-notes.md`` beside the card (how to read the figures, known limits) is
    appended to it, so regenerating the card keeps them.
    """
    history = json.loads((Path(run_dir) / "history.json").read_text())
    card = _card_json(onnx_path, history, evaluation, variants, convergence, refine_bench, rig_set)
    out_path = Path(out_path)
    write_json_atomic(out_path.with_suffix(".json"), card)
    lines = [*_model_lines(card, history), *_evaluation_lines(evaluation),
             *_bench_lines(convergence, refine_bench, rig_set, variants)]
    notes = out_path.with_name(f"{out_path.stem}-notes.md")
    if notes.exists():
        lines += ["", notes.read_text().rstrip()]
    return write_text_atomic(out_path, "\n".join(lines) + "\n")


def _card_json(onnx_path, history: dict, evaluation: dict, variants, convergence, refine_bench, rig_set) -> dict:
    """The card's JSON twin: the model, how it was trained and on what, and every measurement."""
    from hairdigi.inference.encoder import sha256_file   # deferred: loads OpenCV (~0.3 s); only this step needs it

    last = history["epochs"][-1]
    return {
        "model": Path(onnx_path).name, "sha256": sha256_file(onnx_path), "date": time.strftime("%Y-%m-%d"),
        "hairdigi_version": version(),
        "architecture": {**history["encoder"], "parameters": history["parameters"],
                         "description": "strided conv blocks (conv3x3 s2 + conv3x3, BatchNorm, ReLU), global "
                                        "average pooling, MLP 64, sigmoid over 6 normalised parameters"},
        "training": {**history["train"], "epochs_run": last["epoch"], "final_val_mse": last["val_mse"],
                     "seconds": sum(e["seconds"] for e in history["epochs"])},
        "datasets": _datasets(history),
        "preprocessing": "8-bit sRGB; swatch area found or given; central square (whole image for all-hair "
                         "crops, 70% of the area for rig frames); area-resize to the input size in linear "
                         "light; sRGB encoded, minus 0.5; 8 flips/quarter turns averaged at inference",
        "evaluation": evaluation, "variants": variants or [], "convergence": convergence or [],
        "refine_bench": refine_bench or [], "simulated_rig": rig_set or {},
    }


def _datasets(history: dict) -> list[dict]:
    """The datasets a run trained on (older runs name one)."""
    return history.get("datasets") or [history["dataset"]]


def _de(who: str, bucket: dict) -> str:
    """A bucket's mean-colour ΔE2000 of ``who`` (encoder, refined, floor): median / p95 / worst."""
    key = f"{who}_mean_colour_de2000"
    if key not in bucket:
        return "n/a"
    d = bucket[key]
    return f"{d['median']:.2f} / {d['p95']:.2f} / {d['max']:.2f}"


def _mean(bucket: dict, key: str) -> str:
    return f"{bucket[key]['mean']:.3f}" if key in bucket else "n/a"


def _model_lines(card: dict, history: dict) -> list[str]:
    """The card's head: the model, its architecture, training, datasets and preprocessing."""
    datasets = _datasets(history)
    last = history["epochs"][-1]
    return [
        f"# Model card: {card['model']}", "",
        f"- sha256 `{card['sha256']}`, made {card['date']}",
        f"- hairdigi version {card['hairdigi_version']}",
        f"- Architecture: {card['architecture']['description']}; width {history['encoder']['width']}, "
        f"{history['encoder']['blocks']} blocks, input {history['encoder']['input_size']}² px, "
        f"{history['parameters']:,} parameters.",
        f"- Training: `hairdigi train`, AdamW (one-cycle, max lr {history['train']['lr']}), batch "
        f"{history['train']['batch_size']}, {_loss_text(history['train'])}, {last['epoch']} epochs "
        f"({card['training']['seconds'] / 60:.0f} min on {history['train']['threads']} CPU thread(s)); final "
        f"validation MSE {last['val_mse']:.5f}. Augmentation: random square crops ({history['train']['crop_min']}"
        f"–1 of the side), flips, quarter turns, a blur of sigma 0–{history['train'].get('blur_max', 0)} px, then "
        "the capture chain of `render.camera_model` with a calibrated capture's residual errors (exposure "
        "sd 0.015 EV, colour cast sd 0.8%, shot and read noise, 12-bit ADC, 8-bit sRGB).",
        "- Datasets: " + "; ".join(
            f"`hairdigi dataset --n {ds['n']} --size {ds['size']} --spp {ds['spp']} --seed {ds['seed']} "
            f"--store {ds.get('store', 'srgb8')} --strands {ds.get('strands')} "
            f"--swatch-model {ds.get('swatch_model', 'today')} --appearance {ds.get('appearance', 'fixed')}`"
            for ds in datasets) +
        f": uniform Table 1 parameters, cameras uniform on a {datasets[0]['polar_max_deg']}° cap (distance ±"
        f"{100 * datasets[0]['distance_jitter']:.0f}%) clear of the rig lights, a new strand layout per swatch, "
        + ("shine, fibre spread and grey share drawn uniformly over render.domain.appearance.APPEARANCE_DRAW, "
           if datasets[0].get("appearance") == "random" else "") +
        f"crop framing (all hair), linear float16 radiance. {sum(ds['n_loaded'] for ds in datasets)} swatches "
        f"loaded; {100 * history['train']['val_fraction']:.0f}% held for validation.",
        f"- Preprocessing: {card['preprocessing']}.", "",
    ]


def _evaluation_lines(evaluation: dict) -> list[str]:
    """The clean held-out evaluation: ΔE2000 and the paper's metrics, latency, hard cases, errors, intervals."""
    a = evaluation["buckets"]["all"]
    judge = evaluation["judge"]
    lines = [
        f"## Evaluation on clean inputs (`hairdigi evaluate`, {evaluation['n']} held-out swatches, seed "
        f"{evaluation['seed']}, {evaluation['size']}² at {evaluation['spp']} spp, through the camera model)", "",
        "Each estimate and the truth are rendered with the swatch's camera and strand layout and one common new "
        f"sampler seed ({judge['size']}² at {judge['spp']} spp); the mean-colour ΔE2000 compares the two. The "
        "floor compares the input itself with the truth's render: what render noise and the camera leave.", "",
        "| mean-colour ΔE2000 | median / p95 / worst |", "|---|---|",
        f"| encoder alone | {_de('encoder', a)} |",
        f"| encoder + refinement by synthesis | {_de('refined', a)} |",
        f"| floor (input vs truth render) | {_de('floor', a)} |", "",
        "| paper's metrics (judge render vs input) | encoder | refined | truth (floor) | paper (Table 2) |",
        "|---|---|---|---|---|",
        f"| L1 (0–255) | {_mean(a, 'encoder_l1')} | {_mean(a, 'refined_l1')} | {_mean(a, 'floor_l1')} | "
        "7.08 ± 11.79 |",
        f"| MS-SSIM (3 scales at 64²) | {_mean(a, 'encoder_ms_ssim3')} | {_mean(a, 'refined_ms_ssim3')} | "
        f"{_mean(a, 'floor_ms_ssim3')} | 0.20 ± 0.04 (as printed) |",
        "| LPIPS | not computed: no package here ships the pretrained AlexNet/VGG weights | | | 0.12 ± 0.19 |", "",
        f"Encoder latency: {evaluation['latency_ms_median_1_thread']:.3f} ms median (ONNX, 1 thread, one view). "
        + (f"Refinement: {a['refine_s']['median']:.2f} s median once the pose's response curve is cached; "
           f"the curve itself {a['curve_s']['median']:.2f} s median, once per pose (the rig pays it once). "
           "Both measured while other jobs shared the 2 cores; idle figures are in README.md's table."
           if "refine_s" in a else ""), "",
        "Hard cases, mean-colour ΔE2000 median / p95 / worst (encoder; refined):", "",
    ]
    for name, b in evaluation["buckets"].items():
        lines.append(f"- {name} ({b['count']}): {_de('encoder', b)}; {_de('refined', b)}")
    who = "refined" if "refined_abs_err" in a else "encoder"
    lines += ["", f"Mean absolute error per parameter ({who}): " + ", ".join(
        f"{k} {v:.3f}" for k, v in a[f"{who}_abs_err"].items()) + "."]
    if "coverage" in evaluation:
        lines += ["", "68% intervals (`uncertainty.json`, fitted on even held-out rows, measured on odd ones): "
                  "coverage " + ", ".join(f"{k} {100 * v:.0f}%" for k, v in evaluation["coverage"].items()) + "."]
    if "heldout_flagged_out_of_domain" in evaluation:
        lines += ["", f"Out-of-domain checks on the clean held-out set: {evaluation['heldout_flagged_out_of_domain']} "
                  f"of {evaluation['n']} flagged (false alarms)."]
    return lines


def _bench_lines(convergence, refine_bench, rig_set, variants) -> list[str]:
    """The sections of the other measurements given: convergence, refinement, the simulated rig, variants."""
    lines: list[str] = []
    if convergence:
        lines += ["", f"## By input convergence (`hairdigi evaluate --convergence`, first "
                  f"{int(convergence[0]['swatches'])} swatches)", "",
                  "| input spp | render s | encoder median / p95 | refined median / p95 |", "|---|---|---|---|"]
        lines += [f"| {int(r['spp'])} | {r['render_s']:.2f} | {r['encoder_de_median']:.2f} / {r['encoder_de_p95']:.2f} | "
                  f"{r['refined_de_median']:.2f} / {r['refined_de_p95']:.2f} |" for r in convergence]
    if refine_bench:
        lines += ["", "## Refinement: speed against error (`hairdigi bench refine`)", "",
                  "| size | spp | iterations | ΔE2000 median / p95 | curve s | polish s |", "|---|---|---|---|---|---|"]
        lines += [f"| {int(r['size'])}² | {int(r['spp'])} | {int(r['iterations'])} | {r['de_median']:.2f} / "
                  f"{r['de_p95']:.2f} | {r['curve_s']:.2f} | {r['polish_s']:.2f} |" for r in refine_bench]
    if rig_set:
        lines += ["", *chain_section(rig_set.get("summary", rig_set))]
    if variants:
        lines += ["", "## Variants (`hairdigi bench encoder`, encoder alone)", "",
                  "| model | input | parameters | latency ms | ΔE2000 median / p95 |", "|---|---|---|---|---|"]
        lines += [f"| {v['model']} | {int(v['input_size'])}² | {int(v['parameters']):,} | {v['latency_ms']:.3f} | "
                  f"{v['mean_colour_de2000_median']:.2f} / {v['mean_colour_de2000_p95']:.2f} |" for v in variants]
    return lines


def chain_section(summary: dict) -> list[str]:
    """The model card's lines on the whole chain against the truth (``hairdigi evaluate --rig``)."""
    r, e, c = summary["refined"], summary["encoder_alone"], summary["coverage_held_out"]
    lines = ["## The whole chain on the simulated rig, against the truth (`hairdigi evaluate --rig`)", "",
             f"{summary['estimated']} of {summary['captures']} captures estimated (live frames and RAW stills, white-"
             f"balance casts ±10%, exposure ±0.5 EV, through cv2.mcc, the CCM, the swatch area and refinement), each "
             f"judged against its hidden truth at the rig's swatch pose (mean-colour ΔE2000):", "",
             "| | median | p95 | worst | n |", "|---|---|---|---|---|",
             f"| refined (what records say) | {r['median']:.2f} | {r['p95']:.2f} | {r['worst']:.2f} | {r['n']} |",
             f"| encoder alone | {e['median']:.2f} | {e['p95']:.2f} | {e['worst']:.2f} | {e['n']} |"]
    for name, st in {**summary.get("by_source", {}), **summary.get("by_case", {})}.items():
        if st.get("n"):
            lines.append(f"| {name} | {st['median']:.2f} | {st['p95']:.2f} | {st['worst']:.2f} | {st['n']} |")
    lines += ["", f"A record's colour interval is this table's 68% / 95% quantiles; fitted on half the hidden "
                  f"swatches it held for {c['p68']:.0%} / {c['p95']:.0%} of the other half's captures."]
    if summary.get("blocked"):
        lines += ["", "Refused, with the reason the operator is given (no estimate is made from them):", ""]
        lines += [f"- {b}" for b in summary["blocked"]]
    return lines
