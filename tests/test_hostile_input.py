"""Careless and hostile input, through the real command line, one process per case.

Every case checks three things: the exit status; stderr (one line naming the problem, never a
traceback; warnings for the cases that succeed); and that every file in the working folder, the
inputs first, is byte for byte as it was (nothing overwritten, no half-written or temporary file
left). Renders are tiny; most cases stop in the argument checks, before anything is rendered.
"""
import codecs
import hashlib
import json
import re
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from deadlines import within

ROOT = Path(__file__).resolve().parent.parent
SIM = (200, 150)
FRESH = dict(PYTHONPATH=str(ROOT), OMP_WAIT_POLICY="PASSIVE", PYTHONDONTWRITEBYTECODE="1")


# --- running the command line ----------------------------------------------------------------
def hairdigi(*args: str, cwd: Path, prelude: str | None = None, timeout: float = 180) -> subprocess.CompletedProcess:
    """``python -m hairdigi.app.cli ARGS`` in ``cwd``; with ``prelude``, that Python runs first (a fault to inject)."""
    if prelude is None:
        cmd = [sys.executable, "-m", "hairdigi.app.cli", *args]
    else:
        cmd = [sys.executable, "-c", f"{prelude}\nimport sys\nfrom hairdigi.app.cli import main\nsys.exit(main(sys.argv[1:]))",
               *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, **FRESH})


class Reader:
    """A child's pipe (opened in bytes), read in a thread as it comes, so that a test waits for what the
    child says rather than for a fixed time."""

    def __init__(self, pipe) -> None:
        self.text, self._ended = "", False
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(pipe,), daemon=True)
        self._thread.start()

    def _read(self, pipe) -> None:
        decoder = codecs.getincrementaldecoder("utf-8")("replace")
        while chunk := os.read(pipe.fileno(), 4096):
            with self._changed:
                self.text += decoder.decode(chunk)
                self._changed.notify_all()
        with self._changed:
            self._ended = True
            self._changed.notify_all()

    def wait_for(self, piece: str, timeout: float) -> bool:
        """Whether ``piece`` comes within ``timeout`` s; False at once if the pipe ends without it."""
        with self._changed:
            self._changed.wait_for(lambda: piece in self.text or self._ended, timeout)
            return piece in self.text

    def all(self, timeout: float = 60) -> str:
        """Everything the child wrote, once it has closed the pipe (at most ``timeout`` s from now)."""
        self._thread.join(timeout)
        return self.text


_children: list[subprocess.Popen] = []


def started(cmd: list[str], cwd: Path) -> subprocess.Popen:
    """``cmd`` started in ``cwd`` with its stdout and stderr piped (bytes: read them with ``Reader``);
    killed at the end of the test if it is still running then."""
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, **FRESH})
    _children.append(proc)
    return proc


