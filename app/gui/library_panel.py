"""The Library panel (a dock of the main window): search the swatch library, sort by colour, find near a
colour, open a capture's review, and compare two swatches side by side with their ΔE2000.

A view of ``app/library/model.py``'s :class:`LibraryModel` (free of Qt), which owns the query, the rows,
the chosen swatches and their images, and the work behind them: the panel runs the model's works in
the window's worker pool and shows what the model's events carry; it queries nothing and reads no file
on the UI thread. The search runs once typing pauses (``SEARCH_DELAY_MS``), and a newer query
supersedes an older one."""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QItemSelectionModel, Qt, QTimer
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (QAbstractItemView, QComboBox, QDialog, QDockWidget, QFileDialog, QGridLayout, QHBoxLayout,
                               QLabel, QLineEdit, QPushButton, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget)

from hairdigi.app.library import model as library_model
from hairdigi.app.library import view
from hairdigi.app.gui.images import to_pixmap
from hairdigi.app.gui.workers import POOL, Jobs, Task, start
from hairdigi.app.library.store import Library, LibraryError, Swatch, open_library
from hairdigi.app.library.model import MAX_ROWS, LibraryModel
from hairdigi.app.library.swatch_colour import COLOURS

COLUMNS = ("colour", "ΔE2000", "L* a* b*", "captured", "where", "tags", "note", "id")
SORTS = {"newest first": "captured", "by colour (light to dark)": "colour"}
SEARCH_DELAY_MS = 250     # the search runs once typing pauses this long
SELECT_ROW = QItemSelectionModel.SelectionFlag.Select | QItemSelectionModel.SelectionFlag.Rows

__all__ = ["LibraryPanel", "SwatchView", "add_library_dock", "MAX_ROWS", "SEARCH_DELAY_MS"]


def _ink(hex_colour: str) -> str:
    c = QColor(hex_colour)
    return "#000" if 0.3 * c.red() + 0.6 * c.green() + 0.1 * c.blue() > 128 else "#fff"


def _chip(label: QLabel, hex_colour: str | None, text: str = "") -> None:
    if hex_colour is None:
        label.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #444")
        label.setText(text or "no colour")
        return
    label.setStyleSheet(f"background:{hex_colour}; color:{_ink(hex_colour)}; border:1px solid #888")
    label.setText(text or hex_colour)


