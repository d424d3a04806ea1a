"""The swatch library on real SQLite files (and a real PostgreSQL server where this machine can start one):
migrations, import, find, tag, note, export, first run, a SIGKILL mid-import, and two writing processes."""
import csv
import json
import glob
import hashlib
import logging
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from hairdigi.app.cli import main
from hairdigi.app.library.store import SCHEMA_VERSION, Library, LibraryError
from hairdigi.app.library.swatch_colour import hex_lab, lab_hex, rendered_linear, swatch_labs
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.estimate_parts import Provenance
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import CaptureRecord, EstimateRecord, RefinementRecord, write_record
from hairdigi.render.metrics import delta_e2000
from deadlines import within


def make_session(folder: Path, n: int, seed: int = 0, images: bool = True, blocked: int = 0) -> list[HairParams]:
    """A session folder as the rig writes it: per capture an image, its capture record and its result record
    (``images=False``: the image file holds random bytes, not a PNG: quicker for thousands of captures)."""
    rng = np.random.default_rng(seed)
    captures = folder / "captures"
    captures.mkdir(parents=True, exist_ok=True)
    hairs = []
    for i in range(n):
        cid = f"2026{seed:04d}-{i:06d}"
        data = rng.integers(0, 255, 48, dtype=np.uint8).tobytes() + f"{seed}-{i}".encode()
        if images:
            import cv2

            cv2.imwrite(str(captures / f"{cid}.png"), np.frombuffer(data[:48], np.uint8).reshape(4, 4, 3))
            data = (captures / f"{cid}.png").read_bytes()
        else:      # the image's bytes only (no PNG to encode): the import checks its hash all the same
            (captures / f"{cid}.png").write_bytes(data)
        write_record(captures / f"{cid}.json", CaptureRecord(id=cid, image=f"{cid}.png",
                                                              image_sha256=hashlib.sha256(data).hexdigest(),
                                                              captured=f"2026-03-{1 + i % 28:02d}T10:00:00+0000"))
        if i < blocked:
            write_record(captures / f"{cid}.result.json", EstimateRecord(hair=None, capture=f"{cid}.png",
                                                                         blocked=("the swatch is clipped",)))
            continue
        hair = HairParams(tuple(float(v) for v in rng.uniform(0, 255, 3)), float(rng.uniform()),
                          float(rng.uniform()), float(rng.uniform()))
        hairs.append(hair)
        write_record(captures / f"{cid}.result.json", EstimateRecord(hair=hair, capture=f"{cid}.png"))
    return hairs


@pytest.fixture
def lib_env(tmp_path, monkeypatch):
    """A fresh library file and no pre-library sessions, through the settings the CLI and app read."""
    path = tmp_path / "data" / "library.sqlite"
    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(path))
    monkeypatch.setenv("HAIRDIGI_SESSIONS", str(tmp_path / "no-sessions"))
    return path


def _cli(*args, env=None, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "hairdigi.app.cli", *args], capture_output=True, text=True,
                          env={**os.environ, **(env or {})}, timeout=600, **kw)


# --- colours -------------------------------------------------------------------------------------
def test_colours_under_two_lights():
    assert np.allclose(hex_lab("#ffffff"), [100, 0, 0], atol=0.01)
    assert lab_hex(hex_lab("#8a4a30")) == "#8a4a30"
    with pytest.raises(ValueError, match="#RRGGBB"):
        hex_lab("#12345")
    grey = np.array([[0.3, 0.3, 0.3], [3.0, 3.0, 3.0]])
    labs = swatch_labs(grey)
    assert labs["daylight"][0, 0] > labs["daylight"][1, 0]          # more absorption, darker
    assert abs(labs["daylight"][0, 1]) < 1 and abs(labs["daylight"][0, 2]) < 1   # grey fibres stay grey
    assert labs["studio"][0, 2] > labs["daylight"][0, 2] + 10        # tungsten: warmer on a daylight photo


