"""``hairdigi export-onnx``: a trained run as the ONNX encoder, its parity with torch checked."""
from __future__ import annotations

import argparse


def add_parser(sub) -> None:
    p = sub.add_parser("export-onnx", help="export a trained run to ONNX and check parity")
    p.add_argument("--run", required=True, help="the training run folder")
    p.add_argument("--out", default="resources/models/encoder.onnx")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: loads OpenCV and colour-science; training is left out of the desktop build (hairdigi.inference.training)
    from hairdigi.inference.training.onnx_export import export_onnx, parity
    from hairdigi.inference.training.train import load_trained

    model, history = load_trained(args.run)
    size = history["encoder"]["input_size"]
    path = export_onnx(model, args.out, size)
    diff = parity(model, path, size)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB); max |torch - onnxruntime| = {diff:.2e}")
    return 0
