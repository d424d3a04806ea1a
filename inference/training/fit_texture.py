"""Fit the texture model: read the fibre spread and the grey share from the swatch area.

``python -m hairdigi.inference.training.fit_texture render --n 300`` renders the dataset: swatch
areas as the simulated rig captures them (the bench camera's 400x300 frame at full resolution, only
a quarter of its swatch area ``rig_geometry.swatch_roi`` rendered, the quarter drawn per sample: four
times the samples for the render time; each light alone at 32 spp, glints spread, summed at
``NOMINAL_EXPOSURE``, through the camera model's noise and 8-bit quantisation, then back to linear).
Each sample draws sigma_a over Table 1 (``HairParams`` uniform, as ``inference.training.dataset``
draws it, mapped by ``hair_sigma_a``; one in ten black hair, one in ten platinum), shine uniform
0.12-0.5, spread uniform 0-0.5, grey share uniform 0-0.3 and its own strand layout. The three
single-light renders are cached, one file per sample, under ``cache_dir() / "texture"`` (a restart
skips what is done); the camera model is applied when the features are computed, from the sample's
own seed.

``... fit`` fits ``inference.texture``'s model on about 80% of the samples and calibrates its
intervals on out-of-sample errors (the held-out 20% and the training renders' out-of-fold errors);
it writes ``resources/models/texture_model.json`` and the evidence,
``texture_evaluation.json`` and ``.png`` (predicted against true, held-out errors overall and by
lightness, and a learning curve). ``main([])`` does both.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

from hairdigi.inference import texture
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain import rig_geometry
from hairdigi.inference.training.dataset import _die_with_parent
from hairdigi.render.domain.appearance import APPEARANCE_DRAW, Appearance
from hairdigi.render.domain.files import atomic_path, cache_dir
from hairdigi.render.domain.params import HairParams
from hairdigi.render.swatch_family import FAMILY
from hairdigi.resources import MODELS

#: Bumped when what a cached sample holds or how it is rendered changes.
DATA_VERSION = 5   # 2: a quarter of the swatch area per sample; 4: the layered swatch, 8000 fibres; 5: each
#                    sample on a family structure of its own (render.swatch_family.FAMILY)
SEED = 1818
SIZE = (400, 300)
SPP = 32
SHINE_DRAW = APPEARANCE_DRAW["longitudinal_roughness"]
SPREAD_DRAW = APPEARANCE_DRAW["fibre_spread"]
GREY_DRAW = APPEARANCE_DRAW["grey_fraction"]
#: Shares of the draws that are black hair and platinum hair (the rest: Table 1 uniform).
BLACK_SHARE, PLATINUM_SHARE = 0.1, 0.1


def data_dir() -> Path:
    """Where the rendered samples are cached."""
    return cache_dir() / "texture" / f"v{DATA_VERSION}"


def draw_sample(index: int, seed: int = SEED) -> dict:
    """The hidden truth of sample ``index``: sigma_a, shine, spread, grey share, strand and camera seeds."""
    rng = np.random.default_rng([seed, index])
    kind = rng.uniform()
    if kind < BLACK_SHARE:
        params = HairParams((0.0, 0.0, 0.0), float(rng.uniform(0, 0.3)), float(rng.uniform(0.85, 1.0)),
                            float(rng.uniform(0.8, 1.0)))
        family = "black"
    elif kind < BLACK_SHARE + PLATINUM_SHARE:
        params = HairParams(tuple(float(v) for v in rng.uniform(220, 255, 3)), float(rng.uniform(0, 0.15)),
                            float(rng.uniform(0.0, 0.05)), float(rng.uniform(0.0, 0.5)))
        family = "platinum"
    else:
        params = HairParams.from_vector(rng.uniform(0.0, 1.0, size=6))
        family = "table1"
    return {"index": index, "family": family, "params": params.to_dict(),
            "sigma_a": [float(v) for v in hair_sigma_a(params)],
            "shine": float(rng.uniform(*SHINE_DRAW)), "fibre_spread": float(rng.uniform(*SPREAD_DRAW)),
            "grey_fraction": float(rng.uniform(*GREY_DRAW)),
            "strand_seed": int(rng.integers(1000, 2**31 - 1)), "render_seed": int(rng.integers(0, 2**20)),
            "camera_seed": int(rng.integers(0, 2**31 - 1)), "quadrant": int(rng.integers(0, 4)),
            "structure": str(rng.choice(FAMILY))}


def quadrant_roi(quadrant: int, roi: tuple[int, int, int, int] | None = None) -> tuple[int, int, int, int]:
    """One quarter (0-3: top left, top right, bottom left, bottom right) of the bench frame's swatch area.

    A sample renders a quarter of the area, not all of it: four times the samples for the same
    render time. Its statistics are the whole area's with more sampling noise, so the intervals
    calibrated on quarters are, if anything, wide for a whole area."""
    x, y, w, h = roi or rig_geometry.swatch_roi(SIZE)
    hw, hh = w // 2, h // 2
    return (x + (quadrant % 2) * hw, y + (quadrant // 2) * hh, hw, hh)


def render_swatch_lights(sigma_a, shine: float, spread: float, grey: float, strand_seed: int,
                         render_seed: int = 17, renderer=None, roi: tuple[int, int, int, int] | None = None,
                         spp: int = SPP, structure: str | None = None) -> np.ndarray:
    """(3, h, w, 3) linear renders of the bench frame's swatch area (``roi``, default the whole
    ``swatch_roi``) lit by each light alone, glints spread, as ``hardware.sim_rig`` renders them."""
    # deferred: loads colour-science and Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.camera_model import spread_glints
    from hairdigi.render.chart import colorchecker_reflectances
    from hairdigi.render.renderer import Renderer, SceneSpec

    renderer = renderer or Renderer(max_cached=1)
    roi = roi or rig_geometry.swatch_roi(SIZE)
    chart = tuple(map(tuple, colorchecker_reflectances()))
    look = Appearance(float(shine), float(spread), float(grey))
    images = []
    for i in range(rig_geometry.N_LIGHTS):
        lights = tuple(1.0 if j == i else 0.0 for j in range(rig_geometry.N_LIGHTS))
        spec = SceneSpec("swatch", framing="rig", chart=chart, target=rig_geometry.RIG_TARGET,
                         camera=rig_geometry.CameraPose(), half_width=rig_geometry.RIG_HALF_WIDTH,
                         lights=lights, strand_seed=int(strand_seed), crop=tuple(roi), appearance=look,
                         swatch_model=structure)
        linear = renderer.render(np.asarray(sigma_a, float), spec, SIZE, spp, seed=int(render_seed) + i).linear
        images.append(spread_glints(linear))
    return np.stack(images).astype(np.float32)


def capture(lights: np.ndarray, camera_seed: int, exposure_ev: float = 0.0) -> np.ndarray:
    """The all-lights swatch area as a capture gives it: the lights summed at the nominal exposure
    (``exposure_ev`` off it), the camera model (small calibrated errors, noise, 12-bit ADC, 8-bit
    sRGB), decoded to linear and corrected back to radiance at the nominal exposure (linear float32,
    (h, w, 3))."""
    # deferred: loads colour-science (~1 s) and OpenCV; only this step needs them
    from hairdigi.render.camera_model import NOMINAL_EXPOSURE
    from hairdigi.inference.preprocess import to_linear
    from hairdigi.render.camera_model import random_camera, sensor_response

    rng = np.random.default_rng(int(camera_seed))
    camera = random_camera(rng)
    exposure = np.float32(NOMINAL_EXPOSURE * 2.0 ** exposure_ev)
    frame = sensor_response(np.asarray(lights, np.float32).sum(axis=0) * exposure, camera, rng)
    return to_linear(frame) / exposure


def sample_path(index: int) -> Path:
    return data_dir() / f"sample-{index:05d}.npz"


_RENDERER: list = []


def render_sample(index: int, seed: int = SEED, variant: str | None = None) -> str:
    """Render sample ``index`` into the cache (atomically) and return a line saying what it was."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import Renderer
    from hairdigi.render.variant import select_variant

    if variant:
        select_variant(variant)

    if not _RENDERER:   # one renderer per process, reused by its next samples
        _RENDERER.append(Renderer(max_cached=1))
    truth = draw_sample(index, seed)
    start = time.perf_counter()
    lights = render_swatch_lights(truth["sigma_a"], truth["shine"], truth["fibre_spread"],
                                  truth["grey_fraction"], truth["strand_seed"], truth["render_seed"], _RENDERER[0],
                                  roi=quadrant_roi(truth["quadrant"]), structure=truth.get("structure"))
    seconds = time.perf_counter() - start
    truth["render_seconds"] = seconds
    with atomic_path(sample_path(index), ".npz") as tmp:
        np.savez_compressed(tmp, lights=lights.astype(np.float16), truth=json.dumps(truth))
    return (f"sample {index}: {truth['family']} on {truth.get('structure', 'layered')} spread {truth['fibre_spread']:.2f} grey {truth['grey_fraction']:.2f} "
            f"shine {truth['shine']:.2f} in {seconds:.1f} s")


