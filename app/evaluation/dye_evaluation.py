"""``hairdigi evaluate --dye``: dyes characterised on two natural bases, predicted on the third.

The held-out protocol of dye development, through the whole estimate chain:

1. **Truth.** Three natural bases (``inference.levels.EVALUATION_LEVELS``: light, medium, dark) and
   ``dyes`` random dyes: deposit ``dye_sigma_a(rgb, concentration)`` with the colour and the
   concentration drawn uniformly over Table 1's dye range (Kips et al. 2022), lift uniform in
   [0, 0.6]. Dyed truth: ``(1 - lift) * sigma_melanin(base) + deposit``.
2. **Captures.** Each base and each dyed swatch is rendered (all-hair crop at the rig's pose, 64 spp,
   its own strand layout and seed), shot through the camera model (sensor noise, 12-bit ADC, 8-bit
   sRGB; as ``hairdigi evaluate`` does) and estimated by the real estimator
   (``inference.estimate.estimate_image``: encoder + refinement by synthesis). The records are
   written and read back as ``hairdigi dye`` reads them.
3. **Two-pair fit.** For each dye and each base held out, ``characterise`` on the other two pairs and
   ``apply`` to the held-out base's *estimated* record.
4. **The judge.** The prediction's ``sigma_a`` and the truth's are rendered with one strand layout and
   one common sampler seed; the mean-colour ΔE2000 of the two renders is the error.
   The floor: the held-out dyed swatch's own estimate, judged the same way (what the estimator
   alone misses; a prediction cannot be expected to do better).
5. **One-pair fits** (lift assumed): the fitted lift against the true one, and the one-pair
   prediction on each other base, judged the same way.

Timings of characterise, apply and dose (in process) and of one shade card are recorded.
"""
from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.inference.dye import apply, characterise, colour_of, dose, lifted_melanin, load_sample, rig_curve
from hairdigi.inference.dye_card import shade_card
from hairdigi.inference.estimate import estimate_image, record
from hairdigi.inference.levels import EVALUATION_LEVELS, natural_base
from hairdigi.inference.preprocess import Roi
from hairdigi.render.camera_model import CameraModel, sensor_response
from hairdigi.render.domain.absorption import dye_sigma_a, hair_sigma_a
from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, write_record
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.render.io.figures import save_figure
from hairdigi.render.metrics import delta_e2000

GOAL_MEDIAN, GOAL_P95 = 1.0, 2.0


@dataclass(frozen=True)
class DyeEvalConfig:
    """The held-out dye set and its render settings."""

    dyes: int = 12
    seed: int = 190_019
    lift_max: float = 0.6
    size: int = 64              # input renders (as hairdigi evaluate's held-out swatches)
    spp: int = 64
    judge_size: int = 64
    judge_spp: int = 16
    judge_seed: int = 424_242
    judge_strands_seed: int = 777


def draw_dyes(config: DyeEvalConfig) -> list[dict]:
    """The random dyes: Table 1 dye colour and concentration (uniform), and a lift in [0, lift_max]."""
    rng = np.random.default_rng(config.seed)
    dyes = []
    for k in range(config.dyes):
        rgb = rng.uniform(0.0, 255.0, 3)
        conc = float(rng.uniform(0.0, 1.0))
        lift = float(rng.uniform(0.0, config.lift_max))
        dyes.append({"dye": k, "dye_rgb": [float(v) for v in rgb], "dye_concentration": conc,
                     "lift": round(lift, 4), "deposit": dye_sigma_a(tuple(rgb), conc)})
    return dyes


def _capture(linear: np.ndarray, key: list[int]) -> np.ndarray:
    return sensor_response(np.asarray(linear, np.float32), CameraModel(), np.random.default_rng(key))


#: ``capture(hidden, index, path) -> seconds``: capture the hidden Table 1 hair, estimate it, write its record.
Capture = Callable[[HairParams, int, Path], float]


def clean_capture(encoder, config: DyeEvalConfig) -> Capture:
    """Captures as clean renders through the camera model (the default inputs)."""
    return lambda hidden, index, path: _estimate_record(hair_sigma_a(hidden), index, encoder, config, path)[1]


def dyed_hair(base: HairParams, dye: dict) -> HairParams:
    """The natural base with the dye: its melanin lifted, the dye's Table 1 colour and concentration added.

    Its ``sigma_a`` is exactly ``(1 - lift) * sigma_melanin(base) + deposit`` (the melanin remap is
    piecewise linear, and so is its inverse)."""
    return HairParams(tuple(dye["dye_rgb"]), dye["dye_concentration"], lifted_melanin(base, dye["lift"]),
                      base.melanin_ratio)


