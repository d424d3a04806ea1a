"""The ``hairdigi`` command line: one subcommand per job, each a thin call into the science packages."""
from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.threads import start_up
from hairdigi.render.domain.version import version

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # torch's OpenMP spinning starves a 2-core CPU


def interrupted_at_start(signum, frame) -> None:
    """Ctrl-C before ``main`` takes over (the program is still importing): one line, exit 130."""
    try:
        prog = _prog(sys.argv[1:])
    except NameError:   # still loading this module
        prog = "hairdigi"
    sys.stderr.write(f"{prog}: interrupted\n")
    os._exit(130)


if Path((sys.argv or [""])[0]).name == "hairdigi":   # a program, not a library import (-m: __main__.py)
    import signal

    signal.signal(signal.SIGINT, interrupted_at_start)


class CliError(HairdigiError):
    """A user-facing error: printed as one line, exit status 2."""


def _cache_dir() -> Path:
    from hairdigi.render.domain.files import cache_dir

    return cache_dir()


def _use_variant(name: str | None) -> str:
    """Switch Mitsuba to ``--variant`` (``auto``: the GPU when there is one), loading it: the parser
    loads no Mitsuba, so this runs in the command, before any scene is loaded."""
    from hairdigi.render.variant import select_variant

    return select_variant(name)


# --- render -----------------------------------------------------------------------------------
def cmd_render(args: argparse.Namespace) -> int:
    from hairdigi.render.io.images import save_exr, save_png
    from hairdigi.render.domain.params import load_params
    from hairdigi.render.renderer import SceneSpec, render
    from hairdigi.render.scenes import PORTRAIT_CAMERA
    from hairdigi.render.domain.rig_geometry import CAMERA_DISTANCE, CameraPose

    _use_variant(args.variant)
    params = load_params(args.params)
    distance = CAMERA_DISTANCE if args.scene == "swatch" else PORTRAIT_CAMERA.distance
    camera = CameraPose.parse(args.camera, distance) if args.camera else None
    spec = SceneSpec(name=args.scene, camera=camera, env=args.env, framing=args.framing,
                     strands=args.strands, max_depth=args.depth, strand_seed=args.seed, illuminant=args.illuminant)
    result = render(params, spec, args.size, args.spp, args.seed)
    if args.illuminant is not None and args.balance == "light":
        from hairdigi.render.spectra import balanced
        from hairdigi.render.srgb import linear_to_srgb8

        result.linear = balanced(result.linear, args.illuminant)
        result.srgb = linear_to_srgb8(result.linear)
    if spec.hair_file is not None:
        from hairdigi.render.hairfile import model_summary

        print(model_summary(spec.hair_file, spec.n_strands))
    from hairdigi.render.domain.files import atomic_paths

    with atomic_paths(args.out, args.exr) as (png, exr):   # both written, then both published: a failed
        save_png(png, result.srgb)                         # EXR leaves the old PNG in place
        if exr is not None:
            save_exr(exr, result.linear)
    print(f"wrote {args.out} ({result.srgb.shape[1]}x{result.srgb.shape[0]}, {result.spp} spp, "
          f"{result.seconds:.2f} s, {result.nonfinite} non-finite values)")
    if result.nonfinite:
        print(f"warning: the path tracer returned {result.nonfinite} NaN or Inf values, written as 0 (black); "
              f"the image may have dark specks", file=sys.stderr)
    if args.exr:
        print(f"wrote {args.exr} (linear RGB)")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from hairdigi.app.cli.demo import run_demo

    run_demo(Path(args.out), quick=args.quick)
    return 0


# --- dataset, training, export, estimate, evaluate -----------------------------------------
def cmd_dataset(args: argparse.Namespace) -> int:
    from hairdigi.inference.training.dataset import DatasetConfig, generate
    from hairdigi.render.renderer import defaults_for

    # record the resolved strand count and depth, so the manifest stays true if the defaults change
    config = DatasetConfig(n=args.n, size=args.size, spp=args.spp, seed=args.seed,
                           strands=args.strands or defaults_for("swatch").strands,
                           max_depth=args.depth or defaults_for("swatch").max_depth, shard_size=args.shard_size,
                           store=args.store, swatch_model=args.swatch_model, appearance=args.appearance)
    if args.address and args.backend != "ray":
        raise CliError("--address names a Ray cluster: use it with --backend ray")
    # datasets of the first swatch and fixed appearance keep their folder names
    tags = "" if (args.swatch_model, args.appearance) == ("today", "fixed") else f"-{args.swatch_model}-{args.appearance}"
    out = Path(args.out) if args.out else (_cache_dir() / "datasets" /
                                           f"swatch-s{args.seed}-{args.size}px-{args.spp}spp-{args.store}{tags}")
    generate(config, out, workers=args.workers, backend=args.backend, address=args.address, variant=args.variant)
    print(f"dataset complete: {config.n} swatches in {out}")
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from hairdigi.inference.training.model import EncoderConfig
    from hairdigi.inference.training.train import TrainConfig, train

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
    from hairdigi.inference.training.export import export_onnx, parity
    from hairdigi.inference.training.train import load_trained

    model, history = load_trained(args.run)
    size = history["encoder"]["input_size"]
    path = export_onnx(model, args.out, size)
    diff = parity(model, path, size)
    print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB); max |torch - onnxruntime| = {diff:.2e}")
    return 0