@pytest.fixture(autouse=True)
def _no_child_left():
    yield
    while _children:
        proc = _children.pop()
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def snapshot(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder`` (hidden and temporary ones included), by relative path."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def refused(run: subprocess.CompletedProcess, *needles: str, code: int = 2) -> str:
    """The run ended with ``code`` and exactly one stderr line, holding every needle and no traceback."""
    lines = run.stderr.strip().splitlines()
    assert run.returncode == code, (run.returncode, run.stderr[-2000:])
    assert "Traceback" not in run.stderr and len(lines) == 1, run.stderr[-2000:]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


# --- the working folder ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def materials(tmp_path_factory):
    """A parameter file, a simulated rig frame with the chart in view, and a calibration profile from it."""
    from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN
    from hairdigi.render.camera_model import spread_glints
    from hairdigi.inference.calibration import calibrate
    from hairdigi.render.domain import rig_geometry
    from hairdigi.render.camera_model import CameraModel, sensor_response
    from hairdigi.render.chart import colorchecker_reflectances
    from hairdigi.render.renderer import Renderer, SceneSpec

    root = tmp_path_factory.mktemp("materials")
    (root / "p.json").write_text(json.dumps({"hair": DEFAULT_HIDDEN.to_dict()}))
    spec = SceneSpec("swatch", framing="rig", chart=tuple(map(tuple, colorchecker_reflectances())),
                     target=rig_geometry.RIG_TARGET, half_width=rig_geometry.RIG_HALF_WIDTH, strands=1000)
    linear = spread_glints(Renderer(max_cached=1).render(DEFAULT_HIDDEN, spec, SIM, 4, seed=1).linear)
    frame = sensor_response(linear, CameraModel(), np.random.default_rng(0))
    cv2.imwrite(str(root / "photo.png"), frame[..., ::-1])
    profile = calibrate(frame, settings={"camera": "sim-rig", "exposure_ev": 0.0, "gain": 1.0})
    (root / "cal.json").write_text(json.dumps(profile.to_json()))
    return root


@pytest.fixture
def expect() -> set[str]:
    """Files a test makes or is meant to write in its working folder; every other file must not change."""
    return set()


@pytest.fixture
def ws(materials, tmp_path, expect):
    """A fresh working folder holding the materials; afterwards, every file in it but those in
    ``expect`` is byte for byte as before, and no other file has appeared."""
    for p in materials.iterdir():
        shutil.copy(p, tmp_path / p.name)
    before = snapshot(tmp_path)
    yield tmp_path
    after = snapshot(tmp_path)
    assert {k: v for k, v in after.items() if k not in expect} == before, "files changed or left behind"


def no_refine() -> list[str]:
    """``--no-refine``: the encoder alone is enough here, and 6 s faster (an estimate without the
    option fails its parse, and the test with it)."""
    return ["--no-refine"]


# --- 1. outputs never overwrite inputs, and are named for what they hold ------------------------
@pytest.mark.parametrize("args, needles", [
    (["render", "--params", "p.json", "--out", "p.json"], ["--out p.json is also the --params input"]),
    (["estimate", "photo.png", "--out", "photo.png"], ["--out photo.png is also the image input"]),
    (["estimate", "photo.png", "--calibration", "cal.json", "--out", "cal.json"], ["also the --calibration input"]),
    (["render", "--params", "p.json", "--out", "x.png", "--exr", "x.png"], ["--exr x.png is also the --out output"]),
    (["render", "--params", "p.json", "--out", "o.jpg"], ["--out o.jpg", "name it with .png"]),
    (["render", "--params", "p.json", "--out", "o.txt", "--exr", "o.exr"], ["--out o.txt", ".png"]),
    (["estimate", "photo.png", "--out", "e.txt"], ["--out e.txt", "name it with .json"]),
])
def test_outputs_never_replace_inputs_or_each_other(ws, args, needles):
    refused(hairdigi(*args, cwd=ws), f"hairdigi {args[0]}: error:", *needles)


def test_an_output_linked_to_an_input_is_refused(ws):
    (ws / "link.png").symlink_to(ws / "p.json")
    refused(hairdigi("render", "--params", "p.json", "--out", "link.png", cwd=ws), "is also the --params input")


# --- 2. the swatch, not the chart -----------------------------------------------------------
def test_estimate_finds_the_swatch_beside_the_chart_and_records_it(ws, expect):
    from hairdigi.render.domain.rig_geometry import swatch_roi

    run = hairdigi("estimate", "photo.png", "--out", "e.json", *no_refine(), cwd=ws)
    expect |= {"e.json"}
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr[-2000:]
    x, y, w, h = json.loads((ws / "e.json").read_text())["provenance"]["roi"]
    tx, ty, tw, th = swatch_roi(SIM)
    shared = max(0, min(x + w, tx + tw) - max(x, tx)) * max(0, min(y + h, ty + th) - max(y, ty))
    assert shared >= 0.9 * tw * th and x + w < SIM[0] * 0.55, (x, y, w, h)   # the chart is right of centre


# --- 4. parameters are real numbers, RGB exactly three -------------------------------------
@pytest.mark.parametrize("field, value, needle", [
    ("dye_rgb", "123", "dye_rgb must hold 3 values"),
    ("dye_rgb", [[1, 2, 3]], "dye_rgb must hold 3 values"),
    ("dye_concentration", True, "dye_concentration must be a number, got true"),
    ("melanin_ratio", "0.5", "melanin_ratio must be a number, got the string '0.5'"),
])
def test_loose_parameter_types_are_refused(ws, expect, field, value, needle):
    data = json.loads((ws / "p.json").read_text())
    data["hair"][field] = value
    (ws / "loose.json").write_text(json.dumps(data))
    expect |= {"loose.json"}
    refused(hairdigi("render", "--params", "loose.json", "--out", "o.png", "--size", "16", "--spp", "1", cwd=ws),
            "loose.json:", needle)


# --- 5. no silent defaults, no black images -------------------------------------------------
@pytest.mark.parametrize("extra, needles", [
    (["--size", "0"], ["argument --size: 0 is outside 8 to"]),
    (["--spp", "0"], ["argument --spp: 0 is outside 1 to"]),
    (["--depth", "0"], ["argument --depth: 0 is outside 2 to"]),
    (["--camera", "20,nan"], ["--camera 20,nan", "finite"]),
    (["--camera", "20,45,inf"], ["--camera 20,45,inf", "finite"]),
    (["--camera", "20,45,1e9"], ["camera distance 1e+09 must be between"]),
    (["--camera", "0,0,0.01"], ["camera distance 0.01 must be between"]),
])
def test_render_numbers_that_would_be_ignored_or_give_black_are_refused(ws, extra, needles):
    refused(hairdigi("render", "--params", "p.json", "--out", "o.png", *extra, cwd=ws), *needles)


def test_dataset_size_zero_is_refused_not_recorded(ws):
    refused(hairdigi("dataset", "--size", "0", "--out", "ds", cwd=ws), "argument --size: 0 is outside")
    assert not (ws / "ds").exists()


# --- 6. one line, not a traceback -----------------------------------------------------------
@pytest.mark.parametrize("args, needles", [
    (["render", "--params", ".", "--out", "o.png"], ["--params .: is a folder"]),
    (["estimate", "photo.png", "--calibration", "sub", "--out", "e.json"], ["--calibration sub: is a folder"]),
    (["render", "--params", "p.json", "--out", "sub"], ["--out sub: is a folder"]),
    (["render", "--params", "p.json", "--out", "new/"], ["--out new/: is a folder"]),
    (["render", "--params", "p.json", "--out", "p.json/o.png"], ["p.json is a file, so no folder can be made"]),
    (["render", "--params", "p.json", "--out", "o.png", "--size", "100000"], ["argument --size: 100000 is outside"]),
    (["render", "--params", "p.json", "--out", "o.png", "--spp", "1000000000"], ["argument --spp"]),
    (["render", "--params", "p.json", "--out", "o.png", "--size", "4096", "--spp", "65536"], ["samples, over the limit"]),
    (["dataset", "--shard-size", "0", "--out", "ds"], ["argument --shard-size: 0 is outside 1 to"]),
    (["rig", "--sim", "--dead", "5", "--session", "s"], ["argument --dead: 5 is outside 0 to 2"]),
])
def test_bad_paths_and_numbers_are_one_line(ws, args, needles):
    (ws / "sub").mkdir()
    refused(hairdigi(*args, cwd=ws), *needles)
    assert not (ws / "new").exists() and not (ws / "ds").exists() and not (ws / "s").exists()


def test_unreadable_inputs_are_one_line(ws, expect):
    (ws / "bad.json").write_bytes(b'{"dye_rgb": "\xe9"}')        # not UTF-8
    os.mkfifo(ws / "pipe.json")                                   # would block a reader forever
    expect |= {"bad.json"}
    refused(hairdigi("render", "--params", "bad.json", "--out", "o.png", cwd=ws), "bad.json:", "not UTF-8")
    refused(hairdigi("render", "--params", "pipe.json", "--out", "o.png", cwd=ws, timeout=60), "not a regular file")
    (ws / "pipe.json").unlink()
    if os.geteuid() != 0:   # root reads anything: the permission case needs an ordinary user
        (ws / "locked.json").write_text("{}")
        (ws / "locked.json").chmod(0)
        expect.add("locked.json")
        refused(hairdigi("render", "--params", "locked.json", "--out", "o.png", cwd=ws), "cannot be read")
        (ws / "locked.json").chmod(0o644)


@pytest.mark.parametrize("field, value, needle", [
    ("matrix", "abc", "'matrix' is not 3 rows of finite numbers"),
    ("matrix", [[1, 2], [3, 4], [5, 6]], "'matrix' does not fit method"),
    ("time", "yesterday", "'time' is 'yesterday'"),
    ("method", 5, "'method' is 5"),
])
def test_corrupt_calibration_fields_are_named(ws, expect, field, value, needle):
    profile = json.loads((ws / "cal.json").read_text())
    profile[field] = value
    (ws / "bad-cal.json").write_text(json.dumps(profile))
    expect |= {"bad-cal.json"}
    refused(hairdigi("estimate", "photo.png", "--calibration", "bad-cal.json", "--out", "e.json", cwd=ws),
            "bad-cal.json:", needle, "calibrate again")


def test_a_malformed_dataset_manifest_is_one_line(ws, expect):
    (ws / "ds").mkdir()
    (ws / "ds" / "manifest.json").write_text('{"config": ')
    expect |= {"ds/manifest.json"}
    refused(hairdigi("dataset", "--n", "1", "--size", "16", "--spp", "1", "--out", "ds", cwd=ws),
            "manifest.json: not a hairdigi dataset manifest")


def test_a_full_or_read_only_disk_is_found_before_rendering(ws):
    full = ("import collections, shutil\n"
            "shutil.disk_usage = lambda p: collections.namedtuple('U', 'total used free')(1 << 30, 1 << 30, 0)")
    refused(hairdigi("render", "--params", "p.json", "--out", "o.png", cwd=ws, prelude=full),
            "--out o.png", "is full", "free some space")
    if os.geteuid() == 0:   # root writes anywhere: make the folder look read-only to the check
        locked = ("import os\n_a = os.access\n"
                  f"os.access = lambda p, m, **k: os.path.abspath(p) != {str(ws / 'ro')!r} and _a(p, m, **k)")
    else:
        locked = None
    (ws / "ro").mkdir()
    (ws / "ro").chmod(0o555)
    try:
        refused(hairdigi("render", "--params", "p.json", "--out", "ro/o.png", "--size", "16", "--spp", "1",
                         cwd=ws, prelude=locked),
                "the folder", "is not writable")
    finally:
        (ws / "ro").chmod(0o755)


def test_a_disk_that_fills_during_the_render_is_one_line_and_leaves_nothing(ws):
    fills = ("import errno, tempfile\n"
             "def _full(*a, **k): raise OSError(errno.ENOSPC, 'No space left on device', k.get('dir'))\n"
             "tempfile.mkstemp = _full")
    refused(hairdigi("render", "--params", "p.json", "--out", "o.png", "--size", "16", "--spp", "1",
                     "--strands", "100", cwd=ws, prelude=fills), "No space left on device", "free some space")


def as_program(prelude: str) -> str:
    """Code for ``python -c``: ``prelude``, then ``python -m hairdigi.app.cli ARGS`` as ``-m`` runs it."""
    return f"{prelude}\nimport runpy\nrunpy.run_module('hairdigi.app.cli', run_name='__main__', alter_sys=True)\n"


#: Prints "loading mitsuba" when the program starts to import Mitsuba: a Ctrl-C sent on that line lands
#: after Python is up, while Mitsuba loads (render.variant holds it until the import returns).
SAYS_WHEN_LOADING_MITSUBA = """\
import importlib.abc, sys

class Says(importlib.abc.MetaPathFinder):
    said = False

    def find_spec(self, name, path=None, target=None):
        if name == "mitsuba" and not self.said:
            self.said = True
            print("loading mitsuba", flush=True)
        return None   # the import goes on as usual

sys.meta_path.insert(0, Says())"""

#: Prints "rendering" as each ``mitsuba.render`` call starts, inside the renderer's held block: a Ctrl-C
#: sent on that line is delivered when the call returns (render.domain.interrupt). Mitsuba is loaded as
#: the program loads it (render.variant), after the start-up's thread budget.
SAYS_WHEN_RENDERING = """\
from hairdigi.render.domain.threads import start_up
start_up()
from hairdigi.render.variant import mi
_render = mi.render

def render(*a, **k):
    print("rendering", flush=True)
    return _render(*a, **k)

mi.render = render"""


def test_ctrl_c_while_starting_or_working_is_one_line_and_130(ws, expect):
    # while the libraries load
    proc = started([sys.executable, "-c", as_program(SAYS_WHEN_LOADING_MITSUBA), "render", "--params", "p.json",
                    "--out", "o.png"], cwd=ws)
    out, err = Reader(proc.stdout), Reader(proc.stderr)
    assert out.wait_for("loading mitsuba", 120), err.all()[-2000:]
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=60)
    assert proc.returncode == 130 and err.all().strip() == "hairdigi render: interrupted", err.text[-2000:]
    # while the command works: a dataset, its manifest written, rendering its first swatch
    proc = started([sys.executable, "-c", as_program(SAYS_WHEN_RENDERING), "dataset", "--n", "400", "--size", "16",
                    "--spp", "1", "--strands", "50", "--shard-size", "400", "--workers", "1", "--out", "ds"], cwd=ws)
    out, err = Reader(proc.stdout), Reader(proc.stderr)
    assert out.wait_for("rendering", 120), err.all()[-2000:]
    assert (ws / "ds" / "manifest.json").exists()
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=60)
    expect |= {"ds/manifest.json"}
    text = err.all()
    assert proc.returncode == 130, text[-2000:]
    assert "Traceback" not in text and text.strip().splitlines()[-1] == "hairdigi dataset: interrupted", text[-2000:]


