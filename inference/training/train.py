"""``hairdigi train``: fit the encoder to synthetic datasets with an L2 loss in parameter space, plus
an L2 loss on the fibre colour those parameters render (``inference/training/losses.py``).

PyTorch on the CPU (the ``train`` extra). Start Python with ``OMP_WAIT_POLICY=PASSIVE``: on two
cores, OpenMP's default spinning makes training 5-12x slower whenever another process takes a core.
A checkpoint is written after every epoch; a run restarted with the same output folder resumes.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.inference.training.dataset import DatasetError, load, usable
from hairdigi.inference.preprocess import encode
from hairdigi.render.camera_model import CameraModel, CaptureErrors, random_camera, sensor_response
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear
from hairdigi.render.domain.files import atomic_path, write_json_atomic
from hairdigi.render.io.figures import save_figure


@dataclass(frozen=True)
class TrainConfig:
    epochs: int = 100
    batch_size: int = 32
    lr: float = 2e-3
    weight_decay: float = 1e-4
    val_fraction: float = 0.1
    seed: int = 0
    threads: int = 2
    crop_min: float = 0.45   # smallest random crop, as a share of the image side
    appearance_weight: float = 4.0   # weight of the fibre-colour term (inference/training/losses.py); 0: plain L2
    blur_max: float = 1.5    # largest Gaussian blur (px): stands in for sources of higher resolution


def augment(img: np.ndarray, size: int, rng: np.random.Generator, crop_min: float,
            blur_max: float = 0.0, errors: CaptureErrors = CaptureErrors()) -> np.ndarray:
    """A random square crop (scale and position), flips, a quarter turn and a blur, then the capture
    chain, encoded for the net as ``estimate`` encodes a photograph.

    ``img`` is a linear float render (``linear16`` datasets) or, for older datasets, 8-bit sRGB.
    A linear render goes through ``render.camera_model`` with the residual errors of a calibrated
    capture (``errors``: exposure, colour cast, shot and read noise, 12-bit ADC, 8-bit sRGB), so the
    encoder learns what a camera delivers and not a renderer's noise texture. The blur (sigma uniform
    in [0, ``blur_max``] px) stands in for sharper or larger sources, whose resize averages more
    render noise. The hair's colour itself is only perturbed within the calibration's residual.
    """
    h = img.shape[0]
    side = int(round(h * rng.uniform(crop_min, 1.0)))
    y, x = rng.integers(0, h - side + 1, size=2)
    crop = img[y:y + side, x:x + side]
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    if rng.random() < 0.5:
        crop = crop[::-1]
    if rng.random() < 0.5:
        crop = np.rot90(crop)
    rendered_linear = crop.dtype != np.uint8
    linear = np.ascontiguousarray(crop.astype(np.float32) if rendered_linear else srgb8_to_linear(crop),
                                  dtype=np.float32)
    sigma = rng.uniform(0.0, blur_max) if blur_max else 0.0
    if sigma > 0.05:
        linear = cv2.GaussianBlur(linear, (0, 0), sigma)   # in linear light: the mean colour stays
    frame = sensor_response(linear, random_camera(rng, errors), rng) if rendered_linear else linear_to_srgb8(linear)
    return encode(frame, size)


def capture_all(images: np.ndarray, seed: int = 0) -> np.ndarray:
    """8-bit sRGB frames of linear renders through the default camera (fixed noise seed); 8-bit
    images pass unchanged. For validation and evaluation inputs."""
    if images.dtype == np.uint8:
        return images
    rng = np.random.default_rng(seed)
    return np.stack([sensor_response(im.astype(np.float32), CameraModel(), rng) for im in images])


def encode_all(images: np.ndarray, size: int) -> np.ndarray:
    return np.stack([encode(im, size) for im in capture_all(images)])


def split(n: int, fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    order = np.random.default_rng(seed).permutation(n)
    n_val = max(1, int(round(n * fraction)))
    return np.sort(order[n_val:]), np.sort(order[:n_val])


def load_datasets(dataset_dirs) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
    """One or more datasets of one image size, joined: images, parameters, cameras, their manifests' configs."""
    dirs = [dataset_dirs] if isinstance(dataset_dirs, (str, os.PathLike)) else list(dataset_dirs)
    parts = [load(d) for d in dirs]
    sizes = {p[0].shape[1:] for p in parts}
    if len(sizes) > 1:
        raise DatasetError(f"datasets {', '.join(map(str, dirs))} have different image sizes {sorted(sizes)}; "
                           "train on datasets rendered at one --size")
    framings = {p[3]["config"].get("framing", "crop") for p in parts}
    if len(framings) > 1:
        raise DatasetError(f"datasets {', '.join(map(str, dirs))} mix framings {sorted(framings)}; "
                           "train on datasets of one framing")
    configs = [{"path": str(d), **p[3]["config"], "n_loaded": int(len(p[0]))} for d, p in zip(dirs, parts)]
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts]), configs)


