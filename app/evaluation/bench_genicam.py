"""``hairdigi bench genicam``: frame rate and capture latency of the GenICam path on Aravis's fake cameras.

Frames: ``GenICamCamera.read`` in a loop (software trigger, wait, unpack, demosaic, sRGB), on the
in-process fake's own 8-bit pattern (it sends a frame every 40 ms, 25 Hz; the decoding alone is
timed too), on the GigE Vision fake
process over the loopback (where ``arv-fake-gv-camera-0.8`` is installed), and on the 12-bit lab sensor
showing the simulated rig. Captures: ``RigSession.capture`` without the estimate (three single-light
frames and the all-lights frame, each saved, the record written), through the fake camera and, for
comparison, through the simulated rig's own 8-bit camera model.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hairdigi.app.evaluation.results import Result
from hairdigi.app.session.rig_session import RigSession
from hairdigi.hardware.bayer import demosaic, srgb8, unpack
from hairdigi.hardware.genicam import FAKE_ID, GenICamCamera, GenICamSettings, discover
from hairdigi.render.domain.files import write_json_atomic
from hairdigi.render.io.figures import save_figure, save_table

#: The GigE Vision fake's serial while the bench runs.
GV_SERIAL = "HDBENCH"


def _frames(camera, n: int) -> dict:
    """Read ``n`` frames after one warm-up: frames per second and each read's latency."""
    camera.read()
    latencies = []
    start = time.perf_counter()
    for _ in range(n):
        t = time.perf_counter()
        camera.read()
        latencies.append(time.perf_counter() - t)
    seconds = time.perf_counter() - start
    ms = 1000 * np.asarray(latencies)
    return {"frames": n, "fps": round(n / seconds, 2), "latency_ms_median": round(float(np.median(ms)), 1),
            "latency_ms_p95": round(float(np.percentile(ms, 95)), 1)}


def _decoding(camera, n: int) -> dict:
    """The host's share of a read: a frame's mosaic unpacked, demosaiced and encoded, ``n`` times."""
    mosaic, fmt = camera.read().mosaic, camera.format
    data = mosaic.astype(np.uint8).tobytes() if fmt.bits == 8 else mosaic.astype("<u2").tobytes()
    latencies = []
    for _ in range(n):
        t = time.perf_counter()
        srgb8(demosaic(unpack(data, fmt, mosaic.shape[1], mosaic.shape[0]), fmt.layout, 0, fmt.white))
        latencies.append(time.perf_counter() - t)
    ms = 1000 * np.asarray(latencies)
    return {"frames": n, "fps": round(n / float(np.sum(latencies)), 2),
            "latency_ms_median": round(float(np.median(ms)), 1), "latency_ms_p95": round(float(np.percentile(ms, 95)), 1)}


def _captures(session, n: int) -> dict:
    """``n`` captures without the estimate, after one warm-up: seconds each."""
    session.capture(estimate=False)
    seconds = []
    for _ in range(n):
        t = time.perf_counter()
        session.capture(estimate=False)
        seconds.append(time.perf_counter() - t)
    ms = 1000 * np.asarray(seconds)
    return {"frames": 4 * n, "fps": round(4 * n / float(np.sum(seconds)), 2),
            "latency_ms_median": round(float(np.median(ms)), 1), "latency_ms_p95": round(float(np.percentile(ms, 95)), 1)}


def _gv_case(n: int) -> dict | None:
    """The GigE Vision fake process over the loopback, or None where it is not installed."""
    tool = shutil.which("arv-fake-gv-camera-0.8")
    if tool is None:
        return None
    proc = subprocess.Popen([tool, "-i", "127.0.0.1", "-s", GV_SERIAL], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        for _ in range(50):
            if any(d.serial == GV_SERIAL for d in discover()):
                break
            time.sleep(0.1)
        camera = GenICamCamera(f"Aravis-Fake-{GV_SERIAL}")
        try:
            return {"case": "GigE Vision fake process, loopback, 8-bit Bayer 512x512, 25 Hz", **_frames(camera, n)}
        finally:
            camera.close()
    finally:
        proc.kill()
        proc.wait()


def run_genicam_bench(out: Path, quick: bool = False) -> list[dict]:
    """Every case's frame rate and latency; writes ``genicam_bench.csv``, ``.json`` and ``.png``."""
    n, captures = (10, 2) if quick else (60, 8)
    rows = []
    camera = GenICamCamera(FAKE_ID, GenICamSettings())
    try:
        rows.append({"case": "in-process fake, 8-bit Bayer 512x512, 25 Hz", **_frames(camera, n)})
        rows.append({"case": "its decoding alone (unpack, demosaic, sRGB), 512x512", **_decoding(camera, n)})
    finally:
        camera.close()
    gv = _gv_case(n)
    if gv is not None:
        rows.append(gv)
    with tempfile.TemporaryDirectory() as folder:
        spp = 4 if quick else 32
        session = RigSession.simulated_rig(Path(folder) / "genicam", spp=spp, genicam=FAKE_ID)
        try:
            rows.append({"case": "lab sensor (simulated rig), 12-bit BayerRG12 400x300, 25 Hz",
                         **_frames(session.camera, n)})
            rows.append({"case": "capture, fake camera: 4 frames, DNG, 3 PNG, record",
                         **_captures(session, captures)})
        finally:
            session.close()
        session = RigSession.simulated_rig(Path(folder) / "sim", spp=spp)
        try:
            rows.append({"case": "capture, simulated rig's 8-bit camera (comparison)",
                         **_captures(session, captures)})
        finally:
            session.close()
    save_table(out, "genicam_bench", rows, _plot)
    write_json_atomic(out / "genicam_bench.json", {"command": "hairdigi bench genicam", "quick": quick, "cases": rows})
    return rows


def _plot(rows: list[dict], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(10.5, 3.8))
    y = np.arange(len(rows))
    ax.barh(y, [r["latency_ms_median"] for r in rows], color="#4a7ab5",
            xerr=[[0] * len(rows), [r["latency_ms_p95"] - r["latency_ms_median"] for r in rows]])
    for i, r in enumerate(rows):
        ax.annotate(f"{r['fps']:.1f} frames/s", (r["latency_ms_median"], i), xytext=(6, 3),
                    textcoords="offset points", fontsize=7)
    ax.set_yticks(y, [r["case"] for r in rows], fontsize=7)
    ax.invert_yaxis()
    ax.set_xlim(0, 1.25 * max(r["latency_ms_p95"] for r in rows))
    ax.set_xlabel("latency, ms (median; bar to p95): a frame read, or a whole capture")
    ax.grid(True, axis="x", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)


def bench_genicam(args: argparse.Namespace) -> Result:
    """``hairdigi bench genicam``: each case's frame rate and latency; writes the table, JSON and plot."""
    out = Path(args.out)
    rows = run_genicam_bench(out, quick=args.quick)
    return Result("genicam_bench", rows, files=[out / "genicam_bench.csv", out / "genicam_bench.json",
                                                out / "genicam_bench.png"], text=[
        f"{r['case']}: {r['fps']:.1f} frames/s, latency median {r['latency_ms_median']:.1f} ms "
        f"(p95 {r['latency_ms_p95']:.1f})" for r in rows])
