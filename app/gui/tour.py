"""``hairdigi app --sim --tour DIR``: drive the window once (calibrate, capture) and time it.

Writes ``tour.json`` (capture to parameters, capture to the first synthetic swatch, capture to the
first hairstyle pass) and ``window.png``, then quits. Used for documentation and release checks.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from hairdigi.render.io.files import write_json_atomic


def run_tour(window, out_dir: str | Path) -> None:
    """Schedule the tour on the running event loop; the app quits when it is done."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    marks: dict[str, float] = {}

    def step_capture(_profile=None) -> None:
        marks["capture_clicked"] = time.perf_counter()
        window.capture()

    def on_captured(result) -> None:
        marks["parameters"] = time.perf_counter()
        marks["capture_seconds_in_worker"] = result.seconds
        marks["blocked"] = result.blocked
        if result.blocked:
            QTimer.singleShot(300, finish)

    def on_preview(_de) -> None:
        marks.setdefault("first_preview", time.perf_counter())

    def on_pass(_spp) -> None:
        if "first_hairstyle_pass" not in marks and "parameters" in marks:
            marks["first_hairstyle_pass"] = time.perf_counter()

    def finish() -> None:
        if marks.get("finished"):
            return
        marks["finished"] = 1.0
        window.grab().save(str(out / "window.png"))
        t0 = marks["capture_clicked"]
        report = {
            "capture_to_parameters_s": marks["parameters"] - t0,
            "capture_to_first_swatch_preview_s": marks.get("first_preview", float("nan")) - t0,
            "capture_to_first_hairstyle_pass_s": marks.get("first_hairstyle_pass", float("nan")) - t0,
            "capture_worker_s": marks["capture_seconds_in_worker"],
            "blocked": marks.get("blocked"),
            "feed_frames": window.feed.frames,
            "options": window.opts,
        }
        write_json_atomic(out / "tour.json", report)
        print(json.dumps(report, indent=2))
        window.close()
        QApplication.instance().quit()

    def on_done() -> None:
        if "first_hairstyle_pass" in marks and "first_preview" in marks:
            QTimer.singleShot(300, finish)

    window.calibrated.connect(step_capture)
    window.captured.connect(on_captured)
    window.preview_ready.connect(on_preview)
    window.preview_ready.connect(lambda _: on_done())
    window.hairstyle_pass.connect(on_pass)
    window.hairstyle_pass.connect(lambda _: on_done())
    QTimer.singleShot(1500, window.calibrate)
    QTimer.singleShot(600_000, lambda: finish() if "capture_clicked" in marks else QApplication.instance().quit())
