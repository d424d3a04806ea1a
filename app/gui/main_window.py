"""The main window: rig panel, result panel, hairstyle panel and the session list.

The window holds widgets and workers only. The review state and the work behind it are in
app/review/model.py (``ReviewModel``, free of Qt): the window runs the model's works in its workers,
hands what they yield and return back to ``model.apply`` on the UI thread, and redraws on the
model's events, from the model's views (parameters, lights, feed rate, thumbnails).

Why one module over 600 lines: the four panels are one ``QMainWindow``'s, and share its workers,
its model connections and its banner; each panel's builder and the handlers that redraw it sit
together, and the panels that stand alone (the Dye and Library docks) are already modules of their
own (``dye_panel``, ``library_panel``).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import numpy as np
from PySide6.QtCore import QSettings, Qt, QThreadPool, QTimer, Signal
from PySide6.QtWidgets import (QButtonGroup, QCheckBox, QComboBox, QFileDialog, QGridLayout, QGroupBox, QHBoxLayout,
                               QLabel, QListWidget, QListWidgetItem, QMainWindow, QMessageBox, QProgressBar,
                               QPushButton, QSlider, QSplitter, QVBoxLayout, QWidget)

from hairdigi.app.gui.dye_panel import add_dye_dock
from hairdigi.app.review import model as review, previews
from hairdigi.app.review.payloads import (Calibrated, Captured, FrameCheck, HairModel, LightView, Lights, Records,
                                          Shown, StrandPreview, Thumbnail)
from hairdigi.app.session import rig_session as rs
from hairdigi.app.gui.images import DELTA_E_MAX, colour_scale, delta_e_colours, overlay, to_pixmap
from hairdigi.app.gui.library_panel import add_library_dock
from hairdigi.app.gui.workers import POOL, FrameFeed, Task, start
from hairdigi.app.review.previews import HairstylePass, Stage, TwinPreview, hair_colour_rgb8
from hairdigi.app.review.model import HAIRSTYLE_LIGHTS
from hairdigi.app.review.text import APPEARANCE_LABELS, light_name
from hairdigi.app.models.work import Work
from hairdigi.hardware.cameras import RAW_EXTENSIONS
from hairdigi.hardware.exposure import ExposureStatus
from hairdigi.inference.encoder import ModelError
from hairdigi.render.domain.bounds import ENVIRONMENTS
from hairdigi.render.domain.params import VECTOR_FIELDS
from hairdigi.render.domain.version import version
from hairdigi.render.strands import HAIRSTYLES
from hairdigi.render.variant import select_variant

#: Window options beyond ``previews.PreviewSettings``' fields (which include the feed rates).
DEFAULTS: dict = {}


def image_label(text: str, size=(260, 200)) -> QLabel:
    label = QLabel(text)
    label.setAlignment(Qt.AlignmentFlag.AlignCenter)
    label.setMinimumSize(*size)
    label.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #444")
    return label


def chip_style(rgb8) -> str:
    r, g, b = (int(v) for v in rgb8)
    text = "#000" if 0.3 * r + 0.6 * g + 0.1 * b > 128 else "#fff"
    return f"background: rgb({r},{g},{b}); color:{text}; border:1px solid #888; font-size:10px"


def preview_settings(opts: dict) -> previews.PreviewSettings:
    """The preview fields of the window's options, with tuples where the settings want them."""
    fields = {f.name for f in dataclasses.fields(previews.PreviewSettings)}
    chosen = {k: (tuple(v) if isinstance(v, list) else v) for k, v in opts.items() if k in fields}
    return previews.PreviewSettings(**chosen)


