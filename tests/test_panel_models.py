"""The Dye and Library panels: their models without Qt, and the panels as views that do no disk, database
or render work on the UI thread.

Real captures and a real library (SQLite in a tmp folder). Which thread did the work is observed, not
assumed: file opens through a Python audit hook, SQL statements through SQLite's trace callback, and
``characterise`` through a spy that records its thread and calls the real one."""
import sys
import threading
from dataclasses import replace
from pathlib import Path

import pytest

from hairdigi.app.library.store import Library
from hairdigi.inference.levels import natural_base
from hairdigi.render.domain.absorption import dye_sigma_a, hair_sigma_a
from hairdigi.render.domain.records import EstimateRecord, RefinementRecord, write_record
from test_library import make_session

DEPOSIT = dye_sigma_a((190.0, 70.0, 40.0), 0.55)   # a copper dye's absorption
LIFT = 0.35
QUIET_S = 0.6       # longer than the search's debounce: a query still due has started by then

# --- observing threads ---------------------------------------------------------------------------------
_WATCH: dict = {"root": None, "opened": []}


def _audit(event: str, args: tuple) -> None:
    """Every file opened under the watched folder, with the thread that opened it (Python's open and os.open)."""
    root = _WATCH["root"]
    if root is not None and event == "open" and isinstance(args[0], str) and args[0].startswith(root):
        _WATCH["opened"].append((threading.get_ident(), args[0]))


sys.addaudithook(_audit)     # for the process's life: it does nothing while no test watches


@pytest.fixture
def opened(tmp_path):
    """(thread, path) of each file opened under ``tmp_path`` from now to the test's end."""
    _WATCH["opened"] = []
    _WATCH["root"] = str(tmp_path)
    yield _WATCH["opened"]
    _WATCH["root"] = None


def traced(library: Library) -> list[tuple[int, str]]:
    """(thread, SQL) of each statement the library's connection runs from now on."""
    statements: list[tuple[int, str]] = []
    library.db.conn.set_trace_callback(lambda sql: statements.append((threading.get_ident(), sql)))
    return statements


def queries(statements) -> list[str]:
    """The swatch queries among ``statements`` (each of ``Library.all`` and ``Library.find`` runs one)."""
    return [sql for _, sql in statements if sql.lstrip().startswith("SELECT swatches.id")]


# --- real captures and a real library ------------------------------------------------------------------
@pytest.fixture(scope="module")
def curve():
    from hairdigi.inference import dye as D

    return D.rig_curve()


def _estimate(sigma, level: int, capture: str) -> EstimateRecord:
    """An estimate record as ``hairdigi estimate`` writes it, its refinement having found ``sigma``."""
    return EstimateRecord(hair=natural_base(level), capture=capture,
                          refinement=RefinementRecord(ran=True, sigma_a=tuple(map(float, sigma))))


def dye_session(folder: Path) -> dict[str, Path]:
    """A session folder with (natural base, dyed) captures at levels 8 and 5, and one blocked capture."""
    captures, paths = folder / "captures", {}
    for level in (8, 5):
        m = hair_sigma_a(natural_base(level))
        for kind, sigma in (("base", m), ("dyed", (1 - LIFT) * m + DEPOSIT)):
            name = f"{kind}{level}"
            paths[name] = captures / f"{name}.result.json"
            write_record(paths[name], _estimate(sigma, level, f"{name}.png"))
    write_record(captures / "blocked.result.json", EstimateRecord(hair=None, capture="b.png", blocked=("no chart",)))
    return paths


def swatch_library(folder: Path) -> Library:
    """Ten swatches of two sessions, one tagged copper, in a library file of their own."""
    from hairdigi.app.library.importing import import_paths

    make_session(folder / "march", 6, seed=21)
    make_session(folder / "april", 4, seed=22)
    library = Library(folder / "data" / "library.sqlite")
    import_paths(library, [folder / "march", folder / "april"], progress=lambda line: None)
    library.tag("20260021-000001", ["copper"])
    return library