def cmd_estimate(args: argparse.Namespace) -> int:
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.estimate import estimate_file
    from hairdigi.inference.preprocess import Roi
    from hairdigi.render.domain.records import write_record
    from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, CameraPose

    encoder = Encoder(args.model)
    roi = Roi.parse(args.roi) if args.roi else None
    camera = CameraPose.parse(args.camera, RIG_SWATCH_POSE.distance) if args.camera else None
    # a pose given means an all-hair view from there; else a frame with the chart in view is the rig's, and
    # an image of the swatch on its holder without the chart is warned of (its camera is unknown)
    lights = args.lights.split(",") if args.lights else None
    exposures = [2.0 ** args.lights_ev] * len(lights) if lights and args.lights_ev is not None else None
    estimate, record, _ = estimate_file(args.image, encoder, roi, args.calibration, camera,
                                        refine_colour=not args.no_refine, rig_view=False if args.camera else None,
                                        light_paths=lights, light_exposures=exposures,
                                        structure=args.structure)
    write_record(args.out, record)
    p = estimate.params
    refined = estimate.refinement
    how = (f"refined in {refined.seconds:.2f} s, residual ΔE2000 {refined.residual_de2000:.2f}" if refined
           else "encoder alone")
    print(f"dye rgb {tuple(round(v) for v in p.dye_rgb)} at {p.dye_concentration:.2f}, melanin "
          f"{p.melanin_concentration:.2f} (ratio {p.melanin_ratio:.2f}); {how}; wrote {args.out}")
    if record.appearance is not None:
        from hairdigi.app.cli.rig import appearance_lines

        print("appearance: " + "; ".join(appearance_lines(record.appearance)))
    for warning in estimate.warnings:
        print(f"warning: {warning.message}", file=sys.stderr)
    if args.render:
        from hairdigi.render.io.images import save_png
        from hairdigi.render.renderer import SceneSpec, render

        result = render(p, SceneSpec("swatch", framing="rig"), 256, 32, seed=0)
        save_png(args.render, result.srgb)
        print(f"wrote {args.render}")
    return 0


def evaluate_rig_command(args: argparse.Namespace) -> int:
    """``hairdigi evaluate --rig``: the chain against the truth; prints the figures, writes table and plot."""
    from hairdigi.app.evaluation.rig import RigSet, evaluate_rig

    s = evaluate_rig(args.out, RigSet(random=args.rig_random))
    r, e = s["refined"], s["encoder_alone"]
    print(f"{s['estimated']} of {s['captures']} captures estimated; against the hidden truth, mean-colour ΔE2000 "
          f"median {r['median']:.2f}, p95 {r['p95']:.2f}, worst {r['worst']:.2f} (encoder alone {e['median']:.2f} / "
          f"{e['p95']:.2f} / {e['worst']:.2f})")
    for source, st in s["by_source"].items():
        if st["n"]:
            print(f"  {source}: median {st['median']:.2f}, p95 {st['p95']:.2f}, worst {st['worst']:.2f} ({st['n']})")
    for case, st in s["by_case"].items():
        if st["n"]:
            print(f"  {case}: median {st['median']:.2f}, worst {st['worst']:.2f}")
    c = s["coverage_held_out"]
    print(f"colour interval fitted on half the hidden swatches holds on the other half: 68% -> {c['p68']:.0%}, "
          f"95% -> {c['p95']:.0%}")
    for line in s["blocked"]:
        print(f"blocked: {line}")
    if args.ship:
        from hairdigi.inference.estimate import CHAIN_TABLE

        _ship(CHAIN_TABLE, s["table"], "the chain's colour interval")
    print(f"rig_evaluation.csv, .json and .png in {args.out}")
    return 0


def _ship(path: Path, table: dict, what: str) -> None:
    """Write a measured table into the model's resources (``evaluate --ship``)."""
    from hairdigi.render.domain.files import write_json_atomic

    write_json_atomic(path, table)
    print(f"shipped {what}: {path}")


def evaluate_appearance_command(args: argparse.Namespace) -> int:
    """``hairdigi evaluate --appearance``: shine and fibre variation judged away from the rig."""
    from hairdigi.app.evaluation.appearance import AppearanceSet, evaluate_appearance

    s = evaluate_appearance(args.out, AppearanceSet(random=args.rig_random, variation=not args.no_variation))
    for mode in ("read", "no light frames"):
        m = s[mode]
        print(f"{mode} ({m['swatches']} swatches), mean-colour ΔE2000 against the truth, median / p95 / worst:")
        for key, label in (("fit", "fit, rig view"), ("each_light", "each light alone"),
                           ("transfer", "transfer: another camera, key light, grey sky"),
                           ("today_fit", "today's world, fit"), ("today_transfer", "today's world, transfer")):
            st = m[key]
            if st["n"]:
                print(f"  {label}: {st['median']:.2f} / {st['p95']:.2f} / {st['worst']:.2f}")
        for key, label in (("shine_abs_error", "shine"), ("spread_abs_error", "fibre spread"),
                           ("grey_abs_error", "grey share")):
            st = m[key]
            if st["n"]:
                print(f"  {label} absolute error: {st['median']:.3f} / {st['p95']:.3f} / {st['worst']:.3f}")
        print(f"  capture (4 frames) {m['capture_frames_s']['median']:.2f} s; capture and estimate "
              f"{m['capture_s']['median']:.2f} s (medians)")
    for line in s["errors"] + s["blocked"]:
        print(f"not estimated: {line}")
    if args.ship:
        from hairdigi.inference.appearance import UNCERTAINTY

        _ship(UNCERTAINTY, s["table"], "the appearance's intervals")
    print(f"appearance_evaluation.csv, .json and .png in {args.out}")
    return 0