def render_dataset(n: int, seed: int = SEED, log=print, workers: int = 1, variant: str | None = None) -> int:
    """Render samples 0..n-1 that are not cached yet, in ``workers`` processes; returns how many were
    rendered now."""
    data_dir().mkdir(parents=True, exist_ok=True)
    todo = [index for index in range(n) if not sample_path(index).exists()]
    if workers <= 1:
        for line in map(partial(render_sample, seed=seed, variant=variant), todo):
            log(line, flush=True)
        return len(todo)
    with mp.get_context("spawn").Pool(workers, initializer=_die_with_parent) as pool:
        for line in pool.imap_unordered(partial(render_sample, seed=seed, variant=variant), todo):
            log(line, flush=True)
    return len(todo)


def load_samples(n: int | None = None) -> list[tuple[dict, np.ndarray]]:
    """The cached samples (truth, lights), in index order."""
    out = []
    for path in sorted(data_dir().glob("sample-*.npz")):
        try:
            with np.load(path) as data:
                out.append((json.loads(str(data["truth"])), data["lights"].astype(np.float32)))
        except (OSError, ValueError, KeyError):
            continue   # a damaged file is rendered again by the next ``render``
        if n is not None and len(out) >= n:
            break
    return out


def main(argv: list[str] | None = None) -> int:
    """``render [--n N]``, ``fit``, or neither (both)."""
    parser = argparse.ArgumentParser(prog="fit_texture", description=__doc__.splitlines()[0])
    parser.add_argument("command", nargs="?", choices=("render", "fit", "all"), default="all")
    parser.add_argument("--n", type=int, default=150, help="samples to render (cached ones are kept)")
    parser.add_argument("--seed", type=int, default=SEED)
    parser.add_argument("--workers", type=int, default=1, help="render processes")
    parser.add_argument("--variant", default=None,
                        help="Mitsuba variant (scalar_rgb renders these small scenes faster than llvm_ad_rgb)")
    args = parser.parse_args(argv)
    if args.command in ("render", "all"):
        render_dataset(args.n, args.seed, workers=args.workers, variant=args.variant)
    if args.command in ("fit", "all"):
        fit(load_samples())
    return 0


