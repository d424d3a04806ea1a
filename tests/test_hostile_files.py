"""Careless and hostile input, third round: exports, the swatch library, devices and FIFOs as
files, hostile names and sizes, secrets, other programs' files, a dead display.

Most cases run the command line in this process (``main``), which is what a subprocess would run,
minus the start-up; cases that may hang (a FIFO) or need a second process (a lock) run it in a
subprocess with a timeout. Every refused case is one stderr line and exit 2, and leaves the files it
was pointed at byte for byte as they were. Shared helpers: ``tests/hostile.py``.
"""
import csv
import json
import os
import socket
import sqlite3
import threading
import time
import xml.etree.ElementTree as ET

import pytest

from hairdigi.app.cli import main
from hairdigi.render.domain.records import EstimateRecord, write_record
from hostile import CAPTURE, HAIR, cli, dye_record_json, estimate_record, one_line, sha, snapshot, workspace
from deadlines import within


@pytest.fixture
def ws(tmp_path, monkeypatch):
    return workspace(tmp_path, monkeypatch)


# --- data loss, exit 0 --------------------------------------------------------------------------
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


# --- formula injection ------------------------------------------------------------------------------
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


# --- device files and FIFOs as inputs ----------------------------------------------------------------
@pytest.mark.parametrize("args", [
    ["library", "find", "--near", "/dev/zero"],
    ["export", "/dev/zero", "--format", "materialx", "--out", "z.mtlx"],
    ["library", "import", "/dev/zero"],
])
def test_device_files_are_refused_before_a_byte_is_read(ws, capsys, args):
    start = time.perf_counter()
    one_line(main(args), capsys, "/dev/zero")
    assert time.perf_counter() - start < within(30)


def test_device_file_as_a_dye_target_or_record_is_refused(ws, capsys):
    from hairdigi.inference.dye import DyeError, target_colour
    from hairdigi.render.domain.files import read_json
    from hairdigi.render.domain.record_fields import RecordError
    from hairdigi.render.domain.records import read_record, record_sha256

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


# --- the library under a lock or read-only ---------------------------------------------------------------
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


# --- one corrupt old capture --------------------------------------------------------------------------
def test_a_corrupt_old_session_is_skipped_with_one_line_and_the_rest_imported(ws, monkeypatch):
    old = ws / "old"
    for name, corrupt in (("a", False), ("b", True)):
        cap = old / name / "captures"
        cap.mkdir(parents=True)
        (cap / f"{CAPTURE}.png").write_bytes(b"an image " + name.encode())
        (cap / f"{CAPTURE}.json").write_text("{not json" if corrupt else json.dumps(
            {"id": CAPTURE, "image": f"{CAPTURE}.png", "image_sha256": sha(cap / f"{CAPTURE}.png")}))
        write_record(cap / f"{CAPTURE}.result.json", estimate_record(capture=f"{CAPTURE}.png"))
    env = {"HAIRDIGI_LIBRARY": str(ws / "old.sqlite"), "HAIRDIGI_SESSIONS": str(old)}
    run = cli("library", "info", env=env, cwd=ws)
    assert run.returncode == 0, run.stderr
    skipped = [l for l in run.stderr.splitlines() if "skipped" in l]
    assert len(skipped) == 1 and str(old / "b") in skipped[0] and "library import" in skipped[0], run.stderr
    assert "swatches: 1" in run.stdout
    again = cli("library", "info", env=env, cwd=ws)
    assert again.returncode == 0 and "skipped" not in again.stderr, again.stderr


# --- secrets ------------------------------------------------------------------------------------
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


# --- a broken Blender ------------------------------------------------------------------------------
def test_a_broken_blender_stops_evaluate_cycles_with_exit_2(ws, capsys, monkeypatch):
    monkeypatch.setenv("HAIRDIGI_BLENDER", "/bin/false")
    one_line(main(["evaluate", "--cycles", "--out", "ev"]), capsys, "Blender")
    assert not (ws / "ev" / "cycles_evaluation.json").exists()


