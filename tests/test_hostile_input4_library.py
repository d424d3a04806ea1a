"""Careless and hostile input, fourth round: the files a command writes, library addresses and
their passwords, session records that lie, exported tables, stored text echoed to the terminal.

One numbered class of such input per section. Every refused case is one stderr line and exit 2, and leaves
the working folder (and the library) as it was. Addresses of a PostgreSQL library point at a closed port
of this machine, so the driver's own connection error is produced for real, at once.
"""
import csv
import hashlib
import io
import json
import sqlite3
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.render.domain.records import CaptureRecord, write_record
from deadlines import within
from hostile import CAPTURE, dye_record_json, estimate_record, one_line, snapshot, workspace

CLOSED = "127.0.0.1:5999"      # nothing listens there: the driver's "connection refused", at once


@pytest.fixture
def ws(tmp_path, monkeypatch):
    return workspace(tmp_path, monkeypatch)


# --- 1. no writer replaces a record, a dye, a capture, a calibration or a library -------------------
def _session_dye(ws: Path) -> Path:
    dyes = ws / "s" / "dyes"
    dyes.mkdir()
    (dyes / "blonde.json").write_text(json.dumps(dye_record_json("blonde")))
    (ws / "copper.json").write_text(json.dumps(dye_record_json()))
    return dyes


def test_dye_card_never_replaces_a_sessions_dye_record(ws, capsys):
    _session_dye(ws)
    before = snapshot(ws)
    line = one_line(main(["dye", "card", "copper.json", "--out", "s/dyes/blonde.png", "--size", "16", "--spp", "1"]),
                    capsys, "blonde.json", "a dye record")
    assert "refused" in line
    assert snapshot(ws) == before


@pytest.mark.parametrize("name, kind", [("look.pdf", "an estimate record"), ("look.json", "an estimate record"),
                                        ("look.png", "an estimate record")])
def test_dye_card_checks_each_file_it_writes_whatever_the_extension(ws, capsys, name, kind):
    (ws / "copper.json").write_text(json.dumps(dye_record_json()))
    write_record(ws / name, estimate_record())            # a record, under any name
    before = snapshot(ws)
    one_line(main(["dye", "card", "copper.json", "--out", "look.png", "--size", "16", "--spp", "1"]), capsys,
             name, kind)
    assert snapshot(ws) == before


def test_the_shade_card_itself_refuses_before_it_renders(ws):
    """The app's Dye panel calls ``shade_card`` without the command line's checks: the same guard holds."""
    from hairdigi.inference.dye_card import shade_card
    from hairdigi.render.domain.dye_record import DyeRecord
    from hairdigi.render.domain.errors import HairdigiError
    from hairdigi.render.domain.records import read_record

    dyes = _session_dye(ws)
    before = snapshot(ws)
    start = time.perf_counter()
    with pytest.raises(HairdigiError, match="blonde.json.*a dye record"):
        shade_card(read_record(ws / "copper.json", DyeRecord), dyes / "blonde.png", size=16, spp=1)
    assert time.perf_counter() - start < within(5)          # refused before any render
    assert snapshot(ws) == before


@pytest.mark.parametrize("args, needle", [
    (["dye", "apply", "copper.json", "--base", "r.json", "--out", "old.json"], "an estimate record"),
    (["dye", "characterise", "--pair", "r.json", "r.json", "--name", "x", "--out", "s/dyes/blonde.json"],
     "a dye record"),
    (["dye", "dose", "copper.json", "--base", "r.json", "--target", "#8a4a30", "--out", "s/dyes/blonde.json"],
     "a dye record"),
])
def test_no_dye_command_replaces_a_record(ws, capsys, args, needle):
    _session_dye(ws)
    write_record(ws / "old.json", estimate_record())
    before = snapshot(ws)
    one_line(main(args), capsys, "--out", needle, "refused")
    assert snapshot(ws) == before


