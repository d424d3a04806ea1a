"""``hairdigi bench memory``: peak memory and time of the largest inputs hairdigi accepts.

Three cases, each one ``hairdigi`` command in a process of its own, whose peak resident memory is
read from ``getrusage(RUSAGE_CHILDREN)`` in a small parent that runs nothing else:

- ``image``: ``estimate`` of an 8000x8000 PNG, at the pixel cap (``preprocess.MAX_IMAGE_PIXELS``);
- ``raw``: ``rig --still`` of a 48 MP DNG (8000x6000 RGGB, 12-bit) of the simulated rig, chart in view
  (imported, calibrated on its chart, estimated);
- ``hair``: ``render --scene`` of a ``.hair`` model at the point bound (``hairfile.MAX_FILE_POINTS``).

Targets: each at most 2.5 GB and a minute. Writes ``memory_bench.csv``, ``.json`` and ``.png``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import matplotlib.pyplot as plt
import numpy as np
import tifffile

from hairdigi.app.evaluation.results import Result
from hairdigi.hardware.sim_rig import DEFAULT_HIDDEN
from hairdigi.render.chart import colorchecker_reflectances
from hairdigi.render.domain import rig_geometry
from hairdigi.render.domain.files import write_json_atomic
from hairdigi.render.hairfile import _HEADER, HAS_POINTS, HAS_SEGMENTS, MAX_FILE_POINTS
from hairdigi.render.io.figures import save_figure, save_table
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.resources import SAMPLE_PARAMS

MAX_PEAK_GB = 2.5
MAX_SECONDS = 60.0

_PROBE = ("import json, resource, subprocess, sys, time\n"
          "t = time.perf_counter()\n"
          "r = subprocess.run([sys.executable, '-m', 'hairdigi.app.cli', *sys.argv[1:]], capture_output=True, text=True)\n"
          "print(json.dumps({'rc': r.returncode, 'err': r.stderr[-400:], 's': time.perf_counter() - t, "
          "'peak_mb': resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}))")


def measure(args: list[str], cwd: Path, timeout: float = 300) -> dict:
    """Run ``hairdigi ARGS`` alone under a small parent: exit code, seconds, peak RSS (MB), stderr's tail."""
    env = {**os.environ, "OMP_WAIT_POLICY": "PASSIVE"}
    outer = subprocess.run([sys.executable, "-c", _PROBE, *args], cwd=cwd, capture_output=True, text=True,
                           timeout=timeout, env=env)
    return json.loads(outer.stdout)


def _texture(height: int, width: int, seed: int = 0) -> np.ndarray:
    """A small brown, strand-like texture (vertical streaks), 8-bit RGB."""
    rng = np.random.default_rng(seed)
    streaks = np.repeat(rng.normal(0, 1, (1, width)), height, 0) + 0.2 * rng.normal(0, 1, (height, width))
    level = np.clip(0.5 + 0.15 * streaks, 0, 1)[..., None]
    return (level * np.array([150, 95, 60])).astype(np.uint8)


