"""Careless and hostile input, third round (issue 30): export, the library, dye development, single-light frames.

One numbered class of the issue per section. Most cases run the command line in this process
(``main``), which is what a subprocess would run, minus the start-up; cases that may hang (a FIFO)
or need a second process (a lock) run it in a subprocess with a timeout. Every refused case is one
stderr line and exit 2, and leaves the files it was pointed at byte for byte as they were.
"""
import csv
import hashlib
import json
import os
import socket
import sqlite3
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord, RefinementRecord, write_record

ROOT = Path(__file__).resolve().parent.parent
CAPTURE = "20261124-101500-123"
HAIR = HairParams((190.0, 70.0, 40.0), 0.5, 0.3, 0.4)


# --- helpers ---------------------------------------------------------------------------------------
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


@pytest.fixture
def ws(tmp_path, monkeypatch):
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


# --- 1. data loss, exit 0 --------------------------------------------------------------------------
@pytest.mark.parametrize("out, needle", [
    ("r.json", "record input"),                           # the record itself
    ("s/calibration.json", ".mtlx"),
    (f"s/captures/{CAPTURE}.result.json", ".mtlx"),
    (f"s/captures/{CAPTURE}.mtlx", "rig session"),
    ("look.txt", ".mtlx"),                                # no extension checked
    ("lib.sqlite", ".mtlx"),
])
def test_export_never_writes_over_its_record_or_a_session(ws, capsys, out, needle):
    before = snapshot(ws)
    one_line(main(["export", "r.json", "--format", "materialx", "--out", out]), capsys, "--out", needle)
    assert snapshot(ws) == before


def test_export_default_output_never_replaces_a_record_named_like_it(ws, capsys):
    write_record(ws / "look.py", estimate_record())        # a record named look.py, exported as Blender
    before = snapshot(ws)
    one_line(main(["export", "look.py", "--format", "blender"]), capsys, "look.py", "record input")
    assert snapshot(ws) == before


def test_library_export_never_writes_over_the_library_or_a_session(ws, capsys):
    assert main(["library", "import", "r.json"]) == 0
    capsys.readouterr()
    before = snapshot(ws)
    for args, needle in ((["--csv", "lib.sqlite"], "--csv"),                       # the library itself
                         (["--csv", f"s/captures/{CAPTURE}.json"], "--csv"),
                         (["--csv", f"s/captures/{CAPTURE}.csv"], "rig session"),
                         (["--csv", "x.csv", "--xlsx", "x.csv"], "--xlsx"),        # one name for both
                         (["--xlsx", "r.json"], "--xlsx")):
        one_line(main(["library", "export", *args]), capsys, needle)
        assert snapshot(ws) == before, args
    # the library file is refused even under a name with the right extension (a copy named .csv)
    (ws / "copy.csv").write_bytes((ws / "lib.sqlite").read_bytes())
    one_line(main(["library", "export", "--csv", "copy.csv"]), capsys, "SQLite database")


def test_dye_card_never_writes_its_table_over_the_dye_or_a_session(ws, capsys):
    (ws / "copper.json").write_text(json.dumps(dye_record_json()))
    before = snapshot(ws)
    one_line(main(["dye", "card", "copper.json", "--out", "copper.png"]), capsys, "JSON table", "dye input")
    one_line(main(["dye", "card", "copper.json", "--out", "s/calibration.png"]), capsys, "calibration of the rig")
    assert snapshot(ws) == before


def test_dye_apply_checks_the_hairstyles_it_writes_beside_the_render(ws, capsys):
    (ws / "copper.json").write_text(json.dumps(dye_record_json()))
    write_record(ws / "look-wavy.png", estimate_record())     # a base record named like a hairstyle image
    before = snapshot(ws)
    one_line(main(["dye", "apply", "copper.json", "--base", "look-wavy.png", "--out", "p.json", "--render", "look.png",
                   "--scene", "wavy"]), capsys, "--scene wavy", "--base input")
    assert snapshot(ws) == before


def test_dye_panel_never_saves_one_dye_over_another(tmp_path):
    from hairdigi.app.dye.model import dye_path

    saved = []
    for name in ["Copper 7.4", "Copper/7.4", "Copper-7.4", "染料", "色", "dye", ".json"]:
        path = dye_path(tmp_path, name)
        assert path not in saved, (name, path)
        path.write_text(json.dumps(dye_record_json(name)))
        saved.append(path)
    assert dye_path(tmp_path, "Copper/7.4") == saved[1]          # the same dye again replaces its own file
    assert dye_path(tmp_path, "色") == saved[4]