def _estimate_record(sigma: np.ndarray, index: int, encoder, config: DyeEvalConfig, path: Path) -> tuple[Path, float]:
    """Render ``sigma`` as a capture, estimate it with the real estimator, write its record."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec, default_renderer

    spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, framing="crop", strand_seed=1000 + index)
    linear = default_renderer().render(sigma, spec, config.size, config.spp, seed=index).linear
    frame = _capture(linear, [config.seed, index])
    start = time.perf_counter()
    result = estimate_image(frame, encoder, roi=Roi(0, 0, frame.shape[1], frame.shape[0]))
    seconds = time.perf_counter() - start
    rec = record(result, encoder, frame.tobytes())
    if isinstance(rec, dict):        # an estimator that still returns the first layout's dict
        rec = EstimateRecord.from_json(rec)
    write_record(path, rec)
    return path, seconds


def _judge(sigma: np.ndarray, config: DyeEvalConfig) -> np.ndarray:
    """The mean linear colour of ``sigma`` rendered at the judge's layout and common seed."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec, default_renderer

    spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, framing="crop", strand_seed=config.judge_strands_seed)
    out = default_renderer().render(np.clip(sigma, 0, None), spec, config.judge_size, config.judge_spp,
                                    config.judge_seed)
    return out.linear.reshape(-1, 3).mean(0)


def _stats(values) -> dict:
    a = np.asarray(values, float)
    return {"median": float(np.median(a)), "p95": float(np.quantile(a, 0.95)), "max": float(a.max()),
            "mean": float(a.mean()), "n": int(a.size)}


def evaluate_dye(encoder, out_dir: str | os.PathLike, config: DyeEvalConfig = DyeEvalConfig(),
                 progress: bool = True, capture: Capture | None = None, inputs: str = "clean renders") -> dict:
    """Run the protocol; write ``dye_eval.json``, ``dye_eval.csv``, ``dye_eval.png``; return the summary.

    ``capture`` makes each record (default: :func:`clean_capture`); ``inputs`` says what it is."""
    t_all = time.perf_counter()
    out = Path(out_dir)
    (out / "records").mkdir(parents=True, exist_ok=True)
    curve = rig_curve()
    bases = {name: hair_sigma_a(natural_base(level)) for name, level in EVALUATION_LEVELS.items()}
    dyes = draw_dyes(config)
    sample, truth, estimate_s = _captures(dyes, bases, capture or clean_capture(encoder, config), out / "records",
                                          progress)
    judge_truth = {key: _judge(sigma, config) for key, sigma in
                   tqdm(truth.items(), desc="judge renders of the truth", disable=not progress)}
    rows, one_rows, times = [], [], {"characterise_s": [], "apply_s": [], "dose_s": []}
    for d in tqdm(dyes, desc="characterise + predict", disable=not progress):
        rows += _two_pair_rows(d, bases, sample, truth, judge_truth, curve, config, times)
        one_rows += _one_pair_rows(d, bases, sample, judge_truth, curve, config)
    card_s = _timed_card(bases, sample, curve, out / "card-dye0.png")
    summary = _summary(config, bases, rows, one_rows, estimate_s, times, card_s, inputs,
                       total_s=time.perf_counter() - t_all)
    summary["text"] = _text(summary)
    _write(out, summary, rows, one_rows)
    return summary


def _captures(dyes: list[dict], bases: dict, capture: Capture, records: Path, progress: bool):
    """Every base and dyed swatch captured and estimated: (samples by name, dyed truth by (dye, base), seconds)."""
    jobs = [(f"base-{b}", natural_base(level)) for b, level in EVALUATION_LEVELS.items()]
    truth = {}
    for d in dyes:
        for b, level in EVALUATION_LEVELS.items():
            hidden = dyed_hair(natural_base(level), d)
            truth[(d["dye"], b)] = (1.0 - d["lift"]) * bases[b] + d["deposit"]
            assert np.allclose(hair_sigma_a(hidden), truth[(d["dye"], b)], atol=1e-9)
            jobs.append((f"dye{d['dye']:02d}-{b}", hidden))
    estimate_s = []
    for index, (name, hidden) in enumerate(tqdm(jobs, desc="capture + estimate", unit="swatch", disable=not progress)):
        estimate_s.append(capture(hidden, index, records / f"{name}.json"))
    sample = {name: load_sample(records / f"{name}.json") for name, _ in jobs}
    return sample, truth, estimate_s


