"""The main window: rig panel, result panel, hairstyle panel and the session list.

Every slow call (frames, chart detection, calibration, capture, renders) runs in a worker; the
window only starts tasks and shows what they return. The science is in app/rig_session.py,
hardware/, inference/ and render/.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from PySide6.QtCore import QSettings, Qt, QTimer, Signal
from PySide6.QtWidgets import (QCheckBox, QComboBox, QFileDialog, QGridLayout, QGroupBox, QHBoxLayout, QLabel,
                               QListWidget, QListWidgetItem, QMainWindow, QProgressBar, QPushButton, QSplitter,
                               QVBoxLayout, QWidget)

from hairdigi.app import rig_session as rs
from hairdigi.app.gui.images import overlay, to_pixmap
from hairdigi.app.gui.workers import FrameFeed, Task, start
from hairdigi.render.params import VECTOR_FIELDS, HairParams
from hairdigi.render.renderer import SceneSpec, default_renderer
from hairdigi.render.scenes import ENVIRONMENTS
from hairdigi.render.strands import HAIRSTYLES, hairstyle_strands

DEFAULTS = {"hairstyle_size": 384, "hairstyle_strands": 3000, "hairstyle_passes": 8, "hairstyle_spp_per_pass": 2,
            "twin_spp": 16, "feed_fps": 20}


def image_label(text: str, size=(260, 200)) -> QLabel:
    label = QLabel(text)
    label.setAlignment(Qt.AlignmentFlag.AlignCenter)
    label.setMinimumSize(*size)
    label.setStyleSheet("background:#1e1e22; color:#aaa; border:1px solid #444")
    return label


class MainWindow(QMainWindow):
    calibrated = Signal(dict)
    captured = Signal(object)
    preview_ready = Signal(float)           # mean-colour ΔE2000 of real vs synthetic
    hairstyle_pass = Signal(int)             # spp so far
    hairstyle_done = Signal()

    def __init__(self, session: rs.RigSession, settings: dict | None = None, strand_view: bool = True) -> None:
        super().__init__()
        self.session = session
        self.opts = {**DEFAULTS, **(settings or {})}
        self.setWindowTitle(f"hairdigi — {session.folder}")
        self.tasks: list[Task] = []
        self.render_task: Task | None = None
        self.current: dict | None = None     # the shown capture: record, images
        self.chart_box = None
        self.last_frame = None
        self._build(strand_view)
        session.frames.period = 1.0 / self.opts["feed_fps"]
        self.feed = FrameFeed(session.frames)
        self.feed.frame.connect(self._on_frame)
        self.feed.failed.connect(self.show_banner)
        self.feed.start()
        self.chart_timer = QTimer(self)
        self.chart_timer.timeout.connect(self._detect_chart)
        self.chart_timer.start(1500)
        self.refresh_lights()
        self.refresh_calibration()
        self.reload_session()
        source = "simulated rig (no camera or light board found, or --sim)" if session.simulated else "camera"
        self.statusBar().showMessage(f"{source}; session {session.folder}")
        # the refinement's response curve for the rig's pose: built once (cached on disk), off the UI thread
        self.run_task(lambda report, cancelled: session.prepare_refinement(), name="refinement curve")

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
        self.resize(1500, 820)

    def _rig_panel(self) -> QWidget:
        box = QGroupBox("Rig")
        v = QVBoxLayout(box)
        self.feed_label = image_label("waiting for the camera…", (400, 300))
        v.addWidget(self.feed_label)
        row = QHBoxLayout()
        self.light_buttons = []
        for i in range(3):
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
        box = QGroupBox("Result: captured swatch | synthetic twin | difference ×4")
        v = QVBoxLayout(box)
        row = QHBoxLayout()
        self.real_label = image_label("capture")
        self.synth_label = image_label("synthetic")
        self.diff_label = image_label("difference")
        for label in (self.real_label, self.synth_label, self.diff_label):
            label.setMinimumSize(160, 190)
            row.addWidget(label)
        v.addLayout(row)
        self.chip = QLabel("hair")          # the estimated hair's colour: the refined swatch's mean
        self.chip.setFixedSize(60, 60)
        self.dye_chip = QLabel("dye")       # the dye alone, labelled, so brown hair is not read as pink
        self.dye_chip.setFixedSize(60, 22)
        grid = QGridLayout()
        grid.addWidget(self.chip, 0, 0, 2, 1)
        grid.addWidget(self.dye_chip, 2, 0, 1, 1)
        self.param_labels = {}
        for i, (name, _, _) in enumerate(VECTOR_FIELDS):
            label = QLabel(f"{name}: –")
            self.param_labels[name] = label
            grid.addWidget(label, i % 3, 1 + i // 3)
        v.addLayout(grid)
        self.match_label = QLabel("real vs synthetic: –")
        self.match_label.setStyleSheet("font-weight:bold")
        self.result_info = QLabel("")
        self.result_info.setWordWrap(True)
        v.addWidget(self.match_label)
        v.addWidget(self.result_info)
        v.addStretch(1)
        return box

    def _hairstyle_panel(self, with_strand_view: bool) -> QWidget:
        box = QGroupBox("Hairstyles")
        v = QVBoxLayout(box)
        row = QHBoxLayout()
        self.style_box = QComboBox()
        self.style_box.addItems(HAIRSTYLES)
        self.env_box = QComboBox()
        self.env_box.addItems(ENVIRONMENTS)
        self.style_box.currentTextChanged.connect(lambda _: self.render_hairstyle())
        self.env_box.currentTextChanged.connect(lambda _: self.render_hairstyle())
        row.addWidget(self.style_box)
        row.addWidget(self.env_box)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.cancel_render)
        row.addWidget(self.cancel_button)
        v.addLayout(row)
        self.style_label = image_label("capture a swatch, then pick a hairstyle", (360, 360))
        v.addWidget(self.style_label, 1)
        self.render_progress = QProgressBar()
        v.addWidget(self.render_progress)
        self.strand_view = None
        if with_strand_view:
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

    # -- tasks -------------------------------------------------------------------------------
    def run_task(self, fn, on_done=None, on_progress=None, name="task") -> Task:
        task = Task(fn, name)
        if on_done:
            task.signals.done.connect(on_done)
        if on_progress:
            task.signals.progress.connect(on_progress)
        task.signals.failed.connect(self.show_banner)
        task.signals.finished.connect(lambda t=task: self.tasks.remove(t) if t in self.tasks else None)
        self.tasks.append(task)
        return start(task)

    def show_banner(self, text: str) -> None:
        self.banner.setText(f"⚠ {text} — captures so far are saved in {self.session.folder}")
        self.banner.show()

    def busy(self) -> bool:
        return bool(self.tasks)

    # -- rig ---------------------------------------------------------------------------------
    def _on_frame(self, frame) -> None:
        self.last_frame = frame
        img = overlay(frame.srgb, self.session.swatch_roi, self.chart_box, self.zebra_box.isChecked())
        self.feed_label.setPixmap(to_pixmap(img).scaled(self.feed_label.size(), Qt.AspectRatioMode.KeepAspectRatio))

    def _detect_chart(self) -> None:
        if self.last_frame is None or any(t.name == "chart" for t in self.tasks):
            return
        image = self.last_frame.srgb

        def work(report, cancelled):
            from hairdigi.inference.calibration import CalibrationError, detect_chart
            try:
                box = detect_chart(image).box
            except CalibrationError:
                box = None
            return box, self.session.exposure(image)

        def done(result):
            self.chart_box, reports = result
            worst = next((r for r in reports if r.status != "ok"), reports[0])
            colour = "#2a2" if worst.status == "ok" else "#c60"
            self.exposure_label.setText("exposure: " + "; ".join(r.message for r in reports))
            self.exposure_label.setStyleSheet(f"color:{colour}")
        self.run_task(work, done, name="chart")

    def refresh_lights(self) -> None:
        def work(report, cancelled):
            return self.session.light_states(), self.session.lights.identify()

        def done(result):
            states, ident = result
            for b, st in zip(self.light_buttons, states):
                b.setChecked(st.on)
            self.link_label.setText(f"light board: {ident} on {self.session.lights.port_name} — linked")
        self.run_task(work, done, name="lights")

    def set_light(self, index: int, on: bool) -> Task:
        return self.run_task(lambda r, c: self.session.set_light(index, on), lambda _: self.refresh_lights(),
                             name=f"light {index}")

    def set_all(self, on: bool) -> Task:
        return self.run_task(lambda r, c: self.session.set_all(on), lambda _: self.refresh_lights(), name="lights")

    def refresh_calibration(self) -> None:
        status, reasons = self.session.calibration_status()
        p = self.session.profile
        if p is None:
            self.calibration_label.setText("calibration: none — press Calibrate with the chart in view")
            self.calibration_label.setStyleSheet("color:#c60")
            return
        age_min = (time.time() - p["time"]) / 60
        de = p["delta_e2000"]
        text = (f"calibration: {p['method']}, ΔE2000 {de['before']['mean']:.2f} → {de['after']['mean']:.2f} "
                f"(max {de['after']['max']:.2f}), {age_min:.0f} min old")
        if reasons:
            text += " — STALE: " + "; ".join(reasons)
        self.calibration_label.setText(text)
        self.calibration_label.setStyleSheet("color:#2a2" if status == "ok" else "color:#c60")

    def calibrate(self) -> Task:
        self.calibrate_button.setEnabled(False)

        def done(profile):
            self.refresh_calibration()
            self.calibrated.emit(profile)
        task = self.run_task(lambda r, c: self.session.calibrate(), done, name="calibration")
        task.signals.finished.connect(lambda: self.calibrate_button.setEnabled(True))
        return task

    # -- capture and result ------------------------------------------------------------------
    def capture(self) -> Task:
        self.capture_button.setEnabled(False)

        def work(report, cancelled):
            result = self.session.capture()
            frame = self.last_frame.srgb if self.last_frame is not None else None
            return result, frame

        def done(payload):
            result, _ = payload
            self.reload_session(select=result.capture_id)
            self.captured.emit(result)
        task = self.run_task(work, done, name="capture")
        task.signals.finished.connect(lambda: self.capture_button.setEnabled(True))
        return task

    def reload_session(self, select: str | None = None) -> None:
        self.records = rs.load_results(self.session.folder)
        self.session_list.blockSignals(True)
        self.session_list.clear()
        for rec in self.records:
            item = QListWidgetItem(self._record_title(rec))
            thumb = self._thumbnail(rec)
            if thumb is not None:
                item.setIcon(to_pixmap(thumb))
            self.session_list.addItem(item)
        self.session_list.blockSignals(False)
        if self.records:
            ids = [r["id"] for r in self.records]
            self.session_list.setCurrentRow(ids.index(select) if select in ids else len(ids) - 1)

    @staticmethod
    def _record_title(rec: dict) -> str:
        if rec.get("blocked"):
            return f"{rec['id']}  (blocked)"
        h = rec.get("hair", {})
        return f"{rec['id']}  rgb {[round(v) for v in h.get('dye_rgb', [])]}  mel {h.get('melanin_concentration', 0):.2f}"

    def _thumbnail(self, rec: dict):
        import cv2
        path = self.session.folder / "captures" / rec.get("capture", "")
        img = cv2.imread(str(path)) if path.is_file() else None
        if img is None:
            return None
        return cv2.resize(img[..., ::-1], (64, 48))

    def _on_select(self, row: int) -> None:
        if not 0 <= row < len(self.records):
            return
        rec = self.records[row]
        try:
            loaded = self.session.load_capture(rec["id"])
        except FileNotFoundError as exc:
            self.show_banner(str(exc))
            return
        frame, roi = loaded.frame, loaded.roi
        self.current = {"record": rec, "frame": frame, "roi": roi, "capture": loaded}
        if rec.get("blocked"):
            self.result_info.setText("no estimate: " + "; ".join(rec["blocked"]))
            x, y, w, h = roi
            self.real_label.setPixmap(to_pixmap(frame[y:y + h, x:x + w]).scaled(
                self.real_label.size(), Qt.AspectRatioMode.KeepAspectRatio))
            return
        params = HairParams.from_dict(rec)
        self._show_params(params, rec)
        self.preview_twin(params, loaded)
        self.render_hairstyle()

    def _show_params(self, p: HairParams, rec: dict) -> None:
        """Parameters with their measured 68% intervals, the hair and dye chips, and the warnings."""
        prov = rec.get("provenance", {})
        intervals = (rec.get("uncertainty") or {}).get("parameters", {})
        values = dict(zip([f[0] for f in VECTOR_FIELDS], [*p.dye_rgb, p.dye_concentration,
                                                            p.melanin_concentration, p.melanin_ratio]))
        for name, label in self.param_labels.items():
            fmt = "{:.0f}" if name.startswith("dye_") and name[-1] in "rgb" else "{:.2f}"
            iv = intervals.get(name)
            if iv and not iv["determined"]:
                u = " (undetermined)"
            elif iv:
                u = f" ± {fmt.format(iv['half_width'])}"
            else:
                u = ""
            label.setText(f"{name}: {fmt.format(values[name])}{u}")
        hair = (rec.get("refinement") or {}).get("rendered_linear_rgb")
        if hair:
            from hairdigi.render.srgb import linear_to_srgb8

            r, g, b = (int(v) for v in linear_to_srgb8(np.asarray(hair)))
            text = "#000" if 0.3 * r + 0.6 * g + 0.1 * b > 128 else "#fff"
            self.chip.setStyleSheet(f"background: rgb({r},{g},{b}); color:{text}; border:1px solid #888")
        r, g, b = (int(round(v)) for v in p.dye_rgb)
        text = "#000" if 0.3 * r + 0.6 * g + 0.1 * b > 128 else "#fff"
        self.dye_chip.setStyleSheet(f"background: rgb({r},{g},{b}); color:{text}; border:1px solid #888")
        self.dye_chip.setToolTip(f"dye colour alone, at concentration {p.dye_concentration:.2f}")
        refinement = rec.get("refinement") or {}
        lines = [f"model {prov.get('model', {}).get('sha256', '')[:12]}, calibration "
                 f"{(prov.get('calibration') or {}).get('id')}"]
        if refinement.get("ran"):
            lines.append(f"refined in {refinement['seconds']:.1f} s: residual ΔE2000 "
                         f"{refinement['residual_de2000']:.2f}")
        colour = (rec.get("uncertainty") or {}).get("mean_colour_de2000_p68")
        if colour is not None:
            lines.append(f"colour within ΔE2000 {colour:.2f} of the truth in 68% of held-out swatches")
        lines += [f"⚠ {w}" for w in rec.get("warnings", [])]
        self.result_info.setText("\n".join(lines))

    def preview_twin(self, params: HairParams, capture: rs.LoadedCapture) -> Task:
        """The capture (corrected with its own calibration) beside its synthetic twin, off the UI thread."""
        frame, roi = capture.frame, capture.roi
        real = capture.corrected_swatch()
        self.real_label.setPixmap(to_pixmap(real).scaled(self.real_label.size(), Qt.AspectRatioMode.KeepAspectRatio))
        frame_size = (frame.shape[1], frame.shape[0])

        def work(report, cancelled):
            twin = rs.render_twin(params, roi, frame_size, self.opts["twin_spp"], simulated=self.session.simulated)
            de, diff = rs.compare(real, twin.srgb)
            return twin.srgb, diff, de

        def done(result):
            synth, diff, de = result
            for label, img in ((self.synth_label, synth), (self.diff_label, diff)):
                label.setPixmap(to_pixmap(img).scaled(label.size(), Qt.AspectRatioMode.KeepAspectRatio))
            self.match_label.setText(f"real vs synthetic: mean-colour ΔE2000 {de:.2f}")
            self.preview_ready.emit(de)
        return self.run_task(work, done, name="twin")

    # -- hairstyles --------------------------------------------------------------------------
    def cancel_render(self) -> None:
        if self.render_task is not None:
            self.render_task.cancel()
            self.render_task = None

    def render_hairstyle(self) -> Task | None:
        """Render the selected hairstyle with the shown estimate, pass by pass; a new call cancels the last."""
        self.cancel_render()
        if not self.current or self.current["record"].get("blocked"):
            return None
        params = HairParams.from_dict(self.current["record"])
        style, env = self.style_box.currentText(), self.env_box.currentText()
        spec = SceneSpec(style, env=env, strands=self.opts["hairstyle_strands"])
        passes, per_pass, size = (self.opts["hairstyle_passes"], self.opts["hairstyle_spp_per_pass"],
                                  self.opts["hairstyle_size"])
        self.render_progress.setRange(0, passes)
        self.render_progress.setValue(0)
        if self.strand_view is not None:
            from hairdigi.render.absorption import approximate_albedo
            from hairdigi.render.srgb import linear_to_srgb8
            colour = linear_to_srgb8(approximate_albedo(params) * 0.8)
            self.strand_view.show_strands(hairstyle_strands(style, 1500, seed=0), tuple(int(c) for c in colour))

        def work(report, cancelled):
            for i, result in enumerate(default_renderer().render_progressive(params, spec, size, per_pass, passes,
                                                                             cancelled=cancelled)):
                report((i + 1, result.srgb, result.spp))
            return None

        def progress(payload):
            if task is not self.render_task:
                return  # a stale render's last pass
            n, img, spp = payload
            self.style_label.setPixmap(to_pixmap(img).scaled(self.style_label.size(),
                                                             Qt.AspectRatioMode.KeepAspectRatio))
            self.render_progress.setValue(n)
            self.render_progress.setFormat(f"{style}, {env}: {spp} spp")
            self.hairstyle_pass.emit(spp)

        def done(_):
            if task is self.render_task:
                self.render_task = None
                self.hairstyle_done.emit()
        task = self.run_task(work, done, progress, name="hairstyle")
        self.render_task = task
        return task

    # -- export ------------------------------------------------------------------------------
    def export(self, path: str | Path, all_: bool = True) -> Path:
        records = [r for r in self.records if not r.get("blocked")]
        if not all_ and self.current is not None:
            records = [self.current["record"]]
        if not records:
            raise ValueError("nothing to export: no capture has an estimate yet")
        return rs.export_records(records, path)

    def _export_dialog(self, all_: bool) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export parameters", str(self.session.folder / "export.json"),
                                              "JSON (*.json)")
        if path:
            try:
                self.export(path, all_)
                self.statusBar().showMessage(f"exported to {path}")
            except (ValueError, OSError) as exc:
                self.show_banner(str(exc))

    def show_about(self):
        """Help > About: the version, the model's sha256 and the Mitsuba variant (what a bug report needs)."""
        from PySide6.QtWidgets import QMessageBox

        from hairdigi.inference.encoder import ModelError
        from hairdigi.render.io.version import version
        from hairdigi.render.variant import select_variant

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
        self.chart_timer.stop()
        self.feed.stop()
        self.cancel_render()
        for t in list(self.tasks):
            t.cancel()
        from PySide6.QtCore import QThreadPool
        QThreadPool.globalInstance().waitForDone(30000)
        if self.strand_view is not None:
            self.strand_view.close_view()
        super().closeEvent(event)


def settings_store() -> QSettings:
    return QSettings("hairdigi", "hairdigi")
