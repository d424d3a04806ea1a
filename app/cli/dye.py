"""``hairdigi dye``: characterise a dye from swatch pairs, apply it to a base, dose it to a target, print
its shade card (``hairdigi evaluate --dye`` is ``app.evaluation.modes.dye``). The science is ``inference/dye.py``."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hairdigi.app.cli import validation as v
from hairdigi.render.domain.files import atomic_paths, write_json_atomic
from hairdigi.render.domain.records import read_record, record_sha256, write_record
from hairdigi.render.strands import HAIRSTYLES

HAIRSTYLE_SIZE, HAIRSTYLE_SPP = 384, 16
MAX_NAME = 200


def dye_name(text: str) -> str:
    """An argparse type: a dye's name, not empty, at most ``MAX_NAME`` characters, no control characters."""
    if not text.strip():
        raise argparse.ArgumentTypeError("a dye needs a name (it is empty)")
    if len(text) > MAX_NAME:
        raise argparse.ArgumentTypeError(f"a name of {len(text)} characters is longer than {MAX_NAME}; shorten it")
    if any(ord(c) < 32 or 127 <= ord(c) < 160 for c in text):
        raise argparse.ArgumentTypeError("the name holds control characters (an escape sequence?); type it plainly")
    return text


def add_parser(sub) -> None:
    """Register ``hairdigi dye`` and its four actions on the main parser's subparsers."""
    p = sub.add_parser("dye", help="hair-dye development: characterise a dye, predict it on any hair, shade card")
    acts = p.add_subparsers(dest="dye_action", required=True)

    a = acts.add_parser("characterise", help="measure a dye's deposit and lift from (base, dyed) record pairs")
    a.add_argument("--pair", nargs=2, action="append", required=True, metavar=("BASE.json", "DYED.json"),
                   help="a natural base's record and the same hair dyed (estimate records or session "
                        "captures' <id>.result.json); two bases or more measure the lift")
    a.add_argument("--name", required=True, type=dye_name, help=f"the dye's name (at most {MAX_NAME} characters)")
    a.add_argument("--out", required=True, help="the dye record JSON to write")
    a.add_argument("--allow-mixed-calibrations", action="store_true",
                   help="accept records corrected with different calibrations (the record warns)")

    a = acts.add_parser("apply", help="predict a dye on a base: a record with an estimate's layout, renders")
    a.add_argument("dye", help="dye record JSON")
    a.add_argument("--base", required=True, help="the base's record (read as natural hair)")
    a.add_argument("--dose", type=v.float_in(0.0, 10.0), default=1.0, help="deposit scale (1: as characterised)")
    a.add_argument("--out", required=True, help="the prediction JSON (renders with hairdigi render --params)")
    a.add_argument("--render", help="also render the predicted swatch to this PNG")
    a.add_argument("--scene", nargs="+", action="extend", choices=HAIRSTYLES, default=[],
                   help="with --render: also these hairstyles, beside it as <name>-<scene>.png")

    a = acts.add_parser("dose", help="the deposit scale that brings a base nearest a target colour")
    a.add_argument("dye", help="dye record JSON")
    a.add_argument("--base", required=True, help="the base's record")
    a.add_argument("--target", required=True, help="a captured swatch's record, or an sRGB colour #RRGGBB")
    a.add_argument("--out", help="also write the answer as JSON")

    a = acts.add_parser("card", help="the dye on the ten natural levels, rendered: PNG, PDF and JSON")
    a.add_argument("dye", help="dye record JSON")
    a.add_argument("--out", required=True, help="card PNG (a PDF and a JSON table are written beside it)")
    a.add_argument("--dose", type=v.float_in(0.0, 10.0), default=1.0)
    a.add_argument("--size", type=v.int_in(16, 512), default=64, help="swatch side in pixels")
    a.add_argument("--spp", type=v.int_in(1, 4096), default=16)
    p.set_defaults(func=run)