# --- 7. a library address is parsed once: never taken for a file ------------------------------------
@pytest.mark.parametrize("address", [
    f"POSTGRESQL://alice:S3cr3tPW@{CLOSED}/db",
    f"Postgres://alice:S3cr3tPW@{CLOSED}/db",
    f"postgresql+psycopg://alice:S3cr3tPW@{CLOSED}/db",
    f"host=127.0.0.1 port=5999 user=alice password=S3cr3tPW dbname=db",
    f"  dbname=db host=127.0.0.1 port=5999 password = 'S3cr3tPW'",
])
def test_a_postgresql_address_is_never_taken_for_a_file(ws, capsys, monkeypatch, address):
    monkeypatch.setenv("HAIRDIGI_LIBRARY", address)
    before = snapshot(ws)
    line = one_line(main(["library", "import", "r.json"]), capsys, "cannot connect", "127.0.0.1")
    assert "S3cr3tPW" not in line
    assert snapshot(ws) == before, "a file was made for the address"
    assert not list(ws.rglob("*S3cr3t*")) and not (ws / "POSTGRESQL:").exists()


@pytest.mark.parametrize("address, needle", [
    ("mysql://alice:S3cr3tPW@db/x", "mysql://"),
    ("sqlite:///tmp/lib.sqlite", "sqlite://"),
    ("postgresql:/alice:S3cr3tPW@db/x", "postgresql://"),
    ("host=db nonsense=1 password=S3cr3tPW", "nonsense"),
    ("host=db password=S3cr3tPW nonsense=1", "a setting"),      # perhaps the password's second word: not shown
])
def test_an_address_hairdigi_cannot_open_is_refused_in_one_line(ws, capsys, monkeypatch, address, needle):
    monkeypatch.setenv("HAIRDIGI_LIBRARY", address)
    before = snapshot(ws)
    line = one_line(main(["library", "info"]), capsys, "HAIRDIGI_LIBRARY", needle)
    assert "S3cr3tPW" not in line
    assert snapshot(ws) == before


def test_the_one_parser_tells_urls_keywords_and_files_apart(tmp_path):
    from hairdigi.app.library.store import parse_location

    assert parse_location("POSTGRESQL://a:b@h/db").postgres
    assert parse_location("postgresql+psycopg://a:b@h/db").conninfo.startswith("postgresql://")
    assert parse_location("host=h dbname=db").postgres
    for path in ("lib.sqlite", str(tmp_path / "a b" / "lib.sqlite"), "x=y.sqlite", "~/lib.sqlite"):
        address = parse_location(path)
        assert not address.postgres and address.path == Path(path).expanduser()


# --- 8. a password is never printed, by hairdigi or through the driver ------------------------------
SECRETS = {
    f"postgresql://alice:Pa/ss99@{CLOSED}/db": ("Pa/ss", "ss99"),
    f"postgresql://alice:Pa@ss99@{CLOSED}/db": ("Pa@ss", "ss99"),
    f"postgresql://alice:'S3cr 3tPW'@{CLOSED}/db": ("S3cr", "3tPW"),
    f"postgresql://alice:S3cr%203tPW@{CLOSED}/db": ("S3cr", "3tPW"),
    f"host=127.0.0.1 port=5999 user=alice password='S3cr 3tPW' dbname=db": ("S3cr", "3tPW"),
    f"host=127.0.0.1 port=5999 user=alice password=S3cr 3tPW dbname=db": ("S3cr", "3tPW"),
    f"host=127.0.0.1 port=5999 user=alice password='S3cr 3tPW dbname=db": ("S3cr", "3tPW"),
    f"host=127.0.0.1 port=5999 sslpassword=K3yPhr4se user=alice": ("K3yPhr4se",),
    f"postgresql://alice@{CLOSED}/db?password=S3cr3tPW&sslmode=disable": ("S3cr3tPW",),
    # the driver's own message quotes the value of a setting: the password is masked there too
    f"postgresql://alice:S3cr3tPW@{CLOSED}/db?sslmode=S3cr3tPW": ("S3cr3tPW",),
}


@pytest.mark.parametrize("address", sorted(SECRETS))
def test_no_password_is_printed_whole_or_in_part(ws, capsys, monkeypatch, address):
    monkeypatch.setenv("HAIRDIGI_LIBRARY", address)
    before = snapshot(ws)
    start = time.perf_counter()
    code = main(["library", "info"])
    err = capsys.readouterr().err
    assert time.perf_counter() - start < within(10)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for part in SECRETS[address]:
        assert part not in err, (part, err)
    assert snapshot(ws) == before