def test_the_studio_colour_of_a_swatch_with_parameters_comes_from_its_spectrum():
    """Under the 3200 K lamps a dye's absorption band moves as a spectrum does, not as an RGB product:
    measured, a saturated red 3.96 and a copper red 3.51 ΔE2000 from the RGB renderer's studio colour,
    black 0.03; daylight (what the rig measured) is the same either way."""
    import colour

    from hairdigi.render.domain.absorption import hair_sigma_a

    hairs = [HairParams((255, 0, 0), 1.0, 0.0, 0.5),
             HairParams(melanin_concentration=0.98, melanin_ratio=0.9, dye_concentration=0.0)]
    sigma = np.array([hair_sigma_a(h) for h in hairs])
    rgb, spectral = swatch_labs(sigma), swatch_labs(sigma, hairs)
    assert np.allclose(rgb["daylight"], spectral["daylight"])
    moved = colour.delta_E(rgb["studio"], spectral["studio"], method="CIE 2000")
    assert moved[0] > 2.0 and moved[1] < 0.5, moved


# --- migrations ----------------------------------------------------------------------------------
def test_migrations_apply_once_in_order_and_keep_data(lib_env):
    with Library(str(lib_env), migrate_to=1) as old:
        assert old.version == 1
        assert not old.db.has_table("tags")
        old.db.execute("INSERT INTO swatches (id, kind, imported, record) VALUES ('x1', 'estimate', 'now', '{}')")
    with Library(str(lib_env)) as lib:
        assert lib.version == SCHEMA_VERSION == 3
        assert lib.count() == 1 and lib.tag("x1", ["kept"]) == ("kept",)
        assert lib.migrate() == []
        rows = lib.db.query("SELECT version FROM schema_version ORDER BY version")
        assert [r[0] for r in rows] == [1, 2, 3]
    conn = sqlite3.connect(lib_env)
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    conn.execute("INSERT INTO schema_version VALUES (99, 'from the future', 'now')")
    conn.commit()
    conn.close()
    with pytest.raises(LibraryError, match="newer than this hairdigi"):
        Library(str(lib_env))


