"""The finder on thick and thin, dark and light swatches in RAW stills of the rig: before and after.

Each still is rendered as ``tests/test_finder_thick.py`` renders its cases (``rig_still``: Mitsuba, the rig's
scene, lights and chart, the simulated still camera's DNG read back through rawpy), at the simulated rig's
400 x 300 frame and 32 samples a pixel, on a still camera of twice its pixels (800 x 600), as
``hairdigi evaluate --rig`` takes its stills. For each, the region a still is estimated from is found by

- ``before``: the found box less ``CORE_INSET`` (``swatch_core(find_swatch(...))``, the finder until this
  change), and
- ``after``: ``find_swatch_core`` (the largest box of hair like the swatch's interior, less ``HAIR_MARGIN``).

Per region: the share of its pixels that show no hair (a ``position`` AOV says which do), the mean colour's
ΔE2000 from a crop that is hair only (the swatch's footprint inset 0.1 units), and, with ``--estimate``, the
still imported as ``hairdigi rig --still`` imports it (``app.session.rig_session.import_still``: calibrated on
its own chart, then estimated from that region) and the estimate judged against the truth (``render.judge``).

    .venv/bin/python packaging/bench/finder-thick/finder_thick.py --estimate
"""
from __future__ import annotations

import argparse
import csv
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2] / "tests"))

from test_finder_thick import DARK, LIGHT, Swatch, rig_still  # noqa: E402

#: (name, swatch, sigma_a): the thicknesses 5-20% of the width, dark and light, then short off-centre, slightly
#: turned and bound swatches (``tests/test_finder_thick.py``'s cases at the bench's size).
CASES = [(f"{tone} {round(t * 100)}%", Swatch(t), sigma) for tone, sigma in (("dark", DARK), ("light", LIGHT))
         for t in (0.05, 0.10, 0.15, 0.20)] + [
    ("dark 15% short, off-centre", Swatch(0.15, length=0.8, centre=(-0.05, 0.2)), DARK),
    ("light 15% short, off-centre", Swatch(0.15, length=0.8, centre=(-0.05, -0.25)), LIGHT),
    ("dark 18% turned 4°", Swatch(0.18, rotation_deg=4.0), DARK),
    ("dark 15% short, off-centre, white binding", Swatch(0.15, length=0.8, centre=(-0.05, 0.2), binding=0.8), DARK),
    ("light 10% turned 3°, black binding", Swatch(0.10, rotation_deg=3.0, binding=0.05), LIGHT),
]
FIELDS = ["case", "thickness", "sigma_a", "finder", "region", "not_hair_share", "mean_de2000_vs_hair_crop",
          "estimate_sigma_a", "estimate_de2000", "seconds"]


def before(img: np.ndarray):
    """The finder's region until this change: the found box less ``CORE_INSET``."""
    from hairdigi.inference.preprocess import find_swatch, swatch_core

    roi, outline = find_swatch(img)
    return swatch_core(roi, (img.shape[1], img.shape[0])), outline


def estimate(still: Path, folder: Path, finder) -> tuple[list[float] | None, float]:
    """The still imported with ``finder`` as the region's finder: the estimate's sigma_a and its seconds."""
    import hairdigi.inference.preprocess as preprocess
    from hairdigi.app.session.rig_session import import_still
    from hairdigi.inference.encoder import Encoder

    kept = preprocess.find_swatch_core
    preprocess.find_swatch_core = finder
    try:
        start = time.perf_counter()
        result = import_still(folder, still, Encoder())
        seconds = time.perf_counter() - start
    finally:
        preprocess.find_swatch_core = kept
    if result.record is None:
        return None, seconds
    rec = result.record
    sigma = rec.refinement.sigma_a if rec.refinement.sigma_a else None
    return (list(sigma) if sigma is not None else None), seconds


def main(argv: list[str] | None = None) -> None:
    """Render every case, find its region both ways, and write ``finder_thick.csv`` beside this script."""
    from hairdigi.inference.preprocess import find_swatch_core
    from hairdigi.render.judge import judge
    from hairdigi.render.metrics import delta_e2000

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--estimate", action="store_true", help="also import each still and judge the estimate")
    parser.add_argument("--spp", type=int, default=32)
    parser.add_argument("--only", default="", help="only the cases whose name holds this text")
    parser.add_argument("--out", type=Path, default=HERE / "finder_thick.csv")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory(prefix="hairdigi-bench-finder-") as tmp:
        for k, (name, swatch, sigma) in enumerate(CASES):
            if args.only not in name:
                continue
            still = rig_still(swatch, sigma, size=(400, 300), spp=args.spp, upscale=2,
                              keep=Path(tmp) / f"IMG_{k:04d}.dng")
            size = (still.srgb.shape[1], still.srgb.shape[0])
            crop = swatch.hair_only_box(size)
            for finder_name, finder in (("before", before), ("after", find_swatch_core)):
                start = time.perf_counter()
                roi = finder(still.srgb)[0]
                region = (roi.x, roi.y, roi.w, roi.h)
                row = {"case": name, "thickness": swatch.thickness, "sigma_a": "/".join(f"{v:g}" for v in sigma),
                       "finder": finder_name, "region": " ".join(map(str, region)),
                       "not_hair_share": round(still.not_hair(region), 4),
                       "mean_de2000_vs_hair_crop": round(float(delta_e2000(still.mean(region), still.mean(crop))), 3),
                       "seconds": round(time.perf_counter() - start, 3)}
                if args.estimate:
                    found, seconds = estimate(still.path, Path(tmp) / f"session-{k}-{finder_name}", finder)
                    if found is not None:
                        row.update(estimate_sigma_a="/".join(f"{v:.3g}" for v in found),
                                   estimate_de2000=round(judge(np.asarray(sigma), np.asarray(found)).de2000, 3))
                    row["seconds"] = round(seconds, 1)
                rows.append(row)
                print(" | ".join(str(row.get(f, "")) for f in FIELDS), flush=True)
    with open(args.out, "w", newline="") as f:
        writer = csv.DictWriter(f, FIELDS)
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
