"""Helpers of the hostile-input tests (``test_hostile_files.py``, ``test_hostile_dye_frames.py``):
a working folder with a record and a session, file snapshots, the one-line check, the CLI.
"""
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, RefinementRecord, write_record


CAPTURE = "20261124-101500-123"
HAIR = HairParams((190.0, 70.0, 40.0), 0.5, 0.3, 0.4)


def sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): sha(p) for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def one_line(code: int, capsys, *needles: str, expect_code: int = 2) -> str:
    """The command ended with ``expect_code`` and one stderr line holding every needle (no traceback)."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert code == expect_code, (code, err[-2000:])
    assert "Traceback" not in err and len(lines) == 1, err[-2000:]
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def estimate_record(sigma=(0.6, 0.9, 1.4), hair: HairParams = HAIR, **kw) -> EstimateRecord:
    return EstimateRecord(hair=hair, refinement=RefinementRecord(ran=True, sigma_a=tuple(map(float, sigma))), **kw)


def cli(*args, env=None, timeout=120, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hairdigi.app.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, cwd=cwd,
                          env={**os.environ, "OMP_WAIT_POLICY": "PASSIVE", **(env or {})})


def workspace(tmp_path, monkeypatch) -> Path:
    """A working folder: an estimate record, a rig session, a fresh library and no pre-library sessions."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(tmp_path / "lib.sqlite"))
    monkeypatch.setenv("HAIRDIGI_SESSIONS", str(tmp_path / "no-sessions"))
    write_record(tmp_path / "r.json", estimate_record())
    session = tmp_path / "s"
    (session / "captures").mkdir(parents=True)
    (session / "calibration.json").write_text(json.dumps({"kind": "calibration", "matrix": [[1, 0, 0]] * 3,
                                                          "method": "linear"}))
    (session / "captures" / f"{CAPTURE}.json").write_text(json.dumps({"id": CAPTURE, "image": f"{CAPTURE}.png",
                                                                      "image_sha256": "0" * 64}))
    write_record(session / "captures" / f"{CAPTURE}.result.json", estimate_record(capture=f"{CAPTURE}.png"))
    return tmp_path


def dye_record_json(name: str = "copper", deposit=(0.3, 0.6, 0.8), **extra) -> dict:
    pair = {"base": "b.json", "base_sha256": "0" * 64, "dyed": "d.json", "dyed_sha256": "1" * 64,
            "base_sigma_a": [0.5, 0.7, 1.0], "dyed_sigma_a": [0.8, 1.3, 1.8]}
    return {"kind": "dye", "schema_version": 1, "name": name, "deposit_sigma_a": list(deposit), "lift": 0.1,
            "lift_measured": False, "pairs": [pair], **extra}