def _check(args: argparse.Namespace) -> None:
    """The inputs are readable files and the outputs are writable and none of them."""
    if args.dye_action == "characterise":
        inputs = {}
        for i, (base, dyed) in enumerate(args.pair, 1):
            v.check_input_file(base, f"--pair {i} base")
            v.check_input_file(dyed, f"--pair {i} dyed")
            inputs.update({f"--pair {i} base": base, f"--pair {i} dyed": dyed})
        v.check_output_file(args.out, "--out", (".json",), "JSON", inputs)
        return
    v.check_input_file(args.dye, "dye")
    inputs = {"dye": args.dye}
    if getattr(args, "base", None):
        v.check_input_file(args.base, "--base")
        inputs["--base"] = args.base
    if args.dye_action == "apply":
        v.check_distinct({"--out": args.out, "--render": args.render})
        v.check_output_file(args.out, "--out", (".json",), "JSON", inputs)
        if args.render:
            render = v.check_output_file(args.render, "--render", (".png",), "an 8-bit PNG", inputs)
            for scene in dict.fromkeys(args.scene):   # the hairstyles beside it: <name>-<scene>.png
                v.check_output_file(render.with_name(f"{render.stem}-{scene}.png"), f"--scene {scene} (beside "
                                    f"--render)", (".png",), "an 8-bit PNG", {**inputs, "--out": args.out})
        elif args.scene:
            raise v.ArgumentError("--scene renders beside --render: give --render swatch.png too")
    elif args.dye_action == "dose" and args.out:
        v.check_output_file(args.out, "--out", (".json",), "JSON", inputs)
    elif args.dye_action == "card":
        out = v.check_output_file(args.out, "--out", (".png",), "a PNG", inputs)
        v.check_output_file(out.with_suffix(".pdf"), "--out (its PDF)", (".pdf",), "a PDF", inputs)
        v.check_output_file(out.with_suffix(".json"), "--out (its JSON table)", (".json",), "JSON", inputs)


def _read_dye(path: str):
    from hairdigi.render.domain.dye_record import DyeRecord  # deferred: 3 ms to import; the parser must not pay it
    return read_record(path, DyeRecord), record_sha256(path)


def run(args: argparse.Namespace) -> int:
    _check(args)
    return {"characterise": _characterise, "apply": _apply, "dose": _dose, "card": _card}[args.dye_action](args)


def _characterise(args: argparse.Namespace) -> int:
    from hairdigi.inference.dye import characterise, load_sample  # deferred: loads colour-science; the parser must not

    pairs = [(load_sample(base), load_sample(dyed)) for base, dyed in args.pair]
    dye = characterise(pairs, args.name, allow_mixed=args.allow_mixed_calibrations)
    write_record(args.out, dye)
    dep = ", ".join(f"{x:.4f}" for x in dye.deposit_sigma_a)
    if dye.lift_measured:
        lift = f"lift {dye.lift:.3f} (68%: {dye.lift_low:.3f} to {dye.lift_high:.3f})"
    else:
        lift = f"lift {dye.lift:.3f} (not measured: one base)"
    print(f"{dye.name}: deposit sigma_a ({dep}), {lift}; {len(dye.pairs)} pair(s), residual ΔE2000 mean "
          f"{dye.residual_de2000_mean:.2f}, max {dye.residual_de2000_max:.2f}; wrote {args.out}")
    for warning in dye.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return 0


