"""``hairdigi rig``: the capture chain without a window: lights, exposure, calibration, capture, estimate."""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from hairdigi.app.cli import validation as v
from hairdigi.app.cli.arguments import (SPP, add_declare_argument, add_instrument_arguments, add_spectra_arguments,
                                       add_structure_argument, instrument_options)
from hairdigi.app.session.blockers import messages
from hairdigi.app.session.declared_spectra import SIM_LED, SIM_SENSOR, rig_spectra, spectra_problem
from hairdigi.app.session.profile import RigProfile, merged, profile_path, read_profile, write_profile
from hairdigi.render.domain.appearance import Appearance, AppearanceError
from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE, StructureMode
from hairdigi.render.domain.files import read_json
from hairdigi.render.domain.params import HairParamsError, load_params
from hairdigi.render.domain.records import CaptureRecord, read_record
from hairdigi.render.domain.rig_geometry import LIGHT_POSITIONS, N_LIGHTS
from hairdigi.render.swatch_family import STRUCTURES

if TYPE_CHECKING:
    from hairdigi.app.session.rig_session import RigSession


def check_dead_lights(dead) -> set[int]:
    """The simulated dead lights as a set of light numbers; ValueError naming ``--dead`` for any other."""
    n = len(LIGHT_POSITIONS)
    wrong = [d for d in (dead or ()) if isinstance(d, bool) or not isinstance(d, int) or not 0 <= d < n]
    if wrong:
        raise ValueError(f"--dead {' '.join(map(str, wrong))}: the rig has lights 0 to {n - 1}; name only those")
    return set(dead or ())


def open_session(args) -> RigSession:
    """The simulated rig with ``--sim``, else the camera and the light board (``--port``, or found)."""
    # deferred: loads OpenCV and colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.app.session.rig_session import open_rig

    simulated = {}
    if args.sim:
        from hairdigi.render.camera_model import CameraModel  # deferred: loads colour-science; the parser must not

        simulated = {"camera_model": CameraModel(exposure_ev=args.exposure, cast=tuple(args.cast)),
                     "dead": check_dead_lights(args.dead), "spp": args.spp}
        if getattr(args, "hidden", None):
            simulated["hidden"] = load_params(args.hidden)
            simulated["appearance"] = hidden_appearance(args.hidden)
        if getattr(args, "hidden_structure", None):
            simulated["swatch_model"] = args.hidden_structure
    keywords, spectra = rig_spectra(args.sim, getattr(args, "spectral", False), getattr(args, "led", None),
                                    getattr(args, "sensor", None))
    simulated.update(keywords)
    roi = tuple(int(v) for v in args.roi.split(",")) if args.roi else None
    camera = args.camera if getattr(args, "genicam", None) is None else f"genicam:{args.genicam}"
    return open_rig(args.session, args.sim, camera, args.port, roi, require_lights=False, spectra=spectra,
                    structure=getattr(args, "structure", None) or DEFAULT_STRUCTURE, **simulated)[0]


def hidden_appearance(path):
    """The ``appearance`` block of a hidden swatch's JSON (shine, fibre spread, greys), or None."""
    data = read_json(path, HairParamsError, "no such parameter file", "not valid JSON ({exc})")
    if not isinstance(data, dict) or data.get("appearance") is None:
        return None
    try:
        return Appearance.from_dict(data["appearance"])
    except AppearanceError as exc:
        raise HairParamsError(f"{path}: appearance: {exc}") from None


