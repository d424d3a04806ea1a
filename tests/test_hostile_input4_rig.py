"""Careless and hostile input, fourth round (issue 45): stills, spectra, light frames and the display.

One numbered class of the issue per section. Most cases run the command line in this process (``main``);
the races and the display run real processes and real sockets. Every refused case is one stderr line and
exit 2, and leaves the working folder byte for byte as it was. Shared helpers: ``tests/hostile.py``.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hairdigi.app.cli import main
from hostile import one_line, snapshot


def grey_still(path: Path, side: int = 128) -> Path:
    """A readable DNG with no chart in view: imported, kept and blocked (its chart is missing)."""
    from hairdigi.hardware.sim_still import write_raw_still

    return write_raw_still(path, np.full((side, side, 3), 0.3))


@pytest.fixture
def ws(tmp_path, monkeypatch) -> Path:
    monkeypatch.chdir(tmp_path)
    grey_still(tmp_path / "grey.dng")
    return tmp_path


# --- 2. two captures, one id -----------------------------------------------------------------------------
#: A ``rig --still`` whose clock stands still: every capture id it draws is the same millisecond's.
FROZEN_STILL = """
import sys, time, types
import hairdigi.hardware.capture as capture
capture.time = types.SimpleNamespace(time=lambda: 1795000000.5, strftime=time.strftime, localtime=time.localtime)
from hairdigi.app.cli import main
sys.exit(main(["rig", "--still", sys.argv[1], "--session", sys.argv[2]]))
"""


def test_two_processes_importing_stills_in_the_same_millisecond_keep_both(ws):
    env = {**os.environ, "OMP_WAIT_POLICY": "PASSIVE"}
    stills = [grey_still(ws / f"IMG_{i}.dng", 96 + 32 * i) for i in range(2)]
    runs = [subprocess.Popen([sys.executable, "-c", FROZEN_STILL, str(still), str(ws / "s")], env=env,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for still in stills]
    outs = [run.communicate(timeout=120) for run in runs]
    assert [run.returncode for run in runs] == [2, 2], outs     # each kept, blocked: no chart in a grey still
    captures = ws / "s" / "captures"
    records = sorted(p for p in captures.glob("*.json") if not p.name.endswith(".result.json"))
    assert len(records) == 2, sorted(p.name for p in captures.iterdir())
    kept = {json.loads(r.read_text())["image"] for r in records}
    assert sorted((captures / name).read_bytes() for name in kept) == sorted(s.read_bytes() for s in stills)
    assert len(list(captures.glob("*.result.json"))) == 2
    assert not list(captures.glob(".*")), "a capture id's reservation was left behind"


# --- 5. rig --still: an option that does not apply is refused, one that does is honoured ----------------
@pytest.mark.parametrize("flags, needle", [
    (["--sim"], "--sim"), (["--sim", "--spectral"], "--sim --spectral"), (["--genicam"], "--genicam"),
    (["--genicam", "fake-1"], "--genicam"), (["--roi", "1,1,8,8"], "--roi"), (["--port", "/dev/null"], "--port"),
    (["--camera", "2"], "--camera"), (["--dead", "1"], "--dead"), (["--spp", "4"], "--spp"),
    (["--structure", "read"], "--structure read"),
])
def test_rig_still_refuses_what_does_not_apply_to_a_still(ws, capsys, flags, needle):
    before = snapshot(ws)
    code = main(["rig", "--still", "grey.dng", "--session", "s", *flags])
    one_line(code, capsys, needle, "--still" if needle != "--structure read" else "single-light frames")
    assert snapshot(ws) == before and not (ws / "s").exists()


@pytest.mark.slow
def test_rig_still_reads_a_declared_camera_and_leds(ws, capsys):
    """``--led`` and ``--sensor`` with ``--still``: the still's record is read in the declared camera's RGB."""
    from hairdigi.hardware.sim_rig import SimRig
    from hairdigi.hardware.sim_still import write_raw_still

    still = write_raw_still(ws / "rig.dng", (SimRig(spp=4).radiance() * 0.8).repeat(2, 0).repeat(2, 1))
    assert main(["rig", "--still", str(still), "--session", "s", "--led", "LED-B4", "--sensor", "nikon-5100"]) == 0
    assert "read in the camera's RGB (nikon-5100 under LED-B4" in capsys.readouterr().out
    result = json.loads(next((ws / "s" / "captures").glob("*.result.json")).read_text())
    assert result["spectral"]["camera"] == "nikon-5100" and result["spectral"]["led"] == "LED-B4"


# --- 10. a still fills the disk; an unreadable still leaves nothing behind ------------------------------
def test_a_huge_sparse_file_given_as_a_still_is_refused_before_the_copy(ws, capsys):
    before = snapshot(ws)   # (not of the huge file: a snapshot would read its 20 GB)
    huge = ws / "big" / "huge.dng"
    huge.parent.mkdir()
    with open(huge, "wb") as f:
        f.truncate(20 * 10 ** 9)   # 20 GB, sparse: no disk used until something copies it
    one_line(main(["rig", "--still", str(huge), "--session", "s"]), capsys, "huge.dng", "20000 MB", "nothing was copied")
    huge.unlink()
    huge.parent.rmdir()
    assert snapshot(ws) == before and not (ws / "s").exists()


def _unreadable_stills(ws: Path) -> dict[str, Path]:
    import cv2

    from hairdigi.hardware.sim_still import write_raw_still

    picture = np.random.default_rng(0).integers(0, 255, (96, 96, 3), np.uint8)
    cv2.imwrite(str(ws / "p.jpg"), picture)
    cv2.imwrite(str(ws / "p.png"), picture)
    grey = (ws / "grey.dng").read_bytes()
    files = {"jpeg.dng": (ws / "p.jpg").read_bytes(), "png.nef": (ws / "p.png").read_bytes(),
             "truncated.dng": grey[:len(grey) // 3], "empty.dng": b""}
    out = {name: ws / name for name in files}
    for name, data in files.items():
        out[name].write_bytes(data)
    out["tiny.dng"] = write_raw_still(ws / "tiny.dng", np.full((2, 2, 3), 0.3))
    out["small.dng"] = write_raw_still(ws / "small.dng", np.full((32, 32, 3), 0.3))
    return out


def test_a_still_that_cannot_be_read_leaves_nothing_in_the_session(ws, capsys):
    main(["rig", "--still", "grey.dng", "--session", "s"])   # a session with one capture already
    capsys.readouterr()
    for name, still in _unreadable_stills(ws).items():
        for session in ("s", "new"):
            before = snapshot(ws)
            one_line(main(["rig", "--still", str(still), "--session", session]), capsys, name, "nothing was kept")
            assert snapshot(ws) == before, (name, session)
            assert not (ws / "new").exists(), name