def evaluate_cycles_command(args: argparse.Namespace) -> int:
    """``hairdigi evaluate --cycles``: swatches rendered in Blender Cycles, estimated, rendered back in Cycles."""
    from hairdigi.inference.training.evaluate_cycles import CyclesSet, evaluate_cycles
    from hairdigi.render.blender_run import BlenderError, blender_command, probe_blender

    try:
        if blender_command() is None:
            raise BlenderError("no Blender found: set HAIRDIGI_BLENDER to a Python that has bpy (python3.11 -m venv "
                               "VENV && VENV/bin/pip install bpy==5.0.1) or to a blender executable")
        probe_blender()   # a Blender that does not run stops here, before any swatch is made
    except BlenderError as exc:
        print(f"hairdigi evaluate --cycles: error: {exc}", file=sys.stderr)
        return 2
    s = evaluate_cycles(args.out, CyclesSet(random=args.rig_random, size=args.size, spp=args.spp,
                                            shine=not args.default_shine))
    print(f"{s['judged']} of {s['swatches']} Cycles swatches judged; mean-colour ΔE2000 against the truth, "
          f"median / p95 / worst:")
    for mode in ("read", "no light frames"):
        if mode not in s:
            continue
        print(f"  {mode}:")
        for key, label in (("twin_residual", "hairdigi's Mitsuba twin against the input"),
                           ("fit", "the estimate rendered back in Cycles, rig view"),
                           ("transfer", "the same, another camera, a key light and a grey sky"),
                           ("sigma_rel_error", "σa relative error (median channel)")):
            st = s[mode][key]
            if st["n"]:
                print(f"    {label}: {st['median']:.2f} / {st['p95']:.2f} / {st['worst']:.2f}")
    for key, label in (("shine_abs_error", "shine absolute error"),
                       ("encoder_sigma_rel_error", "σa relative error, encoder alone")):
        st = s[key]
        if st["n"]:
            print(f"  {label}: {st['median']:.3f} / {st['p95']:.3f} / {st['worst']:.3f}")
    for line in s["errors"]:
        print(f"not judged: {line}")
    print(f"cycles_evaluation.csv, .json and .png in {args.out}")
    if not s["judged"]:
        raise CliError(f"none of the {s['swatches']} Cycles swatches was judged (first error: "
                       f"{(s['errors'] or ['none given'])[0]}); the figures above are empty")
    return 0


def evaluate_structures_command(args: argparse.Namespace) -> int:
    """``hairdigi evaluate --structures``: hidden hairs in every physical swatch structure, judged on their strands."""
    from hairdigi.inference.training.evaluate_structures import MODES, StructureSet, evaluate_structures
    from hairdigi.render.swatch_family import STRUCTURES

    if args.blender:
        from hairdigi.render.blender_run import BlenderError, blender_command

        try:
            if blender_command() is None:
                raise BlenderError("no Blender found: set HAIRDIGI_BLENDER to a Python that has bpy")
        except BlenderError as exc:
            print(f"hairdigi evaluate --structures --blender: {exc}", file=sys.stderr)
            return 2
    hidden = tuple(args.hidden_structures.split(",")) if args.hidden_structures else StructureSet.structures
    unknown = [name for name in hidden if name not in STRUCTURES]
    if unknown:
        print(f"hairdigi evaluate --structures: unknown structure {unknown[0]!r}; choose among "
              f"{', '.join(STRUCTURES)}", file=sys.stderr)
        return 2
    s = evaluate_structures(args.out, StructureSet(random=args.rig_random, size=min(args.size, 64), spp=args.spp,
                                                   blender=args.blender, structures=hidden, seed=args.held_out))
    print(f"{s['judged']} of {s['swatches']} hidden swatches judged ({s['renderer']}); mean-colour ΔE2000 against "
          f"the truth on the hidden strands, median / p95 / worst:")
    for mode in MODES:
        for group, st in s[mode].items():
            if group in ("by_structure", "layout_nuisance"):
                continue
            fit, away = st["fit"], st["transfer"]
            if fit["n"]:
                print(f"  {mode:8s} {group:14s} fit {fit['median']:.2f} / {fit['p95']:.2f} / {fit['worst']:.2f}, "
                      f"transfer {away['median']:.2f} / {away['p95']:.2f} / {away['worst']:.2f}")
        nuisance = s[mode]["layout_nuisance"]
        if nuisance["n"]:
            print(f"  {mode:8s} layout nuisance {nuisance['median']:.2f} / {nuisance['p95']:.2f} / {nuisance['worst']:.2f}")
    for line in s["errors"]:
        print(f"not judged: {line}")
    if s["judged"] == 0:
        print("hairdigi evaluate --structures: no swatch was judged; see the errors above", file=sys.stderr)
        return 1
    if args.ship:
        from hairdigi.inference.structure import STRUCTURE_TABLE

        _ship(STRUCTURE_TABLE, s["table"], "the colour interval of a swatch of unknown structure")
    print(f"structures_evaluation.csv, .json and .png in {args.out}")
    return 0