def train(dataset_dir, out_dir: str | os.PathLike, encoder_config=None,
          config: TrainConfig = TrainConfig(), progress: bool = True, epochs_now: int | None = None) -> dict:
    """Train (or resume) and return the history; ``out_dir`` gets ``checkpoint.pt``, ``history.json``, a curve.

    ``dataset_dir`` is one dataset folder or a list of them (one image size; e.g. noisy and clean
    renders together). ``epochs_now`` stops after that many epochs in this call; calling again resumes.
    """
    # deferred: torch and onnx are the optional [train] extra
    import torch

    from hairdigi.inference.training.network import EncoderConfig, HairEncoder, parameter_count

    encoder_config = encoder_config or EncoderConfig()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(config.threads)
    cv2.setNumThreads(1)   # the augmentation's tiny images: OpenCV's own pool only competes with torch
    torch.manual_seed(config.seed)
    images, params, cameras, datasets = load_datasets(dataset_dir)
    train_idx, val_idx = split(len(images), config.val_fraction, config.seed)
    clear = usable(cameras, datasets[0].get("framing", "crop"))
    train_idx, val_idx = train_idx[clear[train_idx]], val_idx[clear[val_idx]]
    val_x = torch.from_numpy(encode_all(images[val_idx], encoder_config.input_size)).contiguous(
        memory_format=torch.channels_last)
    val_y = torch.from_numpy(params[val_idx])

    model = HairEncoder(encoder_config).to(memory_format=torch.channels_last)
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    steps_per_epoch = math.ceil(len(train_idx) / config.batch_size)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=config.lr, total_steps=config.epochs * steps_per_epoch,
                                                pct_start=0.15)
    history: dict = {"epochs": [], "encoder": encoder_config.to_dict(), "train": asdict(config),
                     "datasets": datasets, "n_skipped_behind_light": int((~clear).sum()),
                     "parameters": parameter_count(model)}
    ckpt = out / "checkpoint.pt"
    start_epoch = 0
    if ckpt.exists():
        history, start_epoch = _resume(ckpt, model, opt, sched, encoder_config, config)
    last_epoch = config.epochs if epochs_now is None else min(config.epochs, start_epoch + epochs_now)
    for epoch in range(start_epoch, last_epoch):
        t0 = time.perf_counter()
        train_loss = _train_epoch(model, opt, sched, images, params, train_idx, encoder_config, config, epoch,
                                  progress)
        val_mse, val_appearance, val_mae = _validate(model, val_x, val_y)
        row = {"epoch": epoch + 1, "train_loss": train_loss, "val_mse": val_mse,
               "val_appearance_mse": val_appearance,
               "val_mae": val_mae, "seconds": time.perf_counter() - t0, "lr": sched.get_last_lr()[0]}
        history["epochs"].append(row)
        if progress:
            print(f"epoch {epoch + 1}/{config.epochs}: train loss {row['train_loss']:.5f}  val MSE {val_mse:.5f}  "
                  f"val appearance MSE {val_appearance:.5f}  "
                  f"({row['seconds']:.1f} s)", flush=True)
        with atomic_path(ckpt) as tmp:
            torch.save({"model": model.state_dict(), "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
                        "epoch": epoch, "history": history, "encoder": encoder_config.to_dict(),
                        "train": asdict(config)}, tmp)
    write_json_atomic(out / "history.json", history)
    plot_history(history, out / "training_curve.png")
    return history


def _resume(ckpt: Path, model, opt, sched, encoder_config, config: TrainConfig) -> tuple[dict, int]:
    """Load a checkpoint made with the same settings into the model, optimiser and schedule: (history, next epoch)."""
    state = _load_checkpoint(ckpt)
    if state["encoder"] != encoder_config.to_dict() or state["train"] != asdict(config):
        raise DatasetError(f"{ckpt} was made with other settings; use another output folder or the same settings")
    model.load_state_dict(state["model"])
    opt.load_state_dict(state["optimizer"])
    sched.load_state_dict(state["scheduler"])
    return state["history"], state["epoch"] + 1


