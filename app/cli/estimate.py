"""``hairdigi estimate``: hair parameters from an image, written as an estimate record."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hairdigi.app.cli import validation as v
from hairdigi.app.cli.arguments import add_instrument_arguments, add_structure_argument, instrument_options
from hairdigi.app.cli.rig import appearance_lines, say_instrument, say_spectral
from hairdigi.app.session.declared_spectra import rig_spectra, spectra_problem
from hairdigi.app.session.profile import merged, profile_path, read_profile
from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE
from hairdigi.render.domain.records import write_record
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, CameraPose
from hairdigi.render.domain.session_folder import SessionFolder


def add_parser(sub) -> None:
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
    add_structure_argument(p)
    p.add_argument("--lights-ev", type=v.float_in(-10.0, 10.0), default=None, metavar="EV",
                   help="the --lights frames' exposure over IMAGE's, in stops (default: the rig's capture record "
                   "beside IMAGE, else the same exposure)")
    p.add_argument("--led", type=v.illuminant, default=None, help="with --sensor and --calibration: the light the "
                   "photo was taken under, a named light or a CSV of wavelength (nm), power; the record then carries the "
                   "estimate read in the camera's RGB and its colour under daylight, tungsten and a shop LED (as a "
                   "declared rig's). Without them, a calibrated photo's colour interval is widened for the "
                   "metamerism an undeclared camera leaves")
    p.add_argument("--sensor", type=v.camera_sensitivities, default=None, help="with --led: the camera's "
                   "sensitivities: nikon-5100, sigma-sdmerill, cie (the CIE observer), or a CSV of wavelength (nm), "
                   "r, g, b")
    add_instrument_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # deferred: load OpenCV and colour-science (the encoder); the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.inference.encoder import Encoder
    from hairdigi.inference.estimate import estimate_file
    from hairdigi.inference.instrument_reading import with_instrument
    from hairdigi.inference.preprocess import Roi

    session_profile(args)
    encoder = Encoder(args.model)
    roi = Roi.parse(args.roi) if args.roi else None
    camera = CameraPose.parse(args.camera, RIG_SWATCH_POSE.distance) if args.camera else None
    if camera is not None and not args.no_refine:
        say_pose_tables(camera)
    # a pose given means an all-hair view from there; else a frame with the chart in view is the rig's, and
    # an image of the swatch on its holder without the chart is warned of (its camera is unknown)
    lights = args.lights.split(",") if args.lights else None
    exposures = [2.0 ** args.lights_ev] * len(lights) if lights and args.lights_ev is not None else None
    estimate, record, _ = estimate_file(args.image, encoder, roi, args.calibration, camera,
                                        refine_colour=not args.no_refine, rig_view=False if args.camera else None,
                                        light_paths=lights, light_exposures=exposures,
                                        structure=args.structure or DEFAULT_STRUCTURE)
    if args.calibration:    # the spectral world: the declared camera's reading, or an undeclared camera's metamerism
        record = in_spectral_world(record, estimate, args.calibration, args.led, args.sensor)
    record = with_instrument(record, **instrument_options(args))   # what the lab's colour instrument would read
    write_record(args.out, record)
    p = estimate.params
    refined = estimate.refinement
    how = (f"refined in {refined.seconds:.2f} s, residual ΔE2000 {refined.residual_de2000:.2f}" if refined
           else "encoder alone")
    print(f"dye rgb {tuple(round(v) for v in p.dye_rgb)} at {p.dye_concentration:.2f}, melanin "
          f"{p.melanin_concentration:.2f} (ratio {p.melanin_ratio:.2f}); {how}; wrote {args.out}")
    if record.appearance is not None:
        print("appearance: " + "; ".join(appearance_lines(record.appearance)))
    say_spectral(record)
    say_instrument(record)
    for warning in record.warnings:
        print(f"warning: {warning.message}", file=sys.stderr)
    if args.render:
        # deferred: load OpenCV, Mitsuba and colour-science; the parser must not (hairdigi --help in 0.2 s)
        from hairdigi.render.io.images import save_png
        from hairdigi.render.renderer import SceneSpec, render

        result = render(p, SceneSpec("swatch", framing="rig"), 256, 32, seed=0)
        save_png(args.render, result.srgb)
        print(f"wrote {args.render}")
    return 0


def say_pose_tables(camera) -> None:
    """A pose the shipped pose tables do not answer renders its curves first (about a minute on 2 cores): say so
    before the wait."""
    from hairdigi.inference.atlas import POSE_POLARS, load_poses  # deferred: 7 ms to import; the parser must not pay it
    tables = load_poses()
    if tables is None or tables.curve(camera, "layered", 0) is None:
        print(f"camera {camera.polar_deg:g}°, {camera.azimuth_deg:g}°: the shipped pose tables do not reach it (up to "
              f"{POSE_POLARS[-1]:g}° from the swatch's normal, at their distance), so its curves render first, about "
              f"a minute on 2 cores; they are cached for the next estimate there", file=sys.stderr)


def in_spectral_world(record, estimate, calibration: str, led: str | None, sensor: str | None):
    """A calibrated photo's record in the spectral world (``inference.spectral_reading.spectral_record``): read in the
    camera's RGB where ``led`` and ``sensor`` declare its light and camera, else its colour interval widened
    as an undeclared camera's."""
    from hairdigi.inference.calibration import load_profile  # deferred: loads OpenCV and colour-science
    from hairdigi.inference.spectral_reading import spectral_record  # deferred: 7 ms to import; the parser must not

    profile = load_profile(calibration)
    spectra = rig_spectra(False, False, led, sensor)[1]
    curve = None if estimate.refinement is None else estimate.refinement.curve
    return spectral_record(record, spectra, profile, curve)


def session_profile(args: argparse.Namespace) -> None:
    """A session's calibration (``--calibration <session>/calibration.json``) brings the session's rig profile
    (``app.session.profile``): its LEDs, camera and structure mode stand where ``--led``, ``--sensor`` and
    ``--structure`` are not given; each flag that overrides it says so on stderr. "read" without ``--lights``
    (the single-light frames it reads) is read with family, and says so."""
    if not args.calibration:
        return
    folder = Path(args.calibration).parent
    if SessionFolder(folder).calibration.name != Path(args.calibration).name:
        return
    kept = read_profile(folder)
    if kept is None:
        return
    profile, notices = merged(kept, {"sensitivities": args.sensor, "led": args.led, "structure": args.structure})
    for line in notices:
        print(line, file=sys.stderr)
    if args.led is None and profile.led is not None:
        problem = spectra_problem(profile.led, profile.sensitivities)
        if problem is not None:
            raise v.ArgumentError(f"{profile_path(folder)}: {problem}; fix the profile, or give --led and --sensor for this command")
    structure = str(profile.structure)
    if structure == "read" and not args.lights and args.structure is None:
        print("rig profile: the session's structure mode (read) reads the single-light frames, which --lights "
              "does not give: this image is read with family", file=sys.stderr)
        structure = "family"
    args.led, args.sensor, args.structure = profile.led, profile.sensitivities, structure
