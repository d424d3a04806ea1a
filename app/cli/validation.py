"""Checks on a command's arguments, run before any expensive work: numbers in range, paths usable.

Numbers are checked as the command line is parsed (``int_in``, ``float_in``, ...: argparse types
whose message names the bound). Paths and the checks that need several arguments at once run in
``check_args`` before the command starts, so that no render or training is thrown away at the end
because its output cannot be written:

- an input must be a readable file (or folder, where one is asked for);
- an output must not resolve to an input or to another output, must end in its format's extension
  (.png, .exr, .json, ...), must not be an existing folder, and its folder must exist or be
  creatable, be writable, and have some space left.

Why one module over 600 lines: each command's ``check_*`` applies these path rules, and a rule
changed must be changed for every command at once; one module is where a new command's checks are
written and reviewed beside the rules and every other command's use of them.
"""
from __future__ import annotations

import argparse
import csv
import errno
import math
import os
import re
import shutil
import socket
import sys
from pathlib import Path
from typing import Callable, Iterable

from hairdigi.app.evaluation.registry import EVALUATIONS
from hairdigi.app.session.declared_spectra import SIM_LED, SIM_SENSOR, spectra_problem
from hairdigi.render.domain.bounds import (CAMERAS, ILLUMINANTS, BoundsError, SceneKind, check_camera, check_size_spp,
                                          defaults_for)
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import (ProtectedFileError, _checkout_protected, _within, cache_dir, package_folders,
                                         read_json, refuse_protected)
from hairdigi.render.domain.rig_geometry import CAMERA_DISTANCE, CameraPose, GeometryError
from hairdigi.render.domain.session_folder import SessionFolder
from hairdigi.resources import MODELS

#: Bounds of the numbers the commands take (render bounds live in ``render.domain.bounds``).
MAX_SEED = 2 ** 32 - 1           # Mitsuba's and NumPy's seeds are unsigned 32-bit
MAX_DATASET_N = 10_000_000
MAX_SHARD_SIZE = 100_000
MAX_WORKERS = 256
MAX_EPOCHS = 100_000
MAX_BATCH = 65_536
MAX_WIDTH = 1024                 # encoder channels
MAX_BLOCKS = 64
MIN_INPUT_SIZE, MAX_INPUT_SIZE = 16, 1024
MAX_THREADS = 256
MAX_EXPOSURE_EV = 10.0           # simulated exposure error, either way
MAX_CAST = 10.0                  # simulated white-balance gain per channel
MIN_FREE_BYTES = 1 << 20         # an output folder on a disk with less than this left counts as full


def _models_folder() -> str:
    """The shipped model's folder: ``export-onnx`` and ``model-card`` may replace the files there."""
    return str(MODELS)


class ArgumentError(HairdigiError, ValueError):
    """An argument cannot be used; the message names it and says what would work."""