# --- the panels do no work on the UI thread --------------------------------------------------------------
def test_the_dye_panel_reads_and_characterises_off_the_ui_thread(curve, tmp_path, qtbot, opened, monkeypatch):
    from hairdigi.app.gui.dye_panel import DyePanel, select_path
    from hairdigi.inference import dye as D

    paths = dye_session(tmp_path)
    characterised_in, real = [], D.characterise

    def spy(*args, **kw):
        characterised_in.append(threading.get_ident())
        return real(*args, **kw)

    monkeypatch.setattr(D, "characterise", spy)
    ui = threading.get_ident()
    panel = DyePanel(tmp_path)
    qtbot.addWidget(panel)
    qtbot.waitUntil(lambda: panel.base_combo.count() == 4, timeout=20_000)     # the blocked capture is not offered
    for level in (8, 5):
        assert select_path(panel.base_combo, paths[f"base{level}"]) and select_path(panel.dyed_combo, paths[f"dyed{level}"])
        panel.add_pair()
    panel.name_edit.setText("Copper 7/4")
    panel.characterise()
    qtbot.waitUntil(lambda: "lift 0.35" in panel.dye_info.text(), timeout=60_000)
    qtbot.waitUntil(lambda: panel.dye_combo.currentText() == "Copper-7-4", timeout=20_000)
    reads = [(thread, path) for thread, path in opened if path.endswith(".result.json")]
    assert reads and characterised_in                      # the work was seen
    assert [path for thread, path in reads if thread == ui] == []
    assert ui not in characterised_in


def test_the_library_panel_queries_and_reads_off_the_ui_thread(tmp_path, qtbot, opened):
    from hairdigi.app.gui.library_panel import LibraryPanel

    library = swatch_library(tmp_path)
    opened.clear()
    statements = traced(library)
    ui = threading.get_ident()
    panel = LibraryPanel(library)
    qtbot.addWidget(panel)
    panel.show()
    qtbot.waitUntil(lambda: panel.table.rowCount() == 10, timeout=20_000)
    panel.table.selectRow(0)                                # the comparison reads the capture and its record
    qtbot.waitUntil(lambda: not panel.left.image.pixmap().isNull(), timeout=20_000)
    assert queries(statements) and opened                   # the work was seen
    assert [sql for thread, sql in statements if thread == ui] == []
    assert [path for thread, path in opened if thread == ui] == []
    library.close()


def test_typing_five_characters_quickly_runs_at_most_two_queries(tmp_path, qtbot):
    from hairdigi.app.gui.library_panel import LibraryPanel

    library = swatch_library(tmp_path)
    statements = traced(library)
    panel = LibraryPanel(library)
    qtbot.addWidget(panel)
    qtbot.waitUntil(lambda: panel.table.rowCount() == 10, timeout=20_000)
    qtbot.wait(int(QUIET_S * 1000))
    statements.clear()
    qtbot.keyClicks(panel.search, "coppe", delay=20)       # 5 keys in about 0.1 s
    qtbot.waitUntil(lambda: panel.table.rowCount() == 1, timeout=20_000)
    qtbot.wait(int(QUIET_S * 1000))
    assert 1 <= len(queries(statements)) <= 2, queries(statements)
    assert "copper" in panel.table.item(0, 5).text()
    library.close()


def test_a_newer_search_wins_in_the_panel(tmp_path, qtbot):
    from hairdigi.app.gui.library_panel import LibraryPanel

    library = swatch_library(tmp_path)
    panel = LibraryPanel(library)
    qtbot.addWidget(panel)
    qtbot.waitUntil(lambda: panel.table.rowCount() == 10, timeout=20_000)
    panel.search.setText("copper")
    older = panel.refresh()
    panel.search.setText("")
    newer = panel.refresh()
    for task in (older, newer):
        qtbot.waitUntil(lambda task=task: task not in panel.jobs.running, timeout=20_000)
    qtbot.wait(int(QUIET_S * 1000))
    assert panel.table.rowCount() == 10 and panel.model.rows.query.text == ""
    library.close()