class SwatchView(QWidget):
    """One side of the comparison: the captured swatch, its colour chip and where it came from."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        v = QVBoxLayout(self)
        self.swatch: Swatch | None = None
        self.image = QLabel("–")
        self.image.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.image.setMinimumSize(150, 100)
        self.image.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #444")
        self.chip = QLabel()
        self.chip.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.chip.setMinimumHeight(34)
        self.caption = QLabel("select a swatch")
        self.caption.setWordWrap(True)
        self.caption.setStyleSheet("font-size:10px")
        self.caption.setMinimumHeight(30)
        for w in (self.image, self.chip, self.caption):
            v.addWidget(w)
        _chip(self.chip, None, "–")

    def show_swatch(self, swatch: Swatch | None, under: str, image: tuple[bool, object] = (False, None)) -> None:
        """Show ``swatch`` under the light ``under``; ``image``: (read yet, the captured image or None)."""
        self.swatch = swatch
        if swatch is None:
            self.image.clear()
            self.image.setText("–")
            _chip(self.chip, None, "–")
            self.caption.setText("select a swatch")
            return
        self.show_image(*image)
        hex_colour = view.chip_hex(swatch, under)
        _chip(self.chip, hex_colour, f"{hex_colour or 'no colour'} ({under})")
        self.caption.setText(view.describe(swatch))

    def show_image(self, read: bool, rgb) -> None:
        self.image.clear()
        if not read:
            self.image.setText("reading…")
        elif rgb is None:
            self.image.setText("image not on this machine")
        else:
            self.image.setPixmap(to_pixmap(rgb).scaled(150, 110, Qt.AspectRatioMode.KeepAspectRatio,
                                                       Qt.TransformationMode.SmoothTransformation))


class LibraryPanel(QWidget):
    """Search, sort, find near a colour, open a review, compare two swatches."""

    def __init__(self, library: Library, window=None, parent=None) -> None:
        super().__init__(parent)
        self.model = LibraryModel(library)      # the connection is the model's, used in its works only
        self.window_ = window
        self.jobs = Jobs(self.model.apply, lambda text: self.status.setText(f"library: {text}"), owner=self)
        self.search_timer = QTimer(self)
        self.search_timer.setSingleShot(True)
        self.search_timer.setInterval(SEARCH_DELAY_MS)
        self.search_timer.timeout.connect(self.refresh)
        v = QVBoxLayout(self)
        v.addLayout(self._query_row())
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.ExtendedSelection)
        self.table.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.table.verticalHeader().setVisible(False)
        self.table.itemSelectionChanged.connect(self.show_comparison)
        self.table.doubleClicked.connect(lambda _: self.open_review())
        v.addWidget(self.table, 1)
        row = QHBoxLayout()
        for text, slot in (("Open review", self.open_review), ("Export…", self.export_dialog),
                           ("Import session…", self.import_dialog), ("Refresh", self.refresh)):
            b = QPushButton(text)
            b.clicked.connect(lambda _=False, slot=slot: slot())
            row.addWidget(b)
        v.addLayout(row)
        compare = QGridLayout()
        self.left, self.right = SwatchView(), SwatchView()
        compare.addWidget(self.left, 0, 0)
        compare.addWidget(self.right, 0, 1)
        self.delta = QLabel("select two swatches to compare them")
        self.delta.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.delta.setStyleSheet("font-weight:bold")
        compare.addWidget(self.delta, 1, 0, 1, 2)
        v.addLayout(compare)
        self.status = QLabel("reading the library…")
        self.status.setWordWrap(True)
        self.status.setStyleSheet("font-size:10px; color:#666")
        v.addWidget(self.status)
        ev = self.model.events
        for event, callback in ((ev.rows, self._show_rows), (ev.selection, self._show_selection),
                                (ev.image, self._show_image), (ev.changed, lambda _: self.refresh()),
                                (ev.status, self.status.setText)):
            event.connect(callback)
        self.refresh()

    def _query_row(self) -> QHBoxLayout:
        row = QHBoxLayout()
        self.search = QLineEdit()
        self.search.setPlaceholderText("search id, capture, session, tag, note")
        self.search.textChanged.connect(self._typed)
        self.near = QLineEdit()
        self.near.setPlaceholderText("near #RRGGBB or a tress")
        self.near.setMaximumWidth(110)
        self.near.returnPressed.connect(self.refresh)
        self.sort = QComboBox()
        self.sort.addItems(list(SORTS))
        self.sort.currentIndexChanged.connect(lambda _: self.refresh())
        self.light = QComboBox()
        self.light.addItems(list(COLOURS))   # the lights, and the instrument readings (D65, 10°)
        self.light.currentIndexChanged.connect(lambda _: self.refresh())
        for w in (self.search, self.near, self.sort, self.light):
            row.addWidget(w)
        return row

    @property
    def under(self) -> str:
        return self.model.query.under

    @property
    def swatches(self) -> tuple[Swatch, ...]:
        return self.model.rows.swatches

    @property
    def distances(self) -> dict[str, float]:
        return self.model.rows.distances

    # -- the query ------------------------------------------------------------------------------
    def _typed(self, _text: str) -> None:
        """A key in the search: the query runs once typing pauses (each key restarts the wait)."""
        self.search_timer.start()

    def refresh(self) -> Task | None:
        """Query the library again (in a worker) with the search, the colour, the order and the light chosen."""
        self.search_timer.stop()
        self.model.set_query(text=self.search.text(), near=self.near.text(), order=SORTS[self.sort.currentText()],
                             under=self.light.currentText())
        return self.jobs.run("query", self.model.query_work())

    def _show_rows(self, rows: library_model.Rows) -> None:
        under, chosen = rows.query.under, {s.id for s in self.model.selection.swatches}
        self.table.blockSignals(True)
        self.table.clearSelection()
        self.table.setRowCount(len(rows.swatches))
        for r, s in enumerate(rows.swatches):
            hex_colour = view.chip_hex(s, under)
            chip = QTableWidgetItem(hex_colour or "–")
            if hex_colour:
                chip.setBackground(QColor(hex_colour))
                chip.setForeground(QColor(_ink(hex_colour)))
            de = rows.distances.get(s.id)
            where = f"{Path(s.session).name}/{s.capture_id}" if s.session else Path(s.record_path or "").name
            cells = [chip, QTableWidgetItem("" if de is None else f"{de:.2f}"), QTableWidgetItem(view.lab_text(s, under)),
                     QTableWidgetItem(s.captured or ""),
                     QTableWidgetItem(where), QTableWidgetItem(", ".join(s.tags)), QTableWidgetItem(s.note),
                     QTableWidgetItem(s.id)]
            for c, item in enumerate(cells):
                self.table.setItem(r, c, item)
            if s.id in chosen:             # the swatches chosen stay chosen where the new rows hold them
                self.table.selectionModel().select(self.table.model().index(r, 0), SELECT_ROW)
        self.table.blockSignals(False)
        self.table.resizeColumnsToContents()
        self.show_comparison()

    # -- the chosen swatches ------------------------------------------------------------------------
    def selected(self) -> list[Swatch]:
        rows = sorted({i.row() for i in self.table.selectedIndexes()})
        return [self.swatches[r] for r in rows if r < len(self.swatches)]

    def show_comparison(self) -> None:
        self.model.select(self.selected())
        self.jobs.run("images", self.model.image_work())

    def _show_selection(self, selection: library_model.Selection) -> None:
        chosen = selection.swatches
        for side, swatch in ((self.left, chosen[0] if chosen else None),
                             (self.right, chosen[1] if len(chosen) > 1 else None)):
            side.show_swatch(swatch, self.under, self.model.image(swatch) if swatch is not None else (False, None))
        self.delta.setText(selection.comparison.text() if selection.comparison is not None
                           else "select two swatches to compare them")

    def _show_image(self, image: library_model.SwatchImage) -> None:
        dialog = getattr(self, "review_dialog", None)
        sides = [self.left, self.right] + ([dialog.side] if dialog is not None else [])
        for side in sides:
            if side.swatch is not None and side.swatch.id == image.swatch_id:
                side.show_image(True, image.rgb)

    def open_review(self) -> None:
        """The capture's review: in the window when it is of the window's session, else in a dialog."""
        chosen = self.selected()
        if not chosen:
            return
        s = chosen[0]
        session = getattr(getattr(self.window_, "session", None), "folder", None)
        if s.session and session is not None and Path(s.session) == Path(session).resolve() and s.capture_id:
            self.window_.select_capture(s.capture_id)
            return
        dialog = QDialog(self)
        dialog.setWindowTitle(f"hairdigi — {s.capture_id or s.id}")
        layout = QVBoxLayout(dialog)
        dialog.side = SwatchView()
        dialog.side.show_swatch(s, self.under, self.model.image(s))
        layout.addWidget(dialog.side)
        dialog.show()
        self.review_dialog = dialog
        self.jobs.run("review image", self.model.image_work([s]))

    # -- export and import --------------------------------------------------------------------------
    def export_dialog(self) -> None:
        """Export → MaterialX (.mtlx) or Blender (.py) of the selected swatch's estimate."""
        chosen = self.selected()
        if not chosen or not chosen[0].record_path:
            self.status.setText("select a swatch with an estimate to export")
            return
        s = chosen[0]
        default = Path.home() / f"{s.capture_id or s.id}.mtlx"
        path, kind = QFileDialog.getSaveFileName(self, "Export the hair colour", str(default),
                                                 "MaterialX (*.mtlx);;Blender script (*.py)")
        if path:
            self.export_to(s, path, "blender" if path.endswith(".py") or "Blender" in kind else "materialx")

    def export_to(self, swatch: Swatch, path: str, fmt: str) -> Task | None:
        """Write the export in a worker; the status says where when it is done."""
        return self.jobs.run("export", self.model.export_work(swatch, path, fmt))

    def import_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Import a session folder into the library")
        if folder:
            self.import_sessions([folder])

    def import_sessions(self, folders: list[str]) -> Task | None:
        """Import in a worker, on its own connection; the table refreshes when it is done."""
        return self.jobs.run(None, self.model.import_work(folders))      # never cancelled by the next one

    def first_run(self) -> Task | None:
        return self.jobs.run(None, self.model.first_run_work())