def _two_pair_rows(d: dict, bases: dict, sample: dict, truth: dict, judge_truth: dict, curve,
                   config: DyeEvalConfig, times: dict[str, list]) -> list[dict]:
    """One dye fitted on two bases, predicted on the third, for each base held out (timed into ``times``)."""
    rows = []
    k = d["dye"]
    for held in bases:
        train = [b for b in bases if b != held]
        pairs = [(sample[f"base-{b}"], sample[f"dye{k:02d}-{b}"]) for b in train]
        t0 = time.perf_counter()
        dye = characterise(pairs, f"dye {k}", curve)
        t1 = time.perf_counter()
        pred = apply(dye, sample[f"base-{held}"], 1.0, curve)
        t2 = time.perf_counter()
        dose(dye, sample[f"base-{held}"], colour_of(truth[(k, held)], curve), curve)
        t3 = time.perf_counter()
        times["characterise_s"].append(t1 - t0)
        times["apply_s"].append(t2 - t1)
        times["dose_s"].append(t3 - t2)
        de = float(delta_e2000(_judge(pred.sigma_a, config), judge_truth[(k, held)]))
        # what the estimator alone misses on the same swatch: the held-out dyed capture's own estimate
        floor = float(delta_e2000(_judge(sample[f"dye{k:02d}-{held}"].sigma_a, config), judge_truth[(k, held)]))
        rows.append({"dye": k, "held_out": held, "fitted_on": "+".join(train), "true_lift": d["lift"],
                     "lift": round(dye.lift, 4), "lift_low": round(dye.lift_low, 4), "lift_high": round(dye.lift_high, 4),
                     "true_deposit": [round(float(v), 5) for v in d["deposit"]],
                     "deposit": [round(float(v), 5) for v in dye.deposit_sigma_a],
                     "fit_residual_de2000": round(dye.residual_de2000_max, 3),
                     "prediction_de2000": round(de, 3), "estimate_floor_de2000": round(floor, 3),
                     "prediction_de2000_curve": round(float(delta_e2000(
                         colour_of(pred.sigma_a, curve), colour_of(truth[(k, held)], curve))), 3),
                     "predicted_interval_de2000_p68": pred.record.uncertainty.mean_colour_de2000_p68})
    return rows


def _one_pair_rows(d: dict, bases: dict, sample: dict, judge_truth: dict, curve, config: DyeEvalConfig) -> list[dict]:
    """One dye fitted on one pair (lift assumed): the fitted lift against the truth, and the prediction on
    each other base."""
    rows = []
    k = d["dye"]
    for b in bases:
        dye1 = characterise([(sample[f"base-{b}"], sample[f"dye{k:02d}-{b}"])], f"dye {k} on {b}", curve)
        for other in bases:
            if other == b:
                continue
            pred = apply(dye1, sample[f"base-{other}"], 1.0, curve)
            de = float(delta_e2000(_judge(pred.sigma_a, config), judge_truth[(k, other)]))
            rows.append({"dye": k, "fitted_on": b, "predicted": other, "true_lift": d["lift"],
                         "one_pair_lift": round(dye1.lift, 4), "lift_error": round(dye1.lift - d["lift"], 4),
                         "prediction_de2000": round(de, 3)})
    return rows


def _timed_card(bases: dict, sample: dict, curve, path: Path) -> float:
    """The seconds a shade card of dye 0 (fitted on every base) takes to make."""
    t0 = time.perf_counter()
    shade_card(characterise([(sample[f"base-{b}"], sample[f"dye00-{b}"]) for b in bases], "dye 0", curve),
               path, curve=curve)
    return time.perf_counter() - t0


def _summary(config: DyeEvalConfig, bases: dict, rows: list[dict], one_rows: list[dict], estimate_s: list[float],
             times: dict[str, list], card_s: float, inputs: str, total_s: float) -> dict:
    """The protocol's figures: the predictions' ΔE2000 against the goal, the floor, the lifts, the timings."""
    de = [r["prediction_de2000"] for r in rows]
    one_de = [r["prediction_de2000"] for r in one_rows]
    lift_err = [abs(r["lift_error"]) for r in one_rows[::2]]       # one row per (dye, fitted base)
    two_lift_err = [abs(r["lift"] - r["true_lift"]) for r in rows]
    return {
        "config": asdict(config), "levels": EVALUATION_LEVELS, "date": time.strftime("%Y-%m-%d"),
        "prediction_de2000": _stats(de),
        "prediction_de2000_by_held_out": {b: _stats([r["prediction_de2000"] for r in rows if r["held_out"] == b])
                                          for b in bases},
        "goal": {"median": GOAL_MEDIAN, "p95": GOAL_P95,
                 "met": bool(np.median(de) <= GOAL_MEDIAN and np.quantile(de, 0.95) <= GOAL_P95)},
        "estimate_floor_de2000": _stats([r["estimate_floor_de2000"] for r in rows]),
        "two_pair_lift_abs_error": _stats(two_lift_err),
        "one_pair_lift_abs_error": _stats(lift_err),
        "one_pair_prediction_de2000": _stats(one_de),
        "estimate_s": _stats(estimate_s),
        "seconds": {k: _stats(v) for k, v in times.items()} | {"card_s": card_s},
        "total_s": total_s,
        "inputs": inputs,
    }