# --- impossible values -------------------------------------------------------------------------------
@pytest.mark.parametrize("sigma", [(-0.5, 0.9, 1.4), (1e300, 1.0, 1.0)])
def test_impossible_absorption_is_refused_everywhere(ws, capsys, sigma):
    write_record(ws / "bad.json", estimate_record(sigma))
    one_line(main(["export", "bad.json", "--format", "materialx", "--out", "bad.mtlx"]), capsys, "outside 0 to")
    one_line(main(["library", "import", "bad.json"]), capsys, "outside 0 to")
    (ws / "dye.json").write_text(json.dumps(dye_record_json(deposit=(1e300, 0.1, 0.1))))
    from hairdigi.render.domain.dye_record import DyeRecord
    from hairdigi.render.domain.record_fields import RecordError
    from hairdigi.render.domain.records import read_record

    with pytest.raises(RecordError, match="outside 0 to"):
        read_record(ws / "dye.json", DyeRecord)
    assert not (ws / "bad.mtlx").exists()


def test_inverted_intervals_are_refused(ws):
    from hairdigi.render.domain.dye_record import DyeRecord
    from hairdigi.render.domain.record_fields import RecordError

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


# --- hostile file names ------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["copper--v2.result.json", 'x--><evil a="1"><!--.json', "a\x1b[31mred-.json"])
def test_materialx_is_well_formed_whatever_the_record_is_called(ws, capsys, name):
    write_record(ws / name, estimate_record())
    assert main(["export", name, "--format", "materialx", "--out", "out.mtlx"]) == 0
    root = ET.parse(ws / "out.mtlx").getroot()            # raises on a malformed document
    assert root.tag == "materialx" and not root.findall(".//evil")


# --- size --------------------------------------------------------------------------------------
def test_a_10_mb_dye_name_is_refused_at_once(ws, capsys):
    write_record(ws / "b.json", estimate_record())
    write_record(ws / "d.json", estimate_record((0.9, 1.4, 2.0)))
    start = time.perf_counter()
    with pytest.raises(SystemExit) as exc:
        main(["dye", "characterise", "--pair", "b.json", "d.json", "--name", "x" * 10_000_000, "--out", "y.json"])
    assert exc.value.code == 2 and time.perf_counter() - start < within(10)
    assert "longer than 200" in capsys.readouterr().err
    assert not (ws / "y.json").exists()


def test_a_dye_record_with_a_megabyte_name_is_refused(ws, capsys):
    (ws / "big.json").write_text(json.dumps(dye_record_json("x" * 1_000_000)))
    start = time.perf_counter()
    one_line(main(["dye", "card", "big.json", "--out", "card.png"]), capsys, "characters")
    assert time.perf_counter() - start < within(10) and not (ws / "card.png").exists()


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


# --- another program's SQLite file ---------------------------------------------------------------------
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


# --- records of the wrong kind ---------------------------------------------------------------------------
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


# --- small things --------------------------------------------------------------------------------------
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


# --- a dead remote display -----------------------------------------------------------------------------------
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


# --- small things (continued) ----------------------------------------------------------------------------
@pytest.mark.parametrize("args", [["--rig", "--cycles"], ["--appearance", "--rig"], ["--convergence", "4,16", "--rig"],
                                  ["--ship"], ["--no-variation", "--rig"], ["--default-shine"], ["--dye", "--ship"],
                                  ["--structures", "--rig"], ["--blender"], ["--hidden-structures", "loose"],
                                  ["--structure", "family"], ["--structures", "--structure", "read"]])
def test_contradictory_evaluation_flags_are_refused(ws, capsys, args):
    one_line(main(["evaluate", *args, "--out", "ev"]), capsys, "--")
    assert not (ws / "ev").exists()


@pytest.mark.parametrize("args, says", [(["--ship", "--structure", "assumed"], "drop --ship"),
                                        (["--ship", "--structure", "read"], "drop --ship"),
                                        (["--hidden-structures", "deposited,stacked"], "unknown structure 'stacked'")])
def test_a_rig_evaluation_of_other_swatches_is_not_shipped_nor_run_on_a_structure_that_is_not(ws, capsys, args, says):
    """The chain's shipped interval is measured in the default mode (across swatch structures, the records'
    own); a misspelt hidden structure is named before any capture is rendered."""
    assert main(["evaluate", "--rig", *args, "--out", "ev"]) == 2
    assert says in capsys.readouterr().err
    assert not list((ws / "ev").glob("rig_evaluation*"))


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