def _open_or_reason():
    """The library, or the one line why it cannot be opened (run in a worker: a lock or a server may take seconds)."""
    try:
        return open_library()
    except (LibraryError, OSError) as exc:
        return " ".join(str(exc).split())


def unavailable_label(text: str) -> QLabel:
    """A label that shows all of a long message: wrapped, selectable, and in its tooltip."""
    label = QLabel(text)
    label.setWordWrap(True)
    label.setAlignment(Qt.AlignmentFlag.AlignTop | Qt.AlignmentFlag.AlignLeft)
    label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
    label.setToolTip(text)
    label.setMinimumWidth(200)
    return label


def add_library_dock(window) -> QDockWidget:
    """The Library panel as a dock of ``window``, on the library ``HAIRDIGI_LIBRARY`` names (or the default).

    The library is opened in a worker (a held lock or a slow server costs the window nothing): the dock
    says so until it is open, then holds the panel, or the one line why the library is unavailable."""
    dock = QDockWidget("Library", window)
    dock.setWidget(unavailable_label("opening the library…"))

    def opened(result) -> None:
        try:
            if isinstance(result, str):
                dock.setWidget(unavailable_label(f"library unavailable: {result}"))
                return
            panel = LibraryPanel(result, window)
            dock.setWidget(panel)
        except RuntimeError:          # the window closed while the library was opening
            if not isinstance(result, str):
                result.close()
            return
        model = panel.model
        dock.destroyed.connect(lambda *_: model.close())
        panel.first_run()
        captured = getattr(window, "captured", None)
        session = getattr(getattr(window, "session", None), "folder", None)
        if captured is not None and session is not None:   # every capture goes into the library too
            captured.connect(lambda *_: panel.import_sessions([str(session)]))

    task = Task(_open_or_reason, "library")
    task.signals.done.connect(opened)
    task.signals.failed.connect(lambda message: dock.setWidget(unavailable_label(f"library unavailable: {message}")))
    dock.open_task = start(task, POOL)   # kept: the dock owns the worker until it reports
    window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
    other = getattr(window, "dye_dock", None)
    if isinstance(other, QDockWidget):
        window.tabifyDockWidget(other, dock)
    return dock
