"""``hairdigi render``: hair parameters in the swatch rig or a hairstyle, as PNG (and EXR)."""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from hairdigi.app.cli import validation as v
from hairdigi.app.cli.arguments import DEPTH, SEED, SIZE, SPP, STRANDS, VARIANT_HELP, use_variant
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, AppearanceError, AppearanceEstimate
from hairdigi.render.domain.bounds import ENVIRONMENTS, SCENE_NAMES, VARIANT_CHOICES, SceneKind
from hairdigi.render.domain.bounds import ILLUMINANTS as ILLUMINANT_NAMES
from hairdigi.render.domain.files import atomic_paths, read_json
from hairdigi.render.domain.params import HairParamsError, load_params
from hairdigi.render.domain.rig_geometry import CAMERA_DISTANCE, CameraPose


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render hair parameters in the swatch rig or a hairstyle")
    p.add_argument("--params", required=True, help="hair parameter JSON (top level or under 'hair')")
    p.add_argument("--scene", default="swatch", type=v.scene_name(SCENE_NAMES),
                   help=f"{', '.join(SCENE_NAMES)}, or the path of a Cem Yuksel .hair model (fitted to the head)")
    p.add_argument("--size", type=SIZE, default=None, help="image side in pixels (default: the scene's)")
    p.add_argument("--spp", type=SPP, default=None, help="samples per pixel (default: the scene's)")
    p.add_argument("--seed", type=SEED, default=0, help="sampler and strand-layout seed")
    p.add_argument("--camera", help="POLAR,AZIMUTH[,DIST] in degrees around the holder normal / the face")
    p.add_argument("--env", default="studio", choices=ENVIRONMENTS, help="lighting for hairstyles")
    p.add_argument("--framing", default="rig", choices=("rig", "crop"),
                   help="swatch: the whole holder (rig) or hair only (crop, as in training)")
    p.add_argument("--strands", type=STRANDS, default=None, help="strand count (default: the scene's)")
    p.add_argument("--depth", type=DEPTH, default=None, help="maximum path depth (default: the scene's)")
    p.add_argument("--out", required=True, help="output PNG (sRGB 8-bit)")
    p.add_argument("--exr", help="also write linear RGB as OpenEXR")
    p.add_argument("--illuminant", type=v.illuminant,
                   help="render spectrally under this light: " + ", ".join(ILLUMINANT_NAMES)
                   + ", or a CSV of wavelength (nm), power")
    p.add_argument("--balance", choices=("light", "daylight"), default="light",
                   help="with --illuminant: as an eye adapted to the light sees it (light: a white is white), "
                        "or as a daylight-balanced photograph shows it (daylight: tungsten is orange)")
    p.add_argument("--variant", choices=VARIANT_CHOICES, default="auto", help=VARIANT_HELP)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: load OpenCV, Mitsuba and colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.render.io.images import save_exr, save_png
    from hairdigi.render.renderer import SceneSpec, render
    from hairdigi.render.scenes import PORTRAIT_CAMERA

    use_variant(args.variant)
    params = load_params(args.params)
    distance = PORTRAIT_CAMERA.distance if SceneKind.of(args.scene).on_head else CAMERA_DISTANCE
    camera = CameraPose.parse(args.camera, distance) if args.camera else None
    spec = SceneSpec(name=args.scene, camera=camera, env=args.env, framing=args.framing,
                     strands=args.strands, max_depth=args.depth, strand_seed=args.seed, illuminant=args.illuminant,
                     appearance=measured_appearance(args.params))
    result = render(params, spec, args.size, args.spp, args.seed)
    if args.illuminant is not None and args.balance == "light":
        from hairdigi.render.spectra import balanced  # deferred: 3 ms to import; the parser must not pay it
        from hairdigi.render.srgb import linear_to_srgb8  # deferred: loads colour-science; the parser must not

        result.linear = balanced(result.linear, args.illuminant)
        result.srgb = linear_to_srgb8(result.linear)
    if spec.hair_file is not None:
        from hairdigi.render.hairfile import model_summary  # deferred: 3 ms to import; the parser must not pay it

        print(model_summary(spec.hair_file, spec.n_strands))
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


def measured_appearance(path: str):
    """What a parameter file's ``appearance`` block measured (an estimate record's shine and grey share, as
    ``export`` and the app's previews render them; a hidden swatch's block whole), or None: the default look."""
    data = read_json(path, HairParamsError, "no such parameter file", "not valid JSON ({exc})")
    block = data.get("appearance") if isinstance(data, dict) else None
    if block is None:
        return None
    if not isinstance(block, dict):
        raise HairParamsError(f"{path}: appearance must be an object (shine, fibre spread, grey share); fix or "
                              "remove it")
    try:
        estimate = AppearanceEstimate.from_json(block)
    except (AppearanceError, TypeError, ValueError) as exc:
        raise HairParamsError(f"{path}: appearance: {exc}; fix or remove the block") from None
    if not estimate.measured:
        return None
    return replace(DEFAULT_APPEARANCE, **{name: getattr(estimate.value, name) for name in estimate.measured})
