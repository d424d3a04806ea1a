"""``hairdigi evaluate``: the paper's protocol on held-out swatches, beside the render-noise floor.

1. Render ``n`` held-out swatches (a dataset with a seed disjoint from training: resumable, cached).
2. Estimate each with the encoder, and re-render the estimate with the same scene (camera, strand
   layout) and a *new* sampler seed.
3. Re-render the *true* parameters with that same new seed: the noise floor. No estimator can beat
   it, and the estimate and the floor differ only in the hair parameters.
4. Compare each re-render with the original: L1 (0–255), MS-SSIM, ΔE2000 per pixel and of the mean
   colour; and the error of each parameter. Report per hard-case bucket.
"""
from __future__ import annotations

import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from inference.dataset import DatasetConfig, generate, load, sample_spec
from render.metrics import delta_e2000, l1_255, mean_colour_delta_e, ms_ssim
from render.params import VECTOR_FIELDS, HairParams, write_json_atomic
from render.srgb import srgb8_to_linear

EVAL_SEED = 1_000_003  # training datasets use small seeds; this one is disjoint by construction
SPANS = np.array([hi - lo for _, lo, hi in VECTOR_FIELDS])


def image_metrics(original: np.ndarray, other: np.ndarray) -> dict[str, float]:
    """Metrics between two 8-bit sRGB renders of one scene."""
    lin_a, lin_b = srgb8_to_linear(original), srgb8_to_linear(other)
    row = {"l1": l1_255(original, other),
           # the same on 4x4 block means: most of the render noise averages out, the colour error stays
           "l1_blocks4": l1_255(_blocks(original, 4), _blocks(other, 4)),
           "mean_colour_de2000": mean_colour_delta_e(lin_a, lin_b),
           "pixel_de2000": float(np.mean(delta_e2000(lin_a.reshape(-1, 3), lin_b.reshape(-1, 3))))}
    if min(original.shape[:2]) >= 161:
        row["ms_ssim"] = ms_ssim(original, other)
    return row


