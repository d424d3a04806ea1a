"""``hairdigi estimate``: hair parameters from an image, written as an estimate record."""
from __future__ import annotations

import argparse
import sys

from hairdigi.app.cli import validation as v


def add_parser(sub) -> None:
    from hairdigi.render.domain.bounds import STRUCTURE_MODES

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
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
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
