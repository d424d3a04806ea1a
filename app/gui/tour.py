"""``hairdigi app --sim --tour DIR``: drive the window once (warm up, calibrate, capture) and time it.

Writes ``tour.json`` (seconds from the capture click to the encoder's parameters, the refined ones,
the first and the clean twin, the first and the clean hairstyle pass) and ``window.png``, then quits.
"Clean" is the pass whose spp the preview benchmark found within ΔE2000 3 of a 1024-spp reference
(``previews.PreviewSettings``). Used for documentation and release checks.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from PySide6.QtCore import QObject, QTimer
from PySide6.QtWidgets import QApplication

from hairdigi.app.review.previews import Stage
from hairdigi.app.session.blockers import messages
from hairdigi.render.domain.files import write_json_atomic

#: What tour.json reports, in seconds from the capture click, and the mark each is read from.
TARGETS = {"capture_to_parameters_s": ("parameters", 1.0), "capture_to_refined_parameters_s": ("refined", None),
           "capture_to_first_twin_s": ("first_twin", 1.5), "capture_to_clean_twin_s": ("clean_twin", 5.0),
           "capture_to_first_hairstyle_s": ("first_hairstyle", 2.0),
           "capture_to_clean_hairstyle_s": ("clean_hairstyle", 8.0)}


def run_tour(window, out_dir: str | Path, timeout_s: float = 600.0) -> None:
    """Schedule the tour on the running event loop; the app quits when it is done."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tour = Tour(window, out)
    model = window.model
    model.events.warmed.connect(tour.on_warmed)
    model.events.shown.connect(tour.on_shown)
    model.events.twin.connect(tour.on_twin)
    model.events.hairstyle.connect(tour.on_hairstyle)
    window.calibrated.connect(tour.on_calibrated)
    window.captured.connect(tour.on_captured)
    if not model.settings.warm:
        tour.marks["warmed"] = time.perf_counter()
    QTimer.singleShot(1500, window.calibrate)
    QTimer.singleShot(int(timeout_s * 1000),
                      lambda: tour.finish() if "capture_clicked" in tour.marks else QApplication.instance().quit())


class Tour(QObject):
    """One tour of the window: the times it marks (``perf_counter``) and what it learns on the way.

    A child of the window, so it lives as long as the window (Qt holds a plain object's connected
    methods only weakly)."""

    def __init__(self, window, out: Path):
        super().__init__(window)
        self.window = window
        self.out = out
        self.marks: dict[str, float] = {}
        self.info: dict = {}

    def mark(self, name: str) -> None:
        """The first time of ``name``, once the capture was clicked."""
        if "capture_clicked" in self.marks:
            self.marks.setdefault(name, time.perf_counter())

    def maybe_capture(self) -> None:
        """Click capture once the previews are warm and the rig calibrated."""
        if "warmed" in self.marks and "calibrated" in self.marks and "capture_clicked" not in self.marks:
            self.marks["capture_clicked"] = time.perf_counter()
            self.window.capture()

    def on_warmed(self, warmed) -> None:
        self.marks["warmed"] = time.perf_counter()
        self.info["warm_up_s"] = {k: round(v, 3) for k, v in warmed.seconds.items()}
        self.maybe_capture()

    def on_calibrated(self, _profile) -> None:
        self.marks["calibrated"] = time.perf_counter()
        self.maybe_capture()

    def on_shown(self, shown) -> None:
        if shown.params is not None:
            self.mark("parameters")
        if shown.stage is Stage.REFINED:
            self.mark("refined")

    def on_captured(self, result) -> None:
        self.info["capture_worker_s"] = result.seconds
        self.info["blocked"] = list(messages(result.blocked))
        if result.blocked:
            QTimer.singleShot(300, self.finish)

    def on_twin(self, t) -> None:
        self.mark("first_twin")
        if t.stage is Stage.REFINED:
            self.mark("first_refined_twin")
            if t.clean_enough:
                self.mark("clean_twin")
                self.info.setdefault("clean_twin", f"{t.spp} spp at {t.scale:g}x resolution")
            if t.final:
                self.mark("final_twin")
                self.info["real_vs_twin_mean_colour_de2000"] = round(t.delta_e, 3)
                self.info["real_vs_twin_map_mean_de2000"] = round(float(t.delta_e_map.mean()), 3)
        self.done_yet()

    def on_hairstyle(self, p) -> None:
        self.mark("first_hairstyle")
        if p.stage is Stage.REFINED:
            if p.clean_enough:
                self.mark("clean_hairstyle")
                self.info.setdefault("clean_hairstyle_spp", p.spp)
            if p.final:
                self.mark("final_hairstyle")
        self.done_yet()

    def done_yet(self) -> None:
        if "final_twin" in self.marks and "final_hairstyle" in self.marks:
            QTimer.singleShot(500, self.finish)

    def finish(self) -> None:
        """Once: the screenshot and ``tour.json``, then the window closes and the app quits."""
        if self.marks.get("finished"):
            return
        self.marks["finished"] = 1.0
        self.window.grab().save(str(self.out / "window.png"))
        report = tour_report(self.window, self.marks, self.info)
        write_json_atomic(self.out / "tour.json", report)
        print(json.dumps(report, indent=2))
        self.window.close()
        QApplication.instance().quit()


def tour_report(window, marks: dict[str, float], info: dict) -> dict:
    """``tour.json``: each target's seconds from the capture click and whether all were met, what the tour
    learnt, the preview settings, the renderers' scene builds and the machine."""
    model = window.model
    t0 = marks.get("capture_clicked", float("nan"))
    report = {key: round(marks[name] - t0, 3) if name in marks else None for key, (name, _) in TARGETS.items()}
    report["targets_s"] = {key: limit for key, (_, limit) in TARGETS.items() if limit is not None}
    report["met"] = all(report[key] is not None and report[key] <= limit
                        for key, limit in report["targets_s"].items())
    report["capture_to_final_twin_s"] = round(marks["final_twin"] - t0, 3) if "final_twin" in marks else None
    report["capture_to_final_hairstyle_s"] = (round(marks["final_hairstyle"] - t0, 3)
                                              if "final_hairstyle" in marks else None)
    report.update(info)
    settings = model.settings
    report["settings"] = {"twin_passes": settings.twin_passes, "twin_clean_spp": settings.twin_clean_spp,
                          "hairstyle_size": settings.hairstyle_size,
                          "hairstyle_passes": settings.hairstyle_passes,
                          "hairstyle_clean_spp": settings.hairstyle_clean_spp,
                          "denoised": model.show_denoised}
    report["renderer_builds"] = {"twin": model.twin_renderer.builds, "hairstyle": model.style_renderer.builds}
    report["machine"] = {"cpus": os.cpu_count(), "load_1min": round(os.getloadavg()[0], 2)}
    report["feed_frames"] = window.feed.frames
    return report
