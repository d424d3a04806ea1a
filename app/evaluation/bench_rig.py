"""``hairdigi bench rig``'s sweep: chart detection and the colour correction's ΔE2000 on simulated frames."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from tqdm import tqdm

from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN
from hairdigi.inference.calibration import CalibrationError, calibrate
from hairdigi.render.camera_model import CameraModel, sensor_response
from hairdigi.render.chart import colorchecker_reflectances
from hairdigi.render.domain import rig_geometry
from hairdigi.render.domain.files import write_csv_atomic
from hairdigi.render.renderer import Renderer, SceneSpec


def detection_sweep(out_dir: str | Path, size=(400, 300), spp: int = 16) -> list[dict]:
    """``hairdigi bench rig``: chart detection and CCM ΔE over camera poses x noise x casts, and feed fps."""
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
