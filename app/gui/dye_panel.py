"""The Dye panel (a dock of the main window): characterise a dye from captures, preview it on any
capture, show its shade card. The science is ``inference/dye.py``; this file holds widgets only, and
runs the renders in the window's worker pool."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt
from PySide6.QtGui import QPixmap
from PySide6.QtWidgets import (QComboBox, QDockWidget, QDoubleSpinBox, QFileDialog, QGroupBox, QHBoxLayout, QLabel,
                               QLineEdit, QListWidget, QPushButton, QVBoxLayout, QWidget)

from hairdigi.app.gui.images import to_pixmap
from hairdigi.app.gui.workers import POOL, Task, start

PREVIEW_SIZE, PREVIEW_SPP = 128, 16
HAIRSTYLE, HAIRSTYLE_SIZE, HAIRSTYLE_SPP = "wavy", 192, 8


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", name.strip()).strip("-.") or "dye"


def _saved_name(path: Path) -> str | None:
    """The name of the dye saved at ``path`` (None: no such file, or not a dye record)."""
    from hairdigi.render.base.dye_record import DyeRecord
    from hairdigi.render.base.records import RecordError, read_record

    try:
        return read_record(path, DyeRecord).name if path.exists() else None
    except RecordError:
        return ""


def dye_path(folder: Path, name: str) -> Path:
    """Where the dye ``name`` is saved: its name as a file name, numbered (``-2``, ``-3``...) where that file
    holds another dye ("Copper 7.4" and "Copper/7.4" both read ``Copper-7.4``), so no dye is ever written
    over by another; the same name again replaces its own file (the dye characterised again)."""
    name = name.strip()
    slug = _slug(name)[:80]
    path = folder / f"{slug}.json"
    n = 2
    while path.exists() and _saved_name(path) != name:
        path = folder / f"{slug}-{n}.json"
        n += 1
    return path


def select_path(combo: QComboBox, path: Path) -> bool:
    """Make the item holding ``path`` current (Qt's findData does not compare Python objects)."""
    for i in range(combo.count()):
        if Path(combo.itemData(i)) == Path(path):
            combo.setCurrentIndex(i)
            return True
    return False


def session_records(folder: Path) -> list[Path]:
    """The session's captures that hold an estimate (``captures/<id>.result.json`` with ``hair``)."""
    from hairdigi.render.base.files import read_json

    found = []
    for path in sorted((folder / "captures").glob("*.result.json")):
        try:   # a regular file of bounded size (a FIFO among the captures never hangs the window)
            data = read_json(path, ValueError, "missing", "unreadable ({exc})")
        except ValueError:
            continue
        if isinstance(data, dict) and data.get("hair") is not None:
            found.append(path)
    return found


def capture_crop(record_path: Path) -> np.ndarray | None:
    """The captured swatch (8-bit sRGB) of a session capture's record, cropped to its swatch area."""
    import cv2

    from hairdigi.render.base.files import read_json

    try:
        data = read_json(record_path, ValueError, "missing", "unreadable ({exc})")
        image_path = record_path.with_name(data["capture"])
        image = cv2.imread(str(image_path)) if image_path.is_file() else None
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if image is None:
        return None
    x, y, w, h = data.get("swatch_roi") or (0, 0, image.shape[1], image.shape[0])
    return np.ascontiguousarray(image[y:y + h, x:x + w, ::-1])


def preview_work(dye_path: Path, base_path: Path, dose: float):
    """Apply the dye and render the prediction as a swatch and a hairstyle (off the UI thread)."""
    from hairdigi.inference.dye import apply, describe_colour, load_sample
    from hairdigi.render.base.dye_record import DyeRecord
    from hairdigi.render.base.records import read_record
    from hairdigi.render.renderer import SceneSpec, default_renderer

    dye = read_record(dye_path, DyeRecord)
    pred = apply(dye, load_sample(base_path), dose)
    renderer = default_renderer()
    swatch = renderer.render(pred.sigma_a, SceneSpec("swatch", framing="crop"), PREVIEW_SIZE, PREVIEW_SPP, 0).srgb
    yield {"swatch": swatch, "colour": describe_colour(pred.linear_rgb), "params": pred.params}
    style = renderer.render(pred.sigma_a, SceneSpec(HAIRSTYLE), HAIRSTYLE_SIZE, HAIRSTYLE_SPP, 0).srgb
    return {"hairstyle": style}


class DyePanel(QWidget):
    """Pick base and dyed captures, characterise and save; preview a dye on a capture; its shade card."""

    def __init__(self, folder: Path, parent=None) -> None:
        super().__init__(parent)
        self.folder = Path(folder)
        self.dyes_folder = self.folder / "dyes"
        self.records: list[Path] = []
        self.pairs: list[tuple[Path, Path]] = []
        self.tasks: list[Task] = []
        v = QVBoxLayout(self)
        v.addWidget(self._characterise_box())
        v.addWidget(self._preview_box(), 1)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        v.addWidget(self.status)
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
        add = QPushButton("Add pair")
        add.clicked.connect(self.add_pair)
        row.addWidget(add)
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
        preview = QPushButton("Preview")
        preview.clicked.connect(self.preview)
        card = QPushButton("Shade card")
        card.clicked.connect(self.card)
        row.addWidget(preview)
        row.addWidget(card)
        v.addLayout(row)
        row = QHBoxLayout()
        for caption in ("the capture (as dyed: predicted)", "predicted twin", f"predicted hairstyle ({HAIRSTYLE})"):
            text = QLabel(caption.split(" (as")[0])
            text.setAlignment(Qt.AlignmentFlag.AlignCenter)
            row.addWidget(text)
        v.addLayout(row)
        row = QHBoxLayout()
        self.real_label, self.pred_label, self.style_label = (self._image("capture"), self._image("predicted twin"),
                                                              self._image(f"predicted {HAIRSTYLE}"))
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

    # -- data ------------------------------------------------------------------------------
    def reload(self) -> None:
        """Re-read the session's estimated captures and saved dyes."""
        extra = [p for p in self.records if self.folder not in p.parents]
        self.records = session_records(self.folder) + extra
        for combo in (self.base_combo, self.dyed_combo, self.target_combo):
            current = combo.currentData()
            combo.clear()
            for path in self.records:
                combo.addItem(self._name(path), path)
            if current is not None:
                select_path(combo, current)
        if self.dyed_combo.count() > 1 and self.dyed_combo.currentIndex() == self.base_combo.currentIndex():
            self.dyed_combo.setCurrentIndex(1)
        self.dye_combo.clear()
        for path in sorted(self.dyes_folder.glob("*.json")) if self.dyes_folder.exists() else []:
            if not path.name.endswith("-card.json"):
                self.dye_combo.addItem(path.stem, path)

    def _name(self, path: Path) -> str:
        stem = path.name.removesuffix(".result.json").removesuffix(".json")
        return stem if self.folder in path.parents else f"{path.parent.parent.name}/{stem}"

    def add_records_dialog(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Estimate records or captures", str(self.folder),
                                                "records (*.json)")
        self.records += [Path(p) for p in paths if Path(p) not in self.records]
        self.reload()

    def add_pair(self) -> None:
        base, dyed = self.base_combo.currentData(), self.dyed_combo.currentData()
        if base is None or dyed is None or base == dyed:
            self.show_status("choose a base and a different dyed capture")
            return
        self.pairs.append((base, dyed))
        self.pair_list.addItem(f"{self._name(base)}  →  {self._name(dyed)}")

    # -- actions ---------------------------------------------------------------------------
    def characterise(self) -> None:
        from hairdigi.inference.dye import DyeError, characterise, load_sample
        from hairdigi.render.base.records import write_record

        name = self.name_edit.text().strip()
        if not self.pairs or not name:
            self.show_status("add at least one pair and give the dye a name")
            return
        try:
            dye = characterise([(load_sample(b), load_sample(d)) for b, d in self.pairs], name)
        except DyeError as exc:
            self.show_status(str(exc))
            return
        path = dye_path(self.dyes_folder, name)
        write_record(path, dye)
        lift = (f"lift {dye.lift:.2f} ({dye.lift_low:.2f}–{dye.lift_high:.2f})" if dye.lift_measured
                else f"lift {dye.lift:.2f}, assumed (one base)")
        self.dye_info.setText(f"{dye.name}: deposit σa ({', '.join(f'{x:.3f}' for x in dye.deposit_sigma_a)}), {lift}; "
                              f"residual ΔE2000 ≤ {dye.residual_de2000_max:.2f}; saved {path.name}"
                              + "".join(f"\n⚠ {w}" for w in dye.warnings))
        self.reload()
        select_path(self.dye_combo, path)

    def preview(self) -> None:
        dye, target = self.dye_combo.currentData(), self.target_combo.currentData()
        if dye is None or target is None:
            self.show_status("characterise or choose a dye, and a capture to preview it on")
            return
        crop = capture_crop(target)
        if crop is not None:
            self._show(self.real_label, crop)
        self.pred_label.setText("rendering…")
        task = Task(lambda: preview_work(dye, target, self.dose_spin.value()), "dye preview")
        task.signals.progress.connect(self._on_preview)
        task.signals.done.connect(lambda out: out and self._show(self.style_label, out["hairstyle"]))
        task.signals.failed.connect(self.show_status)
        self._run(task)

    def card(self) -> None:
        from hairdigi.inference.dye_card import shade_card
        from hairdigi.render.base.dye_record import DyeRecord
        from hairdigi.render.base.records import read_record

        dye_path = self.dye_combo.currentData()
        if dye_path is None:
            self.show_status("characterise or choose a dye first")
            return
        out = dye_path.with_name(f"{dye_path.stem}-card.png")
        self.card_label.setText("rendering the shade card…")
        task = Task(lambda: shade_card(read_record(dye_path, DyeRecord), out)[0], "shade card")
        task.signals.done.connect(self._on_card)
        task.signals.failed.connect(self.show_status)
        self._run(task)

    # -- results ---------------------------------------------------------------------------
    def _run(self, task: Task) -> None:
        self.tasks.append(task)
        task.signals.finished.connect(lambda: self.tasks.remove(task) if task in self.tasks else None)
        start(task, POOL)

    def _on_preview(self, out: dict) -> None:
        self._show(self.pred_label, out["swatch"])
        p, c = out["params"], out["colour"]
        self.pred_info.setText(f"predicted {c['srgb']}  L*a*b* {c['lab'][0]:.1f} {c['lab'][1]:.1f} {c['lab'][2]:.1f}; "
                               f"Table 1: dye {tuple(round(x) for x in p.dye_rgb)} at {p.dye_concentration:.2f}, "
                               f"melanin {p.melanin_concentration:.2f}")

    def _on_card(self, path) -> None:
        pixmap = QPixmap(str(path))
        self.card_label.setPixmap(pixmap.scaled(self.card_label.size(), Qt.AspectRatioMode.KeepAspectRatio,
                                                Qt.TransformationMode.SmoothTransformation))
        self.show_status(f"shade card: {path} (and its PDF)")

    @staticmethod
    def _show(label: QLabel, rgb: np.ndarray) -> None:
        label.setPixmap(to_pixmap(rgb).scaled(label.size(), Qt.AspectRatioMode.KeepAspectRatio,
                                              Qt.TransformationMode.SmoothTransformation))

    def show_status(self, text: str) -> None:
        self.status.setText(text)


def add_dye_dock(window, folder: Path) -> QDockWidget:
    """Give ``window`` (a QMainWindow) the Dye panel as a dock on its right, tabbable and closable."""
    dock = QDockWidget("Dye", window)
    dock.setObjectName("dye-dock")
    dock.setWidget(DyePanel(folder, dock))
    window.addDockWidget(Qt.DockWidgetArea.RightDockWidgetArea, dock)
    return dock