@pytest.mark.parametrize("address", sorted(SECRETS))
def test_redact_masks_every_part_of_the_password(address):
    from hairdigi.app.library.store import redact

    shown = redact(address)
    assert "***" in shown, shown
    for part in SECRETS[address]:
        assert part not in shown, (part, shown)


def test_library_info_shows_the_address_without_its_password(capsys):
    from hairdigi.app.cli import library as library_cli

    class Fake:
        where, version = f"postgresql://alice:Pa/ss99@{CLOSED}/db", 2

        def count(self):
            return 0

        def sessions(self):
            return []

    library_cli._info(Fake(), None)
    out = capsys.readouterr().out
    assert "Pa/ss" not in out and "ss99" not in out and f"alice:***@{CLOSED}/db" in out, out


# --- 9. a session's records are checked against its images ------------------------------------------
def _capture(session: Path, cid: str, image: str | None = None, sha: str | None = None, seed: int = 0) -> Path:
    """A capture of ``session``: a small PNG ``<cid>.png`` and its records; ``image`` and ``sha`` override
    what the capture record claims."""
    captures = session / "captures"
    captures.mkdir(parents=True, exist_ok=True)
    png = captures / f"{cid}.png"
    rng = np.random.default_rng(seed)
    cv2.imwrite(str(png), rng.integers(0, 255, (6, 6, 3), dtype=np.uint8))
    real = hashlib.sha256(png.read_bytes()).hexdigest()
    write_record(captures / f"{cid}.json", CaptureRecord(id=cid, image=image or png.name, image_sha256=sha or real,
                                                          captured="2026-11-24T10:15:00+0000"))
    write_record(captures / f"{cid}.result.json", estimate_record(capture=png.name))
    return png


def _library_rows(path: Path) -> list[tuple]:
    conn = sqlite3.connect(path)
    try:
        rows = conn.execute("SELECT id, session, capture_id, image_path, note FROM swatches ORDER BY id").fetchall()
        tags = conn.execute("SELECT swatch_id, tag FROM tags ORDER BY swatch_id, tag").fetchall()
        sessions = conn.execute("SELECT path FROM sessions ORDER BY path").fetchall()
    finally:
        conn.close()
    return rows + tags + sessions


def test_a_record_that_claims_another_swatchs_image_hijacks_nothing(ws, capsys):
    good = _capture(ws / "a", "20261124-101500-001", seed=1)
    assert main(["library", "import", "a"]) == 0
    assert main(["library", "tag", "20261124-101500-001", "copper"]) == 0
    assert main(["library", "note", "20261124-101500-001", "the March copper"]) == 0
    capsys.readouterr()
    # another session's capture names its own image but claims the first one's hash
    _capture(ws / "evil", "20261124-101500-002", sha=hashlib.sha256(good.read_bytes()).hexdigest(), seed=2)
    kept, files = _library_rows(ws / "lib.sqlite"), snapshot(ws)
    one_line(main(["library", "import", "evil"]), capsys, "20261124-101500-002", "image_sha256", "does not match")
    assert _library_rows(ws / "lib.sqlite") == kept
    assert {k: v for k, v in snapshot(ws).items() if not k.startswith("lib.sqlite")} == \
        {k: v for k, v in files.items() if not k.startswith("lib.sqlite")}


@pytest.mark.parametrize("image", ["../../../../../../../../etc/passwd", "/etc/passwd", "../../r.json",
                                   "link.png", "missing.png", "sub"])