# --- 2. formula injection ------------------------------------------------------------------------------
def test_exported_tables_neutralise_formulas(ws, capsys):
    from openpyxl import load_workbook

    from hairdigi.app.library.store import Library

    assert main(["library", "import", "r.json"]) == 0
    with Library() as lib:
        sid = lib.all()[0].id
    hostile = ['=HYPERLINK("http://evil/x","click")', "=cmd|' /C calc'!A0", "+1+1", "-2+3", "@SUM(A1)", "\tx", "\rx"]
    for i, text in enumerate(hostile):
        capsys.readouterr()
        assert main(["library", "note", sid, "--", text]) == 0
        assert main(["library", "tag", sid, f"t{i}"]) == 0
        assert main(["library", "export", "--csv", f"t{i}.csv", "--xlsx", f"t{i}.xlsx"]) == 0
        row = next(csv.DictReader(open(ws / f"t{i}.csv", newline="", encoding="utf-8")))
        assert row["note"] == "'" + text, row["note"]
        sheet = load_workbook(ws / f"t{i}.xlsx").active
        header = [c.value for c in sheet[1]]
        cell = sheet.cell(2, header.index("note") + 1)
        assert cell.data_type != "f" and cell.value.startswith("'") and len(cell.value) == len(text) + 1, cell.value  # XML reads CR as LF
    # numbers stay numbers
    assert isinstance(sheet.cell(2, header.index("sigma_r") + 1).value, float)


# --- 5. device files and FIFOs as inputs ----------------------------------------------------------------
@pytest.mark.parametrize("args", [
    ["library", "find", "--near", "/dev/zero"],
    ["export", "/dev/zero", "--format", "materialx", "--out", "z.mtlx"],
    ["library", "import", "/dev/zero"],
])
def test_device_files_are_refused_before_a_byte_is_read(ws, capsys, args):
    start = time.perf_counter()
    one_line(main(args), capsys, "/dev/zero")
    assert time.perf_counter() - start < 30


def test_device_file_as_a_dye_target_or_record_is_refused(ws, capsys):
    from hairdigi.inference.dye import DyeError, target_colour
    from hairdigi.render.domain.files import read_json
    from hairdigi.render.domain.records import RecordError, read_record, record_sha256

    with pytest.raises(DyeError, match="not a regular file"):
        target_colour("/dev/zero", curve=object())
    with pytest.raises(RecordError, match="not a regular file"):
        read_record("/dev/zero", EstimateRecord)
    with pytest.raises(RecordError, match="not a regular file"):
        record_sha256("/dev/zero")
    with pytest.raises(ValueError, match="not a regular file"):
        read_json("/dev/urandom", ValueError, "missing", "bad")


def test_a_fifo_never_hangs_a_command(ws):
    os.mkfifo(ws / "pipe.json")
    run = cli("library", "find", "--near", ws / "pipe.json", cwd=ws, timeout=120,
              env={"HAIRDIGI_LIBRARY": str(ws / "lib.sqlite"), "HAIRDIGI_SESSIONS": str(ws / "none")})
    assert run.returncode == 2 and "not a regular file" in run.stderr and "Traceback" not in run.stderr, run.stderr
    run = cli("export", ws / "pipe.json", "--format", "materialx", "--out", ws / "p.mtlx", cwd=ws, timeout=120)
    assert run.returncode == 2 and "regular file" in run.stderr, run.stderr


# --- 6. the library under a lock or read-only ---------------------------------------------------------------
def test_a_read_only_library_is_one_line(ws, capsys):
    assert main(["library", "info"]) == 0
    capsys.readouterr()
    (ws / "lib.sqlite").chmod(0o444)
    try:
        one_line(main(["library", "info"]), capsys, "read-only", "lib.sqlite")
    finally:
        (ws / "lib.sqlite").chmod(0o644)