def test_the_dye_panel_previews_and_cards_off_the_ui_thread(curve, tmp_path, qtbot, opened):
    from hairdigi.app.gui.dye_panel import DyePanel

    paths = dye_session(tmp_path)
    _capture_image(paths["base5"])
    dye = _saved_dye(tmp_path, paths)
    opened.clear()
    ui = threading.get_ident()
    panel = DyePanel(tmp_path, settings=SMALL)
    qtbot.addWidget(panel)
    qtbot.waitUntil(lambda: panel.dye_combo.count() == 1 and panel.target_combo.count() == 4, timeout=20_000)
    from hairdigi.app.gui.dye_panel import select_path

    assert select_path(panel.target_combo, paths["base5"]) and select_path(panel.dye_combo, dye)
    panel.preview()
    qtbot.waitUntil(lambda: not panel.style_label.pixmap().isNull(), timeout=120_000)
    assert not panel.real_label.pixmap().isNull() and not panel.pred_label.pixmap().isNull()
    assert panel.pred_info.text().startswith("predicted #")
    panel.card()
    qtbot.waitUntil(lambda: not panel.card_label.pixmap().isNull(), timeout=120_000)
    assert (tmp_path / "dyes" / "copper-card.pdf").is_file() and "shade card" in panel.status.text()
    panel.preview()
    panel.cancel()                                          # stopped at its next pass: the labels say so
    qtbot.waitUntil(lambda: panel.pred_label.text() == "–" and panel.style_label.text() == "–", timeout=60_000)
    assert panel.pred_label.pixmap().isNull() and not panel.jobs.busy()
    assert any(path.endswith("base5.result.json") for _, path in opened)
    assert [path for thread, path in opened if thread == ui] == []


def test_the_dye_dock_offers_a_new_capture_once_the_window_has_saved_it(tmp_path, qtbot):
    from PySide6.QtCore import Signal
    from PySide6.QtWidgets import QMainWindow

    from hairdigi.app.gui.dye_panel import add_dye_dock

    class Window(QMainWindow):
        captured = Signal(object)

    dye_session(tmp_path)
    window = Window()
    qtbot.addWidget(window)
    panel = add_dye_dock(window, tmp_path).widget()
    qtbot.waitUntil(lambda: panel.base_combo.count() == 4, timeout=20_000)
    write_record(tmp_path / "captures" / "new.result.json", _estimate(hair_sigma_a(natural_base(6)), 6, "new.png"))
    window.captured.emit(None)
    qtbot.waitUntil(lambda: panel.base_combo.count() == 5, timeout=20_000)


# --- the models without Qt -----------------------------------------------------------------------------
from hairdigi.app.dye import model as dm  # noqa: E402
from hairdigi.app.library import model as lm  # noqa: E402
from hairdigi.app.models.work import run_now  # noqa: E402

SMALL = dm.DyeSettings(preview_size=24, preview_spp=2, hairstyle_size=24, hairstyle_spp=1, card_size=16, card_spp=2)


def _capture_image(record: Path) -> None:
    """The capture's picture beside its record (a flat swatch colour)."""
    import cv2
    import numpy as np

    cv2.imwrite(str(record.with_name(record.name.replace(".result.json", ".png"))), np.full((20, 30, 3), (40, 80, 160), np.uint8))


def _saved_dye(folder: Path, paths) -> Path:
    """A copper characterised from the session's two pairs, saved where the panel finds its dyes."""
    from hairdigi.inference import dye as D

    pairs = [(D.load_sample(paths[f"base{lv}"]), D.load_sample(paths[f"dyed{lv}"])) for lv in (8, 5)]
    path = folder / "dyes" / "copper.json"
    write_record(path, D.characterise(pairs, "copper"))
    return path


def recorder(model) -> list[tuple[str, object]]:
    """(event name, value) of every event the model emits, in order."""
    seen = []
    for name in model.Events.EVENTS:
        getattr(model.events, name).connect(lambda value, name=name: seen.append((name, value)))
    return seen


def test_the_dye_model_lists_estimates_and_dyes_and_an_older_listing_is_dropped(tmp_path):
    folder = tmp_path / "session"
    paths = dye_session(folder)
    other = tmp_path / "other-session" / "captures" / "x.result.json"
    write_record(other, _estimate(hair_sigma_a(natural_base(6)), 6, "x.png"))
    (folder / "dyes").mkdir()
    (folder / "dyes" / "copper-card.json").write_text("{}")        # a shade card's table is no dye
    write_record(folder / "dyes" / "copper.json", EstimateRecord(hair=natural_base(5)))
    model = dm.DyeModel(folder)
    seen = recorder(model)
    older = model.reload_work()
    model.add_records([other, paths["base8"]])                     # the session's own record is no extra
    newer = model.reload_work()
    assert seen == []                                              # nothing is read until a worker runs it
    run_now(newer, model.apply)
    run_now(older, model.apply)                                    # came back last: dropped
    assert model.records == sorted(paths.values()) + [other]
    assert [model.name(p) for p in model.records][-1] == "other-session/x" and model.name(paths["dyed5"]) == "dyed5"
    assert model.dyes == [folder / "dyes" / "copper.json"]
    assert [name for name, _ in seen] == ["records", "dyes"]


