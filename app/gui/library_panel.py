"""The Library panel (a dock of the main window): search the swatch library, sort by colour, find near a
colour, open a capture's review, and compare two swatches side by side with their ΔE2000.

The library is ``app/library.py`` (Qt-free); this file holds widgets only."""
from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (QAbstractItemView, QComboBox, QDialog, QDockWidget, QFileDialog, QGridLayout, QHBoxLayout,
                               QLabel, QLineEdit, QPushButton, QTableWidget, QTableWidgetItem, QVBoxLayout, QWidget)

from hairdigi.app import library_view as view
from hairdigi.app.gui.images import to_pixmap
from hairdigi.app.gui.workers import POOL, Task, start
from hairdigi.app.library import Library, Swatch, redact
from hairdigi.app.swatch_colour import ILLUMINANTS, hex_lab

COLUMNS = ("colour", "ΔE2000", "captured", "where", "tags", "note", "id")
SORTS = {"newest first": "captured", "by colour (light to dark)": "colour"}
MAX_ROWS = 500    # rows the table shows; search or find near a colour to reach the rest


def _chip(label: QLabel, hex_colour: str | None, text: str = "") -> None:
    if hex_colour is None:
        label.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #444")
        label.setText(text or "no colour")
        return
    c = QColor(hex_colour)
    ink = "#000" if 0.3 * c.red() + 0.6 * c.green() + 0.1 * c.blue() > 128 else "#fff"
    label.setStyleSheet(f"background:{hex_colour}; color:{ink}; border:1px solid #888")
    label.setText(text or hex_colour)


