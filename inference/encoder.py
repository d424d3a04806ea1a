"""The ONNX encoder at inference: an image in, ``HairParams`` out, with the training preprocessing."""
from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hairdigi.inference.preprocess import Roi, encode, swatch_crop
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.params import VECTOR_FIELDS, HairParams
from hairdigi.render.domain.threads import plan
from hairdigi.resources import MODELS

DEFAULT_MODEL = MODELS / "encoder.onnx"
#: A logit past this means the sigmoid output is outside [0.001, 0.999]: the encoder presses against
#: the edge of its range, and the swatch may lie outside what it was trained on.
EDGE_LOGIT = 6.9


class ModelError(HairdigiError, RuntimeError):
    """The model file is missing or unusable; the message says how to get one."""


@dataclass
class Estimate:
    params: HairParams
    vector: np.ndarray                 # the (clamped) normalised 6-vector
    at_range_edge: list[str]           # parameters whose raw output reached the range's edge
    view_spread: dict[str, float] = field(default_factory=dict)  # std over the 8 flips/turns, normalised 0–1
    roi: Roi | None = None
    seconds: float = 0.0


def sha256_file(path: str | os.PathLike) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def median_latency_ms(encoder: "Encoder", batch: np.ndarray, repeats: int = 200) -> float:
    """Median milliseconds of ``encoder.predict(batch)`` after one warm-up call."""
    encoder.predict(batch)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        encoder.predict(batch)
        times.append(time.perf_counter() - t)
    return float(np.median(times) * 1000.0)


def _views(x: np.ndarray) -> np.ndarray:
    """The 8 flips and quarter turns of a (3, S, S) input: the swatch looks the same in each."""
    out = []
    for k in range(4):
        r = np.rot90(x, k, axes=(1, 2))
        out += [r, r[:, :, ::-1]]
    return np.ascontiguousarray(np.stack(out))


class Encoder:
    """An onnxruntime session for the encoder; its intra-op threads from the process's thread budget
    (``render.domain.threads``: one; latency is under a millisecond)."""

    def __init__(self, path: str | os.PathLike = DEFAULT_MODEL, threads: int | None = None) -> None:
        import onnxruntime as ort   # deferred: onnxruntime takes ~0.3 s; it loads with the first model

        threads = plan()["onnxruntime"] if threads is None else threads

        self.path = Path(path)
        if not self.path.exists():
            raise ModelError(f"{self.path}: no encoder model; train one with 'hairdigi train' and "
                             f"'hairdigi export-onnx', or reinstall hairdigi")
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = threads
        opts.inter_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(self.path), opts, providers=["CPUExecutionProvider"])
        except Exception as exc:  # onnxruntime raises its own types for corrupt files
            raise ModelError(f"{self.path}: not a usable ONNX model ({exc})") from None
        shape = self.session.get_inputs()[0].shape
        self.input_size = int(shape[-1])
        self.sha256 = sha256_file(self.path)

    def predict(self, batch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3, S, S) encoded inputs to (params in [0, 1], logits), each (N, 6)."""
        params, logits = self.session.run(["params", "logits"], {"image": batch.astype(np.float32)})
        return params, logits

    def estimate(self, image: np.ndarray, roi: Roi | None = None, views: bool = True) -> Estimate:
        """Estimate the hair parameters of an 8-bit RGB image: a rig frame or a crop that is all hair.

        With ``views`` the 8 flips and turns are averaged. Their spread is a check of the input (a
        swatch looks alike in each), not an uncertainty: ``inference.uncertainty`` has measured intervals.
        """
        start = time.perf_counter()
        crop, roi = swatch_crop(image, roi)
        x = encode(crop, self.input_size)
        batch = _views(x) if views else x[None]
        params, logits = self.predict(batch)
        vector = np.clip(params.mean(0), 0.0, 1.0)
        edge = [VECTOR_FIELDS[i][0] for i in np.flatnonzero(np.abs(logits.mean(0)) > EDGE_LOGIT)]
        spread = {name: round(float(s), 5) for (name, _, _), s in zip(VECTOR_FIELDS, params.std(0))} if views else {}
        return Estimate(HairParams.from_vector(vector), vector, edge, spread, roi,
                        time.perf_counter() - start)
