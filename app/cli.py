"""The ``hairdigi`` command line: one subcommand per job, each a thin call into the science packages."""
from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # torch's OpenMP spinning starves a 2-core CPU


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _cache_dir() -> Path:
    return Path(os.environ.get("HAIRDIGI_CACHE", Path.home() / ".cache" / "hairdigi"))


# --- render -----------------------------------------------------------------------------------
def cmd_render(args: argparse.Namespace) -> int:
    from render.imageio import save_exr, save_png
    from render.params import load_params
    from render.renderer import SceneSpec, render
    from render.scenes import CAMERA_DISTANCE, PORTRAIT_CAMERA, CameraPose

    params = load_params(args.params)
    distance = CAMERA_DISTANCE if args.scene == "swatch" else PORTRAIT_CAMERA.distance
    camera = CameraPose.parse(args.camera, distance) if args.camera else None
    spec = SceneSpec(name=args.scene, camera=camera, env=args.env, framing=args.framing,
                     strands=args.strands, max_depth=args.depth, strand_seed=args.seed)
    result = render(params, spec, args.size, args.spp, args.seed)
    save_png(args.out, result.srgb)
    print(f"wrote {args.out} ({result.srgb.shape[1]}x{result.srgb.shape[0]}, {result.spp} spp, "
          f"{result.seconds:.2f} s)")
    if args.exr:
        save_exr(args.exr, result.linear)
        print(f"wrote {args.exr} (linear RGB)")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from app.demo import run_demo

    run_demo(Path(args.out), quick=args.quick)
    return 0


# --- dataset, training, export, estimate, evaluate -----------------------------------------
def cmd_dataset(args: argparse.Namespace) -> int:
    from inference.dataset import DatasetConfig, generate
    from render.renderer import defaults_for

    # record the resolved strand count and depth, so the manifest stays true if the defaults change
    config = DatasetConfig(n=args.n, size=args.size, spp=args.spp, seed=args.seed,
                           strands=args.strands or defaults_for("swatch").strands,
                           max_depth=args.depth or defaults_for("swatch").max_depth, shard_size=args.shard_size)
    out = Path(args.out) if args.out else _cache_dir() / "datasets" / f"swatch-s{args.seed}-{args.size}px-{args.spp}spp"
    generate(config, out, workers=args.workers)
    print(f"dataset complete: {config.n} swatches in {out}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from inference.model import EncoderConfig
    from inference.train import TrainConfig, train

    config = TrainConfig(epochs=args.epochs, batch_size=args.batch_size, lr=args.lr, threads=args.threads,
                         seed=args.seed)
    if args.appearance_weight is not None:
        config = replace(config, appearance_weight=args.appearance_weight)
    if args.blur_max is not None:
        config = replace(config, blur_max=args.blur_max)
    history = train(args.dataset, args.out, EncoderConfig(args.width, args.blocks, args.input_size), config,
                    epochs_now=args.epochs_now)
    last = history["epochs"][-1]
    print(f"trained {history['parameters']} parameters for {last['epoch']} epochs: validation MSE "
          f"{last['val_mse']:.5f}; checkpoint and curve in {args.out}")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from inference.export import export_onnx, parity
    from inference.train import load_trained

    model, history = load_trained(args.run)
    size = history["encoder"]["input_size"]
    path = export_onnx(model, args.out, size)
    diff = parity(model, path, size)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB); max |torch - onnxruntime| = {diff:.2e}")
    return 0