def evaluate_spectral_command(args: argparse.Namespace) -> int:
    """``hairdigi evaluate --spectral``: hidden spectral hairs through a spectral rig, judged under three lights."""
    from hairdigi.app.evaluation.spectral import ANSWERS, LIGHTS, VIEWS, SpectralSet, evaluate_spectral

    config = SpectralSet() if args.held_out is None else SpectralSet(seed=args.held_out, random=args.rig_random)
    s = evaluate_spectral(args.out, config)
    print(f"{s['estimated']} of {s['captures']} spectral-rig captures estimated; mean-colour ΔE2000 against the "
          f"spectral truth (median / p95 / worst), an observer adapted to each light:")
    for answer in ANSWERS:
        for view in VIEWS:
            if answer not in s:
                continue
            cells = [f"{light} {st['median']:.2f} / {st['p95']:.2f} / {st['worst']:.2f}"
                     for light in LIGHTS for st in [s[answer][f"{view} {light}"]] if st["n"]]
            print(f"  {answer:8s} answer, {view:4s}: " + "; ".join(cells))
    for answer, held in s.get("stated_p95_held", {}).items():
        print(f"  the record's stated 95% interval held for the {answer} answer in {100 * held:.0f}% of its cases")
    for line in s["errors"]:
        print(f"not estimated: {line}")
    if args.ship and s.get("table", {}).get("cameras"):
        from hairdigi.inference.spectral import SPECTRAL_TABLE

        _ship(SPECTRAL_TABLE, s["table"], "the spectral world's colour intervals")
    print(f"spectral_evaluation.csv, .json and .png in {args.out}")
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.training.evaluate import evaluate, prepare_heldout

    _use_variant(args.variant)   # the held-out set's worker processes are given the same one
    if args.dye:
        from hairdigi.app.cli.dye import cmd_evaluate_dye
        return cmd_evaluate_dye(args)
    if args.rig:
        return evaluate_rig_command(args)
    if args.appearance:
        return evaluate_appearance_command(args)
    if args.cycles:
        return evaluate_cycles_command(args)
    if args.structures:
        return evaluate_structures_command(args)
    if args.spectral:
        return evaluate_spectral_command(args)
    from hairdigi.render.renderer import DEFAULT_SWATCH_MODEL

    data = Path(args.data) if args.data else _cache_dir() / "datasets" / (
        f"heldout-s1000003-{args.size}px-{args.spp}spp-linear16-{DEFAULT_SWATCH_MODEL}")
    if args.prepare_only:
        root = prepare_heldout(data, args.n, args.size, args.spp, args.workers)
        print(f"held-out swatches and the truth's judge renders ready in {root}")
        return 0
    encoder = Encoder(args.model)
    if args.convergence:
        from hairdigi.inference.training.convergence import convergence_sweep

        prepare_heldout(data, args.n, args.size, args.spp, args.workers)
        spps = [int(v) for v in args.convergence.split(",")]
        for r in convergence_sweep(encoder, data, args.out, spps, args.sweep_n):
            print(f"input {r['spp']:4d} spp ({r['render_s']:.2f} s/render): mean-colour ΔE2000 median encoder "
                  f"{r['encoder_de_median']:.2f}, refined {r['refined_de_median']:.2f} (p95 "
                  f"{r['encoder_de_p95']:.2f} / {r['refined_de_p95']:.2f})")
        print(f"convergence.csv and convergence.png in {args.out}")
        return 0
    summary = evaluate(encoder, args.out, n=args.n, size=args.size, spp=args.spp, workers=args.workers,
                       data_root=data, refine_colour=not args.no_refine)
    a = summary["buckets"]["all"]
    for who in ("encoder", "refined"):
        if f"{who}_mean_colour_de2000" in a:
            de = a[f"{who}_mean_colour_de2000"]
            print(f"{who}: mean-colour ΔE2000 median {de['median']:.2f}, p95 {de['p95']:.2f}, worst {de['max']:.2f}; "
                  f"L1 {a[f'{who}_l1']['mean']:.2f}")
    print(f"{summary['n']} held-out swatches (floor ΔE2000 median {a['floor_mean_colour_de2000']['median']:.2f}, "
          f"L1 {a['floor_l1']['mean']:.2f}); encoder {summary['latency_ms_median_1_thread']:.3f} ms; "
          f"68% interval coverage {summary['coverage']}; report in {args.out}")
    return 0


def cmd_rig(args: argparse.Namespace) -> int:
    if args.list_ports:
        from hairdigi.hardware.lights import discover
        import serial.tools.list_ports

        ports = list(serial.tools.list_ports.comports())
        print(f"{len(ports)} serial port(s): " + ", ".join(p.device for p in ports))
        boards = discover()
        print("light boards: " + (", ".join(f"{p} ({ident})" for p, ident in boards) or "none answered ID?"))
        return 0
    from hairdigi.app.cli.rig import open_session, report_still, run_chain

    if args.still:
        return report_still(args.session, args.still)
    session = open_session(args)
    try:
        run_chain(session)
    finally:
        session.close()
    return 0


def cmd_app(args: argparse.Namespace) -> int:
    from hairdigi.app.gui.main import run_app

    camera = None if args.genicam is None else f"genicam:{args.genicam}"
    return run_app(sim=args.sim, session=args.session, tour=args.tour, camera=camera)


def cmd_model_card(args: argparse.Namespace) -> int:
    import csv
    import json
    import shutil

    from hairdigi.inference.training.report import model_card

    def table(path):
        if not path:
            return None
        with open(path) as f:
            return [{k: (v if k == "model" else float(v)) for k, v in row.items()} for row in csv.DictReader(f)]

    evaluation = json.loads(Path(args.evaluation).read_text())
    rig_set = json.loads(Path(args.rig).read_text()) if args.rig else None
    path = model_card(args.model, args.run, evaluation, args.out, table(args.variants), table(args.convergence),
                      table(args.refine_bench), rig_set)
    intervals = Path(args.evaluation).with_name("uncertainty.json")
    if intervals.exists():   # the measured intervals ship beside the model they were measured for
        shutil.copyfile(intervals, Path(args.out).with_name("uncertainty.json"))
    print(f"wrote {path} and {path.with_suffix('.json')}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from hairdigi.app.evaluation.bench import BENCHES

    return BENCHES[args.what](args)


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error as one line (what is wrong, and where help is), exit status 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}; see {self.prog} --help\n")