def run_chain(session: RigSession, estimate: bool = True, say=print) -> dict:
    """Toggle the lights, check each one and the exposure, calibrate, capture; returns the figures."""
    out: dict = {}
    if session.lights is not None:
        out["dead_lights"] = _light_check(session, say)
    t0 = time.perf_counter()
    n = 30
    for _ in range(n):
        session.frame()
    out["fps"] = n / (time.perf_counter() - t0)
    say(f"feed: {out['fps']:.1f} frames/s")
    for report in session.exposure():
        say(f"exposure: {report.message}")
    profile = session.calibrate()
    de = profile.delta_e2000
    out["delta_e2000"] = de
    say(f"calibration ({profile.method}, targets: {profile.targets}): ΔE2000 mean "
        f"{de['before']['mean']:.2f} -> {de['after']['mean']:.2f}, max {de['before']['max']:.2f} -> "
        f"{de['after']['max']:.2f}; profile {session.profile_path}")
    result = session.capture(estimate=estimate)
    out["capture"] = str(result.image_path)
    say(f"capture: {result.image_path} (+ {result.meta_path.name}), saved before processing")
    if result.blocked:
        say("estimate blocked: " + "; ".join(messages(result.blocked)))
    elif result.params is not None:
        p = result.params
        took = f"{1000 * result.seconds:.0f} ms" if result.seconds < 10 else f"{result.seconds:.0f} s"
        say(f"estimate in {took} from capture: {hair_line(p)}")
        out["params"] = p.to_dict()
        say_record(result.record, say)
        _judge_hidden(session, result, out, say)
    return out


def _light_check(session: RigSession, say) -> list:
    """Each light alone and all on, as the camera sees them; the dead lights."""
    say(f"light board: {session.lights.identify()} on {session.lights.port_name}")
    levels = []
    for i in range(N_LIGHTS):
        session.lights.all_off()
        session.set_light(i, True)
        levels.append(float(session.frame().srgb.mean()))
    session.set_all(True)
    all_on = float(session.frame().srgb.mean())
    say("lights alone -> mean level: " + ", ".join(f"L{i} {v:.1f}" for i, v in enumerate(levels))
        + f"; all on {all_on:.1f}")
    dead = session.check_lights()
    say("light check: " + ("all three light the scene" if not dead else f"DEAD: light(s) {dead}"))
    return dead


def _judge_hidden(session: RigSession, result, out: dict, say) -> None:
    """On a simulated rig, the estimate against the swatch's hidden truth (under three lights on a spectral rig)."""
    hidden = getattr(session.camera, "hidden", None)
    if hidden is None:
        return
    if getattr(session.camera, "illuminant", None) is not None:
        # deferred: loads colour-science; the parser must not (hairdigi --help in 0.2 s)
        from hairdigi.app.evaluation.spectral_evaluation import LIGHTS, judge_record

        where = judge_record(hidden, result.record, session.profile, session.camera.illuminant,
                             session.camera.sensitivities)
        out["truth_de2000_spectral"] = where
        for answer, what in (("rgb", "the RGB answer (its colour times each light's)"),
                             ("spectral", "the spectral answer (refitted, rendered spectrally)"),
                             ("camera", "the camera answer (read in the camera's RGB, rendered spectrally)")):
            if f"{answer}_rig_D65" not in where:
                continue
            say(f"spectral rig, against the hidden hair seen by the CIE observer adapted to each light, "
                f"{what}: " + "; ".join(f"{view} " + ", ".join(f"{light} {where[f'{answer}_{view}_{light}']:.2f}"
                                                            for light in LIGHTS) for view in ("rig", "away")))
        return
    structure = getattr(session.camera, "swatch_model", None)
    say(f"hidden truth of the simulated swatch:  {hair_line(hidden)}"
        + (f" (a {structure} swatch, judged on its strands)" if structure else ""))
    from hairdigi.render.judge import judge, judge_scene  # deferred: loads colour-science; the parser must not

    look = session.camera.appearance
    if result.record.appearance is not None:
        # deferred: loads colour-science; the parser must not (hairdigi --help in 0.2 s)
        from hairdigi.app.evaluation.appearance_evaluation import judge_everywhere

        read = result.record.appearance.value
        say(f"hidden appearance: shine {look.longitudinal_roughness:.2f}, fibre spread {look.fibre_spread:.2f}, "
            f"greys {look.grey_fraction:.2f}; read: shine {read.longitudinal_roughness:.2f}, grey share "
            f"{read.grey_fraction:.2f}")
        where = judge_everywhere((hidden, look), (result.record.sigma_a, read),
                                 session.region(session.frame().srgb), structure)
        out["truth_de2000_everywhere"] = where
        say("against the hidden truth, mean-colour ΔE2000: " + ", ".join(
            f"{name} {de:.2f}" for name, de in where.items()) + " (transfer: another camera, a key light "
            "and a grey sky)")
    read = result.record.appearance
    verdict = judge(hidden, result.record.refinement.sigma_a or result.params, judge_scene(structure),
                    looks=(session.camera.appearance, None if read is None else read.value))
    out["truth_de2000"] = verdict.de2000
    say(f"against the hidden truth (both rendered at the rig's swatch pose, {verdict.spp} spp, common "
        f"seed): mean-colour ΔE2000 {verdict.de2000:.2f}")