def cmd_estimate(args: argparse.Namespace) -> int:
    from inference.encoder import Encoder
    from inference.estimate import estimate_file
    from inference.preprocess import Roi
    from render.params import write_json_atomic

    encoder = Encoder(args.model)
    roi = Roi.parse(args.roi) if args.roi else None
    estimate, record, _ = estimate_file(args.image, encoder, roi, args.calibration)
    write_json_atomic(args.out, record)
    p = estimate.params
    print(f"dye rgb {tuple(round(v) for v in p.dye_rgb)} at {p.dye_concentration:.2f}, melanin "
          f"{p.melanin_concentration:.2f} (ratio {p.melanin_ratio:.2f}); wrote {args.out}")
    if estimate.at_range_edge:
        print(f"warning: the estimate reached the edge of the range for {', '.join(estimate.at_range_edge)}: "
              f"the swatch may be outside what the model was trained on", file=sys.stderr)
    if args.render:
        from render.imageio import save_png
        from render.renderer import SceneSpec, render

        result = render(p, SceneSpec("swatch", framing="rig"), 256, 32, seed=0)
        save_png(args.render, result.srgb)
        print(f"wrote {args.render}")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from inference.encoder import Encoder
    from inference.evaluate import evaluate, prepare_heldout

    if args.prepare_only:
        root = prepare_heldout(args.data or Path(args.out) / "heldout", args.n, args.size, args.spp, args.workers,
                               floors=args.rerender)
        print(f"held-out swatches and noise-floor renders ready in {root}")
        return 0

    encoder = Encoder(args.model)
    if args.noise_sweep:
        from inference.noise_sweep import noise_sweep

        spps = [int(v) for v in args.noise_sweep.split(",")]
        data = args.data or prepare_heldout(Path(args.out) / "heldout", args.n, args.size, args.spp, args.workers)
        for r in noise_sweep(encoder, data, args.out, spps, args.sweep_n):
            print(f"{r['spp']:5d} spp ({r['render_s']:.2f} s/render): L1 {r['est_l1']:.2f} (floor "
                  f"{r['floor_l1']:.2f}), mean-colour ΔE2000 {r['est_mean_colour_de2000']:.2f} "
                  f"(floor {r['floor_mean_colour_de2000']:.2f})")
        print(f"noise_sweep.csv and noise_sweep.png in {args.out}")
        return 0
    summary = evaluate(encoder, args.out, n=args.n, size=args.size, spp=args.spp, workers=args.workers,
                       data_root=args.data, rerender=args.rerender)
    a = summary["buckets"]["all"]
    print(f"{summary['n']} held-out swatches: L1 {a['est_l1']['mean']:.2f} (floor {a['floor_l1']['mean']:.2f}), "
          f"mean-colour ΔE2000 median {a['est_mean_colour_de2000']['median']:.2f} "
          f"(floor {a['floor_mean_colour_de2000']['median']:.2f}); encoder "
          f"{summary['latency_ms_median_1_thread']:.3f} ms; report in {args.out}")
    return 0


def cmd_rig(args: argparse.Namespace) -> int:
    if args.list_ports:
        from hardware.lights import discover
        import serial.tools.list_ports

        ports = list(serial.tools.list_ports.comports())
        print(f"{len(ports)} serial port(s): " + ", ".join(p.device for p in ports))
        boards = discover()
        print("light boards: " + (", ".join(f"{p} ({ident})" for p, ident in boards) or "none answered ID?"))
        return 0
    from app.rig_cli import open_session, run_chain

    session = open_session(args)
    try:
        run_chain(session)
    finally:
        session.close()
    return 0


def cmd_app(args: argparse.Namespace) -> int:
    from app.gui.main import run_app

    return run_app(sim=args.sim, session=args.session, tour=args.tour)


