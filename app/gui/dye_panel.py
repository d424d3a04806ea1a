"""The Dye panel (a dock of the main window): characterise a dye from captures, preview it on any
capture, show its shade card. A view of ``app/dye/model.py``'s :class:`DyeModel` (free of Qt), which
owns the state and the work: the panel runs the model's works in the window's worker pool and shows
what the model's events carry; it reads no file and renders nothing on the UI thread."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QComboBox, QDockWidget, QDoubleSpinBox, QFileDialog, QGroupBox, QHBoxLayout, QLabel,
                               QLineEdit, QListWidget, QPushButton, QVBoxLayout, QWidget)

from hairdigi.app.dye import model as dye_model
from hairdigi.app.dye.model import DyeModel, DyeSettings
from hairdigi.app.gui.images import to_pixmap
from hairdigi.app.gui.workers import Jobs


def select_path(combo: QComboBox, path: Path) -> bool:
    """Make the item holding ``path`` current (Qt's findData does not compare Python objects)."""
    for i in range(combo.count()):
        if Path(combo.itemData(i)) == Path(path):
            combo.setCurrentIndex(i)
            return True
    return False


class DyePanel(QWidget):
    """Pick base and dyed captures, characterise and save; preview a dye on a capture; its shade card."""

    def __init__(self, folder: Path, parent=None, settings: DyeSettings | None = None) -> None:
        super().__init__(parent)
        self.model = DyeModel(folder, settings)
        self.folder = self.model.folder
        self.jobs = Jobs(self.model.apply, self.show_status, owner=self)
        v = QVBoxLayout(self)
        v.addWidget(self._characterise_box())
        v.addWidget(self._preview_box(), 1)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        v.addWidget(self.status)
        ev = self.model.events
        for event, callback in ((ev.records, self._show_records), (ev.dyes, self._show_dyes),
                                (ev.pairs, self._show_pairs), (ev.characterised, self._show_characterised),
                                (ev.capture, lambda crop: self._show(self.real_label, crop.rgb)),
                                (ev.preview, self._show_preview),
                                (ev.hairstyle, lambda p: self._show(self.style_label, p.rgb)),
                                (ev.card, self._show_card), (ev.status, self.status.setText)):
            event.connect(callback)
        self.reload()

    # -- layout ----------------------------------------------------------------------------
    def _characterise_box(self) -> QGroupBox:
        box = QGroupBox("Characterise a dye from (natural base, dyed) captures")
        v = QVBoxLayout(box)
        row = QHBoxLayout()
        self.base_combo, self.dyed_combo = QComboBox(), QComboBox()
        for label, combo in (("base", self.base_combo), ("dyed", self.dyed_combo)):
            row.addWidget(QLabel(label))
            row.addWidget(combo, 1)
        for text, slot in (("Add pair", self.add_pair), ("Clear", self.model.clear_pairs)):
            b = QPushButton(text)
            b.clicked.connect(lambda _=False, slot=slot: slot())
            row.addWidget(b)
        v.addLayout(row)
        self.pair_list = QListWidget()
        self.pair_list.setMaximumHeight(70)
        v.addWidget(self.pair_list)
        row = QHBoxLayout()
        more = QPushButton("Records from other sessions…")
        more.clicked.connect(self.add_records_dialog)
        row.addWidget(more)
        self.name_edit = QLineEdit()
        self.name_edit.setPlaceholderText("dye name, e.g. Copper 7.4")
        row.addWidget(self.name_edit, 1)
        self.name_edit.setMaxLength(200)   # a pasted megabyte is no name (hairdigi dye --name takes 200 too)
        save = QPushButton("Characterise && save")
        save.clicked.connect(self.characterise)
        row.addWidget(save)
        v.addLayout(row)
        self.dye_info = QLabel("no dye yet")
        self.dye_info.setWordWrap(True)
        v.addWidget(self.dye_info)
        return box

    def _preview_box(self) -> QGroupBox:
        style = self.model.settings.hairstyle
        box = QGroupBox("Preview a dye on a capture")
        v = QVBoxLayout(box)
        row = QHBoxLayout()
        self.dye_combo = QComboBox()
        self.target_combo = QComboBox()
        self.dose_spin = QDoubleSpinBox()
        self.dose_spin.setRange(0.0, 3.0)
        self.dose_spin.setSingleStep(0.1)
        self.dose_spin.setValue(1.0)
        for label, widget in (("dye", self.dye_combo), ("on", self.target_combo), ("dose", self.dose_spin)):
            row.addWidget(QLabel(label))
            row.addWidget(widget, 0 if widget is self.dose_spin else 1)
        v.addLayout(row)
        row = QHBoxLayout()
        for text, slot in (("Preview", self.preview), ("Shade card", self.card), ("Cancel", self.cancel)):
            b = QPushButton(text)
            b.clicked.connect(lambda _=False, slot=slot: slot())
            row.addWidget(b)
        v.addLayout(row)
        row = QHBoxLayout()
        for caption in ("the capture", "predicted twin", f"predicted hairstyle ({style})"):
            text = QLabel(caption)
            text.setAlignment(Qt.AlignmentFlag.AlignCenter)
            row.addWidget(text)
        v.addLayout(row)
        row = QHBoxLayout()
        self.real_label, self.pred_label, self.style_label = (self._image("capture"), self._image("predicted twin"),
                                                              self._image(f"predicted {style}"))
        for label in (self.real_label, self.pred_label, self.style_label):
            row.addWidget(label)
        v.addLayout(row)
        self.pred_info = QLabel("")
        self.pred_info.setWordWrap(True)
        v.addWidget(self.pred_info)
        self.card_label = self._image("shade card", (360, 120))
        v.addWidget(self.card_label, 1)
        return box

    @staticmethod
    def _image(text: str, size=(120, 120)) -> QLabel:
        label = QLabel(text)
        label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        label.setMinimumSize(*size)
        label.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #444")
        return label

    # -- the model's state, shown ----------------------------------------------------------------
    def _show_records(self, records: list[Path]) -> None:
        for combo in (self.base_combo, self.dyed_combo, self.target_combo):
            current = combo.currentData()
            combo.clear()
            for path in records:
                combo.addItem(self.model.name(path), path)
            if current is not None:
                select_path(combo, current)
        if self.dyed_combo.count() > 1 and self.dyed_combo.currentIndex() == self.base_combo.currentIndex():
            self.dyed_combo.setCurrentIndex(1)

    def _show_dyes(self, dyes: list[Path]) -> None:
        current = self.dye_combo.currentData()
        self.dye_combo.clear()
        for path in dyes:
            self.dye_combo.addItem(path.stem, path)
        if current is not None:
            select_path(self.dye_combo, current)

    def _show_pairs(self, pairs: list[tuple[Path, Path]]) -> None:
        self.pair_list.clear()
        for base, dyed in pairs:
            self.pair_list.addItem(f"{self.model.name(base)}  →  {self.model.name(dyed)}")

    def _show_characterised(self, done: dye_model.Characterised) -> None:
        self.dye_info.setText(done.text)
        select_path(self.dye_combo, done.path)

    def _show_preview(self, p: dye_model.PreviewPass) -> None:
        self._show(self.pred_label, p.swatch)
        self.pred_info.setText(p.text)

    def _show_card(self, card: dye_model.Card) -> None:
        if card.rgb is None:
            self.card_label.setText(f"shade card written: {card.path}")
        else:
            self._show(self.card_label, card.rgb)

    @staticmethod
    def _show(label: QLabel, rgb: np.ndarray | None) -> None:
        if rgb is not None:
            label.setPixmap(to_pixmap(rgb).scaled(label.size(), Qt.AspectRatioMode.KeepAspectRatio,
                                                  Qt.TransformationMode.SmoothTransformation))

    def show_status(self, text: str) -> None:
        self.status.setText(text)

    # -- actions: the model's works, run in workers ---------------------------------------------
    def reload(self):
        """Re-read the session's estimated captures and saved dyes (in a worker)."""
        return self.jobs.run("records", self.model.reload_work())

    def add_records_dialog(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Estimate records or captures", str(self.folder),
                                                "records (*.json)")
        if paths:
            self.model.add_records(paths)
            self.reload()

    def add_pair(self) -> None:
        self.model.add_pair(self.base_combo.currentData(), self.dyed_combo.currentData())

    def characterise(self):
        work = self.model.characterise_work(self.name_edit.text())
        if work is not None:
            self.dye_info.setText("characterising…")
        return self.jobs.run("characterise", work)

    def preview(self):
        work = self.model.preview_work(self.dye_combo.currentData(), self.target_combo.currentData(),
                                       self.dose_spin.value())
        return self._run("preview", work, (self.pred_label, self.style_label), "rendering…")

    def card(self):
        work = self.model.card_work(self.dye_combo.currentData())
        return self._run("card", work, (self.card_label,), "rendering the shade card…")

    def _run(self, name: str, work, labels: tuple[QLabel, ...], text: str):
        """Run a render job, its labels saying so until it shows them or ends without (failed, cancelled)."""
        if work is None:
            return None
        for label in labels:
            label.clear()
            label.setText(text)
        task = self.jobs.run(name, work)

        def ended() -> None:
            if self.jobs.alive and not self.jobs.busy(name):   # not replaced by a newer one, which says the same
                for label in labels:
                    if label.pixmap().isNull():
                        label.setText("–")
        task.signals.finished.connect(ended)
        return task

    def cancel(self) -> None:
        """Stop the preview and the shade card at their next pass (what they showed stays)."""
        for name in ("preview", "card"):
            self.jobs.run(name, None)
        self.show_status("cancelled")


def add_dye_dock(window, folder: Path) -> QDockWidget:
    """Give ``window`` (a QMainWindow) the Dye panel as a dock on its right, tabbable and closable."""
    dock = QDockWidget("Dye", window)
    dock.setObjectName("dye-dock")
    panel = DyePanel(folder, dock)
    dock.setWidget(panel)
    captured = getattr(window, "captured", None)
    if captured is not None:       # a new capture is offered as soon as its record is saved
        captured.connect(lambda *_: panel.reload())
    window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
    return dock