def hair_line(p) -> str:
    """Table 1 parameters in one line."""
    return (f"dye rgb {tuple(round(v) for v in p.dye_rgb)} at {p.dye_concentration:.2f}, melanin "
            f"{p.melanin_concentration:.2f}, ratio {p.melanin_ratio:.2f}")


def say_record(record, say=print) -> None:
    """The refinement's residual, the chain's stated colour interval, and the warnings of a record."""
    refinement = record.refinement
    if refinement.ran:
        residual = "not recorded" if refinement.residual_de2000 is None else f"{refinement.residual_de2000:.2f}"
        say(f"refined to the swatch's mean colour: residual ΔE2000 {residual} "
            f"in {refinement.seconds:.2f} s (six parameters reach the image through three absorption "
            "values, so other parameters can render the same colour: compare colours, not parameters)")
    u = record.uncertainty
    if u.mean_colour_de2000_p68 is not None:
        say(f"stated colour interval: within ΔE2000 {u.mean_colour_de2000_p68:.2f} of the truth in 68% and "
            f"{u.mean_colour_de2000_p95:.2f} in 95% of held-out captures ({u.mean_colour_source or ''})")
    say_spectral(record, say)
    say_instrument(record, say)
    if record.appearance is not None:
        say("appearance: " + "; ".join(appearance_lines(record.appearance)))
    for warning in record.warnings:
        say(f"warning: {warning.message}")


def say_spectral(record, say=print) -> None:
    """A record's spectral world: its colour interval there, and its reading in the declared camera's RGB."""
    spectral = record.uncertainty.spectral
    if spectral is not None:
        say(f"in the spectral world ({spectral.camera} camera): within ΔE2000 {spectral.mean_colour_de2000_p68:.2f} "
            f"in 68% and {spectral.mean_colour_de2000_p95:.2f} in 95%, for {spectral.holds_for}")
    if record.spectral is not None:
        r = record.spectral
        say(f"read in the camera's RGB ({r.camera} under {r.led}, residual {r.residual:.2f}, {r.seconds:.1f} s): "
            f"{hair_line(r.hair)}; seen under "
            + ", ".join(f"{light} L*a*b* {lab[0]:.1f} {lab[1]:.1f} {lab[2]:.1f}" for light, lab in r.under.items()))


def instrument_line(reading) -> str:
    """One instrument reading as the lab writes it: geometry, light/observer, aperture, L*a*b*, interval."""
    interval = (f", within ΔE2000 {reading.p68:.2f} (68%) / {reading.p95:.2f} (95%)" if reading.p68 is not None
                else ", interval not measured")
    return (f"{reading.geometry} {reading.illuminant}/{reading.observer}° {reading.aperture_mm:g} mm: L*a*b* "
            f"{reading.lab[0]:.1f} {reading.lab[1]:.1f} {reading.lab[2]:.1f}{interval}; the family's structures "
            f"{reading.spread:.2f} apart")


def say_instrument(record, say=print) -> None:
    """A record's instrument readings, one line each."""
    for reading in record.instrument:
        say("as an instrument reads it: " + instrument_line(reading))


#: ``rig``'s flags that act on the live rig only, each with its default: with ``--still`` they are refused.
LIVE_ONLY = {"sim": ("--sim", False), "spectral": ("--spectral", False), "genicam": ("--genicam", None),
             "camera": ("--camera", "0"), "port": ("--port", None), "roi": ("--roi", None),
             "cast": ("--cast", (1.25, 1.0, 0.8)), "exposure": ("--exposure", 0.0), "dead": ("--dead", None),
             "spp": ("--spp", 32), "hidden": ("--hidden", None), "hidden_structure": ("--hidden-structure", None)}