def cmd_model_card(args: argparse.Namespace) -> int:
    import csv
    import json

    from inference.report import model_card

    evaluation = json.loads(Path(args.evaluation).read_text())
    variants = None
    if args.variants:
        with open(args.variants) as f:
            variants = [{k: (float(v) if k not in ("model",) else v) for k, v in row.items()}
                        for row in csv.DictReader(f)]
    sweep = None
    if args.noise_sweep:
        with open(args.noise_sweep) as f:
            sweep = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]
    path = model_card(args.model, args.run, evaluation, args.out, variants, sweep)
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if args.what == "encoder":
        from inference.report import bench_encoders

        if not args.models:
            raise CliError("bench encoder needs --models A.onnx B.onnx ...")
        rows = bench_encoders(args.models, out, n=args.n, rerender=args.rerender, data_root=args.data)
        for r in rows:
            print(f"{r['model']}: {r['latency_ms']:.3f} ms, L1 {r['l1']:.2f} (floor {r['l1_floor']:.2f}), "
                  f"ΔE2000 median {r['mean_colour_de2000_median']:.2f}")
        print(f"wrote {out / 'encoder_bench.csv'} and {out / 'encoder_bench.png'}")
        return 0
    if args.what == "rig":
        from app.rig_cli import detection_sweep

        rows = detection_sweep(out)
        found = [r for r in rows if r["detected"]]
        import numpy as np
        print(f"chart detected in {len(found)}/{len(rows)} simulated frames; ΔE2000 mean before "
              f"{np.mean([r['de_before'] for r in found]):.2f}, after {np.mean([r['de_after'] for r in found]):.2f}; "
              f"wrote {out / 'rig_bench.csv'}")
    if args.what == "render":
        from render.bench import run_render_bench

        rows = run_render_bench(out, quick=args.quick)
        print(f"wrote {out / 'render_bench.csv'} and {out / 'render_bench.png'} ({len(rows)} cases)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from render.renderer import SCENE_NAMES
    from render.scenes import ENVIRONMENTS

    parser = argparse.ArgumentParser(prog="hairdigi", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("render", help="render hair parameters in the swatch rig or a hairstyle")
    p.add_argument("--params", required=True, help="hair parameter JSON (top level or under 'hair')")
    p.add_argument("--scene", default="swatch", choices=SCENE_NAMES)
    p.add_argument("--size", type=int, default=None, help="image side in pixels (default: the scene's)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel (default: the scene's)")
    p.add_argument("--seed", type=int, default=0, help="sampler and strand-layout seed")
    p.add_argument("--camera", help="POLAR,AZIMUTH[,DIST] in degrees around the holder normal / the face")
    p.add_argument("--env", default="studio", choices=ENVIRONMENTS, help="lighting for hairstyles")
    p.add_argument("--framing", default="rig", choices=("rig", "crop"),
                   help="swatch: the whole holder (rig) or hair only (crop, as in training)")
    p.add_argument("--strands", type=int, default=None, help="strand count (default: the scene's)")
    p.add_argument("--depth", type=int, default=None, help="maximum path depth (default: the scene's)")
    p.add_argument("--out", required=True, help="output PNG (sRGB 8-bit)")
    p.add_argument("--exr", help="also write linear RGB as OpenEXR")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("demo", help="headless demo: render the sample swatch and hairstyles")
    p.add_argument("--out", default="out/demo")
    p.add_argument("--quick", action="store_true", help="tiny sizes, for tests")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("dataset", help="render the synthetic swatch dataset (resumable)")
    p.add_argument("--n", type=int, default=5000)
    p.add_argument("--size", type=int, default=96)
    p.add_argument("--spp", type=int, default=4, help="4: the mean colour is converged (bench render)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--strands", type=int, default=None)
    p.add_argument("--depth", type=int, default=None)
    p.add_argument("--shard-size", type=int, default=100)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--out", help="dataset folder (default: in the cache, $HAIRDIGI_CACHE or ~/.cache/hairdigi)")
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser("train", help="train the encoder on a dataset (resumable; needs the train extra)")
    p.add_argument("--dataset", required=True, nargs="+", help="one or more dataset folders (one image size)")
    p.add_argument("--out", required=True, help="run folder: checkpoint, history, curve")
    p.add_argument("--epochs", type=int, default=100)
    p.add_argument("--batch-size", type=int, default=32)
    p.add_argument("--lr", type=float, default=2e-3)
    p.add_argument("--width", type=int, default=16)
    p.add_argument("--blocks", type=int, default=4)
    p.add_argument("--input-size", type=int, default=48)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--appearance-weight", type=float, default=None,
                   help="weight of the fibre-colour loss term (default 4; 0: L2 on the parameters alone)")
    p.add_argument("--blur-max", type=float, default=None,
                   help="largest augmentation blur in px (default 1.5; 0: none)")
    p.add_argument("--epochs-now", type=int, default=None, help="stop after this many epochs; run again to resume")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("export-onnx", help="export a trained run to ONNX and check parity")
    p.add_argument("--run", required=True, help="the training run folder")
    p.add_argument("--out", default="resources/models/encoder.onnx")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("estimate", help="estimate hair parameters from an image")
    p.add_argument("image")
    p.add_argument("--roi", help="swatch area x,y,w,h in pixels (default: found automatically)")
    p.add_argument("--calibration", help="colour calibration profile JSON from the rig")
    p.add_argument("--model", default=None, help="ONNX encoder (default: the shipped one)")
    p.add_argument("--out", required=True, help="parameter JSON to write")
    p.add_argument("--render", help="also render the estimate in the swatch rig to this PNG")
    p.set_defaults(func=cmd_estimate)

    p = sub.add_parser("evaluate", help="the paper's evaluation on held-out swatches, with the noise floor")
    p.add_argument("--n", type=int, default=300)
    p.add_argument("--size", type=int, default=176, help=">= 161 for MS-SSIM's 5 scales")
    p.add_argument("--spp", type=int, default=4)
    p.add_argument("--rerender", type=int, default=None, help="re-render only the first N (default: all)")
    p.add_argument("--prepare-only", action="store_true",
                   help="render the held-out set and the noise floor only (no model needed); resumable")
    p.add_argument("--noise-sweep", metavar="SPP,SPP,...",
                   help="instead: re-render the first --sweep-n swatches at these spp (metrics against spp)")
    p.add_argument("--sweep-n", type=int, default=10)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--data", help="held-out dataset folder (default: OUT/heldout)")
    p.add_argument("--model", default=None)
    p.add_argument("--out", required=True)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("rig", help="the capture chain without a window (use --sim without hardware)")
    p.add_argument("--sim", action="store_true", help="the simulated rig: a pty light board and rendered frames")
    p.add_argument("--camera", default="0", help="OpenCV camera index or URL (real rig)")
    p.add_argument("--port", help="serial port of the light board (real rig); see --list-ports")
    p.add_argument("--roi", help="swatch area x,y,w,h in the camera frame (real rig; default: found)")
    p.add_argument("--list-ports", action="store_true", help="list serial ports and light boards, then exit")
    p.add_argument("--session", default="out/session", help="session folder: captures, calibration, results")
    p.add_argument("--cast", type=float, nargs=3, default=(1.25, 1.0, 0.8), metavar=("R", "G", "B"),
                   help="simulated white-balance error")
    p.add_argument("--exposure", type=float, default=0.0, help="simulated exposure error in EV")
    p.add_argument("--dead", type=int, nargs="*", help="simulated dead light(s)")
    p.add_argument("--spp", type=int, default=32, help="samples per pixel of the simulated rig's light renders")
    p.set_defaults(func=cmd_rig)

    p = sub.add_parser("app", help="the desktop app")
    p.add_argument("--sim", action="store_true", help="use the simulated rig")
    p.add_argument("--session", default=None, help="session folder (default: from the settings)")
    p.add_argument("--tour", help="calibrate and capture once, time it, save a screenshot in this folder, quit")
    p.set_defaults(func=cmd_app)

    p = sub.add_parser("model-card", help="write the model card from a run and its evaluation")
    p.add_argument("--run", required=True)
    p.add_argument("--model", default="resources/models/encoder.onnx")
    p.add_argument("--evaluation", required=True, help="evaluation.json from hairdigi evaluate")
    p.add_argument("--variants", help="encoder_bench.csv from hairdigi bench encoder")
    p.add_argument("--noise-sweep", help="noise_sweep.csv from hairdigi evaluate --noise-sweep")
    p.add_argument("--out", default="resources/models/encoder.md")
    p.set_defaults(func=cmd_model_card)

    p = sub.add_parser("bench", help="speed against error tables and plots")
    p.add_argument("what", choices=("render", "rig", "encoder"))
    p.add_argument("--models", nargs="*", help="encoder: the ONNX models to compare")
    p.add_argument("--n", type=int, default=300, help="encoder: held-out swatches")
    p.add_argument("--rerender", type=int, default=60, help="encoder: swatches re-rendered for image metrics")
    p.add_argument("--data", help="encoder: held-out dataset folder to reuse")
    p.add_argument("--out", default="out/bench")
    p.add_argument("--quick", action="store_true", help="a tiny sweep, for tests")
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from hardware.cameras import CameraError
    from hardware.lights import LightError
    from inference.calibration import CalibrationError
    from inference.encoder import ModelError
    from inference.preprocess import ImageError
    from render.hairfile import HairFileError
    from render.params import HairParamsError

    if getattr(args, "model", "unset") is None:
        from inference.encoder import DEFAULT_MODEL
        args.model = DEFAULT_MODEL
    try:
        return args.func(args)
    except (CliError, HairParamsError, HairFileError, ImageError, ModelError, CalibrationError, CameraError,
            LightError, ValueError, FileNotFoundError) as exc:
        print(f"hairdigi {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"hairdigi {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