def build_parser() -> argparse.ArgumentParser:
    from hairdigi.app.cli import validation as v
    from hairdigi.render.domain.bounds import (ENVIRONMENTS, MAX_DEPTH, MAX_SIZE, MAX_SPP, MAX_STRANDS, MIN_DEPTH,
                                             MIN_SIZE, SCENE_NAMES)
    from hairdigi.render.domain.bounds import ILLUMINANTS as ILLUMINANT_NAMES
    from hairdigi.render.domain.bounds import STRUCTURE_MODES, VARIANT_CHOICES as VARIANTS
    from hairdigi.render.domain.rig_geometry import N_LIGHTS

    size, spp = v.int_in(MIN_SIZE, MAX_SIZE), v.int_in(1, MAX_SPP)
    variant_help = "Mitsuba variant (auto: cuda_ad_rgb when Mitsuba finds a GPU, else llvm_ad_rgb, else scalar_rgb)"
    seed, workers = v.int_in(0, v.MAX_SEED), v.int_in(1, v.MAX_WORKERS)
    strands, depth = v.int_in(1, MAX_STRANDS), v.int_in(MIN_DEPTH, MAX_DEPTH)
    parser = _Parser(prog="hairdigi", description=__doc__)
    parser.add_argument("--version", action="version", version=f"hairdigi {version()}")
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error too (anywhere on the command line)")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("render", help="render hair parameters in the swatch rig or a hairstyle")
    p.add_argument("--params", required=True, help="hair parameter JSON (top level or under 'hair')")
    p.add_argument("--scene", default="swatch", type=v.scene_name(SCENE_NAMES),
                   help=f"{', '.join(SCENE_NAMES)}, or the path of a Cem Yuksel .hair model (fitted to the head)")
    p.add_argument("--size", type=size, default=None, help="image side in pixels (default: the scene's)")
    p.add_argument("--spp", type=spp, default=None, help="samples per pixel (default: the scene's)")
    p.add_argument("--seed", type=seed, default=0, help="sampler and strand-layout seed")
    p.add_argument("--camera", help="POLAR,AZIMUTH[,DIST] in degrees around the holder normal / the face")
    p.add_argument("--env", default="studio", choices=ENVIRONMENTS, help="lighting for hairstyles")
    p.add_argument("--framing", default="rig", choices=("rig", "crop"),
                   help="swatch: the whole holder (rig) or hair only (crop, as in training)")
    p.add_argument("--strands", type=strands, default=None, help="strand count (default: the scene's)")
    p.add_argument("--depth", type=depth, default=None, help="maximum path depth (default: the scene's)")
    p.add_argument("--out", required=True, help="output PNG (sRGB 8-bit)")
    p.add_argument("--exr", help="also write linear RGB as OpenEXR")
    p.add_argument("--illuminant", type=v.illuminant,
                   help="render spectrally under this light: " + ", ".join(ILLUMINANT_NAMES)
                   + ", or a CSV of wavelength (nm), power")
    p.add_argument("--balance", choices=("light", "daylight"), default="light",
                   help="with --illuminant: as an eye adapted to the light sees it (light: a white is white), "
                        "or as a daylight-balanced photograph shows it (daylight: tungsten is orange)")
    p.add_argument("--variant", choices=VARIANTS, default="auto", help=variant_help)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("demo", help="headless demo: render the sample swatch and hairstyles")
    p.add_argument("--out", default="out/demo")
    p.add_argument("--quick", action="store_true", help="tiny sizes, for tests")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("dataset", help="render the synthetic swatch dataset (resumable)")
    p.add_argument("--n", type=v.int_in(1, v.MAX_DATASET_N), default=4000)
    p.add_argument("--size", type=size, default=64)
    p.add_argument("--spp", type=spp, default=16,
                   help="16: the linear mean is within about 1%% of 512 spp (resources/models/encoder-notes.md)")
    p.add_argument("--store", choices=("linear16", "srgb8"), default="linear16",
                   help="linear16: linear float16 radiance (the capture chain is applied in training)")
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--swatch-model", choices=("layered", "today"), default="layered",
                   help="layered: fibres that never meet (the default); today: the first swatch")
    p.add_argument("--appearance", choices=("random", "fixed"), default="random",
                   help="random: shine, fibre spread and greys drawn per swatch; fixed: uniform hair, shine 0.3")
    p.add_argument("--strands", type=strands, default=None)
    p.add_argument("--depth", type=depth, default=None)
    p.add_argument("--shard-size", type=v.int_in(1, v.MAX_SHARD_SIZE), default=50)
    p.add_argument("--workers", type=workers, default=2,
                   help="local: worker processes; ray without --address: CPUs of the local Ray instance")
    p.add_argument("--out", help="dataset folder (default: in the cache, $HAIRDIGI_CACHE or ~/.cache/hairdigi)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local: a process pool here; ray: one Ray task per shard (needs hairdigi[cluster])")
    p.add_argument("--address", help="ray: the cluster to use (auto, HOST:6379, ray://HOST:10001; "
                   "default: a local Ray instance for this run)")
    p.add_argument("--variant", choices=VARIANTS, default="auto",
                   help=variant_help + "; recorded in the manifest, and a resume must use the same")
    p.set_defaults(func=cmd_dataset)

    p = sub.add_parser("train", help="train the encoder on a dataset (resumable; needs the train extra)")
    p.add_argument("--dataset", required=True, nargs="+", help="one or more dataset folders (one image size)")
    p.add_argument("--out", required=True, help="run folder: checkpoint, history, curve")
    p.add_argument("--epochs", type=v.int_in(1, v.MAX_EPOCHS), default=100)
    p.add_argument("--batch-size", type=v.int_in(1, v.MAX_BATCH), default=32)
    p.add_argument("--lr", type=v.float_in(0.0, 10.0, low_open=True), default=2e-3)
    p.add_argument("--width", type=v.int_in(1, v.MAX_WIDTH), default=16)
    p.add_argument("--blocks", type=v.int_in(1, v.MAX_BLOCKS), default=4)
    p.add_argument("--input-size", type=v.int_in(v.MIN_INPUT_SIZE, v.MAX_INPUT_SIZE), default=48)
    p.add_argument("--threads", type=v.int_in(1, v.MAX_THREADS), default=2)
    p.add_argument("--seed", type=seed, default=0)
    p.add_argument("--appearance-weight", type=v.float_in(0.0, 1e6), default=None,
                   help="weight of the fibre-colour loss term (default 4; 0: L2 on the parameters alone)")
    p.add_argument("--blur-max", type=v.float_in(0.0, 100.0), default=None,
                   help="largest augmentation blur in px (default 1.5; 0: none)")
    p.add_argument("--epochs-now", type=v.int_in(1, v.MAX_EPOCHS), default=None, help="stop after this many epochs; run again to resume")
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
    p.add_argument("--camera", help="POLAR,AZIMUTH[,DIST]: the camera as the swatch's centre sees it "
                   "(default: the rig's, 10.3,0)")
    p.add_argument("--no-refine", action="store_true", help="the encoder alone, without refinement by synthesis")
    p.add_argument("--lights", metavar="L0,L1,L2", help="the same view lit by each rig light alone, in light order "
                   "(8/16-bit sRGB PNG or linear EXR): the shine is read from them")
    p.add_argument("--structure", choices=STRUCTURE_MODES, default="assumed",
                   help="the swatch's physical structure: 'assumed', hairdigi's layered swatch; 'family', the answer "
                   "mapped to the mean of render.swatch_family's physical structures (their curves render once per "
                   "view, 56 small renders); 'read' from the --lights frames among them (their per-light tables, "
                   "96 renders each), refined on it. hairdigi evaluate --structures measures each")
    p.add_argument("--lights-ev", type=v.float_in(-10.0, 10.0), default=None, metavar="EV",
                   help="the --lights frames' exposure over IMAGE's, in stops (default: the rig's capture record "
                   "beside IMAGE, else the same exposure)")
    p.set_defaults(func=cmd_estimate)

    p = sub.add_parser("evaluate", help="the estimate on clean held-out swatches, judged against the truth")
    p.add_argument("--n", type=v.int_in(1, v.MAX_DATASET_N), default=300)
    p.add_argument("--size", type=size, default=64, help="held-out render side in pixels")
    p.add_argument("--spp", type=spp, default=64, help="held-out inputs' samples per pixel (clean: >= 64)")
    p.add_argument("--prepare-only", action="store_true",
                   help="render the held-out set and the truth's judge renders only (no model needed); resumable")
    p.add_argument("--convergence", metavar="SPP,SPP,...", type=v.int_list_in(1, MAX_SPP),
                   help="instead: estimate the first --sweep-n swatches from inputs rendered at these spp")
    p.add_argument("--sweep-n", type=v.int_in(1, v.MAX_DATASET_N), default=20)
    p.add_argument("--no-refine", action="store_true", help="judge the encoder alone")
    p.add_argument("--rig", action="store_true", help="instead: the whole chain on the simulated rig (calibrate, "
                   "capture live and RAW, estimate) against the hidden truth; --rig-random N random hidden swatches "
                   "beside the hard cases; --ship writes the chain's colour interval into the model")
    p.add_argument("--rig-random", type=v.int_in(0, 200), default=5)
    p.add_argument("--appearance", action="store_true", help="instead: hidden swatches with random shine, fibre "
                   "spread and greys through the simulated rig, judged in the rig view, each light alone and a "
                   "scene the estimate never saw (--rig-random N random swatches beside the named cases; --ship "
                   "writes the appearance's intervals)")
    p.add_argument("--cycles", action="store_true", help="instead: swatches of another strand generator rendered "
                   "in Blender Cycles (HAIRDIGI_BLENDER), estimated, and rendered back in Cycles: the fit and a "
                   "transfer judged in another renderer (--rig-random N random swatches beside the hard cases; "
                   "--spp: Cycles samples, 128 or more)")
    p.add_argument("--structures", action="store_true", help="instead: hidden hairs in every physical swatch "
                   "structure (render.swatch_family: deposited, tilted, loose, ...), estimated as shipped, mapped to "
                   "the family and with the structure read, and judged on their own strands at the rig and away "
                   "(--rig-random N random hairs beside the hard cases; --blender: hidden swatches in Cycles)")
    p.add_argument("--spectral", action="store_true", help="instead: hidden spectral hairs (melanins, Table 1 "
                   "dyes and banded dyes) through a spectral simulated rig (real cameras' sensitivities, white LEDs, "
                   "the chart's measured spectra), judged by the CIE observer under daylight, tungsten and a shop "
                   "LED, at the rig and away")
    p.add_argument("--blender", action="store_true", help="with --structures: render the hidden swatches and the "
                   "judge in Blender Cycles (HAIRDIGI_BLENDER)")
    p.add_argument("--hidden-structures", metavar="NAME,NAME,...", help="with --structures: the structures to hide "
                   "hairs in (default: layered and the physical family)")
    p.add_argument("--held-out", type=int, metavar="SEED", help="with --structures: in place of the named cases, "
                   "--rig-random N uniform Table 1 hairs and N dark ones (melanin 0.95-1.0) drawn with this seed "
                   "(>= 1), no layouts: a check of rules chosen on the named cases; a run cut short resumes "
                   "from --out. With --spectral: --rig-random N hairs of this seed (Table 1, natural, and band "
                   "dyes on natural bases) in place of the named ones")
    p.add_argument("--default-shine", action="store_true", help="with --cycles: every hidden swatch at the default "
                   "shine, no single-light frames (the renderer and the swatch's structure alone)")
    p.add_argument("--ship", action="store_true", help="with --rig: ship the measured colour interval "
                   "(resources/models/chain_uncertainty.json); with --appearance, the appearance's intervals; with "
                   "--structures, the colour interval of a swatch of unknown structure (structure_uncertainty.json); with "
                   "--spectral, the spectral world's intervals by camera (spectral_uncertainty.json)")
    p.add_argument("--no-variation", action="store_true", help="with --appearance: read the shine only, not the "
                   "fibre spread and greys (what the texture reading adds)")
    p.add_argument("--dye", action="store_true", help="instead: dyes characterised on two natural bases, predicted "
                   "on the third (--n: dyes, default 12)")
    p.add_argument("--workers", type=workers, default=2)
    p.add_argument("--data", help="held-out dataset folder (default: in the cache)")
    p.add_argument("--model", default=None)
    p.add_argument("--out", required=True)
    p.add_argument("--variant", choices=VARIANTS, default="auto", help=variant_help)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("rig", help="the capture chain without a window (use --sim without hardware)")
    p.add_argument("--sim", action="store_true", help="the simulated rig: a pty light board and rendered frames")
    p.add_argument("--camera", default="0", help="OpenCV camera index or URL (real rig)")
    p.add_argument("--genicam", nargs="?", const="", metavar="ID", help="a GenICam camera through Aravis (the first "
                   "found, or its ID: arv-tool-0.8 lists them); with --sim, the simulated rig through Aravis's fake camera")
    p.add_argument("--port", help="serial port of the light board (real rig); see --list-ports")
    p.add_argument("--roi", help="swatch area x,y,w,h in the camera frame (real rig; default: found)")
    p.add_argument("--list-ports", action="store_true", help="list serial ports and light boards, then exit")
    p.add_argument("--session", default="out/session", help="session folder: captures, calibration, results")
    p.add_argument("--cast", type=v.float_in(0.0, v.MAX_CAST, low_open=True), nargs=3, default=(1.25, 1.0, 0.8),
                   metavar=("R", "G", "B"), help="simulated white-balance error")
    p.add_argument("--exposure", type=v.float_in(-v.MAX_EXPOSURE_EV, v.MAX_EXPOSURE_EV), default=0.0,
                   help="simulated exposure error in EV")
    p.add_argument("--dead", type=v.int_in(0, N_LIGHTS - 1), nargs="*",
                   help="simulated dead light(s), numbered from 0")
    p.add_argument("--spp", type=spp, default=32, help="samples per pixel of the simulated rig's light renders")
    p.add_argument("--hidden", metavar="PARAMS.json",
                   help="the simulated swatch's hidden parameters (Table 1, as render --params reads them, and "
                        "optionally an \"appearance\" block: longitudinal_roughness, fibre_spread, grey_fraction); "
                        "the chain's estimate is then judged against them, at the rig and away from it")
    p.add_argument("--still", help="import a RAW still of the rig (DNG, CR2, NEF, ...; the chart in view) into "
                                   "the session and estimate it; needs no camera or light board")
    p.add_argument("--spectral", action="store_true", help="with --sim: a spectral rig: white LEDs of an SPD "
                   "(--led), the ColorChecker's measured spectra, spectral hair, seen through a camera's "
                   "sensitivities (--sensor)")
    p.add_argument("--led", type=v.illuminant, default=None, help="the rig's LEDs, a named light or a CSV of "
                   "wavelength (nm), power: with --sim --spectral, the simulated LEDs (default LED-B4, a 5109 K "
                   "phosphor LED); on a real rig, with --sensor, its declared LEDs (each record then carries the "
                   "estimate read in the camera's RGB and its colour under daylight, tungsten and a shop LED)")
    p.add_argument("--sensor", type=v.camera_sensitivities, default=None, help="the camera's sensitivities: "
                   "nikon-5100, sigma-sdmerill, cie (the CIE observer, an ideal camera), or a CSV of wavelength (nm), "
                   "r, g, b: with --sim --spectral, the simulated camera (default nikon-5100); on a real rig, with "
                   "--led, its declared camera")
    p.set_defaults(func=cmd_rig)

    p = sub.add_parser("app", help="the desktop app")
    p.add_argument("--sim", action="store_true", help="use the simulated rig")
    p.add_argument("--genicam", nargs="?", const="", metavar="ID", help="a GenICam camera (as rig --genicam)")
    p.add_argument("--session", default=None, help="session folder (default: from the settings)")
    p.add_argument("--tour", help="calibrate and capture once, time it, save a screenshot in this folder, quit")
    p.set_defaults(func=cmd_app)

    from hairdigi.app.cli.dye import add_dye_parser
    add_dye_parser(sub)

    p = sub.add_parser("model-card", help="write the model card from a run and its evaluation")
    p.add_argument("--run", required=True)
    p.add_argument("--model", default="resources/models/encoder.onnx")
    p.add_argument("--evaluation", required=True, help="evaluation.json from hairdigi evaluate (its "
                   "uncertainty.json is copied beside the model)")
    p.add_argument("--variants", help="encoder_bench.csv from hairdigi bench encoder")
    p.add_argument("--convergence", help="convergence.csv from hairdigi evaluate --convergence")
    p.add_argument("--refine-bench", help="refine_bench.csv from hairdigi bench refine")
    p.add_argument("--rig", help="rig_evaluation.json from hairdigi evaluate --rig (the chain against the truth)")
    p.add_argument("--out", default="resources/models/encoder.md")
    p.set_defaults(func=cmd_model_card)

    from hairdigi.app.evaluation.bench import BENCH_OUT, BENCHES

    p = sub.add_parser("bench", help="speed against error tables and plots")
    p.add_argument("what", choices=tuple(BENCHES))
    p.add_argument("--models", nargs="*", help="encoder: the ONNX models to compare")
    p.add_argument("--n", type=v.int_in(1, v.MAX_DATASET_N), default=None, help="held-out swatches (encoder: 300, refine: 10); "
                   "dataset: swatches per case (16)")
    p.add_argument("--data", help="encoder, refine: held-out dataset folder to reuse")
    p.add_argument("--model", default=None, help="refine: the encoder giving the prior (default: shipped)")
    p.add_argument("--out", default=BENCH_OUT, help="results folder (previews: out/bench/previews)")
    p.add_argument("--quick", action="store_true", help="a tiny sweep, for tests")
    p.set_defaults(func=cmd_bench)

    from hairdigi.app.cli import export, library
    export.add_parser(sub)
    library.add_parser(sub)
    return parser


