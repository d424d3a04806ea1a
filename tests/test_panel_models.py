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

from hairdigi.app.library import Library
from hairdigi.inference.levels import natural_base
from hairdigi.render.absorption import dye_sigma_a, hair_sigma_a
from hairdigi.render.base.records import EstimateRecord, RefinementRecord, write_record
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
    from hairdigi.app.library_import import import_paths

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
    assert "copper" in panel.table.item(0, 4).text()
    library.close()