def _apply(args: argparse.Namespace) -> int:
    from hairdigi.inference.dye import apply, describe_colour, load_sample  # deferred: loads colour-science

    dye, sha = _read_dye(args.dye)
    base = load_sample(args.base)
    pred = apply(dye, base, args.dose, dye_path=args.dye, dye_sha256=sha)
    renders = _render_prediction(pred.sigma_a, Path(args.render), args.scene) if args.render else []
    # the prediction and its renders are published together: a failed render leaves no prediction behind
    with atomic_paths(args.out, *(path for path, _ in renders)) as (record_tmp, *image_tmps):
        from hairdigi.render.io.images import save_png  # deferred: loads OpenCV; the parser must not

        record_tmp.write_text(json.dumps(pred.record.to_json(), indent=2) + "\n", encoding="utf-8")
        for tmp, (_, srgb) in zip(image_tmps, renders):
            save_png(tmp, srgb)
    p = pred.params
    colour = describe_colour(pred.linear_rgb)
    print(f"{dye.name} at dose {args.dose:g} on {args.base}: sigma_a ({', '.join(f'{x:.4f}' for x in pred.sigma_a)}), "
          f"swatch {colour['srgb']} L*a*b* {colour['lab']}; Table 1: dye rgb {tuple(round(x) for x in p.dye_rgb)} at "
          f"{p.dye_concentration:.2f}, melanin {p.melanin_concentration:.3f} (ratio {p.melanin_ratio:.2f}); "
          f"wrote {args.out}")
    for w in pred.record.warnings[1:]:
        print(f"warning: {w.message}", file=sys.stderr)
    for path, _ in renders:
        print(f"wrote {path}")
    return 0


def _render_prediction(sigma, path: Path, scenes: list[str]) -> list[tuple[Path, object]]:
    """The predicted swatch and each hairstyle, rendered (not yet written): ``[(path, srgb), ...]``."""
    # deferred: loads Mitsuba and colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.render.renderer import SceneSpec, default_renderer

    renderer = default_renderer()
    result = renderer.render(sigma, SceneSpec("swatch", framing="rig"), 256, 32, seed=0)
    print(f"rendered the swatch ({result.seconds:.1f} s)")
    out = [(path, result.srgb)]
    for scene in dict.fromkeys(scenes):   # each hairstyle once, however often it was named
        result = renderer.render(sigma, SceneSpec(scene), HAIRSTYLE_SIZE, HAIRSTYLE_SPP, seed=0)
        print(f"rendered {scene} ({result.seconds:.1f} s)")
        out.append((path.with_name(f"{path.stem}-{scene}.png"), result.srgb))
    return out


def _dose(args: argparse.Namespace) -> int:
    # deferred: loads colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.inference.dye import describe_colour, dose, load_sample, target_colour

    dye, _ = _read_dye(args.dye)
    base = load_sample(args.base)
    target, label = target_colour(args.target)
    result = dose(dye, base, target)
    reached, wanted = describe_colour(result.linear_rgb), describe_colour(result.target_linear_rgb)
    named = "" if label == wanted["srgb"] else f" {wanted['srgb']}"
    print(f"{result.message}: base {args.base} -> {reached['srgb']} L*a*b* {reached['lab']}, target {label}{named} "
          f"L*a*b* {wanted['lab']}")
    if args.out:
        write_json_atomic(args.out, {"dye": dye.name, "base": args.base, "target": label, "scale": round(result.scale, 4),
                                     "de2000": round(result.de2000, 3), "reachable": result.reachable,
                                     "reached": reached, "wanted": wanted, "message": result.message,
                                     "sigma_a": [round(float(x), 6) for x in result.sigma_a]})
        print(f"wrote {args.out}")
    return 0


def _card(args: argparse.Namespace) -> int:
    from hairdigi.inference.dye_card import shade_card  # deferred: loads colour-science; the parser must not

    dye, _ = _read_dye(args.dye)
    png, pdf, table, rows = shade_card(dye, args.out, args.dose, args.size, args.spp)
    for r in rows:
        print(f"level {r['level']:2d} {r['base']['srgb']} -> {r['result']['srgb']} L*a*b* "
              f"{' '.join(f'{x:.1f}' for x in r['result']['lab'])}, ΔE2000 {r['de2000']:.1f}")
    print(f"wrote {png}, {pdf} and {table}")
    return 0