def test_a_capture_image_outside_its_session_or_missing_is_refused(ws, capsys, image):
    evil = ws / "evil"
    target = Path("/etc/passwd") if "passwd" in image else ws / "r.json"
    sha = hashlib.sha256(target.read_bytes()).hexdigest()
    _capture(evil, CAPTURE, image=image, sha=sha)
    (evil / "captures" / "link.png").symlink_to(target)
    (evil / "captures" / "sub").mkdir()
    assert main(["library", "import", "r.json"]) == 0
    capsys.readouterr()
    kept, files = _library_rows(ws / "lib.sqlite"), snapshot(ws)
    line = one_line(main(["library", "import", "evil"]), capsys, CAPTURE)
    assert any(word in line for word in ("outside", "no image", "not a regular file")), line
    assert _library_rows(ws / "lib.sqlite") == kept
    assert {k: v for k, v in snapshot(ws).items() if not k.startswith("lib.sqlite")} == \
        {k: v for k, v in files.items() if not k.startswith("lib.sqlite")}


def test_an_honest_session_still_imports(ws, capsys):
    for i in range(3):
        _capture(ws / "good", f"20261124-10150{i}-000", seed=10 + i)
    assert main(["library", "import", "good"]) == 0
    assert "imported 3 swatches" in capsys.readouterr().out


# --- 12. exported cells are neutral at every separator ----------------------------------------------
HOSTILE_NOTES = ["fine;=1+2;-3+4", "a,=HYPERLINK(\"http://evil/x\")", "ok\t+1+1", "x\n@SUM(A1)", "y|=cmd",
                 "z; =1+2", 'w;"=1+2"', "v\r-2+3"]


def _segments_safe(text: str) -> bool:
    """Whether no piece of ``text``, split wherever a spreadsheet may split it, starts a formula."""
    import re

    pieces = re.split(r"[,;|\t\r\n]", text)
    return all(not p.lstrip(" \"").startswith(("=", "+", "-", "@")) for p in pieces)


def test_exported_cells_are_neutral_at_every_separator(ws, capsys):
    from openpyxl import load_workbook

    from hairdigi.app.library.store import Library

    assert main(["library", "import", "r.json"]) == 0
    with Library() as lib:
        sid = lib.all()[0].id
    for i, text in enumerate(HOSTILE_NOTES):
        assert main(["library", "note", sid, "--", text]) == 0
        assert main(["library", "tag", sid, "--", f"t{i}", f"=t{i}+1", f"-{i}"]) == 0
        assert main(["library", "export", "--csv", f"t{i}.csv", "--xlsx", f"t{i}.xlsx"]) == 0
        raw = (ws / f"t{i}.csv").read_text(encoding="utf-8")
        for delimiter in (",", ";", "\t"):     # read as a spreadsheet of any locale would split the file
            for row in csv.reader(io.StringIO(raw, newline=""), delimiter=delimiter):
                assert all(_segments_safe(cell) for cell in row), (delimiter, row)
        row = next(csv.DictReader(open(ws / f"t{i}.csv", newline="", encoding="utf-8")))
        assert _segments_safe(row["note"]) and _segments_safe(row["tags"]), row
        sheet = load_workbook(ws / f"t{i}.xlsx").active
        header = [c.value for c in sheet[1]]
        for column in ("note", "tags"):
            cell = sheet.cell(2, header.index(column) + 1)
            assert cell.data_type != "f" and _segments_safe(cell.value), cell.value
        capsys.readouterr()


def test_neutral_cell_keeps_plain_text_and_is_idempotent():
    from hairdigi.app.cli.library import neutral_cell

    for text in ("copper", "2026-11-24T10:15:00+0000", "/data/s/captures/x.png", "a;b", "", "1.5"):
        assert neutral_cell(text) == text
    for text in HOSTILE_NOTES + ["=1+2", "-3", "@x", "\tx", "\rx", " =1"]:
        once = neutral_cell(text)
        assert neutral_cell(once) == once and _segments_safe(once), (text, once)
    assert neutral_cell(3.5) == 3.5 and neutral_cell(None) is None


# --- 14a. stored text never reaches the terminal raw -------------------------------------------------
def test_library_tag_echoes_no_escape_sequence(ws, capsys):
    assert main(["library", "import", "r.json"]) == 0
    from hairdigi.app.library.store import Library

    with Library() as lib:
        sid = lib.all()[0].id
        lib.tag(sid, ["\x1b]0;pwned\x07\x1b[2J"])       # stored by another program or an older hairdigi
    capsys.readouterr()
    assert main(["library", "tag", sid, "plain"]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "plain" in out, repr(out)