def _train_epoch(model, opt, sched, images: np.ndarray, params: np.ndarray, train_idx: np.ndarray, encoder_config,
                 config: TrainConfig, epoch: int, progress: bool) -> float:
    """One epoch over the training rows, augmented, in the epoch's seeded order: the mean training loss."""
    # deferred: torch and onnx are the optional [train] extra
    import torch
    from hairdigi.inference.training.losses import encoder_loss

    steps_per_epoch = math.ceil(len(train_idx) / config.batch_size)
    rng = np.random.default_rng([config.seed, epoch])
    order = rng.permutation(train_idx)
    model.train()
    total = 0.0
    bar = tqdm(range(steps_per_epoch), desc=f"epoch {epoch + 1}/{config.epochs}", disable=not progress,
               leave=False, dynamic_ncols=True)
    for step in bar:
        idx = order[step * config.batch_size:(step + 1) * config.batch_size]
        x = torch.from_numpy(np.stack([augment(images[i], encoder_config.input_size, rng, config.crop_min,
                                               config.blur_max) for i in idx]))
        x = x.contiguous(memory_format=torch.channels_last)
        y = torch.from_numpy(params[idx])
        pred, _ = model(x)
        loss = encoder_loss(pred, y, config.appearance_weight)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        total += loss.item() * len(idx)
        bar.set_postfix(loss=f"{loss.item():.4f}")
    return total / len(train_idx)


def _validate(model, val_x, val_y) -> tuple[float, float, list[float]]:
    """The validation rows' parameter MSE, fibre-colour MSE and per-parameter mean absolute error."""
    # deferred: torch and onnx are the optional [train] extra
    import torch

    from hairdigi.inference.training.losses import appearance

    model.eval()
    with torch.no_grad():
        val_pred = torch.cat([model(val_x[i:i + 256])[0] for i in range(0, len(val_x), 256)])
    val_mse = float(((val_pred - val_y) ** 2).mean())
    val_appearance = float(((appearance(val_pred) - appearance(val_y)) ** 2).mean())
    return val_mse, val_appearance, (val_pred - val_y).abs().mean(0).tolist()


def _load_checkpoint(path: Path) -> dict:
    """A training checkpoint; a damaged one raises DatasetError naming the file (one line)."""
    import torch   # deferred: torch and onnx are the optional [train] extra

    try:
        state = torch.load(path, weights_only=False)
    except FileNotFoundError:
        raise
    except Exception as exc:   # torch raises pickle, zip and runtime errors for a damaged file
        why = " ".join(str(exc).split())[:100] or type(exc).__name__
        raise DatasetError(f"{path}: damaged training checkpoint ({why}); delete it to train afresh, or "
                           f"restore it from a copy") from None
    if not isinstance(state, dict) or not {"encoder", "model"} <= set(state):
        raise DatasetError(f"{path}: not a hairdigi training checkpoint; delete it to train afresh")
    return state


def load_trained(out_dir: str | os.PathLike):
    """The model from a training folder's checkpoint, in eval mode."""
    # deferred: torch and onnx are the optional [train] extra
    from hairdigi.inference.training.network import EncoderConfig, HairEncoder

    state = _load_checkpoint(Path(out_dir) / "checkpoint.pt")
    model = HairEncoder(EncoderConfig(**state["encoder"]))
    model.load_state_dict(state["model"])
    return model.eval(), state["history"]


def plot_history(history: dict, path: Path) -> Path:
    rows = history["epochs"]
    fig, ax = plt.subplots(figsize=(6, 4))
    epochs = [r["epoch"] for r in rows]
    ax.semilogy(epochs, [r.get("train_loss", r.get("train_mse")) for r in rows], label="training loss (augmented)")
    ax.semilogy(epochs, [r["val_mse"] for r in rows], label="validation MSE, parameters")
    if "val_appearance_mse" in rows[-1]:
        ax.semilogy(epochs, [r["val_appearance_mse"] for r in rows], label="validation MSE, fibre colour")
    ax.set_xlabel("epoch")
    ax.set_ylabel("mean squared error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    return save_figure(fig, path)