def test_the_dye_model_characterises_in_its_work_and_says_why_not(curve, tmp_path):
    paths = dye_session(tmp_path)
    model = dm.DyeModel(tmp_path)
    run_now(model.reload_work(), model.apply)
    seen = recorder(model)
    assert not model.add_pair(paths["base8"], paths["base8"]) and "different dyed" in model.status
    assert model.characterise_work("Copper 7/4") is None and "add at least one pair" in model.status
    for level in (8, 5):
        assert model.add_pair(paths[f"base{level}"], paths[f"dyed{level}"])
    assert model.characterise_work("  ") is None
    work = model.characterise_work("Copper 7/4")
    assert not (tmp_path / "dyes").exists()                         # asked for, not done
    done = run_now(work, model.apply)
    assert isinstance(done, dm.Characterised) and done.path == tmp_path / "dyes" / "Copper-7-4.json"
    assert done.dye.lift == pytest.approx(LIFT, abs=1e-4) and "lift 0.35" in done.text
    assert model.dyes == [done.path] and model.characterised is done
    names = [name for name, _ in seen]
    assert names[-4:] == ["records", "dyes", "status", "characterised"] and names.count("pairs") == 2
    # a record that is no estimate: one line, nothing saved
    junk = tmp_path / "junk.json"
    junk.write_text('{"not": "a record"}')
    model.clear_pairs()
    model.add_pair(junk, paths["dyed8"])
    assert run_now(model.characterise_work("Junk"), model.apply) == dm.Status(model.status)
    assert "junk.json" in model.status and not (tmp_path / "dyes" / "Junk.json").exists()


def test_the_dye_model_previews_then_a_newer_preview_stops_the_older(curve, tmp_path):
    paths = dye_session(tmp_path)
    _capture_image(paths["base5"])
    dye = _saved_dye(tmp_path, paths)
    model = dm.DyeModel(tmp_path, SMALL)
    seen = recorder(model)
    assert model.preview_work(None, paths["base5"], 1.0) is None and "choose a dye" in model.status
    older = model.preview_work(dye, paths["base5"], 1.0).run()
    crop = next(older)                                              # the capture, read in the work
    run_now(model.preview_work(dye, paths["dyed5"], 1.5), model.apply)
    model.apply(crop)                                               # the older work's: dropped
    with pytest.raises(StopIteration) as stop:                       # and it stops before it renders
        next(older)
    assert stop.value.value is None
    assert [name for name, _ in seen if name != "status"] == ["capture", "preview", "hairstyle"]
    assert model.crop.rgb is None                                   # dyed5 has no picture on this machine
    assert model.preview.swatch.shape == (24, 24, 3) and model.hairstyle.rgb.shape[:2] == (24, 24)
    assert model.preview.text.startswith("predicted #") and model.status == "preview ready"
    card = run_now(model.card_work(dye), model.apply)
    assert card.path == tmp_path / "dyes" / "copper-card.png" and card.rgb.ndim == 3 and seen[-1] == ("card", card)


