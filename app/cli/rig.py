"""``hairdigi rig``: the capture chain without a window: lights, exposure, calibration, capture, estimate."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from hairdigi.app.session.blockers import messages
from hairdigi.app.session.rig_session import RigSession
from hairdigi.render.domain.rig_geometry import N_LIGHTS


def check_dead_lights(dead) -> set[int]:
    """The simulated dead lights as a set of light numbers; ValueError naming ``--dead`` for any other."""
    from hairdigi.render.domain.rig_geometry import LIGHT_POSITIONS

    n = len(LIGHT_POSITIONS)
    wrong = [d for d in (dead or ()) if isinstance(d, bool) or not isinstance(d, int) or not 0 <= d < n]
    if wrong:
        raise ValueError(f"--dead {' '.join(map(str, wrong))}: the rig has lights 0 to {n - 1}; name only those")
    return set(dead or ())


def open_session(args) -> RigSession:
    """The simulated rig with ``--sim``, else the camera and the light board (``--port``, or found)."""
    from hairdigi.app.session.rig_session import open_rig

    simulated = {}
    if args.sim:
        from hairdigi.render.camera_model import CameraModel

        simulated = {"camera_model": CameraModel(exposure_ev=args.exposure, cast=tuple(args.cast)),
                     "dead": check_dead_lights(args.dead), "spp": args.spp}
        if getattr(args, "hidden", None):
            from hairdigi.render.domain.params import load_params

            simulated["hidden"] = load_params(args.hidden)
            simulated["appearance"] = hidden_appearance(args.hidden)
        if getattr(args, "spectral", False):   # LEDs of an SPD, the chart's spectra, a real camera's sensitivities
            simulated["illuminant"] = args.led or "LED-B4"
            sensor = args.sensor or "nikon-5100"
            simulated["sensitivities"] = None if sensor == "cie" else sensor
    spectra = None
    if not args.sim and getattr(args, "led", None):   # a real rig's declared LEDs and camera
        from hairdigi.inference.spectral import RigSpectra

        spectra = RigSpectra(args.led, None if args.sensor == "cie" else args.sensor)
    roi = tuple(int(v) for v in args.roi.split(",")) if args.roi else None
    camera = args.camera if getattr(args, "genicam", None) is None else f"genicam:{args.genicam}"
    return open_rig(args.session, args.sim, camera, args.port, roi, require_lights=False, spectra=spectra,
                    **simulated)[0]


def hidden_appearance(path):
    """The ``appearance`` block of a hidden swatch's JSON (shine, fibre spread, greys), or None."""
    from hairdigi.render.domain.appearance import Appearance, AppearanceError
    from hairdigi.render.domain.files import read_json
    from hairdigi.render.domain.params import HairParamsError

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
        out["dead_lights"] = dead
        say("light check: " + ("all three light the scene" if not dead else f"DEAD: light(s) {dead}"))
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
        say(f"estimate in {1000 * result.seconds:.0f} ms from capture: {hair_line(p)}")
        out["params"] = p.to_dict()
        say_record(result.record, say)
        hidden = getattr(session.camera, "hidden", None)
        if hidden is not None and getattr(session.camera, "illuminant", None) is not None:
            from hairdigi.app.evaluation.spectral import LIGHTS, judge_record

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
            return out
        if hidden is not None:
            say(f"hidden truth of the simulated swatch:  {hair_line(hidden)}")
            from hairdigi.render.judge import judge

            look = session.camera.appearance
            if result.record.appearance is not None:
                from hairdigi.app.evaluation.appearance import judge_everywhere

                read = result.record.appearance.value
                say(f"hidden appearance: shine {look.longitudinal_roughness:.2f}, fibre spread {look.fibre_spread:.2f}, "
                    f"greys {look.grey_fraction:.2f}; read: shine {read.longitudinal_roughness:.2f}, grey share "
                    f"{read.grey_fraction:.2f}")
                where = judge_everywhere((hidden, look), (result.record.sigma_a, read),
                                         session.region(session.frame().srgb))
                out["truth_de2000_everywhere"] = where
                say("against the hidden truth, mean-colour ΔE2000: " + ", ".join(
                    f"{name} {de:.2f}" for name, de in where.items()) + " (transfer: another camera, a key light "
                    "and a grey sky)")
            read = result.record.appearance
            verdict = judge(hidden, result.record.refinement.sigma_a or p,
                            looks=(session.camera.appearance, None if read is None else read.value))
            out["truth_de2000"] = verdict.de2000
            say(f"against the hidden truth (both rendered at the rig's swatch pose, {verdict.spp} spp, common "
                f"seed): mean-colour ΔE2000 {verdict.de2000:.2f}")
    return out


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
    spectral = u.spectral
    if spectral is not None:
        say(f"in the spectral world ({spectral.camera} camera): within ΔE2000 {spectral.mean_colour_de2000_p68:.2f} "
            f"in 68% and {spectral.mean_colour_de2000_p95:.2f} in 95%, for {spectral.holds_for}")
    if record.spectral is not None:
        r = record.spectral
        say(f"read in the camera's RGB ({r.camera} under {r.led}, residual {r.residual:.2f}, {r.seconds:.1f} s): "
            f"{hair_line(r.hair)}; seen under "
            + ", ".join(f"{light} L*a*b* {lab[0]:.1f} {lab[1]:.1f} {lab[2]:.1f}" for light, lab in r.under.items()))
    if record.appearance is not None:
        say("appearance: " + "; ".join(appearance_lines(record.appearance)))
    for warning in record.warnings:
        say(f"warning: {warning.message}")