# --- 7. stale calibration is flagged --------------------------------------------------------
def test_a_stale_or_mismatched_calibration_is_flagged(ws, expect):
    profile = json.loads((ws / "cal.json").read_text())
    profile["time"] -= 3 * 24 * 3600
    (ws / "old.json").write_text(json.dumps(profile))
    # a capture saved by the rig, with its record: taken at another exposure than the calibration
    shutil.copy(ws / "photo.png", ws / "cap.png")
    (ws / "cap.json").write_text(json.dumps({
        "image_sha256": hashlib.sha256((ws / "cap.png").read_bytes()).hexdigest(),
        "captured": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "frame_meta": {"camera": "sim-rig", "camera_model": {"exposure_ev": 1.0, "gain": 1.0}}}))
    expect |= {"old.json", "cap.png", "cap.json", "e.json", "f.json"}
    run = hairdigi("estimate", "photo.png", "--calibration", "old.json", "--out", "e.json", *no_refine(), cwd=ws)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert re.search(r"warning: calibration: the calibration is 72\.\d h old \(limit 8 h\)", run.stderr)
    run = hairdigi("estimate", "cap.png", "--calibration", "cal.json", "--out", "f.json", *no_refine(), cwd=ws)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert "warning: calibration: settings changed since calibration: exposure_ev" in run.stderr


