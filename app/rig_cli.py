"""``hairdigi rig``: the capture chain without a window: lights, exposure, calibration, capture, estimate."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from app.rig_session import RigSession


def open_session(args) -> RigSession:
    """The simulated rig with ``--sim``, else the camera and light board named on the command line."""
    if args.sim:
        from hardware.sim_rig import CameraModel

        model = CameraModel(exposure_ev=args.exposure, cast=tuple(args.cast))
        return RigSession.simulated_rig(args.session, camera_model=model, dead=set(args.dead or ()), spp=args.spp)
    from hardware.cameras import OpenCVCamera
    from hardware.lights import LightController

    camera = OpenCVCamera(int(args.camera) if str(args.camera).isdigit() else args.camera)
    lights = LightController(args.port) if args.port else None
    roi = tuple(int(v) for v in args.roi.split(",")) if args.roi else None
    return RigSession(camera, lights, args.session, roi)


def run_chain(session: RigSession, estimate: bool = True, say=print) -> dict:
    """Toggle the lights, check each one and the exposure, calibrate, capture; returns the figures."""
    out: dict = {}
    if session.lights is not None:
        say(f"light board: {session.lights.identify()} on {session.lights.port_name}")
        levels = []
        for i in range(3):
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
    de = profile["delta_e2000"]
    out["delta_e2000"] = de
    say(f"calibration ({profile['method']}, targets: {profile['targets']}): ΔE2000 mean "
        f"{de['before']['mean']:.2f} -> {de['after']['mean']:.2f}, max {de['before']['max']:.2f} -> "
        f"{de['after']['max']:.2f}; profile {session.profile_path}")
    result = session.capture(estimate=estimate)
    out["capture"] = str(result.image_path)
    say(f"capture: {result.image_path} (+ {result.meta_path.name}), saved before processing")
    if result.blocked:
        say("estimate blocked: " + "; ".join(result.blocked))
    elif result.params is not None:
        p = result.params
        say(f"estimate in {1000 * result.seconds:.0f} ms from capture: dye rgb "
            f"{tuple(round(v) for v in p.dye_rgb)} at {p.dye_concentration:.2f}, melanin "
            f"{p.melanin_concentration:.2f}, ratio {p.melanin_ratio:.2f}")
        out["params"] = p.to_dict()
        hidden = getattr(session.camera, "hidden", None)
        if hidden is not None:
            say(f"hidden truth of the simulated swatch:  dye rgb {tuple(round(v) for v in hidden.dye_rgb)} at "
                f"{hidden.dye_concentration:.2f}, melanin {hidden.melanin_concentration:.2f}, "
                f"ratio {hidden.melanin_ratio:.2f}")
    return out


def detection_sweep(out_dir: str | Path, size=(400, 300), spp: int = 16) -> list[dict]:
    """``hairdigi bench rig``: chart detection and CCM ΔE over camera poses x noise x casts, and feed fps."""
    from hardware.sim_rig import DEFAULT_HIDDEN, CameraModel, sensor_response
    from inference.calibration import CalibrationError, calibrate
    from render import scenes
    from render.bench import write_csv_atomic
    from render.chart import colorchecker_reflectances
    from render.renderer import Renderer, SceneSpec
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
        spec = SceneSpec("swatch", framing="rig", chart=chart, target=scenes.RIG_TARGET,
                         half_width=scenes.RIG_HALF_WIDTH * 1.1,
                         camera=scenes.CameraPose(polar, azimuth))
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