def report_still(session_folder: str | Path, still: str | Path, say=print) -> int:
    """``hairdigi rig --still``: import a RAW still into the session, estimate it, and say what came out."""
    from hairdigi.app.session.rig_session import import_still
    from hairdigi.inference.encoder import Encoder, ModelError

    def encoder():
        try:
            return Encoder()
        except ModelError as exc:
            return str(exc)

    result = import_still(session_folder, still, encoder)
    say(f"still: {result.image_path} (+ {result.meta_path.name}), copied before processing")
    from hairdigi.render.domain.records import CaptureRecord, read_record

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


def detection_sweep(out_dir: str | Path, size=(400, 300), spp: int = 16) -> list[dict]:
    """``hairdigi bench rig``: chart detection and CCM ΔE over camera poses x noise x casts, and feed fps."""
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN
    from hairdigi.render.camera_model import CameraModel, sensor_response
    from hairdigi.inference.calibration import CalibrationError, calibrate
    from hairdigi.render.domain import rig_geometry
    from hairdigi.render.domain.files import write_csv_atomic
    from hairdigi.render.chart import colorchecker_reflectances
    from hairdigi.render.renderer import Renderer, SceneSpec
    from tqdm import tqdm

    renderer = Renderer(max_cached=1)
    chart = tuple(map(tuple, colorchecker_reflectances()))
    rows = []
    poses = [(0, 0), (10, 30), (20, 120), (30, 250)]
    noises = [(0.0005, 0.001), (0.0015, 0.002), (0.006, 0.006)]
    casts = [(1.0, 1.0, 1.0), (1.3, 1.0, 0.7), (0.8, 1.0, 1.25)]
    exposures = [-0.7, 0.0]
    rng = np.random.default_rng(0)
    for polar, azimuth in tqdm(poses, desc="rig poses", unit="pose"):
        spec = SceneSpec("swatch", framing="rig", chart=chart, target=rig_geometry.RIG_TARGET,
                         half_width=rig_geometry.RIG_HALF_WIDTH * 1.1,
                         camera=rig_geometry.CameraPose(polar, azimuth))
        linear = renderer.render(DEFAULT_HIDDEN, spec, size, spp, seed=polar).linear
        for shot, read in noises:
            for cast in casts:
                for ev in exposures:
                    img = sensor_response(linear, CameraModel(ev, 1.0, cast, shot, read), rng)
                    row = {"polar": polar, "azimuth": azimuth, "shot_noise": shot, "read_noise": read,
                           "cast": "/".join(map(str, cast)), "exposure_ev": ev}
                    try:
                        p = calibrate(img)
                        row.update(detected=1, de_before=p["delta_e2000"]["before"]["mean"],
                                   de_after=p["delta_e2000"]["after"]["mean"],
                                   de_after_max=p["delta_e2000"]["after"]["max"])
                    except CalibrationError:
                        row.update(detected=0, de_before=float("nan"), de_after=float("nan"),
                                   de_after_max=float("nan"))
                    rows.append(row)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_csv_atomic(out / "rig_bench.csv", rows)
    return rows


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