class MainWindow(QMainWindow):
    calibrated = Signal(object)             # the new CalibrationProfile
    captured = Signal(object)
    preview_ready = Signal(float)           # mean-colour ΔE2000 of real vs synthetic (each twin pass)
    hairstyle_pass = Signal(int)            # spp so far
    hairstyle_done = Signal()

    def __init__(self, session: rs.RigSession, settings: dict | None = None, strand_view: bool = True) -> None:
        super().__init__()
        self.session = session
        self.opts = {**DEFAULTS, **(settings or {})}
        self.model = review.ReviewModel(session, preview_settings(self.opts))
        self.setWindowTitle(f"hairdigi — {session.folder}")
        self.tasks: list[Task] = []
        self.closed = False                  # set on close: a task that finishes later touches nothing here
        self.jobs: dict[str, Task] = {}      # the running twin, hairstyle and strand work, by name
        self.hair_models: dict[str, Path] = {}   # opened .hair models, by their entry in the style list
        self.last_frame = None
        self._build(strand_view)
        self._connect_model()
        session.frames.period = self.model.feed_period()
        self.feed = FrameFeed(session.frames)
        self.feed.frame.connect(self._on_frame)
        self.feed.failed.connect(self.show_banner)
        self.feed.start()
        self.refresh_lights()
        self.refresh_calibration()
        camera = getattr(session.camera, "name", "camera")
        source = f"simulated rig (no camera or light board found, or --sim); {camera}" if session.simulated else camera
        self.statusBar().showMessage(f"{source}; session {session.folder}")
        if self.model.settings.warm:   # the preview scenes are built before the first capture needs them
            self.run_task(self.model.warm_work())
        self.run_task(self.model.reload_work())

    # -- layout ------------------------------------------------------------------------------
    def _build(self, with_strand_view: bool) -> None:
        central = QWidget()
        outer = QVBoxLayout(central)
        self.banner = QLabel()
        self.banner.setStyleSheet("background:#8b1e1e; color:white; padding:6px; font-weight:bold")
        self.banner.setWordWrap(True)
        self.banner.hide()
        outer.addWidget(self.banner)
        splitter = QSplitter()
        splitter.addWidget(self._rig_panel())
        splitter.addWidget(self._result_panel())
        splitter.addWidget(self._hairstyle_panel(with_strand_view))
        outer.addWidget(splitter, 1)
        self.setCentralWidget(central)
        self.resize(1500, 860)
        self.dye_dock = add_dye_dock(self, self.session.folder)
        self.library_dock = add_library_dock(self)

    def _rig_panel(self) -> QWidget:
        box = QGroupBox("Rig")
        v = QVBoxLayout(box)
        self.feed_label = image_label("waiting for the camera…", (400, 300))
        v.addWidget(self.feed_label)
        row = QHBoxLayout()
        self.light_buttons = []
        for i in range(self.model.light_count()):
            b = QPushButton(f"Light {i}")
            b.setCheckable(True)
            b.clicked.connect(lambda on, i=i: self.set_light(i, on))
            self.light_buttons.append(b)
            row.addWidget(b)
        for text, on in (("All on", True), ("All off", False)):
            b = QPushButton(text)
            b.clicked.connect(lambda _=False, on=on: self.set_all(on))
            row.addWidget(b)
        v.addLayout(row)
        self.link_label = QLabel("light board: …")
        self.exposure_label = QLabel("exposure: …")
        self.calibration_label = QLabel("calibration: …")
        for label in (self.link_label, self.exposure_label, self.calibration_label):
            label.setWordWrap(True)
            v.addWidget(label)
        row = QHBoxLayout()
        self.calibrate_button = QPushButton("Calibrate")
        self.calibrate_button.clicked.connect(self.calibrate)
        self.capture_button = QPushButton("Capture")
        self.capture_button.setStyleSheet("font-weight:bold")
        self.capture_button.clicked.connect(self.capture)
        row.addWidget(self.calibrate_button)
        row.addWidget(self.capture_button)
        v.addLayout(row)
        v.addWidget(QLabel("Session"))
        self.session_list = QListWidget()
        self.session_list.setIconSize(self.session_list.iconSize() * 2)
        self.session_list.currentRowChanged.connect(self._on_select)
        v.addWidget(self.session_list, 1)
        row = QHBoxLayout()
        b = QPushButton("Export selected…")
        b.clicked.connect(lambda: self._export_dialog(all_=False))
        row.addWidget(b)
        b = QPushButton("Export all…")
        b.clicked.connect(lambda: self._export_dialog(all_=True))
        row.addWidget(b)
        v.addLayout(row)
        return box

    def _result_panel(self) -> QWidget:
        box = QGroupBox("Result: captured swatch | synthetic twin | ΔE2000 map")
        v = QVBoxLayout(box)
        v.addLayout(self._light_selector())
        row = QHBoxLayout()
        self.real_label = image_label("capture")
        self.synth_label = image_label("synthetic")
        self.diff_label = image_label("ΔE2000")
        for label in (self.real_label, self.synth_label, self.diff_label):
            label.setMinimumSize(160, 215)    # the swatch's aspect (130 x 154 in the simulated rig's view)
            row.addWidget(label)
        v.addLayout(row)
        row = QHBoxLayout()
        self.twin_info = QLabel("twin: –")
        row.addWidget(self.twin_info, 1)
        self.scale_label = QLabel()         # the ΔE map's colour scale, under the map
        self.scale_label.setPixmap(to_pixmap(colour_scale(200, 14)))
        self.scale_label.setToolTip(f"ΔE2000 of real vs twin, both smoothed at the fibre scale "
                                    f"({self.model.settings.fibre_px:g} px): 0 (black) to {DELTA_E_MAX:g}+ (white)")
        scale = QVBoxLayout()
        scale.addWidget(self.scale_label)
        ticks = QHBoxLayout()
        for t in ("0", "1", "2", "3", "4", "5", f"{DELTA_E_MAX:g}+ ΔE"):
            tick = QLabel(t)
            tick.setStyleSheet("font-size:9px")
            ticks.addWidget(tick)
        scale.addLayout(ticks)
        row.addLayout(scale)
        v.addLayout(row)
        row = QHBoxLayout()
        self.denoise_box = QCheckBox("denoised (untick for the raw path-traced passes)")
        self.denoise_box.setChecked(self.model.show_denoised)
        self.denoise_box.setEnabled(self.model.show_denoised)
        if not self.model.show_denoised:
            self.denoise_box.setToolTip("no denoiser: pip install pyoidn==2.5.1.0")
        self.denoise_box.toggled.connect(self.model.set_denoised)
        row.addWidget(self.denoise_box)
        b = QPushButton("Save twin…")
        b.clicked.connect(lambda: self._save_dialog("twin"))
        row.addWidget(b)
        v.addLayout(row)
        self.chip = QLabel("hair")          # the estimated hair colour: the twin's mean (raw)
        self.chip.setFixedSize(70, 44)
        self.chip.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.chip.setToolTip("estimated hair colour: the mean of the synthetic twin")
        self.dye_chip = QLabel("dye")       # the dye alone, labelled, so brown hair is not read as pink
        self.dye_chip.setFixedSize(70, 44)
        self.dye_chip.setAlignment(Qt.AlignmentFlag.AlignCenter)
        grid = QGridLayout()
        grid.addWidget(self.chip, 0, 0, 2, 1)
        grid.addWidget(self.dye_chip, 0, 1, 2, 1)
        self.param_labels = {}
        for i, (name, _, _) in enumerate(VECTOR_FIELDS):
            label = QLabel(f"{name}: –")
            self.param_labels[name] = label
            grid.addWidget(label, i % 3, 2 + i // 3)
        v.addLayout(grid)
        appearance = QGridLayout()           # shine, fibre spread, grey share, with their intervals
        title = QLabel("Appearance")
        title.setStyleSheet("font-weight:bold")
        title.setToolTip("shine (Mitsuba's β_m, lower is glossier), the spread of ln σa across fibres, and the "
                         "share of grey fibres, each with its 68% interval; the twin and hairstyles render them")
        appearance.addWidget(title, 0, 0)
        self.appearance_labels = {}
        for i, name in enumerate(APPEARANCE_LABELS):
            label = QLabel(f"{APPEARANCE_LABELS[name][0]}: –")
            self.appearance_labels[name] = label
            appearance.addWidget(label, i, 1)
        appearance.setColumnStretch(1, 1)
        v.addLayout(appearance)
        self.match_label = QLabel("real vs synthetic: –")
        self.match_label.setStyleSheet("font-weight:bold")
        self.result_info = QLabel("")
        self.result_info.setWordWrap(True)
        v.addWidget(self.match_label)
        v.addWidget(self.result_info)
        v.addStretch(1)
        return box

    def _light_selector(self) -> QHBoxLayout:
        """All lights, or one light alone: the captured frame beside its twin lit the same way."""
        row = QHBoxLayout()
        row.addWidget(QLabel("Compare under:"))
        self.light_view_group = QButtonGroup(self)
        self.light_view_group.setExclusive(True)
        self.light_view_buttons: dict[int | None, QPushButton] = {}
        for light in (None, *range(self.model.light_count())):
            b = QPushButton("All lights" if light is None else f"Light {light} alone")
            b.setCheckable(True)
            b.setChecked(light is None)
            b.setToolTip("the capture's frame with every light on, beside its twin" if light is None else
                         f"the frame the capture took with light {light} alone, beside the twin lit by it alone")
            b.clicked.connect(lambda _=False, light=light: self.model.set_light_view(light))
            self.light_view_group.addButton(b)
            self.light_view_buttons[light] = b
            row.addWidget(b)
        row.addStretch(1)
        return row

    def _hairstyle_panel(self, with_strand_view: bool) -> QWidget:
        box = QGroupBox("Hairstyles")
        v = QVBoxLayout(box)
        row = QHBoxLayout()
        self.style_box = QComboBox()
        self.style_box.addItems(HAIRSTYLES)
        self.env_box = QComboBox()
        self.env_box.addItems(ENVIRONMENTS)
        self.style_box.currentTextChanged.connect(self._on_style)
        self.env_box.currentTextChanged.connect(lambda e: self.model.set_view(env=e))
        self.light_box = QComboBox()
        for label, name in HAIRSTYLE_LIGHTS:
            self.light_box.addItem(label, name)
        self.light_box.setToolTip("the light the hairstyle is seen under: the rig's white lights (RGB), or a "
                                  "real light rendered spectrally and shown as an eye adapted to it sees it")
        self.light_box.currentIndexChanged.connect(
            lambda i: self.model.set_view(illuminant=self.light_box.itemData(i)))
        row.addWidget(self.style_box)
        row.addWidget(self.env_box)
        row.addWidget(QLabel("under"))
        row.addWidget(self.light_box)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.cancel_render)
        row.addWidget(self.cancel_button)
        b = QPushButton("Save render…")
        b.clicked.connect(lambda: self._save_dialog("hairstyle"))
        row.addWidget(b)
        v.addLayout(row)
        row = QHBoxLayout()
        b = QPushButton("Open hair model…")
        b.setToolTip("a Cem Yuksel .hair model, fitted to the head and rendered with the estimate")
        b.clicked.connect(self.open_hair_dialog)
        row.addWidget(b)
        row.addStretch(1)
        v.addLayout(row)
        self.style_label = image_label("capture a swatch, then pick a hairstyle", (360, 360))
        v.addWidget(self.style_label, 1)
        self.render_progress = QProgressBar()
        v.addWidget(self.render_progress)
        orbit = QGridLayout()
        self.orbit_sliders = []
        for i, (name, limit) in enumerate((("azimuth", 80), ("elevation", 60))):
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(-limit, limit)
            slider.setValue(0)
            label = QLabel(f"{name} 0°")
            slider.valueChanged.connect(lambda value, label=label, name=name: label.setText(f"{name} {value}°"))
            slider.valueChanged.connect(lambda _: self.orbit_timer.start())
            orbit.addWidget(label, i, 0)
            orbit.addWidget(slider, i, 1)
            self.orbit_sliders.append(slider)
        self.orbit_timer = QTimer(self)          # one render per slider gesture, not per step
        self.orbit_timer.setSingleShot(True)
        self.orbit_timer.setInterval(250)
        self.orbit_timer.timeout.connect(
            lambda: self.model.set_view(orbit=tuple(s.value() for s in self.orbit_sliders)))
        v.addLayout(orbit)
        self.strand_view = None
        if with_strand_view:
            # deferred: pyvista and VTK take ~1 s; they load when the 3-D view first opens
            from hairdigi.app.gui.strand_view import StrandView
            self.strand_view = StrandView(self)
            self.strand_view.setMinimumHeight(260)
            v.addWidget(self.strand_view, 1)
        else:
            v.addWidget(QLabel("3-D strand view: needs a display (not available offscreen)"))
        self.zebra_box = QCheckBox("zebra on clipped pixels")
        self.zebra_box.setChecked(True)
        v.addWidget(self.zebra_box)
        return box

    # -- the model's events ------------------------------------------------------------------
    def _connect_model(self) -> None:
        ev = self.model.events
        self._subscriptions = [
            (ev.records, self._show_records), (ev.shown, self._show_capture),
            (ev.parameters, lambda _: self.start_previews()), (ev.view, lambda _: self.start_hairstyle()),
            (ev.twin, self._show_twin), (ev.hairstyle, self._show_hairstyle), (ev.strands, self._show_strands),
            (ev.frame_check, self._show_frame_check), (ev.calibration, self._on_calibrated),
            (ev.lights, self._show_lights), (ev.thumbnail, self._show_thumbnail),
            (ev.warnings, lambda _: self._show_parameters()),
            (ev.feed_fps, lambda rate: setattr(self.session.frames, "period", 1.0 / rate.fps)),
            (ev.status, lambda status: self.statusBar().showMessage(status.text)),
            (ev.error, lambda problem: self.show_banner(problem.text)),
            (ev.hair_model, self._on_hair_model), (ev.light_view, self._show_light_view)]
        for event, callback in self._subscriptions:
            event.connect(callback)

    def _disconnect_model(self) -> None:
        """Work still in flight when the window closes reports to the model, which no longer draws here."""
        for event, callback in self._subscriptions:
            event.disconnect(callback)

    def _show_records(self, listing: Records) -> None:
        records, shown = listing.entries, self.model.shown
        select = shown.capture_id if shown is not None else None
        self.session_list.blockSignals(True)
        self.session_list.clear()
        for entry in records:
            item = QListWidgetItem(entry.title)
            thumb = self.model.thumbnails.get(entry.id)
            if thumb is not None:
                item.setIcon(to_pixmap(thumb))
            self.session_list.addItem(item)
        self.session_list.blockSignals(False)
        if records:
            ids = [e.id for e in records]
            row = ids.index(select) if select in ids else len(ids) - 1
            self.session_list.setCurrentRow(row)
        self.run_job("thumbnails", self.model.thumbnail_work())

    def _show_thumbnail(self, thumb: Thumbnail) -> None:
        ids = [e.id for e in self.model.records]
        if thumb.rgb is not None and thumb.capture_id in ids:
            self.session_list.item(ids.index(thumb.capture_id)).setIcon(to_pixmap(thumb.rgb))

    def _on_select(self, row: int) -> None:
        if 0 <= row < len(self.model.records):
            self.select_capture(self.model.records[row].id)

    def select_capture(self, capture_id: str) -> Task | None:
        """Review a saved capture: read back in a worker, then shown (a newer selection replaces it)."""
        return self.run_job("select", self.model.select_work(capture_id))

    def _show_captured_side(self) -> bool:
        """The captured swatch under the chosen light, or why there is none; True when there is one."""
        image = self.model.captured_image()
        if image is None:
            self.real_label.clear()
            self.real_label.setText(self.model.captured_text())
            return False
        self._set_image(self.real_label, image)
        self.real_label.setToolTip(self.model.captured_text())
        return True

    def _show_light_view(self, view: LightView) -> None:
        """The capture and its twin under one light alone (or all lights)."""
        button = self.light_view_buttons.get(view.light)
        if button is not None and not button.isChecked():
            button.setChecked(True)
        if not self._show_captured_side():
            self.run_job("twin", None)
            for label in (self.synth_label, self.diff_label):
                label.clear()
                label.setText("–")
            self.twin_info.setText(f"twin: {self.model.captured_text()} (choose All lights)")
            return
        if self.model.shown is not None and self.model.shown.params is not None:
            self.synth_label.setText("rendering…")
            self.run_job("twin", self.model.twin_work())

    def _show_capture(self, shown: Shown) -> None:
        has_image = self._show_captured_side()     # False: no frame of this capture under the chosen light
        if self.model.twin is None or not has_image:   # the first look's twin stays up until the refined one comes
            for label, text in ((self.synth_label, "rendering…"), (self.diff_label, "ΔE2000")):
                label.clear()
                label.setText(text if shown.params is not None and has_image else "–")
            self.chip.setText("hair\n…")
            self.chip.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #888; font-size:10px")
        self._show_parameters()

    def _show_parameters(self) -> None:
        """Parameters with their measured 68% intervals, the dye chip, and the lines under them."""
        view = self.model.parameter_view()
        if view is None:
            return
        texts = dict(view.lines)
        for name, label in self.param_labels.items():
            label.setText(texts.get(name, f"{name}: –"))
        texts = dict(view.appearance)
        for name, label in self.appearance_labels.items():
            label.setText(texts.get(name, f"{APPEARANCE_LABELS[name][0]}: –"))
        if view.dye_rgb8 is not None:
            self.dye_chip.setText("dye")
            self.dye_chip.setStyleSheet(chip_style(view.dye_rgb8))
            self.dye_chip.setToolTip(view.dye_tooltip)
        self.result_info.setText(view.info)

    def _show_twin(self, t: TwinPreview) -> None:
        self._set_image(self.synth_label, self.model.twin_image(t))
        self._set_image(self.diff_label, delta_e_colours(t.delta_e_map))
        shown = "denoised" if self.model.show_denoised and t.clean is not None else "raw"
        scale = "" if t.scale == 1 else " at ½ resolution" if t.scale == 0.5 else f" at {t.scale:g}x"
        self.twin_info.setText(f"twin, {light_name(t.light)}: {t.spp} spp{scale}, {shown}; "
                               f"map mean ΔE {float(t.delta_e_map.mean()):.2f}")
        stage = "encoder's estimate" if t.stage == Stage.ENCODER else "refined estimate"
        self.match_label.setText(f"real vs synthetic: mean-colour ΔE2000 {t.delta_e:.2f} ({stage})")
        self.chip.setText("hair")
        self.chip.setStyleSheet(chip_style(hair_colour_rgb8(t.hair_linear)))
        self.preview_ready.emit(t.delta_e)

    def _show_hairstyle(self, p: HairstylePass) -> None:
        self._set_image(self.style_label, self.model.hairstyle_image(p))
        self.render_progress.setRange(0, p.passes)
        self.render_progress.setValue(p.index)
        shown = "denoised" if self.model.show_denoised and p.clean is not None else "raw"
        self.render_progress.setFormat(f"{p.label}: {p.spp} spp, {shown}")
        self.hairstyle_pass.emit(p.spp)
        if p.final:
            self.hairstyle_done.emit()

    def _show_strands(self, s: StrandPreview) -> None:
        if self.strand_view is not None:
            self.strand_view.show_strands(s.strands, s.colour_rgb8, scalp_linear=s.scalp_linear)

    def _show_frame_check(self, check: FrameCheck) -> None:
        reports = check.exposure
        worst = next((r for r in reports if r.status is not ExposureStatus.OK), reports[0])
        self.exposure_label.setText("exposure: " + "; ".join(r.message for r in reports))
        self.exposure_label.setStyleSheet(f"color:{'#2a2' if worst.status is ExposureStatus.OK else '#c60'}")

    @staticmethod
    def _set_image(label: QLabel, rgb: np.ndarray | None) -> None:
        if rgb is not None:
            label.setPixmap(to_pixmap(rgb).scaled(label.size(), Qt.AspectRatioMode.KeepAspectRatio,
                                                  Qt.TransformationMode.SmoothTransformation))

    # -- tasks -------------------------------------------------------------------------------
    def run_task(self, work: Work, on_done=None, on_progress=None) -> Task:
        """Run the model's ``work`` in a worker; what it yields and returns goes to the model by default,
        and its ``ended`` runs here on the UI thread when it is over."""
        task = Task(work.run, work.name, work.must_start)
        task.signals.done.connect(self.while_open(on_done or self.model.apply))
        task.signals.progress.connect(self.while_open(on_progress or self.model.apply))
        task.signals.failed.connect(self.while_open(self.show_banner))
        task.signals.finished.connect(lambda t=task: self.tasks.remove(t) if t in self.tasks else None)
        if work.ended is not None:
            task.signals.finished.connect(work.ended)     # the model's own bookkeeping: runs after a close too
        self.tasks.append(task)
        return start(task, POOL)

    def while_open(self, slot: Callable) -> Callable:
        """``slot``, called only while this window is open: a task that outlives the window (a render that
        finishes after close) must not touch its deleted widgets."""
        def guarded(*args) -> None:
            if not self.closed:
                slot(*args)
        return guarded

    def run_job(self, name: str, work: Work | None) -> Task | None:
        """Run the model's ``work`` as the one job called ``name``; the previous one is cancelled."""
        old = self.jobs.pop(name, None)
        if old is not None:
            old.cancel()
        if work is None:
            return None
        task = self.jobs[name] = self.run_task(work)
        task.signals.finished.connect(lambda: self.jobs.pop(name) if self.jobs.get(name) is task else None)
        return task

    def show_banner(self, text: str) -> None:
        self.banner.setText(f"⚠ {text} — captures so far are saved in {self.session.folder}")
        self.banner.show()

    # -- rig ---------------------------------------------------------------------------------
    def _on_frame(self, frame) -> None:
        self.last_frame = frame
        if self.banner.isVisible() and self.banner.text().startswith("⚠ camera:"):
            self.banner.hide()      # the camera came back (the frame source waited for it)
        check = self.model.frame_check
        img = overlay(frame.srgb, self.session.swatch_roi, None if check is None else check.chart_box,
                      self.zebra_box.isChecked())
        self.feed_label.setPixmap(to_pixmap(img).scaled(self.feed_label.size(), Qt.AspectRatioMode.KeepAspectRatio))
        if self.model.frame_check_due():
            self.run_task(self.model.frame_check_work(frame.srgb))

    def refresh_lights(self) -> Task:
        return self.run_task(self.model.lights_work())

    def _show_lights(self, lights: Lights) -> None:
        for b, on in zip(self.light_buttons, lights.on):
            b.setChecked(on)
        self.link_label.setText(f"light board: {lights.identity} on {lights.port} — linked")
        self.refresh_calibration()

    def set_light(self, index: int, on: bool) -> Task:
        return self.run_task(self.model.set_light_work(index, on))

    def set_all(self, on: bool) -> Task:
        return self.run_task(self.model.set_all_work(on))

    def refresh_calibration(self) -> Task:
        """The calibration's status line, read in a worker."""
        return self.run_task(self.model.calibration_work(), self._show_calibration)

    def _show_calibration(self, calibration: tuple[rs.CalibrationStatus, str]) -> None:
        status, text = calibration
        self.calibration_label.setText(text)
        self.calibration_label.setStyleSheet("color:#2a2" if status is rs.CalibrationStatus.OK else "color:#c60")

    def calibrate(self) -> Task:
        self.calibrate_button.setEnabled(False)
        task = self.run_task(self.model.calibrate_work())
        task.signals.finished.connect(self.while_open(lambda: self.calibrate_button.setEnabled(True)))
        return task

    def _on_calibrated(self, calibrated: Calibrated) -> None:
        self.refresh_calibration()
        self.calibrated.emit(calibrated.profile)

    # -- capture and previews ----------------------------------------------------------------
    def capture(self) -> Task:
        """Capture; the encoder's estimate shows first, then the refined one (the model relays both)."""
        self.capture_button.setEnabled(False)
        for name in ("twin", "hairstyle"):        # stale renders stop now (the model's generation moved too)
            self.run_job(name, None)

        def done(captured: Captured) -> None:
            self.model.apply(captured)
            self.captured.emit(captured.result)
        task = self.run_task(self.model.capture_work(), done)
        task.signals.finished.connect(self.while_open(lambda: self.capture_button.setEnabled(True)))
        return task

    def start_previews(self) -> None:
        self.run_job("twin", self.model.twin_work())
        self.start_hairstyle()

    def start_hairstyle(self) -> None:
        self.render_progress.setValue(0)
        self.run_job("hairstyle", self.model.hairstyle_work() or self.model.warm_view_work())
        strands = self.model.strand_work() if self.strand_view is not None else None
        if strands is not None:
            self.run_job("strands", strands)

    def _on_style(self, text: str) -> None:
        if text in HAIRSTYLES:
            self.model.set_view(style=text)
        elif text in self.hair_models:
            self.model.set_view(hair_file=self.hair_models[text])

    def import_still(self, path: str | Path) -> Task:
        """A RAW still of the rig as a capture: copied into the session first, calibrated on the chart
        in the still, estimated, then shown like a live capture."""
        def done(captured: Captured) -> None:
            self.model.apply(captured)
            self.captured.emit(captured.result)
        return self.run_task(self.model.import_still_work(path), done)

    def import_still_dialog(self) -> None:
        patterns = " ".join(f"*{e} *{e.upper()}" for e in sorted(RAW_EXTENSIONS))
        path, _ = QFileDialog.getOpenFileName(self, "Import a RAW still of the rig", str(Path.home()),
                                              f"RAW stills ({patterns});;All files (*)")
        if path:
            self.import_still(path)

    def open_hair_model(self, path: str | Path) -> Task:
        """Read and check a .hair model in a worker; a bad file shows its error in the banner."""
        return self.run_task(self.model.open_hair_work(path))

    def open_hair_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open a hair model", str(Path.home()),
                                              "Cem Yuksel hair models (*.hair);;All files (*)")
        if path:
            self.open_hair_model(path)

    def _on_hair_model(self, hair: HairModel) -> None:
        """The opened model joins the style list, selected (a built-in style there closes it)."""
        label = hair.path.name
        self.hair_models[label] = hair.path
        self.style_box.blockSignals(True)
        if self.style_box.findText(label) < 0:
            self.style_box.addItem(label)
        self.style_box.setCurrentText(label)
        self.style_box.blockSignals(False)

    def cancel_render(self) -> None:
        self.run_job("hairstyle", None)

    @property
    def render_task(self) -> Task | None:
        return self.jobs.get("hairstyle")

    # -- export ------------------------------------------------------------------------------
    def export(self, path: str | Path, all_: bool = True) -> Task:
        """Export the estimates as JSON in a worker (nothing to export is refused here, at once)."""
        return self.run_task(self.model.export_work(path, all_),
                             lambda written: self.statusBar().showMessage(f"exported to {written}"))

    def save_render(self, which: str, path: str | Path) -> Task:
        """Save the shown ``"hairstyle"`` or ``"twin"`` render (PNG, and linear EXR beside it) in a worker."""
        return self.run_task(self.model.save_render_work(which, path),
                             lambda written: self.statusBar().showMessage("saved " + " and ".join(map(str, written))))

    def _export_dialog(self, all_: bool) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export parameters", str(self.session.folder / "export.json"),
                                              "JSON (*.json)")
        if path:
            try:
                self.export(path, all_)
            except ValueError as exc:
                self.show_banner(str(exc))

    def _save_dialog(self, which: str) -> None:
        default = str(self.session.folder / f"{which}.png")
        path, _ = QFileDialog.getSaveFileName(self, f"Save the {which} render (PNG, and linear EXR beside it)",
                                              default, "PNG (*.png)")
        if path:
            try:
                self.save_render(which, path)
            except ValueError as exc:
                self.show_banner(str(exc))

    def show_about(self):
        """Help > About: the version, the model's sha256 and the Mitsuba variant (what a bug report needs)."""
        try:
            model = f"{self.session.encoder.path.name}, sha256 {self.session.encoder.sha256}"
        except ModelError as exc:
            model = f"not loaded: {exc}"
        box = QMessageBox(QMessageBox.Icon.Information, "About hairdigi", f"hairdigi {version()}", parent=self)
        box.setInformativeText(f"Model: {model}\nMitsuba variant: {select_variant()}")
        box.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        box.open()   # not modal to the app: the feed and renders keep running
        return box

    # -- shutdown ----------------------------------------------------------------------------
    def closeEvent(self, event) -> None:
        self.closed = True
        self._disconnect_model()
        self.feed.stop()
        for t in list(self.tasks):
            t.cancel()
        self.model.stop()
        POOL.waitForDone(30000)
        QThreadPool.globalInstance().waitForDone(30000)
        if self.strand_view is not None:
            self.strand_view.close_view()
        super().closeEvent(event)


def settings_store() -> QSettings:
    return QSettings("hairdigi", "hairdigi")