def check_still_flags(args) -> None:
    """``rig --still`` takes the session, ``--structure`` and a real camera's ``--led``/``--sensor``; any flag of
    the live rig is refused in one line, never ignored, and so is ``--structure read`` (a still has no
    single-light frames to read it from, as ``estimate`` refuses it without ``--lights``)."""
    given = [flag for dest, (flag, default) in LIVE_ONLY.items() if _given(getattr(args, dest, default), default)]
    if given:
        raise v.ArgumentError(f"{' '.join(given)} acts on the live rig, which --still does not open (a still is read "
                              "from its file, with its own chart): leave it out, or run hairdigi rig without --still")
    if getattr(args, "structure", None) == "read":
        raise v.ArgumentError("--structure read reads the swatch's structure from its single-light frames, which a "
                              "RAW still does not have: use --structure family (or assumed)")


def rig_profile(args, still: bool, say=None) -> RigProfile:
    """The rig this command works with: the session's profile (``app.session.profile``) with the flags given in
    its place, each override said on stderr; ``args``' ``led``, ``sensor``, ``structure`` (and ``spectral`` on the
    simulated rig) are set from it. A live rig's profile, simulated spectra filled in, is what the session keeps."""
    say = say or (lambda line: print(line, file=sys.stderr))
    kept = read_profile(args.session)
    profile, notices = merged(kept, {"sensitivities": args.sensor, "led": args.led, "structure": args.structure})
    for line in notices:
        say(line)
    sim = not still and args.sim
    if sim and profile.spectral and not args.spectral:
        say(f"rig profile: the session declares its LEDs ({profile.led}) and camera ({profile.sensitivities}): "
            "the simulated rig is spectral")
        args.spectral = True
    if sim and args.spectral:
        profile = replace(profile, led=profile.led or SIM_LED, sensitivities=profile.sensitivities or SIM_SENSOR)
    if kept is not None and (profile.led, profile.sensitivities) != (args.led, args.sensor):
        problem = spectra_problem(profile.led, profile.sensitivities)   # the profile's spectra, read now
        if problem is not None:
            raise v.ArgumentError(f"{profile_path(args.session)}: {problem}; fix the profile, or give --led and --sensor for this command")
    args.led, args.sensor, args.structure = profile.led, profile.sensitivities, str(profile.structure)
    return profile


def still_structure(structure: str) -> str:
    """The structure mode a still is read with: the profile's, except "read", which needs the single-light frames
    a still has not (``family`` in its place, said on stderr)."""
    if structure != StructureMode.READ:
        return str(structure)
    print("rig profile: the session's structure mode (read) reads the single-light frames, which a still has not: "
          "this still is read with family", file=sys.stderr)
    return str(StructureMode.FAMILY)


def _given(value, default) -> bool:
    """Whether a flag's value differs from its default (a list given for a tuple default compared as one)."""
    return (tuple(value) if isinstance(value, list) else value) != default


def still_spectra(led: str | None, sensor: str | None):
    """A still camera's declared LEDs and sensitivities (``--led``/``--sensor``) as ``import_still``'s
    ``in_spectral_world``: its record read in the camera's RGB as a declared rig's; None where none is declared."""
    spectra = rig_spectra(False, False, led, sensor)[1]
    if spectra is None:
        return None
    # deferred: 7 ms to import, for a declared camera only; the parser must not pay it (hairdigi --help in 0.2 s)
    from hairdigi.inference.spectral_reading import spectral_record

    return lambda record, profile, curve: spectral_record(record, spectra, profile, curve)


