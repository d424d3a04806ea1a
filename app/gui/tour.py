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

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication

from hairdigi.render.domain.files import write_json_atomic

#: What tour.json reports, in seconds from the capture click, and the mark each is read from.
TARGETS = {"capture_to_parameters_s": ("parameters", 1.0), "capture_to_refined_parameters_s": ("refined", None),
           "capture_to_first_twin_s": ("first_twin", 1.5), "capture_to_clean_twin_s": ("clean_twin", 5.0),
           "capture_to_first_hairstyle_s": ("first_hairstyle", 2.0),
           "capture_to_clean_hairstyle_s": ("clean_hairstyle", 20.0)}


def run_tour(window, out_dir: str | Path, timeout_s: float = 600.0) -> None:
    """Schedule the tour on the running event loop; the app quits when it is done."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = window.model
    marks: dict[str, float] = {}
    info: dict = {}

    def mark(name: str) -> None:
        if "capture_clicked" in marks:
            marks.setdefault(name, time.perf_counter())

    def maybe_capture(_=None) -> None:
        if "warmed" in marks and "calibrated" in marks and "capture_clicked" not in marks:
            marks["capture_clicked"] = time.perf_counter()
            window.capture()

    def on_warmed(warmed) -> None:
        marks["warmed"] = time.perf_counter()
        info["warm_up_s"] = {k: round(v, 3) for k, v in warmed.seconds.items()}
        maybe_capture()

    def on_calibrated(_profile) -> None:
        marks["calibrated"] = time.perf_counter()
        maybe_capture()

    def on_shown(shown) -> None:
        if shown.params is not None:
            mark("parameters")
        if shown.stage == "refined":
            mark("refined")

    def on_captured(result) -> None:
        info["capture_worker_s"] = result.seconds
        info["blocked"] = result.blocked
        if result.blocked:
            QTimer.singleShot(300, finish)

    def on_twin(t) -> None:
        mark("first_twin")
        if t.stage == "refined":
            mark("first_refined_twin")
            if t.clean_enough:
                mark("clean_twin")
                info.setdefault("clean_twin", f"{t.spp} spp at {t.scale:g}x resolution")
            if t.final:
                mark("final_twin")
                info["real_vs_twin_mean_colour_de2000"] = round(t.delta_e, 3)
                info["real_vs_twin_map_mean_de2000"] = round(float(t.delta_e_map.mean()), 3)
        done_yet()

    def on_hairstyle(p) -> None:
        mark("first_hairstyle")
        if p.stage == "refined":
            if p.clean_enough:
                mark("clean_hairstyle")
                info.setdefault("clean_hairstyle_spp", p.spp)
            if p.final:
                mark("final_hairstyle")
        done_yet()

    def done_yet() -> None:
        if "final_twin" in marks and "final_hairstyle" in marks:
            QTimer.singleShot(500, finish)

    def finish() -> None:
        if marks.get("finished"):
            return
        marks["finished"] = 1.0
        window.grab().save(str(out / "window.png"))
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
        write_json_atomic(out / "tour.json", report)
        print(json.dumps(report, indent=2))
        window.close()
        QApplication.instance().quit()

    model.events.warmed.connect(on_warmed)
    model.events.shown.connect(on_shown)
    model.events.twin.connect(on_twin)
    model.events.hairstyle.connect(on_hairstyle)
    window.calibrated.connect(on_calibrated)
    window.captured.connect(on_captured)
    if not model.settings.warm:
        marks["warmed"] = time.perf_counter()
    QTimer.singleShot(1500, window.calibrate)
    QTimer.singleShot(int(timeout_s * 1000),
                      lambda: finish() if "capture_clicked" in marks else QApplication.instance().quit())