def test_the_library_model_queries_and_an_older_answer_never_overwrites_a_newer(tmp_path):
    library = swatch_library(tmp_path)
    statements = traced(library)
    model = lm.LibraryModel(library)
    seen = recorder(model)
    run_now(model.query_work(), model.apply)
    assert len(model.swatches) == 10 and "10 swatches; 10 shown" in model.status
    model.set_query(text="copper")
    older = model.query_work()
    model.set_query(text="")
    newer = model.query_work()
    statements.clear()
    run_now(newer, model.apply)
    assert run_now(older, model.apply) is None                       # superseded before it ran: no query at all
    assert len(queries(statements)) == 1 and len(model.swatches) == 10 and model.rows.query.text == ""
    model.set_query(text="copper")
    rows = _returned(model.query_work().run())                       # it ran (a slow query) ...
    assert [s.tags for s in rows.swatches] == [("copper",)]
    model.set_query(text="")
    run_now(model.query_work(), model.apply)                         # ... and a newer one came back first
    model.apply(rows)
    assert len(model.swatches) == 10 and model.rows.query.text == ""
    model.set_query(text="", order="colour")
    run_now(model.query_work(), model.apply)
    lightness = [s.labs["daylight"][0] for s in model.swatches]
    assert lightness == sorted(lightness, reverse=True)
    model.set_query(near="#8a4a30")
    run_now(model.query_work(), model.apply)
    des = [model.rows.distances[s.id] for s in model.swatches]
    assert des == sorted(des) and len(des) == 10
    model.set_query(near="#12")
    run_now(model.query_work(), model.apply)                         # a bad colour: one line, the rows kept
    assert "#RRGGBB" in model.status and len(model.swatches) == 10
    assert [name for name, _ in seen].count("rows") == 5              # the stale ones never emitted
    with pytest.raises(ValueError):
        model.set_query(order="random")
    library.close()


def _returned(generator):
    """Run a work's generator to its end; what it returned."""
    try:
        while True:
            next(generator)
    except StopIteration as stop:
        return stop.value


def test_the_library_model_compares_reads_images_imports_and_exports(tmp_path):
    from hairdigi.app.library.view import compare

    library = swatch_library(tmp_path)
    model = lm.LibraryModel(library)
    run_now(model.query_work(), model.apply)
    seen = recorder(model)
    chosen = model.swatches[:2]
    selection = model.select(model.swatches[:3])                     # two at most
    assert selection.swatches == chosen and selection.comparison.text() == compare(*chosen).text()
    assert model.image(chosen[0]) == (False, None)
    images = []
    run_now(model.image_work(), lambda image: (images.append(image), model.apply(image)))
    assert [i.swatch_id for i in images] == [s.id for s in chosen] and all(i.rgb.shape == (4, 4, 3) for i in images)
    assert model.image(chosen[1])[0] and model.image_work() is None  # read once
    model.set_query(under="studio")                                  # another light: the comparison again
    assert seen[-1][0] == "selection" and model.selection.swatches == chosen
    # an import on a connection of its own, then the panel queries again
    make_session(tmp_path / "may", 3, seed=23)
    imported = run_now(model.import_work([str(tmp_path / "may")]), model.apply)
    assert imported.count == 3 and ("changed", 3) in seen and "imported" in model.status
    run_now(model.query_work(), model.apply)
    assert len(model.swatches) == 13
    # export in the work; a swatch without an estimate says so
    exported = run_now(model.export_work(chosen[0], tmp_path / "chosen.mtlx", "materialx"), model.apply)
    assert "chiang_hair_bsdf" in exported.paths[0].read_text() and model.status.startswith("wrote")
    assert model.export_work(replace(chosen[0], record_path=None), tmp_path / "x.mtlx", "materialx") is None
    assert "select a swatch with an estimate" in model.status
    failed = run_now(model.export_work(chosen[0], tmp_path / "x.mtlx", "obj"), model.apply)
    assert isinstance(failed, dm.Status) and "unknown export format" in model.status
    library.close()


def test_the_library_model_closes_after_its_running_work_and_changes_on_its_own_thread(tmp_path):
    library = swatch_library(tmp_path)
    model = lm.LibraryModel(library)
    with model._connection():                                        # a work holds the connection ...
        model.close()                                                # ... the UI thread does not wait for it
        assert library.count() == 10
    with pytest.raises(Exception, match="closed"):
        library.count()
    run_now(model.query_work(), model.apply)
    assert "closed" in model.status
    other = lm.LibraryModel(swatch_library(tmp_path / "b"))
    failures = []
    thread = threading.Thread(target=lambda: _catch(failures, lambda: other.apply(lm.SwatchImage("x", None))))
    thread.start()
    thread.join()
    assert "own thread" in str(failures[0])
    other.close()


def _catch(failures: list, fn) -> None:
    try:
        fn()
    except RuntimeError as exc:
        failures.append(exc)


def test_the_models_import_without_qt():
    import subprocess

    code = ("import sys, hairdigi.app.dye.model, hairdigi.app.library.model; "
            "print(sorted(m for m in ('PySide6', 'pyvista', 'pyvistaqt', 'vtk') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]"
