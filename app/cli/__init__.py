"""The ``hairdigi`` command line: one subcommand per job, each a thin call into the science packages."""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import traceback
from pathlib import Path

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.interrupt import stop_among
from hairdigi.render.domain.threads import start_up
from hairdigi.render.domain.version import version

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # torch's OpenMP spinning starves a 2-core CPU


def interrupted_at_start(signum, frame) -> None:
    """Ctrl-C before ``main`` takes over (the program is still importing): one line, exit 130."""
    try:
        prog = _prog(sys.argv[1:])
    except NameError:   # still loading this module
        prog = "hairdigi"
    sys.stderr.write(f"{prog}: interrupted\n")
    os._exit(130)


if Path((sys.argv or [""])[0]).name == "hairdigi":   # a program, not a library import (-m: __main__.py)
    signal.signal(signal.SIGINT, interrupted_at_start)


class CliError(HairdigiError):
    """A user-facing error: printed as one line, exit status 2."""


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error as one line (what is wrong, and where help is), exit status 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message}; see {self.prog} --help\n")


#: The commands, one module of this package each (``add_parser(sub)``, ``run(args)``), in ``--help``'s order.
COMMANDS = ("render", "demo", "dataset", "train", "export_onnx", "estimate", "evaluate", "rig", "app", "dye",
            "model_card", "bench", "export", "library")


def build_parser() -> argparse.ArgumentParser:
    """The whole parser: each command's module adds its subparser (importing none of the science)."""
    parser = _Parser(prog="hairdigi", description=__doc__)
    parser.add_argument("--version", action="version", version=f"hairdigi {version()}")
    parser.add_argument("--debug", action="store_true",
                        help="show the traceback of an error too (anywhere on the command line)")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f"{__name__}.{name}").add_parser(sub)
    return parser


def _prog(argv: list[str]) -> str:
    """``hairdigi COMMAND`` for messages, from the raw arguments (before they are parsed)."""
    command = next((a for a in argv if not a.startswith("-")), None)
    return f"hairdigi {command}" if command else "hairdigi"


def _error_line(exc: BaseException) -> str:
    """What went wrong, on one line, for an expected failure."""
    # deferred: the commands' modules (validation: 12 ms) load with the parser, not before --version's instant answer
    from hairdigi.app.cli.validation import describe_os_error, one_line

    if isinstance(exc, MemoryError):
        return "not enough memory for this job; lower --size, --spp or the image size, or close other programs"
    if isinstance(exc, OSError):
        return describe_os_error(exc)
    return one_line(str(exc) or type(exc).__name__)


#: Optional extras: a missing top-level module (or hairdigi subpackage) and the install that brings it.
EXTRAS = {"torch": "train", "onnx": "train", "hairdigi.inference.training": "train", "ray": "cluster"}


def _missing_extra(exc: BaseException) -> str | None:
    """The one-line fix when a command needs an extra this install lacks (the desktop build has none)."""
    if not isinstance(exc, ModuleNotFoundError):
        return None
    name = exc.name or ""
    extra = next((e for m, e in EXTRAS.items() if name == m or name.startswith(m + ".")), None)
    if extra == "train":
        return "training needs a developer install: pip install 'hairdigi[train]'"
    if extra == "cluster":
        return "--backend ray needs the cluster extra: pip install 'hairdigi[cluster]'"
    return None


def _caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among the causes of ``exc``."""
    return stop_among(exc, (KeyboardInterrupt,)) is not None


def main(argv: list[str] | None = None) -> int:
    """Run one command. An expected failure (bad input, a file that cannot be read or written) is one
    line on stderr and exit status 2; Ctrl-C at any moment is one line and 130; a bug keeps its
    traceback. ``--debug`` anywhere on the line shows the traceback of expected failures too."""
    # Run as a program, Ctrl-C while starting (native libraries load) ends at once, with one line;
    # once the command runs it raises KeyboardInterrupt, so that files and devices are closed.
    program = signal.getsignal(signal.SIGINT) is interrupted_at_start
    start_up()   # the process's thread budget, before numpy's BLAS loads (render.domain.threads)
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv == ["--version"]:   # answered before the parser is built, so it is instant
        print(f"hairdigi {version()}")
        return 0
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    prog = _prog(argv)
    try:
        args = build_parser().parse_args(argv)
        # deferred: the commands' modules load with the parser (above), not before --version's instant answer
        from hairdigi.app.cli.validation import check_args

        if getattr(args, "model", "unset") is None:
            # deferred: loads OpenCV and colour-science (the encoder); the parser must not (hairdigi --help in 0.2 s)
            from hairdigi.inference.encoder import DEFAULT_MODEL
            args.model = DEFAULT_MODEL
        check_args(args)
        if program:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            return args.func(args)
        finally:
            if program:   # the work is done: a late Ctrl-C must not kill the exit with a traceback
                signal.signal(signal.SIGINT, signal.SIG_IGN)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:
        # deferred: the commands' modules load with the parser, not before --version's instant answer
        from hairdigi.app.cli.validation import is_expected

        if _caused_by_interrupt(exc):   # native code (Mitsuba, drjit) wraps a Ctrl-C in its own error
            print(f"{prog}: interrupted", file=sys.stderr)
            return 130
        missing = _missing_extra(exc)
        if missing:
            if debug:
                traceback.print_exc()
            print(f"{prog}: error: {missing}", file=sys.stderr)
            return 2
        if not is_expected(exc):
            traceback.print_exc()
            print(f"{prog}: internal error (a bug in hairdigi): {type(exc).__name__}; please report it with "
                  f"the traceback above", file=sys.stderr)
            return 1
        if debug:
            traceback.print_exc()
        print(f"{prog}: error: {_error_line(exc)}", file=sys.stderr)
        return 2