def _write(out: Path, summary: dict, rows: list[dict], one_rows: list[dict]) -> None:
    """``dye_eval.json`` (the summary and every row), the two CSVs and the figure."""
    write_json_atomic(out / "dye_eval.json", {**summary, "rows": rows, "one_pair_rows": one_rows})
    write_csv_atomic(out / "dye_eval.csv", [{k: (v if not isinstance(v, list) else " ".join(map(str, v)))
                                             for k, v in r.items()} for r in rows])
    write_csv_atomic(out / "dye_eval_one_pair.csv", one_rows)
    _plot(rows, one_rows, out / "dye_eval.png")


def _text(s: dict) -> list[str]:
    p, o = s["prediction_de2000"], s["one_pair_prediction_de2000"]
    sec = s["seconds"]
    lines = [f"two bases -> the third: mean-colour ΔE2000 median {p['median']:.2f}, p95 {p['p95']:.2f}, worst "
             f"{p['max']:.2f} over {p['n']} predictions (goal median <= {GOAL_MEDIAN}, p95 <= {GOAL_P95}: "
             f"{'met' if s['goal']['met'] else 'NOT met'})"]
    lines += [f"  held out {b}: median {v['median']:.2f}, p95 {v['p95']:.2f}"
              for b, v in s["prediction_de2000_by_held_out"].items()]
    f = s["estimate_floor_de2000"]
    lines.append(f"  the estimator alone on the same dyed swatches (the floor): median {f['median']:.2f}, p95 {f['p95']:.2f}")
    lines.append(f"lift |error|: two bases median {s['two_pair_lift_abs_error']['median']:.3f} (worst "
                 f"{s['two_pair_lift_abs_error']['max']:.3f}); one base (lift assumed) median "
                 f"{s['one_pair_lift_abs_error']['median']:.3f} (worst {s['one_pair_lift_abs_error']['max']:.3f}); "
                 f"one-pair predictions on the other bases ΔE2000 median {o['median']:.2f}, p95 {o['p95']:.2f}")
    lines.append(f"times: estimate {s['estimate_s']['median']:.2f} s/swatch; characterise "
                 f"{sec['characterise_s']['median']:.3f} s, apply {sec['apply_s']['median']:.3f} s, dose "
                 f"{sec['dose_s']['median']:.3f} s (medians, in process); shade card {sec['card_s']:.1f} s; "
                 f"all {s['total_s']:.0f} s")
    return lines


def _plot(rows: list[dict], one_rows: list[dict], path: Path) -> None:
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
    held = sorted({r["held_out"] for r in rows})
    a.boxplot([[r["prediction_de2000"] for r in rows if r["held_out"] == h] for h in held])
    a.boxplot([[r["prediction_de2000"] for r in one_rows if r["predicted"] == h] for h in held],
              positions=np.arange(1, len(held) + 1) + 0.3, widths=0.2)
    a.set_xticks(np.arange(1, len(held) + 1), held)
    a.axhline(GOAL_MEDIAN, ls="--", c="g", lw=0.8, label="goal: median 1.0")
    a.axhline(GOAL_P95, ls=":", c="r", lw=0.8, label="goal: p95 2.0")
    a.set_ylabel("mean-colour ΔE2000, prediction vs truth")
    a.set_xlabel("held-out base (left: two-pair fit; right: one-pair fits)")
    a.legend(fontsize=7)
    tl = [r["true_lift"] for r in rows]
    b.plot([0, 0.65], [0, 0.65], "k-", lw=0.5)
    b.scatter(tl, [r["lift"] for r in rows], s=12, label="two bases")
    b.scatter([r["true_lift"] for r in one_rows[::2]], [r["one_pair_lift"] for r in one_rows[::2]], s=12, marker="x",
              label="one base (lift assumed)")
    b.set_xlabel("true lift")
    b.set_ylabel("fitted lift")
    b.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)