def _prog(argv: list[str]) -> str:
    """``hairdigi COMMAND`` for messages, from the raw arguments (before they are parsed)."""
    command = next((a for a in argv if not a.startswith("-")), None)
    return f"hairdigi {command}" if command else "hairdigi"


def _error_line(exc: BaseException) -> str:
    """What went wrong, on one line, for an expected failure."""
    from hairdigi.app.cli.validation import describe_os_error, one_line

    if isinstance(exc, MemoryError):
        return "not enough memory for this job; lower --size, --spp or the image size, or close other programs"
    if isinstance(exc, OSError):
        return describe_os_error(exc)
    return one_line(str(exc) or type(exc).__name__)


#: Optional extras: a missing top-level module (or hairdigi subpackage) and the install that brings it.
EXTRAS = {"torch": "train", "onnx": "train", "hairdigi.inference.training": "train", "ray": "cluster"}


def _missing_extra(exc: BaseException) -> str | None:
    """The one-line fix when a command needs an extra this install lacks (the desktop build has none)."""
    if not isinstance(exc, ModuleNotFoundError):
        return None
    name = exc.name or ""
    extra = next((e for m, e in EXTRAS.items() if name == m or name.startswith(m + ".")), None)
    if extra == "train":
        return "training needs a developer install: pip install 'hairdigi[train]'"
    if extra == "cluster":
        return "--backend ray needs the cluster extra: pip install 'hairdigi[cluster]'"
    return None