def test_not_a_library_is_one_line_and_exit_2(tmp_path, monkeypatch, capsys):
    bad = tmp_path / "junk.sqlite"
    bad.write_bytes(b"this is not a database" * 100)
    monkeypatch.setenv("HAIRDIGI_LIBRARY", str(bad))
    assert main(["library", "info"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a hairdigi library" in err


# --- import, find, tag, note, export ---------------------------------------------------------------
def test_import_find_tag_note_export(tmp_path, lib_env, capsys):
    hairs = make_session(tmp_path / "march", 12, seed=1, blocked=2)
    assert main(["library", "import", str(tmp_path / "march")]) == 0
    assert "imported 12 swatches" in capsys.readouterr().out
    with Library() as lib:
        assert lib.count() == 12                      # every capture, blocked ones too
        assert sum(bool(s.labs) for s in lib.all()) == 10
    # a record of one of them finds it first, at ΔE 0; the rest in rising ΔE, checked independently
    record = tmp_path / "march" / "captures" / "20260001-000005.result.json"
    assert main(["library", "find", "--near", str(record), "--k", "4"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 4 and "20260001-000005" in lines[0] and "ΔE2000   0.00" in lines[0]
    des = [float(line.split("ΔE2000")[1].split()[0]) for line in lines]
    assert des == sorted(des)
    target = rendered_linear(hair_sigma_a(hairs[3]))
    expected = sorted(float(delta_e2000(rendered_linear(hair_sigma_a(h)), target)) for h in hairs)[:4]
    assert np.allclose(des, expected, atol=0.006)
    # by hex, under the studio light
    assert main(["library", "find", "--near", "#8a4a30", "--under", "studio", "--k", "3"]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == 3
    # tag and note by capture id; re-import keeps them and adds nothing
    assert main(["library", "tag", "20260001-000005", "copper", "march"]) == 0
    assert main(["library", "note", "20260001-000005", "the copper we measured in March"]) == 0
    assert main(["library", "import", str(tmp_path / "march")]) == 0
    capsys.readouterr()
    with Library() as lib:
        assert lib.count() == 12
        swatch = lib.get("20260001-000005")
        assert swatch.tags == ("copper", "march") and swatch.note == "the copper we measured in March"
        assert [s.capture_id for s in lib.all("copper")] == ["20260001-000005"]
        by_colour = [s.labs["daylight"][0] for s in lib.all(order="colour") if s.labs]
        assert by_colour == sorted(by_colour, reverse=True)
    assert main(["library", "tag", "20260001-000005", "march", "--remove"]) == 0
    # export
    out_csv, out_xlsx = tmp_path / "lib.csv", tmp_path / "lib.xlsx"
    assert main(["library", "export", "--csv", str(out_csv), "--xlsx", str(out_xlsx)]) == 0
    rows = list(csv.DictReader(out_csv.open()))
    assert len(rows) == 12 and {r["tags"] for r in rows} >= {"copper"}
    import openpyxl

    sheet = openpyxl.load_workbook(out_xlsx).active
    assert sheet.max_row == 13 and sheet.cell(1, 1).value == "id"
    # expected failures: one line, exit 2
    capsys.readouterr()
    for argv in (["library", "find", "--near", "#zzzzzz"], ["library", "tag", "nosuch", "x"],
                 ["library", "import", str(tmp_path / "nowhere")], ["library", "export"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("hairdigi library: error:"), err


def test_lone_estimates_and_dye_predictions_are_swatches_too(tmp_path, lib_env):
    from hairdigi.app.library.importing import import_paths

    hair = HairParams((120.0, 60.0, 160.0), 0.7, 0.3, 0.5)
    estimate = write_record(tmp_path / "violet.json", EstimateRecord(hair=hair))
    prediction = write_record(tmp_path / "violet-on-blonde.json", EstimateRecord(
        hair=hair, refinement=RefinementRecord(ran=True, sigma_a=(0.2, 0.5, 0.1)),
        provenance=Provenance(prediction={"dye": "violet", "dose": 1.0})))
    with Library() as lib:
        assert import_paths(lib, [estimate, prediction], progress=lambda line: None) == 2
        kinds = {s.record_path: s.kind for s in lib.all()}
        assert kinds == {str(estimate.resolve()): "estimate", str(prediction.resolve()): "dye"}
        dye = next(s for s in lib.all() if s.kind == "dye")
        assert dye.sigma_a == (0.2, 0.5, 0.1)          # the prediction's sigma_a, not Table 1's mapping


def test_two_captures_of_one_image_are_one_swatch_and_import(tmp_path, lib_env):
    """A session where two captures hold the same image (a still imported twice; the simulated rig's first frame in
    two app runs) imports as one swatch, the later capture's, where it failed on the colours' unique key."""
    from hairdigi.app.library.importing import import_paths

    folder = tmp_path / "session"
    make_session(folder, 2)
    captures = folder / "captures"
    first, second = sorted(captures.glob("*.png"))
    shutil.copyfile(first, second)                       # the second capture's image is the first's, byte for byte
    record = CaptureRecord.from_json(json.loads((captures / f"{second.stem}.json").read_text()))
    write_record(captures / f"{second.stem}.json", CaptureRecord(
        id=record.id, image=record.image, image_sha256=hashlib.sha256(first.read_bytes()).hexdigest(),
        captured=record.captured))
    with Library() as lib:
        assert import_paths(lib, [folder], progress=lambda line: None) == 1
        (swatch,) = lib.all()
        assert swatch.capture_id == second.stem                      # the later capture's record stands
        assert import_paths(lib, [folder], progress=lambda line: None) == 1 and len(lib.all()) == 1


def test_rows_are_typed_and_the_columns_keep_their_bytes(tmp_path, lib_env, caplog):
    """A row carries its records typed (``SwatchRecord``) and its parameters as ``HairParams``; what is written
    is what the library always wrote (the record column: ``{"capture", "result"}`` of a capture, a lone
    record itself; the hair column: ``HairParams.to_dict()``), and a library written before reads back,
    first-layout records and record-less rows included."""
    import json

    from hairdigi.app.library.importing import capture_rows, import_paths, record_row
    from hairdigi.app.library.store import SwatchRecord
    from hairdigi.render.domain.records import InstrumentReading, SpectralReading

    make_session(tmp_path / "march", 2, seed=7, blocked=1)
    spectral = HairParams((190.0, 90.0, 50.0), 0.45, 0.5, 0.6)
    lone = write_record(tmp_path / "lone.json", EstimateRecord(
        hair=HairParams((200.0, 80.0, 40.0), 0.4, 0.5, 0.6),
        spectral=SpectralReading(hair=spectral, led="D65", camera="cie", residual=0.2),
        instrument=(InstrumentReading("d/8 SCI", (40.0, 10.0, 20.0)),
                    InstrumentReading("d/8 SCE", (41.0, 10.0, 20.0), observer="2"))))   # not 10°: not stored
    blocked, captured = capture_rows(tmp_path / "march")
    assert isinstance(captured.record.capture, CaptureRecord) and isinstance(captured.hair, HairParams)
    assert captured.record.estimate.hair == captured.hair and blocked.hair is None
    assert blocked.record.estimate.blocked == ("the swatch is clipped",)
    row = record_row(lone)
    assert row.record.capture is None and set(row.labs) == {"daylight", "studio", "d/8 SCI"}
    assert row.labs["d/8 SCI"] == (40.0, 10.0, 20.0)
    # the studio colour comes from the spectral answer's hair, the daylight colour from sigma_a
    want = swatch_labs(np.array([row.sigma_a]), [spectral])
    assert np.allclose(row.labs["studio"], want["studio"][0]) and np.allclose(row.labs["daylight"], want["daylight"][0])

    with Library() as lib:
        import_paths(lib, [tmp_path / "march", lone], progress=lambda line: None)
        stored = dict(lib.db.query("SELECT id, record FROM swatches"))
        hairs = dict(lib.db.query("SELECT id, hair FROM swatches"))
        for r in (blocked, captured, row):
            files = ({"capture": json.loads((tmp_path / "march" / "captures" / f"{r.capture_id}.json").read_text()),
                      "result": json.loads(Path(r.record_path).read_text())} if r.capture_id
                     else json.loads(lone.read_text()))
            assert stored[r.id] == json.dumps(files)           # the records as written, key for key
            assert hairs[r.id] == (None if r.hair is None else json.dumps(r.hair.to_dict()))
            assert lib.record(r.id) == r.record and lib.get(r.id).hair == r.hair

    # a library of an earlier hairdigi: first-layout records (no kind, no schema_version) and a row without one
    old = {"dye_rgb": [12.5, 250.0, 3.0], "dye_concentration": 0.25, "melanin_concentration": 0.5, "melanin_ratio": 0.75}
    with Library(str(tmp_path / "old.sqlite"), migrate_to=1) as lib:
        for sid, kind, hair, record in (
                ("c1", "capture", old, {"capture": {"image": "a.png", "image_sha256": "ab", "captured": "then"},
                                        "result": {"hair": old, "capture": "a.png"}}),
                ("c2", "capture", None, {"capture": {"image": "b.png", "image_sha256": "cd"}, "result": None}),
                ("e1", "estimate", old, {"hair": old}),
                ("x1", "estimate", None, {})):
            lib.db.execute("INSERT INTO swatches (id, kind, imported, hair, record) VALUES (?, ?, 'then', ?, ?)",
                           (sid, kind, None if hair is None else json.dumps(hair), json.dumps(record)))
    with Library(str(tmp_path / "old.sqlite")) as lib:
        assert lib.get("c1").hair == lib.get("e1").hair == HairParams((12.5, 250.0, 3.0), 0.25, 0.5, 0.75)
        assert lib.get("c2").hair is None
        c1 = lib.record("c1")
        assert c1.capture.image == "a.png" and c1.estimate.hair == lib.get("c1").hair and c1.estimate.capture == "a.png"
        assert lib.record("c2") == SwatchRecord(capture=lib.record("c2").capture) and lib.record("c2").estimate is None
        assert lib.record("e1").capture is None and lib.record("e1").estimate.hair.melanin_ratio == 0.75
        assert lib.record("x1") == SwatchRecord() and SwatchRecord().to_json() == {}
        lib.db.execute("UPDATE swatches SET hair = ? WHERE id = 'e1'", ('{"dye_rgb": [1, 2]}',))
        lib.db.execute("UPDATE swatches SET record = ? WHERE id = 'x1'", ('{"kind": "dye"}',))
        with caplog.at_level(logging.WARNING):      # a damaged row is listed without parameters, never hides the rest
            damaged = lib.get("e1")
        assert damaged.hair is None and not damaged.reliable and "swatch e1: its stored parameters" in caplog.text
        assert {s.id for s in lib.all()} == {"c1", "c2", "e1", "x1"}
        with pytest.raises(LibraryError, match="swatch x1: its stored record cannot be read"):
            lib.record("x1")


def test_find_through_the_lightness_index_is_exact(lib_env):
    """``find`` reads a band of L* only; it must rank exactly as a scan of every swatch does."""
    from hairdigi.app.evaluation.bench_library import synthetic_rows
    from hairdigi.app.library.swatch_colour import delta_e

    with Library() as lib:
        lib.add(synthetic_rows(1500, seed=4))
        rows = lib.db.query("SELECT swatch_id, l, a, b FROM colours WHERE illuminant = ?", ("studio",))
        ids, labs = [r[0] for r in rows], np.array([r[1:] for r in rows])
        rng = np.random.default_rng(5)
        for _ in range(60):
            q = np.array([rng.uniform(0, 100), rng.uniform(-70, 70), rng.uniform(-70, 70)])
            k = int(rng.integers(1, 40))
            de = delta_e(labs, q[None])
            want = [ids[i] for i in np.argsort(de, kind="stable")[:k]]
            got = lib.find(q, "studio", k)
            assert [s.id for s, _ in got] == want
            assert np.allclose([d for _, d in got], np.sort(de)[:k])


def test_first_run_imports_sessions_written_before_the_library(tmp_path, lib_env, monkeypatch, capsys):
    make_session(tmp_path / "sessions" / "a", 3, seed=2)
    make_session(tmp_path / "sessions" / "b", 2, seed=3)
    monkeypatch.setenv("HAIRDIGI_SESSIONS", str(tmp_path / "sessions"))
    assert main(["library", "info"]) == 0
    assert "swatches: 5" in capsys.readouterr().out
    make_session(tmp_path / "sessions" / "c", 4, seed=4)     # written after: imported by hand, not again
    assert main(["library", "info"]) == 0
    assert "swatches: 5" in capsys.readouterr().out


# --- crashes and concurrency -------------------------------------------------------------------------
def _session_counts(path: Path, session: Path) -> tuple[int, int, int, str]:
    conn = sqlite3.connect(path)
    try:
        swatches = conn.execute("SELECT COUNT(*) FROM swatches WHERE session = ?", (str(session),)).fetchone()[0]
        colours = conn.execute("SELECT COUNT(*) FROM colours").fetchone()[0]
        marked = conn.execute("SELECT COUNT(*) FROM sessions WHERE path = ?", (str(session),)).fetchone()[0]
        check = conn.execute("PRAGMA integrity_check").fetchone()[0]
    finally:
        conn.close()
    return swatches, colours, marked, check


@pytest.mark.slow
def test_sigkill_mid_import_leaves_a_consistent_library(tmp_path, lib_env):
    """A real process killed with SIGKILL while it writes a session: the session is all there or not at all."""
    big = tmp_path / "big"
    n = 3000
    make_session(big, n, seed=5, images=False)
    with Library() as lib:     # create it and its first-run mark first
        lib.set_setting("first_run_import", "{}")
    outcomes = []
    for delay in (0.0, 0.0, 0.02, 0.05):
        proc = subprocess.Popen([sys.executable, "-m", "hairdigi.app.cli", "library", "import", str(big)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for line in proc.stdout:
            if line.startswith("writing"):
                break
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
        assert proc.returncode == -signal.SIGKILL
        swatches, colours, marked, check = _session_counts(lib_env, big.resolve())
        assert check == "ok"
        assert (swatches, colours, marked) in ((0, 0, 0), (n, 2 * n, 1)), (delay, swatches, colours, marked)
        outcomes.append(swatches)
        if swatches:          # committed before the kill: start again from an empty library
            with Library() as lib, lib.db.transaction():
                lib.db.execute("DELETE FROM swatches")
                lib.db.execute("DELETE FROM sessions")
    assert 0 in outcomes, "no kill landed before the commit: the test did not test a kill mid-import"
    done = _cli("library", "import", str(big))
    assert done.returncode == 0, done.stderr
    assert _session_counts(lib_env, big.resolve()) == (n, 2 * n, 1, "ok")


@pytest.mark.slow
def test_two_writers_do_not_corrupt_the_library(tmp_path, lib_env):
    """Two processes import different sessions and tag at the same time: both finish, nothing is lost."""
    sessions = {w: [tmp_path / f"{w}{i}" for i in range(3)] for w in ("a", "b")}
    for w, folders in sessions.items():
        for i, folder in enumerate(folders):
            make_session(folder, 300, seed=10 * (w == "b") + i, images=False)
    with Library() as lib:
        lib.set_setting("first_run_import", "{}")
    procs = [subprocess.Popen([sys.executable, "-m", "hairdigi.app.cli", "library", "import", *map(str, folders)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for folders in sessions.values()]
    with Library() as lib:      # a third writer tags, and reads, while they import
        for _ in range(20):
            ids = [r[0] for r in lib.db.query("SELECT id FROM swatches LIMIT 5")]
            for sid in ids:
                lib.tag(sid, ["seen"])
            with Library() as reader:     # opening and finding never wait for the importers' write lock
                start = time.perf_counter()
                reader.find(hex_lab("#8a4a30"), "daylight", 3)
                assert time.perf_counter() - start < within(5.0)
            time.sleep(0.05)
    for proc in procs:
        out, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err
    with Library() as lib:
        assert lib.count() == 1800 and len(lib.sessions()) == 6 and lib.integrity() == []
        assert int(lib.db.query("SELECT COUNT(*) FROM colours")[0][0]) == 3600


# --- PostgreSQL ------------------------------------------------------------------------------------
def _initdb() -> str | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb")) or [shutil.which("initdb")]
    return found[-1] if found and found[-1] else None


@pytest.fixture(scope="module")
def postgres_url(tmp_path_factory):
    """A throw-away PostgreSQL server in a temporary folder (Debian's postgresql package), or a skip."""
    pytest.importorskip("psycopg")
    initdb = _initdb()
    if initdb is None:
        pytest.skip("no PostgreSQL server binaries (Debian: apt-get install postgresql)")
    bindir = Path(initdb).parent
    root = Path(tempfile.mkdtemp(prefix="hairdigi-pg-"))   # not under pytest's folder: the server's user must reach it
    as_user = []
    if os.geteuid() == 0:           # initdb refuses root: run the server as the postgres user
        if shutil.which("runuser") is None:
            pytest.skip("running as root without runuser: cannot start PostgreSQL as another user")
        shutil.chown(root, "postgres")
        as_user = ["runuser", "-u", "postgres", "--"]
    data, port = root / "data", 54000 + os.getpid() % 1000
    subprocess.run([*as_user, str(initdb), "-D", str(data), "-A", "trust", "-U", "postgres"], check=True,
                   capture_output=True, timeout=120)
    subprocess.run([*as_user, str(bindir / "pg_ctl"), "-D", str(data), "-l", str(root / "log"), "-w", "-o",
                    f"-p {port} -k {root} -c listen_addresses=''", "start"], check=True, capture_output=True, timeout=120)
    import psycopg

    with psycopg.connect(f"postgresql://postgres@/postgres?host={root}&port={port}", autocommit=True) as conn:
        conn.execute("CREATE DATABASE hairdigi_test")
    yield f"postgresql://postgres@/hairdigi_test?host={root}&port={port}"
    subprocess.run([*as_user, str(bindir / "pg_ctl"), "-D", str(data), "-m", "immediate", "stop"], capture_output=True)
    shutil.rmtree(root, ignore_errors=True)


def test_postgresql_same_schema_same_commands(tmp_path, postgres_url, monkeypatch, capsys):
    monkeypatch.setenv("HAIRDIGI_LIBRARY", postgres_url)
    monkeypatch.setenv("HAIRDIGI_SESSIONS", str(tmp_path / "none"))
    make_session(tmp_path / "shared", 8, seed=7)
    assert main(["library", "import", str(tmp_path / "shared")]) == 0
    assert main(["library", "tag", "20260007-000002", "shared"]) == 0
    assert main(["library", "find", "--near", str(tmp_path / "shared" / "captures" / "20260007-000002.result.json"),
                 "--k", "3"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert "20260007-000002" in lines[-3] and "ΔE2000   0.00" in lines[-3] and "[shared]" in lines[-3]
    with Library() as lib:
        assert lib.db.postgres and lib.version == SCHEMA_VERSION and lib.count() == 8 and lib.integrity() == []
        with pytest.raises(RuntimeError):    # a failed transaction leaves nothing behind
            with lib.db.transaction():
                lib.db.execute("UPDATE swatches SET note = 'half' WHERE capture_id = '20260007-000001'")
                raise RuntimeError("killed")
        assert lib.get("20260007-000001").note == ""
    # a second process on the same server sees it all
    proc = _cli("library", "info", env={"HAIRDIGI_LIBRARY": postgres_url})
    assert proc.returncode == 0 and "swatches: 8" in proc.stdout


# --- the Library panel -----------------------------------------------------------------------------
def test_library_panel_search_sort_find_compare_review(tmp_path, lib_env, qtbot, test_output):
    from hairdigi.app.gui.library_panel import LibraryPanel
    from hairdigi.app.library.view import compare

    make_session(tmp_path / "march", 6, seed=21)
    make_session(tmp_path / "april", 4, seed=22)
    with Library() as lib:
        from hairdigi.app.library.importing import import_paths

        import_paths(lib, [tmp_path / "march", tmp_path / "april"], progress=lambda line: None)
        lib.tag("20260021-000001", ["copper"])
    library = Library()
    panel = LibraryPanel(library)           # queries run in workers: the table fills when they are done
    qtbot.addWidget(panel)
    panel.resize(900, 700)
    panel.show()
    qtbot.waitUntil(lambda: panel.table.rowCount() == 10, timeout=20_000)
    panel.search.setText("copper")          # run once typing pauses
    qtbot.waitUntil(lambda: panel.table.rowCount() == 1, timeout=20_000)
    assert "copper" in panel.table.item(0, 5).text()
    panel.search.setText("")
    qtbot.waitUntil(lambda: panel.table.rowCount() == 10, timeout=20_000)
    panel.sort.setCurrentIndex(1)           # by colour, light to dark
    qtbot.waitUntil(lambda: panel.model.rows.query.order == "colour", timeout=20_000)
    lightness = [s.labs["daylight"][0] for s in panel.swatches]
    assert lightness == sorted(lightness, reverse=True)
    panel.near.setText("#8a4a30")
    panel.refresh()
    qtbot.waitUntil(lambda: panel.table.item(0, 1) is not None and panel.table.item(0, 1).text() != "", timeout=20_000)
    des = [float(panel.table.item(r, 1).text()) for r in range(panel.table.rowCount())]
    assert des == sorted(des) and len(des) == 10
    lab = panel.swatches[0].labs["daylight"]
    assert panel.table.item(0, 2).text() == f"{lab[0]:.1f} {lab[1]:.1f} {lab[2]:.1f}"
    reference = panel.swatches[3]
    panel.near.setText(reference.capture_id)          # near a reference tress: its own colour first
    panel.refresh()
    qtbot.waitUntil(lambda: panel.swatches and panel.swatches[0].id == reference.id, timeout=20_000)
    assert panel.table.item(0, 1).text() == "0.00"
    panel.near.setText("#8a4a30")
    panel.refresh()
    qtbot.waitUntil(lambda: panel.swatches and panel.swatches[0].id != reference.id, timeout=20_000)
    panel.table.selectRow(0)
    panel.table.setSelectionMode(panel.table.SelectionMode.MultiSelection)
    panel.table.selectRow(3)
    chosen = panel.selected()
    assert len(chosen) == 2
    expected = compare(*chosen).text()
    assert panel.delta.text() == expected and "daylight: ΔE2000" in expected
    assert panel.left.chip.text().startswith("#") and panel.right.caption.text().startswith("march") or \
        panel.right.caption.text().startswith("april")
    qtbot.waitUntil(lambda: not panel.left.image.pixmap().isNull() and not panel.right.image.pixmap().isNull(),
                    timeout=20_000)         # the captures, read in a worker
    panel.open_review()                     # not the window's session: a dialog with the capture
    assert panel.review_dialog.isVisible() and not panel.review_dialog.side.image.pixmap().isNull()
    task = panel.export_to(chosen[0], str(tmp_path / "chosen.mtlx"), "materialx")    # Export → MaterialX
    qtbot.waitUntil(lambda: panel.status.text().startswith("wrote"), timeout=20_000)
    assert task is not None and "chiang_hair_bsdf" in (tmp_path / "chosen.mtlx").read_text()
    panel.grab().save(str(test_output / "library-panel.png"))
    library.close()