# --- 8. huge images -------------------------------------------------------------------------
def measured(args: list[str], cwd: Path) -> tuple[subprocess.CompletedProcess, float, float]:
    """Run the CLI alone under a small parent, so its peak RSS is its own: (run, seconds, peak MB)."""
    probe = ("import json, resource, subprocess, sys, time\n"
             "t = time.perf_counter()\n"
             "r = subprocess.run([sys.executable, '-m', 'hairdigi.app.cli', *sys.argv[1:]], capture_output=True, text=True)\n"
             "print(json.dumps({'rc': r.returncode, 'err': r.stderr, 'out': r.stdout, "
             "'s': time.perf_counter() - t, 'mb': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}))")
    outer = subprocess.run([sys.executable, "-c", probe, *args], cwd=cwd, capture_output=True, text=True,
                           timeout=900, env={**os.environ, **FRESH})
    r = json.loads(outer.stdout)
    return subprocess.CompletedProcess(args, r["rc"], r["out"], r["err"]), r["s"], r["mb"]


def test_a_20000_px_png_is_refused_in_seconds_and_little_memory(ws, expect):
    from test_preprocess import flat_png

    flat_png(ws / "huge.png", 20000, 20000)
    expect |= {"huge.png"}
    run, seconds, mb = measured(["estimate", "huge.png", "--out", "e.json"], ws)
    refused(run, "huge.png: 20000x20000 px is more than hairdigi decodes")
    assert seconds < within(30) and mb < 2048, (seconds, mb)