def _blocks(img: np.ndarray, k: int) -> np.ndarray:
    h, w = (img.shape[0] // k) * k, (img.shape[1] // k) * k
    return img[:h, :w].astype(float).reshape(h // k, k, w // k, k, -1).mean((1, 3))


def buckets(params: HairParams, polar_deg: float) -> list[str]:
    """The hard cases a sample belongs to."""
    rgb = np.asarray(params.dye_rgb)
    out = ["all"]
    if params.melanin_concentration >= 0.9:
        out.append("black")
    if params.melanin_concentration <= 0.1 and params.dye_concentration <= 0.1:
        out.append("platinum")
    if params.dye_concentration >= 0.7 and rgb.max() - rgb.min() >= 150 and params.melanin_concentration <= 0.5:
        out.append("saturated_dye")
    if polar_deg >= 35.0:
        out.append("grazing_camera")
    return out


def _rerender(config: DatasetConfig, index: int, params: HairParams, spp: int | None = None,
              seed_offset: int = 1):
    """Sample ``index``'s scene (camera, strand layout) with other hair; a new sampler seed by default."""
    from render.renderer import SceneSpec, default_renderer

    s = sample_spec(config, index)
    spec = SceneSpec("swatch", camera=s.camera, framing=config.framing, strands=config.strands,
                     strand_seed=s.strand_seed, max_depth=config.max_depth)
    return default_renderer().render(params, spec, config.size, spp or config.spp, s.render_seed + seed_offset).srgb


def heldout_config(n: int, size: int, spp: int) -> DatasetConfig:
    from render.renderer import defaults_for

    sw = defaults_for("swatch")
    return DatasetConfig(n=n, size=size, spp=spp, seed=EVAL_SEED, strands=sw.strands, max_depth=sw.max_depth,
                         shard_size=50)


def prepare_heldout(root: str | os.PathLike, n: int = 300, size: int = 176, spp: int = 4, workers: int = 2,
                    floors: int | None = None, progress: bool = True) -> Path:
    """Render the held-out swatches and the noise-floor re-renders of the first ``floors`` of them.

    Neither depends on the encoder, so this can run before training ends. Resumable: the images
    are dataset shards, the floors are saved to ``floor.npz`` every 10.
    """
    from tqdm import tqdm

    root = Path(root)
    config = heldout_config(n, size, spp)
    generate(config, root, workers=workers, progress=progress)
    cache = root / "floor.npz"
    have = dict(np.load(cache)) if cache.exists() else {}
    _, vectors, _, _ = load(root)
    todo = [i for i in range(min(len(vectors), floors if floors is not None else n)) if f"floor_{i}" not in have]
    for k, i in enumerate(tqdm(todo, desc="noise floor", unit="swatch", disable=not progress)):
        have[f"floor_{i}"] = _rerender(config, i, HairParams.from_vector(vectors[i]))
        if k % 10 == 9:
            _save_npz(cache, have)
    _save_npz(cache, have)
    return root


def _save_npz(path: Path, arrays: dict) -> None:
    tmp = path.with_name(f".{path.stem}.tmp.npz")
    np.savez(tmp, **arrays)
    os.replace(tmp, path)


def evaluate(encoder, out_dir: str | os.PathLike, n: int = 300, size: int = 176, spp: int = 4,
             data_root: str | os.PathLike | None = None, workers: int = 2, rerender: int | None = None,
             progress: bool = True) -> dict:
    """Run the protocol; write ``evaluation.json``, ``samples.json`` and return the summary.

    ``rerender`` limits the image metrics to the first samples (all when None); the parameter
    errors always use all ``n``.
    """
    from tqdm import tqdm

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    config = heldout_config(n, size, spp)
    root = Path(data_root) if data_root else out / "heldout"
    n_img = n if rerender is None else min(rerender, n)
    prepare_heldout(root, n, size, spp, workers, floors=n_img, progress=progress)
    images, vectors, cameras, _ = load(root)
    floors = dict(np.load(root / "floor.npz"))

    from inference.preprocess import ImageError

    t0 = time.perf_counter()
    estimates, invalid = [], {}
    for i, img in enumerate(images):
        try:
            estimates.append(encoder.estimate(img, roi=_whole(img), views=True))
        except ImageError as exc:   # e.g. a camera that looks into the back of a light: a black frame
            estimates.append(None)
            invalid[i] = str(exc)
    latency = _latency(encoder, images[next(i for i, e in enumerate(estimates) if e is not None)])
    rows = []
    for i in tqdm(range(len(images)), desc="evaluate", unit="swatch", disable=not progress):
        truth = HairParams.from_vector(vectors[i])
        est = estimates[i]
        if est is None:
            continue
        row = {"index": i, "polar_deg": float(cameras[i][0]), "buckets": buckets(truth, float(cameras[i][0])),
               "at_range_edge": est.at_range_edge}
        for (name, _, _), t, e, span in zip(VECTOR_FIELDS, vectors[i], est.vector, SPANS):
            row[f"abs_err_{name}"] = float(abs(t - e) * span)
        if i < n_img:
            rerendered = _rerender(config, i, est.params)
            row.update({f"est_{k}": v for k, v in image_metrics(images[i], rerendered).items()})
            row.update({f"floor_{k}": v for k, v in image_metrics(images[i], floors[f"floor_{i}"]).items()})
        rows.append(row)
    summary = summarise(rows)
    summary.update({"n": len(rows), "n_rerendered": sum(1 for r in rows if "est_l1" in r),
                    "invalid": {str(k): v for k, v in invalid.items()}, "size": size, "spp": spp, "seed": EVAL_SEED,
                    "model": str(encoder.path), "model_sha256": encoder.sha256,
                    "latency_ms_median_1_thread": latency, "seconds": time.perf_counter() - t0,
                    "dataset": asdict(config), "date": time.strftime("%Y-%m-%d"),
                    "lpips": "not computed: it needs pretrained AlexNet/VGG weights, which no package here ships",
                    "paper_table_2": {"l1": "7.08 ± 11.79", "ms_ssim": "0.20 ± 0.04 (as printed)",
                                      "lpips": "0.12 ± 0.19"}})
    write_json_atomic(out / "evaluation.json", summary)
    write_json_atomic(out / "samples.json", rows)
    return summary


def _whole(img):
    from inference.preprocess import Roi
    return Roi(0, 0, img.shape[1], img.shape[0])


def _latency(encoder, image: np.ndarray, repeats: int = 200) -> float:
    """Median milliseconds of one encoder call (one view, batch 1) on preprocessed input."""
    from inference.encoder import median_latency_ms
    from inference.preprocess import encode

    return median_latency_ms(encoder, encode(image, encoder.input_size)[None], repeats)


def summarise(rows: list[dict]) -> dict:
    """Mean ± std of every metric per bucket, and the ratio of each image metric to its floor."""
    metrics = sorted({k for r in rows for k in r if k.startswith(("abs_err_", "est_", "floor_"))})
    out: dict = {"buckets": {}}
    for bucket in sorted({b for r in rows for b in r["buckets"]}):
        rs = [r for r in rows if bucket in r["buckets"]]
        entry: dict = {"count": len(rs)}
        for m in metrics:
            vals = np.array([r[m] for r in rs if m in r], dtype=float)
            if len(vals):
                entry[m] = {"mean": float(vals.mean()), "std": float(vals.std()), "median": float(np.median(vals))}
        for m in metrics:
            if m.startswith("est_") and m.replace("est_", "floor_") in entry:
                est, floor = entry[m]["mean"], entry[m.replace("est_", "floor_")]["mean"]
                name = m[4:]
                # MS-SSIM is a similarity: compare its distance 1 - MS-SSIM to the floor's
                ratio = (1 - est) / max(1 - floor, 1e-9) if name == "ms_ssim" else est / max(floor, 1e-9)
                entry[f"ratio_to_floor_{name}"] = float(ratio)
        out["buckets"][bucket] = entry
    return out