class SwatchView(QWidget):
    """One side of the comparison: the captured swatch, its colour chip and where it came from."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        v = QVBoxLayout(self)
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

    def show_swatch(self, swatch: Swatch | None, under: str) -> None:
        if swatch is None:
            self.image.clear()
            self.image.setText("–")
            _chip(self.chip, None, "–")
            self.caption.setText("select a swatch")
            return
        image = view.capture_image(swatch)
        if image is None:
            self.image.clear()
            self.image.setText("image not on this machine")
        else:
            self.image.setPixmap(to_pixmap(image).scaled(150, 110, Qt.AspectRatioMode.KeepAspectRatio,
                                                         Qt.TransformationMode.SmoothTransformation))
        _chip(self.chip, view.chip_hex(swatch, under), f"{view.chip_hex(swatch, under) or 'no colour'} ({under})")
        self.caption.setText(view.describe(swatch))


class LibraryPanel(QWidget):
    """Search, sort, find near a colour, open a review, compare two swatches."""

    def __init__(self, library: Library, window=None, parent=None) -> None:
        super().__init__(parent)
        self.library = library
        self.window_ = window
        self.swatches: list[Swatch] = []
        self.distances: dict[str, float] = {}
        v = QVBoxLayout(self)
        row = QHBoxLayout()
        self.search = QLineEdit()
        self.search.setPlaceholderText("search id, capture, session, tag, note")
        self.search.textChanged.connect(lambda _: self.refresh())
        self.near = QLineEdit()
        self.near.setPlaceholderText("near #RRGGBB")
        self.near.setMaximumWidth(110)
        self.near.returnPressed.connect(self.refresh)
        self.sort = QComboBox()
        self.sort.addItems(list(SORTS))
        self.sort.currentIndexChanged.connect(lambda _: self.refresh())
        self.light = QComboBox()
        self.light.addItems(list(ILLUMINANTS))
        self.light.currentIndexChanged.connect(lambda _: self.refresh())
        for w in (self.search, self.near, self.sort, self.light):
            row.addWidget(w)
        v.addLayout(row)
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
            b.clicked.connect(slot)
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
        self.status = QLabel()
        self.status.setWordWrap(True)
        self.status.setStyleSheet("font-size:10px; color:#666")
        v.addWidget(self.status)
        self.refresh()

    @property
    def under(self) -> str:
        return self.light.currentText()

    def refresh(self) -> None:
        """Read the library again with the search, the colour and the order chosen."""
        near = self.near.text().strip()
        self.distances = {}
        try:
            if near:
                matches = self.library.find(hex_lab(near), self.under, k=200)
                text = self.search.text().strip().lower()
                matches = [(s, d) for s, d in matches if not text or text in
                           " ".join([s.id, s.capture_id or "", s.session or "", s.note, *s.tags]).lower()]
                self.swatches = [s for s, _ in matches]
                self.distances = {s.id: d for s, d in matches}
            else:
                self.swatches = self.library.all(self.search.text().strip(), SORTS[self.sort.currentText()],
                                                 limit=MAX_ROWS)
        except ValueError as exc:
            self.status.setText(str(exc))
            return
        self.table.setRowCount(len(self.swatches))
        for r, s in enumerate(self.swatches):
            hex_colour = view.chip_hex(s, self.under)
            chip = QTableWidgetItem(hex_colour or "–")
            if hex_colour:
                chip.setBackground(QColor(hex_colour))
                c = QColor(hex_colour)
                chip.setForeground(QColor("#000" if 0.3 * c.red() + 0.6 * c.green() + 0.1 * c.blue() > 128 else "#fff"))
            de = self.distances.get(s.id)
            where = f"{Path(s.session).name}/{s.capture_id}" if s.session else Path(s.record_path or "").name
            cells = [chip, QTableWidgetItem("" if de is None else f"{de:.2f}"), QTableWidgetItem(s.captured or ""),
                     QTableWidgetItem(where), QTableWidgetItem(", ".join(s.tags)), QTableWidgetItem(s.note),
                     QTableWidgetItem(s.id)]
            for c, item in enumerate(cells):
                self.table.setItem(r, c, item)
        self.table.resizeColumnsToContents()
        self.status.setText(f"library {redact(self.library.where)}: {self.library.count()} swatches; "
                            f"{len(self.swatches)} shown" + (" (the first ones: search to narrow)" if len(self.swatches) >= MAX_ROWS
                                                               else ""))
        self.show_comparison()

    def selected(self) -> list[Swatch]:
        rows = sorted({i.row() for i in self.table.selectedIndexes()})
        return [self.swatches[r] for r in rows if r < len(self.swatches)]

    def show_comparison(self) -> None:
        chosen = self.selected()[:2]
        self.left.show_swatch(chosen[0] if chosen else None, self.under)
        self.right.show_swatch(chosen[1] if len(chosen) > 1 else None, self.under)
        if len(chosen) == 2:
            self.delta.setText(view.compare(*chosen).text())
        else:
            self.delta.setText("select two swatches to compare them")

    def open_review(self) -> None:
        """The capture's review: in the window when it is of the window's session, else in a dialog."""
        chosen = self.selected()
        if not chosen:
            return
        s = chosen[0]
        session = getattr(getattr(self.window_, "session", None), "folder", None)
        if s.session and session is not None and Path(s.session) == Path(session).resolve() and s.capture_id:
            self.window_.model.select(s.capture_id)
            return
        dialog = QDialog(self)
        dialog.setWindowTitle(f"hairdigi — {s.capture_id or s.id}")
        layout = QVBoxLayout(dialog)
        side = SwatchView()
        side.show_swatch(s, self.under)
        layout.addWidget(side)
        dialog.show()
        self.review_dialog = dialog

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

    def export_to(self, swatch: Swatch, path: str, fmt: str) -> None:
        from hairdigi.app.export_cli import export_record

        try:
            written = export_record(swatch.record_path, fmt, path, name=swatch.capture_id or swatch.id)
        except (ValueError, OSError) as exc:
            self.status.setText(f"export: {exc}")
            return
        self.status.setText(f"wrote {written[0]}")

    def import_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Import a session folder into the library")
        if folder:
            self.import_sessions([folder])

    def import_sessions(self, folders: list[str]) -> Task:
        """Import in a worker, on its own connection; the table refreshes when it is done."""
        where = self.library.where

        def work():
            from hairdigi.app.library_import import import_paths

            with Library(where) as lib:
                return import_paths(lib, folders, progress=lambda line: None)
        return self._run(work, f"imported {', '.join(folders)}")

    def first_run(self) -> Task:
        where = self.library.where

        def work():
            from hairdigi.app.library_import import first_run

            with Library(where) as lib:
                return first_run(lib, progress=lambda line: None)
        return self._run(work, "sessions written before the library imported")

    def _run(self, fn, done_text: str) -> Task:
        task = Task(fn, "library")
        task.signals.done.connect(lambda n: (self.refresh(), self.status.setText(f"{done_text}: {n} swatches")))
        task.signals.failed.connect(lambda message: self.status.setText(f"library: {message}"))
        self._task = task
        return start(task, POOL)


def _open_or_reason():
    """The library, or the one line why it cannot be opened (run in a worker: a lock or a server may take seconds)."""
    from hairdigi.app.library import LibraryError, open_library

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
        dock.destroyed.connect(lambda *_: result.close())
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