def write_large_png(path: Path, width: int = 8000, height: int = 8000) -> Path:
    """An all-hair-like PNG of ``width`` x ``height`` (a small texture scaled up: a small file)."""
    small = _texture(height // 16, width // 16)
    big = cv2.resize(small, (width, height), interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(path), big[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 1])
    return path


#: The simulated still camera's DNG tags (as ``hardware.sim_still`` writes them): RGGB, 12-bit, identity matrix.
WHITE = 4095


def rig_still_linear(size: tuple[int, int] = (400, 300)) -> np.ndarray:
    """The simulated rig's view (swatch and ColorChecker on the holder), linear RGB scaled to the sensor."""
    spec = SceneSpec("swatch", framing="rig", chart=tuple(map(tuple, colorchecker_reflectances())),
                     target=rig_geometry.RIG_TARGET, half_width=rig_geometry.RIG_HALF_WIDTH, strands=1000)
    linear = Renderer(max_cached=1).render(DEFAULT_HIDDEN, spec, size, 8, seed=1).linear
    return np.clip(linear * (0.55 / max(float(np.percentile(linear, 99)), 1e-6)), 0.0, 1.0).astype(np.float32)


def write_large_dng(path: Path, width: int = 8000, height: int = 6000, small: np.ndarray | None = None) -> Path:
    """A 12-bit RGGB DNG of ``width`` x ``height`` showing ``small`` (linear RGB in [0, 1]; default: the hair
    texture) scaled up."""
    if small is None:
        small = _texture(height // 16, width // 16).astype(np.float32) / 255.0
    counts = cv2.resize((small * WHITE).astype(np.uint16), (width, height), interpolation=cv2.INTER_NEAREST)
    cfa = np.empty((height, width), np.uint16)
    cfa[0::2, 0::2] = counts[0::2, 0::2, 0]
    cfa[0::2, 1::2] = counts[0::2, 1::2, 1]
    cfa[1::2, 0::2] = counts[1::2, 0::2, 1]
    cfa[1::2, 1::2] = counts[1::2, 1::2, 2]
    del counts
    identity = [(1, 1), (0, 1), (0, 1), (0, 1), (1, 1), (0, 1), (0, 1), (0, 1), (1, 1)]
    tags = [(50706, "B", 4, (1, 4, 0, 0), True), (50707, "B", 4, (1, 1, 0, 0), True),
            (50708, "s", 0, "hairdigi simulated still camera", True), (33421, "H", 2, (2, 2), True),
            (33422, "B", 4, (0, 1, 1, 2), True), (50714, "H", 1, 0, True), (50717, "H", 1, WHITE, True),
            (50721, "2i", 9, [v for pair in identity for v in pair], True), (50778, "H", 1, 21, True),
            (50728, "2I", 3, (1, 1, 1, 1, 1, 1), True)]
    tifffile.imwrite(path, cfa, photometric=32803, extratags=tags, subfiletype=0)
    return path


def write_large_hair(path: Path, points: int | None = None, per_strand: int = 80) -> Path:
    """A ``.hair`` model of ``points`` points (default: the bound), strands of ``per_strand`` hanging down."""
    n_strands = (points or MAX_FILE_POINTS) // per_strand
    rng = np.random.default_rng(0)
    roots = rng.normal(0, 1, (n_strands, 3)).astype(np.float32)
    roots /= np.linalg.norm(roots, axis=1, keepdims=True)
    roots[:, 1] = np.abs(roots[:, 1])
    with open(path, "wb") as f:
        f.write(_HEADER.pack(b"HAIR", n_strands, n_strands * per_strand, HAS_SEGMENTS | HAS_POINTS, 0, 1.0, 0.0,
                             1.0, 1.0, 1.0, b"hairdigi bench memory".ljust(88, b"\0")))
        f.write(np.full(n_strands, per_strand - 1, "<u2").tobytes())
        drop = np.linspace(0, 1.5, per_strand, dtype=np.float32)
        for start in range(0, n_strands, 10_000):   # in blocks of strands, so the writer stays small
            block = roots[start:start + 10_000, None, :] - drop[None, :, None] * np.float32([0, 1, 0])
            f.write(block.astype("<f4").tobytes())
    return path


def run_cases(out_dir: Path, quick: bool = False, say=print) -> list[dict]:
    """Make the three inputs in a scratch folder, run each case, and return its rows; ``say`` each case's line."""
    with tempfile.TemporaryDirectory(prefix="hairdigi-bench-memory-") as scratch:
        work = Path(scratch)
        scale = 4 if quick else 1
        image = write_large_png(work / "large.png", 8000 // scale, 8000 // scale)
        still = write_large_dng(work / "large.dng", 8000 // scale, 6000 // scale, rig_still_linear())
        hair = write_large_hair(work / "large.hair", MAX_FILE_POINTS // scale ** 2)
        cases = [
            ("image", f"estimate of a {8000 // scale}x{8000 // scale} PNG",
             ["estimate", str(image), "--out", str(work / "e.json")]),
            ("raw", f"rig --still of a {8000 // scale}x{6000 // scale} DNG of the rig (chart in view)",
             ["rig", "--still", str(still), "--session", str(work / "session")]),
            ("hair", f"render of a .hair model with {MAX_FILE_POINTS // scale ** 2} points",
             ["render", "--params", str(_sample_params()), "--scene", str(hair), "--size", "64", "--spp", "1",
              "--out", str(work / "h.png")]),
        ]
        rows = []
        for name, what, args in cases:
            r = measure(args, work)
            rows.append({"case": name, "what": what, "exit_code": r["rc"], "seconds": round(r["s"], 2),
                         "peak_rss_gb": round(r["peak_mb"] / 1024, 3),
                         "within_targets": r["peak_mb"] / 1024 <= MAX_PEAK_GB and r["s"] <= MAX_SECONDS,
                         "stderr": " ".join(r["err"].split())[-200:]})
            say(f"{name}: {what}: exit {r['rc']}, {r['s']:.1f} s, peak RSS {r['peak_mb'] / 1024:.2f} GB")
    return rows


def _sample_params() -> Path:
    return Path(str(SAMPLE_PARAMS))


def _plot(rows: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(8, 3))
    names = [r["case"] for r in rows]
    axes[0].bar(names, [r["peak_rss_gb"] for r in rows], color="#8a5a3c")
    axes[0].axhline(MAX_PEAK_GB, color="k", ls="--", lw=1)
    axes[0].set_ylabel("peak RSS (GB)")
    axes[1].bar(names, [r["seconds"] for r in rows], color="#5a7a8a")
    axes[1].axhline(MAX_SECONDS, color="k", ls="--", lw=1)
    axes[1].set_ylabel("seconds")
    fig.suptitle("hairdigi bench memory: the largest accepted inputs")
    fig.tight_layout()
    save_figure(fig, path)


def bench_memory(args: argparse.Namespace) -> Result:
    """``hairdigi bench memory``: run the cases, write the table, the JSON and the plot; a case beyond the
    targets is named in a line of its own (``within_targets`` in the table)."""
    out = Path(args.out)
    out = out / "memory" if str(args.out) == "out/bench" else out
    text: list[str] = []
    rows = run_cases(out, quick=args.quick, say=text.append)
    save_table(out, "memory_bench", rows, _plot)
    write_json_atomic(out / "memory_bench.json", {"targets": {"peak_rss_gb": MAX_PEAK_GB, "seconds": MAX_SECONDS},
                                                  "cases": rows})
    beyond = [r["case"] for r in rows if not r["within_targets"]]
    if beyond:
        text.append(f"beyond the targets ({MAX_PEAK_GB} GB, {MAX_SECONDS:.0f} s): {', '.join(beyond)}")
    return Result("memory_bench", rows, text=text,
                  files=[out / "memory_bench.csv", out / "memory_bench.json", out / "memory_bench.png"])
