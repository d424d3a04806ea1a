"""The ``hairdigi`` command line: one subcommand per job, each a thin call into the science packages."""
from __future__ import annotations

import argparse
import os
import sys
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


def cmd_bench(args: argparse.Namespace) -> int:
    out = Path(args.out)
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

    p = sub.add_parser("bench", help="speed against error tables and plots")
    p.add_argument("what", choices=("render",))
    p.add_argument("--out", default="out/bench")
    p.add_argument("--quick", action="store_true", help="a tiny sweep, for tests")
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from render.hairfile import HairFileError
    from render.params import HairParamsError

    try:
        return args.func(args)
    except (CliError, HairParamsError, HairFileError, ValueError, FileNotFoundError) as exc:
        print(f"hairdigi {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"hairdigi {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