def report_still(session_folder: str | Path, still: str | Path, say=print, structure: str = DEFAULT_STRUCTURE,
                 led: str | None = None, sensor: str | None = None, instrument: dict | None = None) -> int:
    """``hairdigi rig --still``: import a RAW still into the session, estimate it (``structure``: ``--structure``;
    ``led`` and ``sensor``, the declared spectra it is read under), and say what came out. No rig is opened, so the
    still's structure is not read from the rig's frames."""
    # deferred: load OpenCV and colour-science (the encoder); the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.app.session.rig_session import import_still
    from hairdigi.inference.encoder import Encoder, ModelError

    def encoder():
        try:
            return Encoder()
        except ModelError as exc:
            return str(exc)

    result = import_still(session_folder, still, encoder, still_spectra(led, sensor), structure=structure,
                          instrument=instrument)
    say(f"still: {result.image_path} (+ {result.meta_path.name}), copied before processing")
    profile = read_record(result.meta_path, CaptureRecord).calibration
    if profile is not None:
        say(f"calibrated on the still's own chart: ΔE2000 mean {profile.delta_e2000['before']['mean']:.2f} "
            f"-> {profile.delta_e2000['after']['mean']:.2f}")
    if result.blocked:
        say("estimate blocked: " + "; ".join(messages(result.blocked)))
        return 2    # an input the still cannot serve (no chart, clipped), not a bug
    p = result.params
    say(f"estimate in {result.seconds:.1f} s: {hair_line(p)}")
    say_record(result.record, say)
    return 0


def appearance_lines(estimate) -> list[str]:
    """Each appearance field with its 68% interval, or "not measured" (an ``AppearanceEstimate``)."""
    names = {"longitudinal_roughness": "shine", "fibre_spread": "fibre spread", "grey_fraction": "grey share"}
    lines = []
    for key, label in names.items():
        value = getattr(estimate.value, key)
        if key not in estimate.measured:
            lines.append(f"{label} {value:.2f} (not measured)")
        else:
            lines.append(f"{label} {value:.2f}" + estimate.interval_text(key))
    return lines


def add_parser(sub) -> None:
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
    p.add_argument("--spp", type=SPP, default=32, help="samples per pixel of the simulated rig's light renders")
    p.add_argument("--hidden", metavar="PARAMS.json",
                   help="the simulated swatch's hidden parameters (Table 1, as render --params reads them, and "
                        "optionally an \"appearance\" block: longitudinal_roughness, fibre_spread, grey_fraction); "
                        "the chain's estimate is then judged against them, at the rig and away from it")
    p.add_argument("--still", help="import a RAW still of the rig (DNG, CR2, NEF, ...; the chart in view) into "
                                   "the session and estimate it; needs no camera or light board")
    add_spectra_arguments(p)
    add_structure_argument(p, "how the session's estimates treat the swatch's")
    add_declare_argument(p)
    add_instrument_arguments(p)
    p.add_argument("--hidden-structure", choices=STRUCTURES, default=None, metavar="NAME",
                   help="with --sim: the simulated swatch's physical structure (render.swatch_family: "
                   + ", ".join(STRUCTURES) + "; default layered, hairdigi's own); the truth is judged on its strands")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if not str(args.session).strip():
        raise v.ArgumentError("--session '': an empty session folder would put captures/ in the current folder; "
                              "name the session folder (default out/session)")
    if args.list_ports:
        # deferred: pyserial and the light board's driver, 6 ms to import, for --list-ports only; the parser must not
        import serial.tools.list_ports
        from hairdigi.hardware.lights import discover

        ports = list(serial.tools.list_ports.comports())
        print(f"{len(ports)} serial port(s): " + ", ".join(p.device for p in ports))
        boards = discover()
        print("light boards: " + (", ".join(f"{p} ({ident})" for p, ident in boards) or "none answered ID?"))
        return 0
    if args.still:
        check_still_flags(args)
        profile = rig_profile(args, still=True)
        if args.declare:
            write_profile(args.session, profile)
        return report_still(args.session, args.still, structure=still_structure(profile.structure),
                            led=profile.led, sensor=profile.sensitivities, instrument=instrument_options(args))
    profile = rig_profile(args, still=False)
    session = open_session(args)
    session.instrument = instrument_options(args)
    try:
        if not profile_path(args.session).exists() or args.declare:
            write_profile(args.session, profile)   # declared once: the session's first run, or --declare
        run_chain(session)
    finally:
        session.close()
    return 0