def _caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among the causes of ``exc``."""
    from hairdigi.render.domain.interrupt import stop_among

    return stop_among(exc, (KeyboardInterrupt,)) is not None


def main(argv: list[str] | None = None) -> int:
    """Run one command. An expected failure (bad input, a file that cannot be read or written) is one
    line on stderr and exit status 2; Ctrl-C at any moment is one line and 130; a bug keeps its
    traceback. ``--debug`` anywhere on the line shows the traceback of expected failures too."""
    import signal
    import traceback

    # Run as a program, Ctrl-C while starting (native libraries load) ends at once, with one line;
    # once the command runs it raises KeyboardInterrupt, so that files and devices are closed.
    program = signal.getsignal(signal.SIGINT) is interrupted_at_start
    start_up()   # the process's thread budget, before numpy's BLAS loads (render.domain.threads)
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv == ["--version"]:   # answered before the parser is built, so it is instant
        print(f"hairdigi {version()}")
        return 0
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    prog = _prog(argv)
    try:
        args = build_parser().parse_args(argv)
        from hairdigi.app.cli.validation import check_args

        if getattr(args, "model", "unset") is None:
            from hairdigi.inference.encoder import DEFAULT_MODEL
            args.model = DEFAULT_MODEL
        check_args(args)
        if program:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            return args.func(args)
        finally:
            if program:   # the work is done: a late Ctrl-C must not kill the exit with a traceback
                signal.signal(signal.SIGINT, signal.SIG_IGN)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        from hairdigi.app.cli.validation import is_expected

        if _caused_by_interrupt(exc):   # native code (Mitsuba, drjit) wraps a Ctrl-C in its own error
            print(f"{prog}: interrupted", file=sys.stderr)
            return 130
        missing = _missing_extra(exc)
        if missing:
            if debug:
                traceback.print_exc()
            print(f"{prog}: error: {missing}", file=sys.stderr)
            return 2
        if not is_expected(exc):
            traceback.print_exc()
            print(f"{prog}: internal error (a bug in hairdigi): {type(exc).__name__}; please report it with "
                  f"the traceback above", file=sys.stderr)
            return 1
        if debug:
            traceback.print_exc()
        print(f"{prog}: error: {_error_line(exc)}", file=sys.stderr)
        return 2

