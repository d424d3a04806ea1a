"""The headless demo: the whole chain on the simulated rig, then renders of the estimate."""
from __future__ import annotations

import argparse
from pathlib import Path

from hairdigi.app.cli.rig import run_chain
from hairdigi.render.domain.params import HairParams


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="headless demo: render the sample swatch and hairstyles")
    p.add_argument("--out", default="out/demo")
    p.add_argument("--quick", action="store_true", help="tiny sizes, for tests")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    run_demo(Path(args.out), quick=args.quick)
    return 0


def run_demo(out: Path, quick: bool = False) -> list[Path]:
    """Lights, exposure, calibration and a capture on the simulated rig; estimate; render the
    estimate as a rig swatch and two hairstyles. Returns the written images."""
    # deferred: load Mitsuba, OpenCV and colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.app.session.rig_session import RigSession
    from hairdigi.render.camera_model import CameraModel
    from hairdigi.render.io.images import save_png
    from hairdigi.render.renderer import SceneSpec, render

    out = Path(out)
    session = RigSession.simulated_rig(out / "session", camera_model=CameraModel(cast=(1.2, 1.0, 0.8)),
                                       spp=8 if quick else 32)
    try:
        figures = run_chain(session)
        hidden = session.camera.hidden
    finally:
        session.close()
    if "params" in figures:
        params, source = HairParams.from_dict(figures["params"]), "the estimate"
    else:
        params, source = hidden, "the simulated swatch's hidden parameters (no estimate was made)"
    print(f"rendering {source}")
    jobs = [
        ("swatch", SceneSpec("swatch", framing="rig"), 64 if quick else 256, 4 if quick else 32),
        ("straight", SceneSpec("straight", env="studio", strands=300 if quick else None), 64 if quick else 384, 2 if quick else 16),
        ("curly", SceneSpec("curly", env="soft", strands=300 if quick else None), 64 if quick else 384, 2 if quick else 16),
    ]
    written = []
    for name, spec, size, spp in jobs:
        result = render(params, spec, size, spp, seed=0)
        path = save_png(out / f"{name}.png", result.srgb)
        print(f"  {path}  ({size}x{size}, {spp} spp, {result.seconds:.1f} s)")
        written.append(path)
    print(f"demo output is in {out.resolve()}")
    return written
