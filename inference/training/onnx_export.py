"""``hairdigi export-onnx``: write the trained encoder as ONNX and check it against PyTorch."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from hairdigi.render.domain.files import atomic_path


def export_onnx(model, path: str | os.PathLike, input_size: int) -> Path:
    """Export with a dynamic batch axis; outputs ``params`` (sigmoid) and ``logits``. Written atomically."""
    import torch   # deferred: torch and onnx are the optional [train] extra

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    model = model.eval().to(memory_format=torch.contiguous_format)
    dummy = torch.zeros(1, 3, input_size, input_size)
    with atomic_path(path, ".onnx") as tmp:
        # the TorchScript exporter needs no onnxscript; one file, weights inside
        torch.onnx.export(model, (dummy,), str(tmp), dynamo=False, input_names=["image"],
                          output_names=["params", "logits"], opset_version=17,
                          dynamic_axes={"image": {0: "batch"}, "params": {0: "batch"}, "logits": {0: "batch"}})
    return path


def parity(model, onnx_path: str | os.PathLike, input_size: int, n: int = 8, seed: int = 0) -> float:
    """Largest absolute difference between PyTorch and onnxruntime outputs on random inputs."""
    # deferred: onnxruntime takes ~0.3 s; it loads with the first model; torch and onnx are the optional [train] extra
    import onnxruntime as ort
    import torch

    x = np.random.default_rng(seed).uniform(-0.5, 0.5, (n, 3, input_size, input_size)).astype(np.float32)
    with torch.no_grad():
        ref = model.eval()(torch.from_numpy(x))[0].numpy()
    sess = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    got = sess.run(["params"], {"image": x})[0]
    return float(np.abs(ref - got).max())
