"""``hairdigi app``: the desktop app."""
from __future__ import annotations

import argparse

from hairdigi.app.cli.arguments import add_spectra_arguments, add_structure_argument
from hairdigi.app.cli.display import display_problem
from hairdigi.app.cli.validation import ArgumentError


def add_parser(sub) -> None:
    p = sub.add_parser("app", help="the desktop app")
    p.add_argument("--sim", action="store_true", help="use the simulated rig")
    p.add_argument("--genicam", nargs="?", const="", metavar="ID", help="a GenICam camera (as rig --genicam)")
    p.add_argument("--session", default=None, help="session folder (default: from the settings)")
    p.add_argument("--tour", help="calibrate and capture once, time it, save a screenshot in this folder, quit")
    add_spectra_arguments(p)   # a real rig's --led and --sensor are remembered in the settings
    add_structure_argument(p, "remembered in the settings: how estimates treat the swatch's")
    p.set_defaults(func=run, structure=None)


def run(args: argparse.Namespace) -> int:
    if args.session is not None and not str(args.session).strip():
        raise ArgumentError("--session '': an empty session folder would put captures/ in the current folder; "
                            "name the session folder, or leave --session out for the settings' one")
    problem = display_problem()   # before Qt: a display that is not X aborts it or hangs it
    if problem is not None:
        raise ArgumentError(problem)
    # deferred: loads Qt (PySide6), Mitsuba, OpenCV and colour-science; the parser must not (hairdigi --help in 0.2 s)
    from hairdigi.app.gui.main import run_app

    camera = None if args.genicam is None else f"genicam:{args.genicam}"
    return run_app(sim=args.sim, session=args.session, tour=args.tour, camera=camera, spectral=args.spectral,
                   led=args.led, sensor=args.sensor, structure=args.structure)