#: The estimate's errors the reading is fitted and calibrated under: sigma_a refined to about 10%,
#: shine read to about 0.03 (``hairdigi bench shine``), drawn per sample from its camera seed.
SIGMA_JITTER, SHINE_JITTER = 0.10, 0.03
HOLDOUT_SHARE = 0.2
#: Pseudo-count pulling a lightness bin's error scale towards the overall one.
SHRINK = 5.0
ALPHAS = tuple(10.0 ** np.arange(-3, 3.01, 0.5))


def estimate_inputs(truth: dict) -> tuple[np.ndarray, float]:
    """The sigma_a and shine an estimate would give for this sample: the truth with the estimate's
    errors (``SIGMA_JITTER``, ``SHINE_JITTER``) drawn from the sample's camera seed."""
    rng = np.random.default_rng([int(truth["camera_seed"]), 7])
    sigma = np.asarray(truth["sigma_a"]) * np.exp(rng.normal(0.0, SIGMA_JITTER, 3))
    shine = float(np.clip(truth["shine"] + rng.normal(0.0, SHINE_JITTER), 0.05, 1.0))
    return sigma, shine


def sample_inputs(truth: dict, lights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(features, covariates as the estimate would give them, true [spread, grey]) of one sample."""
    sigma, shine = estimate_inputs(truth)
    features = texture.texture_features(capture(lights, truth["camera_seed"]))
    return features, texture.covariates(sigma, shine), np.array([truth["fibre_spread"], truth["grey_fraction"]])


def ridge_fit(x: np.ndarray, y: np.ndarray, alphas=ALPHAS) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Ridge on standardised ``x`` for one target, alpha chosen by leave-one-out error (closed form);
    returns (mean, scale, coef, intercept, alpha)."""
    mean, scale = x.mean(axis=0), x.std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    z = (x - mean) / scale
    y0 = y.mean()
    u, s, vt = np.linalg.svd(z, full_matrices=False)
    uty = u.T @ (y - y0)
    best = (np.inf, None, None)
    for alpha in alphas:
        d = s / (s ** 2 + alpha)
        coef = vt.T @ (d * uty)
        hat = np.sum(u ** 2 * (s ** 2 / (s ** 2 + alpha)), axis=1) + 1.0 / len(y)
        loo = (y - y0 - z @ coef) / np.maximum(1.0 - hat, 1e-6)
        err = float(np.mean(loo ** 2))
        if err < best[0]:
            best = (err, coef, alpha)
    return mean, scale, best[1], float(y0), float(best[2])


def fit_model(features: np.ndarray, cov: np.ndarray, targets: np.ndarray, kinds: dict[str, str] | None = None):
    """A ``TextureModel`` (without intervals) fitted on the given samples; ``kinds`` (the design per
    target) default to the one with the lower 5-fold cross-validated error on these samples."""
    kinds = dict(kinds) if kinds else {}
    for k, target in enumerate(texture.TARGETS):
        if target not in kinds:
            errs = {kind: float(np.mean(np.abs(_oof(features, cov, targets, {t: kind for t in texture.TARGETS})[:, k]
                                               - targets[:, k]))) for kind in texture.DESIGNS}
            kinds[target] = min(errs, key=errs.get)
    mean, scale, coef, intercept, alphas = {}, {}, {}, {}, {}
    for k, target in enumerate(texture.TARGETS):
        x = texture.design(features, cov, kinds[target])
        mean[target], scale[target], coef[target], intercept[target], alphas[target] = ridge_fit(x, targets[:, k])
    return texture.TextureModel(kinds, mean, scale, coef, intercept, {}, meta={"alpha": alphas})


def _oof(features, cov, targets, kinds: dict[str, str] | None = None, folds: int = 5, seed: int = 0) -> np.ndarray:
    """Out-of-fold predictions (n, 2) by ``folds``-fold cross-fitting (designs chosen per fold unless given)."""
    order = np.random.default_rng(seed).permutation(len(targets))
    pred = np.zeros_like(targets)
    for f in range(folds):
        test = order[f::folds]
        train = np.setdiff1d(order, test)
        model = fit_model(features[train], cov[train], targets[train], kinds)
        p = model.predict(features[test], cov[test])
        pred[test] = np.column_stack([p[t] for t in texture.TARGETS])
    return pred


def conformal_k(ratios: np.ndarray, level: float) -> float:
    """The split-conformal quantile of |residual| / scale: the ceil((n + 1) level)-th smallest."""
    ratios = np.sort(np.asarray(ratios, float))
    rank = int(np.ceil((len(ratios) + 1) * level))
    return float(ratios[min(rank, len(ratios)) - 1])


def fit(samples: list, out_dir: Path | None = None, plot: bool = True) -> dict:
    """Fit on ~80% of ``samples``, calibrate the intervals on out-of-sample errors (the held-out ~20%
    and the training renders' out-of-fold errors), write the model and
    the evidence to ``out_dir`` (default: the package's ``resources/models``); returns the evaluation."""
    out_dir = Path(out_dir) if out_dir is not None else MODELS
    start = time.perf_counter()
    rows = [sample_inputs(truth, lights) for truth, lights in samples]
    features = np.array([r[0] for r in rows])
    cov = np.array([r[1] for r in rows])
    targets = np.array([r[2] for r in rows])
    truths = [t for t, _ in samples]
    light = np.array([texture.lightness(estimate_inputs(t)[0]) for t in truths])
    feature_seconds = (time.perf_counter() - start) / len(rows)
    n = len(rows)
    order = np.random.default_rng(SEED).permutation(n)
    n_hold = max(5, int(round(HOLDOUT_SHARE * n)))
    hold, train = np.sort(order[:n_hold]), np.sort(order[n_hold:])

    model = fit_model(features[train], cov[train], targets[train])
    # the residual's scale by lightness: |out-of-fold residual| on the training samples, per bin
    oof = _oof(features[train], cov[train], targets[train], model.kinds)
    interval = {}
    pred_hold = model.predict(features[hold], cov[hold])
    for k, target in enumerate(texture.TARGETS):
        resid = np.abs(oof[:, k] - targets[train, k])
        scales = {}
        for name, (lo, hi) in texture.LIGHTNESS_BINS.items():
            m = (light[train] >= lo) & (light[train] < hi)
            # shrunk towards the overall mean |error| when the bin holds few renders
            scales[name] = float((resid[m].sum() + SHRINK * resid.mean()) / (m.sum() + SHRINK))
        spec = {"scale": scales, "n_bins": {name: int(np.sum((light[train] >= lo) & (light[train] < hi)))
                                            for name, (lo, hi) in texture.LIGHTNESS_BINS.items()}}
        interval[target] = spec
        tmp = texture.TextureModel(model.kinds, model.mean, model.scale, model.coef, model.intercept, interval)
        lo, hi = texture.TARGET_LIMITS[target]
        p = np.clip(pred_hold[target], lo, hi)
        ratios = np.abs(p - targets[hold, k]) / tmp.residual_scale(target, light[hold])
        # the held-out renders alone (~20%) give a p95 from one or two errors: the training renders'
        # out-of-fold errors (each read by a model that did not see it) join them
        oof_ratios = np.abs(np.clip(oof[:, k], lo, hi) - targets[train, k]) / tmp.residual_scale(target, light[train])
        both = np.concatenate([ratios, oof_ratios])
        spec["k"] = {"p68": conformal_k(both, 0.68), "p95": conformal_k(both, 0.95)}
        spec["k_from"] = {"held_out": int(len(ratios)), "out_of_fold": int(len(oof_ratios))}
    model = texture.TextureModel(model.kinds, model.mean, model.scale, model.coef, model.intercept, interval,
                                 meta={**model.meta, "samples": n, "train": int(len(train)), "held_out": int(n_hold),
                                       "data_version": DATA_VERSION, "spp": SPP, "sigma_jitter": SIGMA_JITTER,
                                       "shine_jitter": SHINE_JITTER,
                                       "fitted_by": "python -m hairdigi.inference.training.fit_texture fit"})
    evaluation = evaluate(model, features, cov, targets, light, truths, train, hold)
    evaluation["feature_seconds_per_sample"] = feature_seconds
    evaluation["render_seconds_per_sample_median"] = float(np.median([t.get("render_seconds", np.nan) for t in truths]))
    evaluation["learning_curve"] = learning_curve(features, cov, targets, train, hold, model.kinds)
    # the intervals' coverage on the training renders' out-of-fold errors (part of their calibration)
    evaluation["oof_train"] = {}
    for k, t in enumerate(texture.TARGETS):
        lo, hi = texture.TARGET_LIMITS[t]
        r = np.abs(np.clip(oof[:, k], lo, hi) - targets[train, k]) / model.residual_scale(t, light[train])
        evaluation["oof_train"][t] = {"mae": float(np.mean(np.abs(np.clip(oof[:, k], lo, hi) - targets[train, k]))),
                                      "coverage_p68": float(np.mean(r <= interval[t]["k"]["p68"])),
                                      "coverage_p95": float(np.mean(r <= interval[t]["k"]["p95"]))}
    out_dir.mkdir(parents=True, exist_ok=True)
    with atomic_path(out_dir / texture.MODEL_FILE) as tmp:
        tmp.write_text(json.dumps(model.to_dict(), indent=1) + "\n")
    with atomic_path(out_dir / "texture_evaluation.json") as tmp:
        tmp.write_text(json.dumps(evaluation, indent=1) + "\n")
    if plot:
        plot_evaluation(evaluation, out_dir / "texture_evaluation.png")
    return evaluation


def _errors(err: np.ndarray, inside68: np.ndarray, inside95: np.ndarray) -> dict:
    return {"n": int(len(err)), "mae": float(np.mean(np.abs(err))) if len(err) else None,
            "p95_abs": float(np.quantile(np.abs(err), 0.95)) if len(err) else None,
            "coverage_p68": float(np.mean(inside68)) if len(err) else None,
            "coverage_p95": float(np.mean(inside95)) if len(err) else None}


def evaluate(model, features, cov, targets, light, truths, train, hold) -> dict:
    """Held-out errors, overall and by lightness, and the points for the plot."""
    out = {"targets": list(texture.TARGETS), "n_train": int(len(train)), "n_held_out": int(len(hold)),
           "lightness_bins": {k: [float(v) for v in b] for k, b in texture.LIGHTNESS_BINS.items()},
           "note": ("held-out: renders the model was not fitted on; the intervals' k was calibrated on their "
                    "errors together with the training renders' out-of-fold errors (oof_train)"),
           "held_out": {}, "points": []}
    readings = [texture.reading_from(model, features[i], *estimate_inputs(truths[i])) for i in hold]
    for k, target in enumerate(texture.TARGETS):
        pred = np.array([getattr(r, target) for r in readings])
        err = pred - targets[hold, k]
        in68 = np.array([r.intervals[target]["p68"][0] <= t <= r.intervals[target]["p68"][1]
                         for r, t in zip(readings, targets[hold, k])])
        in95 = np.array([r.intervals[target]["p95"][0] <= t <= r.intervals[target]["p95"][1]
                         for r, t in zip(readings, targets[hold, k])])
        block = {"overall": _errors(err, in68, in95)}
        # what the texture adds: the error of reading every swatch as the training mean
        block["overall"]["mae_of_the_training_mean"] = float(np.mean(np.abs(targets[train, k].mean() - targets[hold, k])))
        for name, (lo, hi) in texture.LIGHTNESS_BINS.items():
            m = (light[hold] >= lo) & (light[hold] < hi)
            block[name] = _errors(err[m], in68[m], in95[m])
            block[name]["p95_half_width_mean"] = float(np.mean([np.diff(r.intervals[target]["p95"])[0] / 2
                                                                for r, mm in zip(readings, m) if mm])) if m.any() else None
        out["held_out"][target] = block
    for r, i in zip(readings, hold):
        out["points"].append({"index": truths[i]["index"], "family": truths[i]["family"], "lightness": float(light[i]),
                              "true": [float(v) for v in targets[i]],
                              "pred": [r.fibre_spread, r.grey_fraction],
                              "p95": [r.intervals["fibre_spread"]["p95"], r.intervals["grey_fraction"]["p95"]]})
    return out


def learning_curve(features, cov, targets, train, hold, kinds: dict[str, str], sizes=(0.25, 0.5, 1.0)) -> list[dict]:
    """Held-out MAE of models fitted on growing shares of the training samples."""
    out = []
    for share in sizes:
        m = max(10, int(round(share * len(train))))
        sub = train[:m]
        model = fit_model(features[sub], cov[sub], targets[sub], kinds)
        p = model.predict(features[hold], cov[hold])
        row = {"n_train": int(m)}
        for k, target in enumerate(texture.TARGETS):
            lo, hi = texture.TARGET_LIMITS[target]
            row[f"{target}_mae"] = float(np.mean(np.abs(np.clip(p[target], lo, hi) - targets[hold, k])))
        out.append(row)
    return out


def plot_evaluation(evaluation: dict, path: Path) -> None:
    """Predicted against true (held-out, p95 bars, coloured by lightness) and the learning curve."""
    import matplotlib   # deferred: matplotlib only for the plot
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt   # deferred: matplotlib only for the plot

    pts = evaluation["points"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    names = {"fibre_spread": "fibre spread (std ln sigma_a)", "grey_fraction": "grey share"}
    for k, target in enumerate(evaluation["targets"]):
        ax = axes[k]
        true = np.array([p["true"][k] for p in pts])
        pred = np.array([p["pred"][k] for p in pts])
        lo = np.array([p["p95"][k][0] for p in pts])
        hi = np.array([p["p95"][k][1] for p in pts])
        light = np.array([p["lightness"] for p in pts])
        ax.errorbar(true, pred, yerr=[pred - lo, hi - pred], fmt="none", ecolor="0.75", lw=1, zorder=1)
        sc = ax.scatter(true, pred, c=light, cmap="copper", s=22, zorder=2, edgecolors="k", linewidths=0.3)
        top = max(true.max(), hi.max()) * 1.05
        ax.plot([0, top], [0, top], "k--", lw=0.8)
        block = evaluation["held_out"][target]["overall"]
        ax.set_title(f"{names[target]}\nheld-out MAE {block['mae']:.3f}, |err| p95 {block['p95_abs']:.3f}", fontsize=9)
        ax.set_xlabel("true")
        ax.set_ylabel("read (bars: p95 interval)")
    fig.colorbar(sc, ax=axes[1], label="lightness  -mean ln(sigma_a + 0.01)")
    ax = axes[2]
    lc = evaluation["learning_curve"]
    for target, colour in zip(evaluation["targets"], ("C0", "C1")):
        ax.plot([r["n_train"] for r in lc], [r[f"{target}_mae"] for r in lc], "o-", color=colour, label=names[target])
        ax.axhline(evaluation["held_out"][target]["overall"]["mae_of_the_training_mean"], color=colour, ls=":", lw=1,
                   label=f"{target}: reading the training mean")
    ax.set_xlabel("training renders")
    ax.set_ylabel("held-out MAE")
    ax.set_title("learning curve", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path, ".png") as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