# --- numbers, as argparse types --------------------------------------------------------------
def int_in(low: int, high: int) -> Callable[[str], int]:
    """An argparse type: a whole number from ``low`` to ``high``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number (use {low} to {high})") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is outside {low} to {high}")
        return value
    return parse


def float_in(low: float, high: float, low_open: bool = False) -> Callable[[str], float]:
    """An argparse type: a finite number from ``low`` to ``high`` (above ``low`` when ``low_open``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        above = value > low if low_open else value >= low
        if not math.isfinite(value) or not above or value > high:
            raise argparse.ArgumentTypeError(f"{text} is outside {'(' if low_open else '['}{low:g}, {high:g}]")
        return value
    return parse


def int_list_in(low: int, high: int) -> Callable[[str], str]:
    """An argparse type: comma-separated whole numbers, each from ``low`` to ``high`` (kept as text)."""
    one = int_in(low, high)

    def parse(text: str) -> str:
        values = [one(v.strip()) for v in text.split(",") if v.strip()]
        if not values:
            raise argparse.ArgumentTypeError(f"{text!r} holds no numbers; give e.g. 4,16,64")
        return ",".join(map(str, values))
    return parse


# --- paths -------------------------------------------------------------------------------------
def _same(a: Path, b: Path) -> bool:
    """Whether two paths name one file: same resolved path, or (both existing) the same inode."""
    if a.resolve() == b.resolve():
        return True
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def check_input_file(path: str | os.PathLike, flag: str) -> Path:
    """``path`` must be a readable regular file; the error names ``flag``."""
    p = Path(path)
    if not p.exists():
        raise ArgumentError(f"{flag} {p}: no such file; check the path")
    if p.is_dir():
        raise ArgumentError(f"{flag} {p}: is a folder; give the path of a file")
    if not p.is_file():
        raise ArgumentError(f"{flag} {p}: is not a regular file (a pipe or a device?); give a file")
    try:
        with open(p, "rb") as f:
            f.read(1)
    except OSError as exc:
        raise ArgumentError(f"{flag} {p}: cannot be read ({exc.strerror}); make it readable (chmod +r) "
                            f"or use a copy") from None
    return p


def check_input_dir(path: str | os.PathLike, flag: str) -> Path:
    """``path`` must be an existing folder."""
    p = Path(path)
    if not p.is_dir():
        raise ArgumentError(f"{flag} {p}: {'is a file, not a folder' if p.exists() else 'no such folder'}; "
                            f"check the path")
    return p


def _writable_folder(folder: Path, flag: str, shown: Path) -> None:
    """The nearest existing ancestor of ``folder`` must be a writable folder on a disk with room left."""
    probe = folder
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise ArgumentError(f"{flag} {shown}: {probe} is a file, so no folder can be made there; choose "
                            f"another path")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise ArgumentError(f"{flag} {shown}: the folder {probe} is not writable; choose another path or "
                            f"fix its permissions")
    try:
        free = shutil.disk_usage(probe).free
    except OSError:
        return
    if free < MIN_FREE_BYTES:
        raise ArgumentError(f"{flag} {shown}: the disk holding {probe} is full ({free // 1024} kB free); "
                            f"free some space or write to another disk")


def check_output_file(path: str | os.PathLike, flag: str, suffixes: Iterable[str], fmt: str,
                      inputs: dict[str, str | os.PathLike | None] | None = None, allow: tuple = ()) -> Path:
    """``path`` is where a ``fmt`` file will be written: the right extension, not a folder, not one of
    ``inputs`` (flag: path), in a folder that exists or can be made, and writable."""
    text = os.fspath(path)
    p = Path(text)
    suffixes = tuple(suffixes)
    if text.endswith((os.sep, "/")) or p.is_dir():
        raise ArgumentError(f"{flag} {text}: is a folder; give a file name such as "
                            f"{p / ('out' + suffixes[0])}")
    for other_flag, other in (inputs or {}).items():
        if other is not None and _same(p, Path(other)):
            raise ArgumentError(f"{flag} {text} is also the {other_flag} input; choose another output name")
    if p.suffix.lower() not in suffixes:
        raise ArgumentError(f"{flag} {text}: this writes {fmt}; name it with {' or '.join(suffixes)}, e.g. "
                            f"{p.with_suffix(suffixes[0]).name}")
    check_not_protected(p, flag, allow)
    _name_fits(p, flag)
    if p.is_file() and not p.stat().st_mode & 0o222:
        raise ArgumentError(f"{flag} {text}: the file is read-only (chmod 444), so it is kept; make it writable "
                            f"(chmod u+w) or choose another name")
    _writable_folder(p.parent, flag, p)
    return p


def check_not_protected(path: str | os.PathLike, flag: str, allow: tuple = ()) -> None:
    """``path`` must not be a file hairdigi reads back: a session's, a dataset's or the package's, or a
    record, a dye or a library of any name (the one guard: ``render.domain.files.refuse_protected``)."""
    try:
        refuse_protected((path,), allow)
    except ProtectedFileError as exc:
        raise ArgumentError(f"{flag} {exc}") from None


def _name_fits(p: Path, flag: str) -> None:
    """The file name and the whole path must fit the file system's limits (checked before the work)."""
    probe = p.parent
    while not probe.exists() and probe.parent != probe:
        probe = probe.parent
    try:
        name_max = os.pathconf(probe, "PC_NAME_MAX")
        path_max = os.pathconf(probe, "PC_PATH_MAX")
    except (OSError, ValueError):
        name_max, path_max = 255, 4096
    for part in p.parts:
        if len(os.fsencode(part)) > name_max:
            raise ArgumentError(f"{flag} {p}: the name {part[:40]}... is {len(os.fsencode(part))} bytes, over the "
                                f"file system's {name_max}; use a shorter name")
    if len(os.fsencode(str(p.absolute()))) >= path_max:
        raise ArgumentError(f"{flag} {p}: the path is longer than the file system's {path_max} bytes; use a "
                            f"shorter path")


def check_output_dir(path: str | os.PathLike, flag: str,
                     inputs: dict[str, str | os.PathLike | None] | None = None, dataset_ok: bool = False) -> Path:
    """``path`` is a folder that will be written into: not a file, not an input, creatable, writable."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise ArgumentError(f"{flag} {p}: is a file, not a folder; choose a folder name")
    for other_flag, other in (inputs or {}).items():
        if other is not None and _same(p, Path(other)):
            raise ArgumentError(f"{flag} {p} is also the {other_flag} input; choose another folder")
    _not_a_protected_folder(p, flag, dataset_ok)
    _name_fits(p / "x", flag)
    _writable_folder(p, flag, p)
    return p


def _not_a_protected_folder(p: Path, flag: str, dataset_ok: bool) -> None:
    """An output folder must not be the package's, a session's captures, or (but for ``dataset``) a dataset."""
    real = p.resolve()
    folders = package_folders()
    if any(_within(real, f) for f in folders + _checkout_protected(folders)[0]):
        raise ArgumentError(f"{flag} {p} is inside the hairdigi package (its code, tests or resources); "
                            f"writing there is refused: choose another folder")
    if SessionFolder.of_captures(real) is not None or SessionFolder.of_captures(real.parent) is not None:
        raise ArgumentError(f"{flag} {p} is the captures folder of the rig session {real.parent}; writing there "
                            f"is refused: choose another folder")
    if not dataset_ok and (real / "manifest.json").is_file():
        raise ArgumentError(f"{flag} {p} is a dataset folder (it holds manifest.json); writing there is "
                            f"refused: choose another folder")


def check_distinct(outputs: dict[str, str | os.PathLike | None]) -> None:
    """No two outputs may name the same file."""
    named = [(flag, Path(p)) for flag, p in outputs.items() if p is not None]
    for i, (flag_a, a) in enumerate(named):
        for flag_b, b in named[i + 1:]:
            if _same(a, b):
                raise ArgumentError(f"{flag_b} {b} is also the {flag_a} output; give each output its own name")


# --- per command ---------------------------------------------------------------------------
def scene_name(names) -> Callable[[str], str]:
    """An argparse type: one of the scene ``names``, or a path ending in ``.hair`` (checked later)."""
    def parse(text: str) -> str:
        if text in names or text.lower().endswith(".hair"):
            return text
        raise argparse.ArgumentTypeError(f"{text!r} is not a scene: choose one of {', '.join(names)}, "
                                         f"or give the path of a .hair file")
    return parse


def illuminant(text: str) -> str:
    """An argparse type: a named light (``render.domain.bounds.ILLUMINANTS``) or a CSV's path (read later)."""
    if text in ILLUMINANTS or text.lower().endswith((".csv", ".txt")):
        return text
    raise argparse.ArgumentTypeError(f"{text!r} is not a light: choose one of {', '.join(ILLUMINANTS)}, "
                                     f"or give a CSV file of wavelength (nm), power")


def check_render(args: argparse.Namespace) -> None:
    """``hairdigi render``: the parameter file, the outputs, and size x spp, depth and camera together."""
    from hairdigi.render.scenes import PORTRAIT_CAMERA  # deferred: loads Mitsuba; the parser must not (--help in 0.2 s)

    check_input_file(args.params, "--params")
    inputs = {"--params": args.params}
    if args.scene.lower().endswith(".hair"):
        from hairdigi.render.hairfile import HairFileError, read_hair_file  # deferred: 3 ms; the parser must not pay it

        check_input_file(args.scene, "--scene")
        inputs["--scene"] = args.scene
        try:
            read_hair_file(args.scene)   # a malformed model stops here, before any scene is built
        except HairFileError as exc:
            raise ArgumentError(f"--scene {exc}") from None
    check_distinct({"--out": args.out, "--exr": args.exr})
    check_output_file(args.out, "--out", (".png",), "an 8-bit PNG", inputs)
    if args.exr:
        check_output_file(args.exr, "--exr", (".exr",), "an OpenEXR image", inputs)
    defaults = defaults_for(args.scene)
    size = defaults.size if args.size is None else args.size
    spp = defaults.spp if args.spp is None else args.spp
    try:
        check_size_spp(size, spp)
    except BoundsError as exc:
        raise ArgumentError(f"--size {size} --spp {spp}: {exc}") from None
    if args.camera:
        distance = PORTRAIT_CAMERA.distance if SceneKind.of(args.scene).on_head else CAMERA_DISTANCE
        try:
            check_camera(CameraPose.parse(args.camera, distance), args.scene)
        except (GeometryError, BoundsError) as exc:
            raise ArgumentError(f"--camera {args.camera}: {exc}") from None


def check_estimate(args: argparse.Namespace) -> None:
    """``hairdigi estimate``: the image, profile and model are readable; the outputs are none of them."""
    check_input_file(args.image, "image")
    inputs = {"image": args.image, "--calibration": args.calibration, "--model": args.model}
    if args.calibration:
        # deferred: loads OpenCV and colour-science; the parser must not (hairdigi --help in 0.2 s)
        from hairdigi.inference.calibration import load_profile

        check_input_file(args.calibration, "--calibration")
        load_profile(args.calibration)   # a corrupt profile stops here, before the model is loaded
    led, sensor = getattr(args, "led", None), getattr(args, "sensor", None)
    if (led or sensor) and not args.calibration:
        raise ArgumentError("--led and --sensor read the estimate in the camera's RGB through its chart correction: "
                            "add --calibration (the photo's calibration profile)")
    if led or sensor:
        problem = spectra_problem(led, sensor)
        if problem is not None:
            raise ArgumentError(problem)
    if args.model:
        check_input_file(args.model, "--model")
    for i, light in enumerate((getattr(args, "lights", None) or "").split(",") if getattr(args, "lights", None) else ()):
        check_input_file(light, f"--lights (light {i})")   # a device or FIFO is refused before it is read
        inputs[f"--lights (light {i})"] = light
    if getattr(args, "structure", None) == "read" and not getattr(args, "lights", None):
        raise ArgumentError("--structure read reads the swatch's structure from its single-light frames: pass "
                            "--lights L0,L1,L2, or use --structure family")
    if getattr(args, "structure", None) and getattr(args, "no_refine", False):
        raise ArgumentError(f"--structure {args.structure} acts on the refinement, which --no-refine skips; "
                            f"leave one of them out")
    check_distinct({"--out": args.out, "--render": args.render})
    check_output_file(args.out, "--out", (".json",), "JSON", inputs)
    if not getattr(args, "no_refine", False):
        check_cache_writable()   # refinement stores the camera pose's response curve there
    if args.render:
        check_output_file(args.render, "--render", (".png",), "an 8-bit PNG", inputs)


def check_dataset_folder(path: str | os.PathLike) -> None:
    """An existing dataset folder must hold a readable manifest (``{"config": {...}}``) or none."""
    manifest = Path(path) / "manifest.json"
    if not manifest.exists():
        return
    data = read_json(manifest, ArgumentError, "no manifest", "not a hairdigi dataset manifest ({exc})")
    if not isinstance(data, dict) or not isinstance(data.get("config"), dict):
        raise ArgumentError(f"{manifest}: not a hairdigi dataset manifest (no \"config\" object); choose "
                            f"another --out, or move the folder away to start afresh")


def check_dataset(args: argparse.Namespace) -> None:
    """``hairdigi dataset``: the output folder, and its manifest when resuming."""
    if args.out:
        check_output_dir(args.out, "--out", dataset_ok=True)
        check_dataset_folder(args.out)


def camera_sensitivities(text: str) -> str:
    """An argparse type: a named camera (``render.domain.bounds.CAMERAS``), ``cie``, or a CSV's path (read later)."""
    if text in CAMERAS or text == "cie" or text.lower().endswith((".csv", ".txt")):
        return text
    raise argparse.ArgumentTypeError(f"{text!r} is not a camera: choose one of {', '.join(CAMERAS)}, cie, "
                                     f"or give a CSV file of wavelength (nm), r, g, b")


def check_rig(args: argparse.Namespace) -> None:
    """``hairdigi rig``: the session folder, the swatch area, a RAW still to import, a spectral rig's parts."""
    check_session_folder(args.session, "--session")
    check_spectra(args)
    if args.roi:
        _parse_roi(args.roi, "--roi")
    if getattr(args, "still", None):
        # deferred: loads OpenCV and colour-science; the parser must not (hairdigi --help in 0.2 s)
        from hairdigi.hardware.cameras import RAW_EXTENSIONS

        still = check_input_file(args.still, "--still")
        if still.suffix.lower() not in RAW_EXTENSIONS:
            raise ArgumentError(f"--still {still}: not a RAW still ({', '.join(sorted(RAW_EXTENSIONS))}); "
                                "estimate images with hairdigi estimate")


def check_spectra(args: argparse.Namespace) -> None:
    """``--spectral``, ``--led`` and ``--sensor`` (``rig`` and ``app``): the simulated rig's with --spectral, a
    real rig's both together, and each a known spectrum or a readable CSV."""
    if args.spectral and not args.sim:
        raise ArgumentError("--spectral is the simulated rig's: add --sim (a real rig is spectral already)")
    for flag in ("led", "sensor"):
        if getattr(args, flag) is not None and args.sim and not args.spectral:
            raise ArgumentError(f"--{flag} goes with --spectral on the simulated rig; add --spectral or leave "
                                f"--{flag} out")
    if args.sim and not args.spectral:
        return
    declared = (args.led or SIM_LED, args.sensor or SIM_SENSOR) if args.sim else (args.led, args.sensor)
    problem = spectra_problem(*declared)
    if problem is not None:
        raise ArgumentError(problem)


def check_session_folder(path: str | os.PathLike, flag: str) -> Path:
    """A session folder: usable as an output folder, its ``captures`` a folder and its calibration a file."""
    p = check_output_dir(path, flag)
    captures, calibration = SessionFolder(p).captures, SessionFolder(p).calibration
    if captures.exists() and not captures.is_dir():
        raise ArgumentError(f"{flag} {p}: {captures} is a file, where the session keeps its captures folder; "
                            f"move that file away or choose another session folder")
    if calibration.is_dir():
        raise ArgumentError(f"{flag} {p}: {calibration} is a folder, where the session keeps its calibration "
                            f"file; move it away or choose another session folder")
    return p


def check_cache_writable() -> None:
    """The cache folder (``HAIRDIGI_CACHE``) must be writable before work that stores results there."""
    cache = cache_dir()
    try:
        _writable_folder(cache, "HAIRDIGI_CACHE", cache)
    except ArgumentError as exc:
        raise ArgumentError(f"{exc}; or set HAIRDIGI_CACHE to a writable folder") from None


def check_display() -> None:
    """A window needs a display: on Linux, a reachable X server or Wayland, or an offscreen Qt platform.

    Checked before Qt starts, since Qt aborts the process (exit 134) on a display it cannot open: a
    Wayland socket must exist; ``DISPLAY`` must be ``[host]:number[.screen]``, a local one must have its
    socket, a remote one (``localhost:10.0`` of an ssh -X session, ``remotehost:0``) must answer on its
    TCP port within ``DISPLAY_TIMEOUT_S``."""
    platform = os.environ.get("QT_QPA_PLATFORM", "")
    if not sys.platform.startswith("linux") or platform.split(":")[0] in ("offscreen", "minimal", "vnc", "eglfs",
                                                                         "linuxfb"):
        return
    fix = "run it on the desktop, or without one under a virtual X server: xvfb-run hairdigi app ..."
    wayland, display = os.environ.get("WAYLAND_DISPLAY"), os.environ.get("DISPLAY")
    wayland_problem = _wayland_problem(wayland) if wayland else None
    if wayland and wayland_problem is None:
        return
    if not display:
        if wayland_problem:
            raise ArgumentError(f"no display: {wayland_problem}, and DISPLAY is not set; {fix}")
        raise ArgumentError(f"no display: DISPLAY is not set (no X server or Wayland to open the window on); {fix}")
    problem = _x_display_problem(display)
    if problem:
        raise ArgumentError(f"no display: {problem}" + (f" (and {wayland_problem})" if wayland_problem else "")
                            + f"; {fix}")


DISPLAY_TIMEOUT_S = 3.0


def _wayland_problem(name: str) -> str | None:
    """Why ``WAYLAND_DISPLAY`` names no running compositor (its socket is missing), or None."""
    runtime = os.environ.get("XDG_RUNTIME_DIR", "")
    socket_path = Path(name) if os.path.isabs(name) else Path(runtime or "/nonexistent") / name
    if socket_path.is_socket():
        return None
    return f"WAYLAND_DISPLAY={name[:60]} names no running compositor (no socket {socket_path})"


def _x_display_problem(display: str) -> str | None:
    """Why ``DISPLAY`` names no X server this process can reach, or None."""
    shown = "".join(c if 32 <= ord(c) < 127 else "?" for c in display[:60])   # no escape reaches the terminal
    match = re.fullmatch(r"(?:(?P<proto>[A-Za-z]+)/)?(?P<host>[^:]*):(?P<number>\d+)(?:\.\d+)?", display)
    if not match:
        return f"DISPLAY={shown!r} is not a display name ([host]:number[.screen], e.g. :0)"
    host, number = match.group("host"), int(match.group("number"))
    if host in ("", "unix") and match.group("proto") in (None, "unix"):
        if not Path(f"/tmp/.X11-unix/X{number}").exists():
            return f"DISPLAY={shown} names no running X server (no /tmp/.X11-unix/X{number})"
        return None
    port = 6000 + number
    try:
        with socket.create_connection((host, port), timeout=DISPLAY_TIMEOUT_S):
            return None
    except OSError as exc:
        why = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
        where = "".join(c if 32 <= ord(c) < 127 else "?" for c in host[:60])
        return (f"DISPLAY={shown}: no X server answers at {where}:{port} ({why}; an ssh -X session that has "
                f"ended?)")


def _parse_roi(text: str, flag: str) -> tuple[int, int, int, int]:
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise ArgumentError(f"{flag} {text!r} must be x,y,w,h in pixels, e.g. 120,80,300,360") from None
    if x < 0 or y < 0 or w < 1 or h < 1:
        raise ArgumentError(f"{flag} {text}: x and y must be >= 0 and w, h >= 1 pixels")
    return x, y, w, h


def check_train(args: argparse.Namespace) -> None:
    """``hairdigi train``: dataset folders exist with readable manifests; the run folder is none of them."""
    for d in args.dataset:
        check_input_dir(d, "--dataset")
        check_dataset_folder(d)
    check_output_dir(args.out, "--out", {f"--dataset {d}": d for d in args.dataset})


def check_export(args: argparse.Namespace) -> None:
    """``hairdigi export-onnx``: the run folder exists; the model file is new or a model."""
    check_input_dir(args.run, "--run")
    check_output_file(args.out, "--out", (".onnx",), "an ONNX model", {"--run": args.run}, allow=(_models_folder(),))


#: ``evaluate``'s modes: at most one runs (``--dye --rig`` is the dye protocol on the simulated rig).
EVALUATE_MODES = tuple(EVALUATIONS)
#: Flags that go with one mode only.
EVALUATE_MODE_FLAGS = {"ship": ("rig", "appearance", "structures", "spectral", "instrument"), "lab": ("instrument",), "spectral_rig": ("instrument",), "no_variation": ("appearance",),
                       "default_shine": ("cycles",), "blender": ("structures",), "hidden_structures": ("structures", "rig", "instrument"),
                       "held_out": ("structures", "spectral")}


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def check_evaluate_modes(args: argparse.Namespace) -> None:
    """Contradictory modes (``--rig --cycles``) and flags without their mode are refused, not half obeyed."""
    chosen = [m for m in EVALUATE_MODES if getattr(args, m, None)]
    if chosen[:2] == ["dye", "rig"]:
        chosen = ["dye"] + chosen[2:]
    if len(chosen) > 1:
        raise ArgumentError(f"{' and '.join(map(_flag, chosen))} are different evaluations; run them one at a time")
    for flag, modes in EVALUATE_MODE_FLAGS.items():
        if getattr(args, flag, False) and not any(getattr(args, m, False) for m in modes) or (
                flag == "ship" and args.ship and getattr(args, "dye", False)):
            raise ArgumentError(f"{_flag(flag)} goes with {' or '.join(map(_flag, modes))}; add it or leave "
                                f"{_flag(flag)} out")
    if getattr(args, "structure", None) and not getattr(args, "rig", False):
        raise ArgumentError(f"--structure {args.structure} goes with --rig (--structures judges every mode at once); "
                            "add --rig or leave --structure out")


def check_evaluate(args: argparse.Namespace) -> None:
    """``hairdigi evaluate``: its modes, the model and the output folder."""
    check_evaluate_modes(args)
    if getattr(args, "held_out", None) is not None and args.held_out < 1:
        raise ArgumentError(f"--held-out {args.held_out}: a seed is a whole number >= 1 (the named cases use their own)")
    if args.model and not args.prepare_only:
        check_input_file(args.model, "--model")
    check_output_dir(args.out, "--out", {"--model": args.model})


def check_model_card(args: argparse.Namespace) -> None:
    """``hairdigi model-card``: its inputs are readable and neither the card nor its JSON twin is one."""
    inputs = {"--evaluation": args.evaluation, "--variants": args.variants, "--convergence": args.convergence,
              "--refine-bench": args.refine_bench, "--rig": args.rig, "--model": args.model}
    for flag, path in inputs.items():
        if path:
            check_input_file(path, flag)
    check_input_dir(args.run, "--run")
    out = check_output_file(args.out, "--out", (".md",), "Markdown", inputs, allow=(_models_folder(),))
    check_output_file(out.with_suffix(".json"), "--out (its .json twin)", (".json",), "JSON", inputs,
                      allow=(_models_folder(),))
    check_output_file(out.with_name("uncertainty.json"), "--out (the intervals beside it)", (".json",), "JSON",
                      inputs, allow=(_models_folder(),))
    evaluation = _json_object(args.evaluation, "--evaluation", "hairdigi evaluate's evaluation.json")
    if not isinstance(evaluation.get("buckets"), dict) or not isinstance(evaluation["buckets"].get("all"), dict):
        raise ArgumentError(f"--evaluation {args.evaluation}: holds no \"buckets\": {{\"all\": ...}}, so it is not "
                            f"hairdigi evaluate's evaluation.json; give that file")
    if args.rig:
        _json_object(args.rig, "--rig", "hairdigi evaluate --rig's JSON")
    history = _json_object(Path(args.run) / "history.json", "--run", "a training run's history.json")
    if not isinstance(history.get("epochs"), list) or not history["epochs"]:
        raise ArgumentError(f"--run {args.run}: its history.json holds no finished epoch; train it first")
    for flag, path in (("--variants", args.variants), ("--convergence", args.convergence),
                       ("--refine-bench", args.refine_bench)):
        if path:
            _check_number_table(path, flag)


def _json_object(path: str | os.PathLike, flag: str, what: str) -> dict:
    """A JSON file holding an object, or an ArgumentError naming ``flag`` and the file."""
    data = read_json(path, ArgumentError, f"no such file; give {what} as {flag}",
                     f"not JSON ({{exc}}); give {what} as {flag}")
    if not isinstance(data, dict):
        raise ArgumentError(f"{flag} {path}: holds a JSON {type(data).__name__}, not an object; give {what}")
    return data


def _check_number_table(path: str | os.PathLike, flag: str) -> None:
    """A CSV table whose cells are numbers, but for its ``model`` column (as ``model-card`` reads it)."""
    line = 1
    try:
        with open(path, newline="", encoding="utf-8") as f:
            for line, row in enumerate(csv.DictReader(f), 2):
                for key, value in row.items():
                    if key != "model":
                        float(value)
    except (ValueError, TypeError, csv.Error) as exc:   # UnicodeDecodeError is a ValueError
        raise ArgumentError(f"{flag} {path}: line {line} is not a row of numbers ({one_line(str(exc))[:80]}); "
                            f"give the CSV that hairdigi bench wrote") from None


def check_bench(args: argparse.Namespace) -> None:
    """``hairdigi bench``: the models exist and the output folder is usable."""
    for m in args.models or ():
        check_input_file(m, "--models")
    check_output_dir(args.out, "--out")


def check_folder_out(args: argparse.Namespace) -> None:
    """Commands whose only path is an output folder (``demo``)."""
    check_output_dir(args.out, "--out")


def check_app(args: argparse.Namespace) -> None:
    """``hairdigi app``: the session and tour folders, when given."""
    check_spectra(args)
    check_display()
    if args.session:
        check_session_folder(args.session, "--session")
    if args.tour:
        check_output_dir(args.tour, "--tour")


CHECKS: dict[str, Callable[[argparse.Namespace], None]] = {
    "render": check_render, "estimate": check_estimate, "dataset": check_dataset, "rig": check_rig,
    "train": check_train, "export-onnx": check_export, "evaluate": check_evaluate,
    "model-card": check_model_card, "bench": check_bench, "demo": check_folder_out, "app": check_app,
}


def check_args(args: argparse.Namespace) -> None:
    """Run the checks of ``args.command``, if it has any; raises ArgumentError naming the argument."""
    check = CHECKS.get(args.command)
    if check is not None:
        check(args)


def one_line(text: str) -> str:
    """A message on one line: newlines and runs of spaces become single spaces."""
    return " ".join(str(text).split())


def describe_os_error(exc: OSError) -> str:
    """An OSError as ``path: reason; fix``."""
    fixes = {errno.ENOSPC: "free some space or write to another disk",
             errno.EDQUOT: "free some space or write to another disk",
             errno.EACCES: "check its permissions or choose another path",
             errno.EPERM: "check its permissions or choose another path",
             errno.EROFS: "the disk is read-only; choose another path",
             errno.EISDIR: "it is a folder; give a file name",
             errno.ENOTDIR: "part of the path is a file, not a folder; check the path",
             errno.ENOENT: "check the path",
             errno.ENAMETOOLONG: "use a shorter name"}
    if exc.errno is None:
        return one_line(str(exc))
    where = f"{exc.filename}: " if exc.filename else ""
    fix = fixes.get(exc.errno)
    return one_line(f"{where}{exc.strerror or exc}" + (f"; {fix}" if fix else ""))


def is_expected(exc: BaseException) -> bool:
    """Whether ``exc`` is a failure the user can fix (one line, exit status 2) rather than a bug (its
    traceback, exit status 1).

    The user's: a :class:`~hairdigi.render.domain.errors.HairdigiError` (hairdigi's own errors, whose
    message names the problem and the fix), an ``OSError`` (the file system: a full disk, a permission,
    a missing path), a ``MemoryError``, and an argument argparse refuses. A plain ``ValueError``,
    ``TypeError``, ``KeyError`` or ``RuntimeError`` is a bug, numpy's and json's included: code that
    reads a user's data converts those into its module's ``HairdigiError`` where it reads them."""
    return isinstance(exc, (HairdigiError, OSError, MemoryError, argparse.ArgumentError,
                            argparse.ArgumentTypeError))