def test_a_6000_by_4000_jpeg_is_estimated_in_seconds(ws, expect):
    frame = cv2.imread(str(ws / "photo.png"))
    cv2.imwrite(str(ws / "big.jpg"), cv2.resize(frame, (6000, 4000), interpolation=cv2.INTER_CUBIC),
                [cv2.IMWRITE_JPEG_QUALITY, 90])
    expect |= {"big.jpg", "e.json"}
    run, seconds, mb = measured(["estimate", "big.jpg", "--out", "e.json", *no_refine()], ws)
    assert run.returncode == 0 and "Traceback" not in run.stderr, run.stderr[-2000:]
    assert seconds < within(30) and mb < 2048, (seconds, mb)
    x, y, w, h = json.loads((ws / "e.json").read_text())["provenance"]["roi"]
    assert 0.2 < w / 6000 < 0.5 and x + w < 3300, (x, y, w, h)   # the swatch, in full-size pixels


# --- the installed entry point ----------------------------------------------------------------
def test_the_hairdigi_entry_point_behaves_the_same(ws):
    exe = shutil.which("hairdigi", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("hairdigi is not installed in this environment")
    run = subprocess.run([exe, "render", "--params", "p.json", "--out", "o.jpg"], cwd=ws, capture_output=True,
                         text=True, timeout=180, env={**os.environ, **FRESH})
    refused(run, "hairdigi render: error: --out o.jpg", "name it with .png")


def test_profile_warnings_follow_the_one_staleness_rule(materials):
    """In process: the rule behind the warnings above (``calibration.staleness``), and its edges."""
    from hairdigi.inference.calibration import STALE_AFTER_S, profile_warnings

    from hairdigi.render.domain.records import CalibrationProfile

    profile = CalibrationProfile.from_json(json.loads((materials / "cal.json").read_text()))
    now = profile.time
    assert profile_warnings(profile, profile.settings, now + STALE_AFTER_S - 60) == []
    late = profile_warnings(profile, None, now + STALE_AFTER_S + 3600)
    assert len(late) == 1 and "h old (limit 8 h)" in late[0] and "calibrate again" in late[0]
    other = profile_warnings(profile, {**profile.settings, "gain": 2.0}, now)
    assert len(other) == 1 and "settings changed since calibration: gain" in other[0]
    assert "check the computer's clock" in profile_warnings(profile, None, now - 3600)[0]