def test_a_held_lock_times_out_in_seconds_naming_the_library(ws, capsys):
    from hairdigi.app.library.store import BUSY_TIMEOUT_S

    assert main(["library", "import", "r.json"]) == 0
    capsys.readouterr()
    holder = sqlite3.connect(ws / "lib.sqlite", isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")            # another process writing, for longer than the timeout
    try:
        from hairdigi.app.library.store import Library

        with Library() as lib:
            sid = lib.all()[0].id
        start = time.perf_counter()
        one_line(main(["library", "tag", sid, "x"]), capsys, "locked", "lib.sqlite")
        assert time.perf_counter() - start < BUSY_TIMEOUT_S + 5
    finally:
        holder.execute("ROLLBACK")
        holder.close()
    assert BUSY_TIMEOUT_S <= 5


class SilentServer:
    """A TCP server that accepts connections and never answers (a PostgreSQL host that hangs)."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.held = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.held.append(conn)

    def close(self) -> None:
        self.sock.close()
        for c in self.held:
            c.close()


def test_a_postgresql_server_that_never_answers_times_out_without_the_password(ws, capsys, monkeypatch):
    pytest.importorskip("psycopg")
    from hairdigi.app.library.store import CONNECT_TIMEOUT_S

    server = SilentServer()
    try:
        monkeypatch.setenv("HAIRDIGI_LIBRARY", f"postgresql://lab:s3cr3t-pw@127.0.0.1:{server.port}/hairdigi")
        start = time.perf_counter()
        line = one_line(main(["library", "info"]), capsys, "127.0.0.1", "lab:***@")
        assert time.perf_counter() - start < 2 * CONNECT_TIMEOUT_S + 5
        assert "s3cr3t" not in line
    finally:
        server.close()


def test_postgresql_sessions_have_lock_and_statement_timeouts(monkeypatch):
    psycopg = pytest.importorskip("psycopg")
    from hairdigi.app.library import store as L

    seen = {}

    def fake_connect(where, **kw):
        seen.update(kw)
        raise psycopg.OperationalError("connection refused")

    monkeypatch.setattr(psycopg, "connect", fake_connect)
    with pytest.raises(L.LibraryError):
        L._Db("postgresql://u:pw@h/db")
    assert seen["connect_timeout"] <= 5
    assert "lock_timeout=" in seen["options"] and "statement_timeout=" in seen["options"]


# --- 7. one corrupt old capture --------------------------------------------------------------------------
def test_a_corrupt_old_session_is_skipped_with_one_line_and_the_rest_imported(ws, monkeypatch):
    old = ws / "old"
    for name, corrupt in (("a", False), ("b", True)):
        cap = old / name / "captures"
        cap.mkdir(parents=True)
        (cap / f"{CAPTURE}.json").write_text("{not json" if corrupt else json.dumps(
            {"id": CAPTURE, "image": f"{CAPTURE}.png", "image_sha256": "1" * 64}))
        write_record(cap / f"{CAPTURE}.result.json", estimate_record(capture=f"{CAPTURE}.png"))
    env = {"HAIRDIGI_LIBRARY": str(ws / "old.sqlite"), "HAIRDIGI_SESSIONS": str(old)}
    run = cli("library", "info", env=env, cwd=ws)
    assert run.returncode == 0, run.stderr
    skipped = [l for l in run.stderr.splitlines() if "skipped" in l]
    assert len(skipped) == 1 and str(old / "b") in skipped[0] and "library import" in skipped[0], run.stderr
    assert "swatches: 1" in run.stdout
    again = cli("library", "info", env=env, cwd=ws)
    assert again.returncode == 0 and "skipped" not in again.stderr, again.stderr


# --- 8. secrets ------------------------------------------------------------------------------------
def test_no_password_is_shown(monkeypatch):
    from hairdigi.app.library.store import _first_line, redact

    for url in ("postgresql://lab:s3cr3t@db.lab:5432/hairdigi", "postgres://lab:s3cr3t@db/x?sslmode=require",
                "postgresql://db/x?user=lab&password=s3cr3t", "host=db password=s3cr3t dbname=x"):
        assert "s3cr3t" not in redact(url) and "***" in redact(url), redact(url)
    assert "s3cr3t" not in _first_line(ValueError("FATAL: bad s3cr3t"), "postgresql://lab:s3cr3t@db/x")


def test_library_info_masks_the_password():
    from hairdigi.app.cli import library as library_cli

    class Fake:
        where, version = "postgresql://lab:s3cr3t@db/x", 2

        def count(self):
            return 0

        def sessions(self):
            return []

    import io
    from contextlib import redirect_stdout

    buf = io.StringIO()
    with redirect_stdout(buf):
        library_cli._info(Fake(), None)
    assert "s3cr3t" not in buf.getvalue() and "lab:***@db" in buf.getvalue()


# --- 9. a broken Blender ------------------------------------------------------------------------------
def test_a_broken_blender_stops_evaluate_cycles_with_exit_2(ws, capsys, monkeypatch):
    monkeypatch.setenv("HAIRDIGI_BLENDER", "/bin/false")
    one_line(main(["evaluate", "--cycles", "--out", "ev"]), capsys, "Blender")
    assert not (ws / "ev" / "cycles_evaluation.json").exists()


# --- 10. impossible values -------------------------------------------------------------------------------
@pytest.mark.parametrize("sigma", [(-0.5, 0.9, 1.4), (1e300, 1.0, 1.0)])
def test_impossible_absorption_is_refused_everywhere(ws, capsys, sigma):
    write_record(ws / "bad.json", estimate_record(sigma))
    one_line(main(["export", "bad.json", "--format", "materialx", "--out", "bad.mtlx"]), capsys, "outside 0 to")
    one_line(main(["library", "import", "bad.json"]), capsys, "outside 0 to")
    (ws / "dye.json").write_text(json.dumps(dye_record_json(deposit=(1e300, 0.1, 0.1))))
    from hairdigi.render.domain.dye_record import DyeRecord
    from hairdigi.render.domain.records import RecordError, read_record

    with pytest.raises(RecordError, match="outside 0 to"):
        read_record(ws / "dye.json", DyeRecord)
    assert not (ws / "bad.mtlx").exists()


def test_inverted_intervals_are_refused(ws):
    from hairdigi.render.domain.dye_record import DyeRecord
    from hairdigi.render.domain.records import RecordError

    data = estimate_record().to_json()
    data["uncertainty"] = {"parameters": {"melanin_ratio": {"value": 0.4, "low": 0.6, "high": 0.2}}}
    with pytest.raises(RecordError, match="inverted"):
        EstimateRecord.from_json(data)
    data = estimate_record().to_json()
    data["appearance"] = {"longitudinal_roughness": 0.3, "measured": ["longitudinal_roughness"],
                          "intervals": {"longitudinal_roughness": {"p68": [0.4, 0.2]}}}
    with pytest.raises(RecordError, match="inverted"):
        EstimateRecord.from_json(data)
    with pytest.raises(RecordError, match="inverted"):
        DyeRecord.from_json(dye_record_json(lift_measured=True, lift_low=0.5, lift_high=0.1))
    with pytest.raises(RecordError, match="inverted"):
        DyeRecord.from_json(dye_record_json(deposit_low=[0.5, 0.1, 0.1], deposit_high=[0.1, 0.9, 0.9]))


# --- 12. hostile file names ------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["copper--v2.result.json", 'x--><evil a="1"><!--.json', "a\x1b[31mred-.json"])
def test_materialx_is_well_formed_whatever_the_record_is_called(ws, capsys, name):
    write_record(ws / name, estimate_record())
    assert main(["export", name, "--format", "materialx", "--out", "out.mtlx"]) == 0
    root = ET.parse(ws / "out.mtlx").getroot()            # raises on a malformed document
    assert root.tag == "materialx" and not root.findall(".//evil")


# --- 14. size --------------------------------------------------------------------------------------
def test_a_10_mb_dye_name_is_refused_at_once(ws, capsys):
    write_record(ws / "b.json", estimate_record())
    write_record(ws / "d.json", estimate_record((0.9, 1.4, 2.0)))
    start = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        main(["dye", "characterise", "--pair", "b.json", "d.json", "--name", "x" * 10_000_000, "--out", "y.json"])
    assert exc.value.code == 2 and time.perf_counter() - start < 10
    assert "longer than 200" in capsys.readouterr().err
    assert not (ws / "y.json").exists()


def test_a_dye_record_with_a_megabyte_name_is_refused(ws, capsys):
    (ws / "big.json").write_text(json.dumps(dye_record_json("x" * 1_000_000)))
    start = time.perf_counter()
    one_line(main(["dye", "card", "big.json", "--out", "card.png"]), capsys, "characters")
    assert time.perf_counter() - start < 10 and not (ws / "card.png").exists()


def test_an_xlsx_cell_over_excels_limit_is_refused_not_cut(ws, capsys):
    from hairdigi.app.library.store import Library

    assert main(["library", "import", "r.json"]) == 0
    with Library() as lib:
        lib.note(lib.all()[0].id, "n" * 40_000)
    capsys.readouterr()
    one_line(main(["library", "export", "--xlsx", "big.xlsx", "--csv", "big.csv"]), capsys, "32767", "note")
    assert not (ws / "big.xlsx").exists() and not (ws / "big.csv").exists()
    with pytest.raises(SystemExit):
        main(["library", "note", "x", "n" * 20_000])         # the command line takes at most 10,000


# --- 15. another program's SQLite file ---------------------------------------------------------------------
def test_another_programs_database_is_left_alone(ws, capsys, monkeypatch):
    other = ws / "firefox.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE moz_places (id INTEGER, url TEXT)")
    con.commit()
    con.close()
    before = sha(other)
    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(other))
    one_line(main(["library", "info"]), capsys, "another program", "moz_places")
    assert sha(other) == before and not (ws / "firefox.sqlite-wal").exists()


# --- 16. records of the wrong kind ---------------------------------------------------------------------------
def test_records_of_another_kind_are_named_not_read_as_estimates(ws, capsys):
    (ws / "dye.json").write_text(json.dumps(dye_record_json()))
    one_line(main(["library", "import", "dye.json"]), capsys, "'dye' record")
    one_line(main(["library", "import", "s/calibration.json"]), capsys, "'calibration' record")
    (ws / "profile.json").write_text(json.dumps({"matrix": [[1, 0, 0]] * 3, "method": "linear"}))
    one_line(main(["library", "import", "profile.json"]), capsys, "'calibration' record")
    (ws / "other.json").write_text(json.dumps({"anything": 1}))
    one_line(main(["export", "other.json", "--format", "materialx", "--out", "o.mtlx"]), capsys, "not an estimate")
    from hairdigi.inference.dye import DyeError, load_sample

    with pytest.raises(DyeError, match="'dye' record"):
        load_sample(ws / "dye.json")


# --- 17. small things --------------------------------------------------------------------------------------
@pytest.mark.parametrize("k", ["0", "-1"])
def test_find_k_must_be_positive(ws, capsys, k):
    with pytest.raises(SystemExit) as exc:
        main(["library", "find", "--near", "#8a4a30", "--k", k])
    assert exc.value.code == 2


def test_repeated_scene_keeps_every_one():
    from hairdigi.app.cli import build_parser

    args = build_parser().parse_args(["dye", "apply", "d.json", "--base", "b.json", "--out", "p.json", "--render",
                                      "p.png", "--scene", "wavy", "--scene", "bob"])
    assert args.scene == ["wavy", "bob"]


def test_like_wildcards_match_literally(ws):
    from hairdigi.app.library.store import Library, LibraryError

    assert main(["library", "import", "r.json"]) == 0
    with Library() as lib:
        with pytest.raises(LibraryError, match="no swatch"):
            lib.resolve("%")
        with pytest.raises(LibraryError, match="no swatch"):
            lib.resolve("_")
        assert lib.all("%") == [] and lib.all("_") == []
        sid = lib.all()[0].id
        lib.note(sid, "100% grey_ish")
        assert [s.id for s in lib.all("0% g")] == [sid] and [s.id for s in lib.all("y_i")] == [sid]


def test_escape_sequences_never_reach_the_terminal(ws, capsys):
    from hairdigi.app.library.store import Library

    assert main(["library", "import", "r.json"]) == 0
    with Library() as lib:
        sid = lib.all()[0].id
        lib.note(sid, "\x1b]0;pwned\x07\x1b[2J note\r")
    capsys.readouterr()
    assert main(["library", "find", "--near", "#8a4a30"]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "\r" not in out and "note" in out


# --- 3. single-light frames that are not one capture ----------------------------------------------------------
@pytest.fixture(scope="module")
def rig_capture(tmp_path_factory):
    """One simulated capture (8 spp): the all-lights frame, the three single-light frames and their exposures."""
    from hairdigi.app.session.rig_session import RigSession

    folder = tmp_path_factory.mktemp("rig") / "s"
    session = RigSession.simulated_rig(folder, spp=8)
    try:
        cid = session.capture(estimate=False).capture_id
    finally:
        session.close()
    meta = json.loads((folder / "captures" / f"{cid}.json").read_text())
    names = [folder / "captures" / n for n in meta["light_images"]]
    return folder / "captures" / f"{cid}.png", names, list(meta["light_exposures"])


def _srgb8(path: Path) -> np.ndarray:
    import cv2

    return cv2.imread(str(path))[..., ::-1].copy()


def _write_png(path: Path, rgb: np.ndarray) -> Path:
    import cv2

    cv2.imwrite(str(path), np.ascontiguousarray(rgb[..., ::-1]))
    return path


def test_one_captures_frames_add_up_and_garbage_does_not(rig_capture):
    from hairdigi.inference.appearance import light_frames_problem
    from hairdigi.inference.preprocess import to_linear

    image_path, names, exposures = rig_capture
    image = _srgb8(image_path)
    singles = [to_linear(_srgb8(n)) / np.float32(k) for n, k in zip(names, exposures)]
    assert light_frames_problem(singles, image) is None
    rng = np.random.default_rng(0)
    noise = [to_linear(rng.integers(0, 256, image.shape, dtype=np.uint8)) / np.float32(k) for k in exposures]
    assert "add up to" in light_frames_problem(noise, image)
    assert "add up to" in light_frames_problem([3 * s for s in singles], image)                 # 3x brighter
    assert "add up to 3.00x" in light_frames_problem([to_linear(image)] * 3, image)            # the image 3 times
    assert "same picture" in light_frames_problem([to_linear(image) / np.float32(3)] * 3, image)   # ... at 1/3
    scaled = [s * np.float32(exposures[0]) for s in singles]                                    # exposure lost
    assert "--lights-ev 1.5" in light_frames_problem(scaled, image)
    shifted = [np.roll(s, 37, axis=1) for s in singles]                                         # another view
    assert "pixel by pixel" in light_frames_problem(shifted, image)


def test_estimate_refuses_frames_that_are_not_its_capture(rig_capture, tmp_path, capsys):
    image_path, names, _ = rig_capture
    image = tmp_path / "frame.png"                # frames taken away from their capture record
    image.write_bytes(image_path.read_bytes())
    moved = []
    for i, n in enumerate(names):
        moved.append(tmp_path / f"l{i}.png")
        moved[-1].write_bytes(n.read_bytes())
    rng = np.random.default_rng(1)
    noise = [_write_png(tmp_path / f"n{i}.png", rng.integers(0, 256, _srgb8(image).shape, dtype=np.uint8))
             for i in range(3)]
    for lights, needle in (([image] * 3, "add up to 3.00x"), (noise, "add up to"),
                           (moved, "--lights-ev 1.5")):
        code = main(["estimate", str(image), "--no-refine", "--lights", ",".join(map(str, lights)),
                     "--out", str(tmp_path / "e.json")])
        one_line(code, capsys, needle)
        assert not (tmp_path / "e.json").exists()
    # the same frames with their exposure given are one capture again
    assert main(["estimate", str(image), "--no-refine", "--lights", ",".join(map(str, moved)), "--lights-ev", "1.5",
                 "--out", str(tmp_path / "e.json")]) == 0


# --- 4. --lights takes what its help names: 16-bit PNG and linear EXR -------------------------------------------
def test_16_bit_png_and_exr_light_frames_are_read(rig_capture, tmp_path, capsys):
    import cv2

    from hairdigi.inference.light_frames import read_light_frame
    from hairdigi.inference.preprocess import to_linear
    from hairdigi.render.io.images import save_exr

    image_path, names, exposures = rig_capture
    linear = [to_linear(_srgb8(n)) for n in names]
    png16, exr = [], []
    for i, lin in enumerate(linear):
        srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * np.power(lin, 1 / 2.4) - 0.055)
        png16.append(tmp_path / f"l{i}-16.png")
        cv2.imwrite(str(png16[-1]), np.round(np.clip(srgb, 0, 1) * 65535).astype(np.uint16)[..., ::-1])
        exr.append(save_exr(tmp_path / f"l{i}.exr", lin))
        for path in (png16[-1], exr[-1]):
            frame = read_light_frame(path)
            assert frame.dtype == np.float32 and np.allclose(frame, lin, atol=2e-3), path
    image = tmp_path / "frame.png"
    image.write_bytes(image_path.read_bytes())
    for lights in (png16, exr):
        assert main(["estimate", str(image), "--no-refine", "--lights", ",".join(map(str, lights)), "--lights-ev",
                     "1.5", "--out", str(tmp_path / "e.json")]) == 0, capsys.readouterr().err


def test_a_device_as_a_light_frame_is_refused_before_it_is_read(ws, capsys):
    from test_hostile_input2 import hair_like

    _write_png(ws / "img.png", hair_like())
    one_line(main(["estimate", "img.png", "--lights", "/dev/zero,/dev/zero,/dev/zero", "--out", "e.json"]), capsys,
             "/dev/zero", "regular file")


# --- 11. dye characterisation questions what it is given ----------------------------------------------------------
@pytest.fixture(scope="module")
def curve():
    from hairdigi.inference import dye as D

    return D.rig_curve()


def _natural(level: int):
    from hairdigi.inference.levels import natural_base
    from hairdigi.render.domain.absorption import hair_sigma_a

    return natural_base(level), hair_sigma_a(natural_base(level))


def test_one_record_as_base_and_dyed_is_refused(curve, ws, capsys):
    hair, m = _natural(6)
    write_record(ws / "b.json", estimate_record(m, hair))
    one_line(main(["dye", "characterise", "--pair", "b.json", "b.json", "--name", "x", "--out", "x.json"]), capsys,
             "same record")
    assert not (ws / "x.json").exists()


def test_pairs_that_disagree_on_one_base_are_warned_about(curve):
    from hairdigi.inference import dye as D

    hair, m = _natural(6)
    deposit = np.array([0.1, 0.35, 0.5])
    base = D.sample_of(estimate_record(m, hair), "base", "b")
    one = D.sample_of(estimate_record(m + deposit, hair), "dyed1", "d1")
    two = D.sample_of(estimate_record(m + 3 * deposit, hair), "dyed2", "d2")
    from hairdigi.render.metrics import delta_e2000

    assert float(delta_e2000(D.colour_of(one.sigma_a, curve), D.colour_of(two.sigma_a, curve))) > 4
    dye = D.characterise([(base, one), (base, two)], "x", curve)
    assert any("disagree" in w for w in dye.warnings), dye.warnings


def test_an_interval_always_holds_its_estimate(curve):
    from hairdigi.inference import dye as D

    # found on main by a random search: the lift's and a zero channel's 68% intervals excluded the estimate
    for levels, deposit, lift in (((4, 5), (0.0, 0.534, 0.0), 0.416), ((1,), (0.347, 0.118, 0.0), 0.674),
                                  ((1, 8), (0.202, 0.0, 0.0), 0.283)):
        pairs = []
        for level in levels:
            hair, m = _natural(level)
            dyed = (1 - lift) * m + np.array(deposit)
            pairs.append((D.sample_of(estimate_record(m, hair), f"b{level}", f"b{level}"),
                          D.sample_of(estimate_record(dyed, hair), f"d{level}", f"d{level}")))
        dye = D.characterise(pairs, "x", curve)
        assert all(lo <= d <= hi for lo, d, hi in zip(dye.deposit_low, dye.deposit_sigma_a, dye.deposit_high)), dye
        if dye.lift_measured:
            assert dye.lift_low <= dye.lift <= dye.lift_high, dye


def test_a_dye_on_a_dyed_base_is_said_to_be(curve):
    from dataclasses import replace

    from hairdigi.inference import dye as D

    hair, m = _natural(6)
    dye = D.characterise([(D.sample_of(estimate_record(m, hair), "b", "b"),
                           D.sample_of(estimate_record(m + 0.3, hair), "d", "d"))], "x", curve)
    prediction = D.apply(dye, D.sample_of(estimate_record(m, hair), "b", "b"), curve=curve).record
    assert not any("dyed base" in w.message for w in prediction.warnings)
    again = D.apply(dye, D.sample_of(prediction, "pred.json", "p"), curve=curve).record
    assert any("dyed base" in w.message for w in again.warnings)
    dyed_hair = replace(hair, dye_concentration=0.8)
    on_dyed = D.apply(dye, D.sample_of(estimate_record(m, dyed_hair), "dyed.json", "x"), curve=curve).record
    assert any("dyed base" in w.message for w in on_dyed.warnings)


# --- 13. a dead remote display -----------------------------------------------------------------------------------
@pytest.mark.parametrize("display, needle", [("localhost:10.0", "no X server answers"),
                                             ("remotehost.invalid:0", "no X server answers"),
                                             ("garbage", "not a display name"), ("\x1b[2J:0", "no X server")])
def test_a_display_that_cannot_be_opened_is_one_line_before_qt(monkeypatch, display, needle):
    from hairdigi.app.cli import validation as v

    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("DISPLAY", display)
    free = socket.socket()
    free.bind(("127.0.0.1", 6010))    # nothing listens on localhost:10's port while this is held
    try:
        start = time.perf_counter()
        with pytest.raises(v.ArgumentError, match=needle) as exc:
            v.check_display()
        assert time.perf_counter() - start < v.DISPLAY_TIMEOUT_S + 5 and "\x1b" not in str(exc.value)
    finally:
        free.close()


def test_a_stale_wayland_display_is_one_line(monkeypatch, tmp_path):
    from hairdigi.app.cli import validation as v

    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    with pytest.raises(v.ArgumentError, match="no running compositor"):
        v.check_display()


# --- 17. small things (continued) ----------------------------------------------------------------------------
@pytest.mark.parametrize("args", [["--rig", "--cycles"], ["--appearance", "--rig"], ["--convergence", "4,16", "--rig"],
                                  ["--ship"], ["--no-variation", "--rig"], ["--default-shine"], ["--dye", "--ship"],
                                  ["--structures", "--rig"], ["--blender"], ["--hidden-structures", "loose"]])
def test_contradictory_evaluation_flags_are_refused(ws, capsys, args):
    one_line(main(["evaluate", *args, "--out", "ev"]), capsys, "--")
    assert not (ws / "ev").exists()


def test_evaluate_dye_takes_size_and_spp_and_judges_no_goal_on_a_few(monkeypatch, capsys):
    import argparse

    from hairdigi.app.cli import dye as dye_cli
    from hairdigi.inference.training import evaluate_dye

    seen = {}

    def fake(encoder, out, config):
        seen["config"] = config
        return {"prediction_de2000": {"n": 3}, "text": ["two bases -> the third: ... over 3 predictions (goal "
                                                         "median <= 1.0, p95 <= 2.0: met)"]}

    monkeypatch.setattr(evaluate_dye, "evaluate_dye", fake)
    monkeypatch.setattr("hairdigi.inference.encoder.Encoder", lambda model: None)
    args = argparse.Namespace(n=1, size=32, spp=8, model=None, out="x", rig=False)
    assert dye_cli.cmd_evaluate_dye(args) == 0
    assert (seen["config"].size, seen["config"].spp, seen["config"].dyes) == (32, 8, 1)
    out = capsys.readouterr().out
    assert "met)" not in out and "too few" in out


def test_a_misspelt_hidden_appearance_key_is_refused(tmp_path):
    from hairdigi.render.domain.appearance import Appearance, AppearanceError

    with pytest.raises(AppearanceError, match="did you mean 'grey_fraction'"):
        Appearance.from_dict({"grey_fracton": 0.2})
    from hairdigi.app.cli.rig import hidden_appearance
    from hairdigi.render.domain.params import HairParamsError

    (tmp_path / "h.json").write_text(json.dumps({"hair": HAIR.to_dict(), "appearance": {"fibre_sprad": 0.3}}))
    with pytest.raises(HairParamsError, match="fibre_spread"):
        hidden_appearance(tmp_path / "h.json")


def test_errors_name_the_file_asked_for_never_a_temporary_one(tmp_path):
    import errno

    from hairdigi.app.cli.validation import describe_os_error
    from hairdigi.render.domain.files import atomic_path

    with pytest.raises(OSError) as exc:
        with atomic_path(tmp_path / "out.png") as tmp:
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
    line = describe_os_error(exc.value)
    assert str(tmp_path / "out.png") in line and ".hd-" not in line
    with pytest.raises(ValueError) as exc:
        with atomic_path(tmp_path / "out.png") as tmp:
            raise ValueError(f"could not encode {tmp}")
    assert ".hd-" not in str(exc.value) and "out.png" in str(exc.value)


def test_a_failing_card_leaves_no_partial_outputs(ws, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from hairdigi.inference import dye_card
    from hairdigi.render.domain.dye_record import DyeRecord

    class Failing(Figure):
        def savefig(self, fname, *a, format=None, **kw):
            if format == "png":
                raise OSError(28, "No space left on device", str(fname))
            return super().savefig(fname, *a, format=format, **kw)

    monkeypatch.setattr(dye_card, "card_rows", lambda *a, **kw: [])
    monkeypatch.setattr(dye_card, "draw_card", lambda *a, **kw: Failing())
    with pytest.raises(OSError):
        dye_card.shade_card(DyeRecord.from_json(dye_record_json()), ws / "card.png")
    assert not any(p.name.startswith("card") or p.name.startswith(".hd-") for p in ws.iterdir())


def test_a_failing_render_leaves_no_prediction_behind(ws, capsys, monkeypatch, curve):
    from hairdigi.render import renderer

    hair, m = _natural(6)
    write_record(ws / "b.json", estimate_record(m, hair))
    (ws / "copper.json").write_text(json.dumps(dye_record_json()))

    def broken():
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(renderer, "default_renderer", broken)
    before = snapshot(ws)
    one_line(main(["dye", "apply", "copper.json", "--base", "b.json", "--out", "p.json", "--render", "p.png"]), capsys,
             "No space left")
    assert snapshot(ws) == before


def test_the_window_opens_the_library_off_the_ui_thread_and_shows_why_not(ws, qtbot, monkeypatch):
    from PySide6.QtWidgets import QLabel, QMainWindow

    from hairdigi.app.gui import library_panel

    opened_in = []
    release = threading.Event()
    real = library_panel._open_or_reason

    def held():
        opened_in.append(threading.current_thread() is threading.main_thread())
        release.wait(20)                                   # the library opens only when the test says so
        return real()

    monkeypatch.setattr(library_panel, "_open_or_reason", held)
    window = QMainWindow()
    qtbot.addWidget(window)
    dock = library_panel.add_library_dock(window)
    # the window goes on while the library is still opening: the dock is there, the panel not yet
    assert not isinstance(dock.widget(), library_panel.LibraryPanel)
    qtbot.waitUntil(lambda: opened_in == [False], timeout=20_000)   # opening, off the UI thread
    release.set()
    qtbot.waitUntil(lambda: isinstance(dock.widget(), library_panel.LibraryPanel), timeout=20_000)
    assert opened_in == [False]
    # a library that cannot be opened: the whole reason, wrapped, in the dock
    other = ws / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE places (id INTEGER)")
    con.commit()
    con.close()
    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(other))
    dock = library_panel.add_library_dock(window)
    qtbot.waitUntil(lambda: "unavailable" in getattr(dock.widget(), "text", lambda: "")(), timeout=20_000)
    label = dock.widget()
    assert isinstance(label, QLabel) and label.wordWrap() and "another program" in label.toolTip()
