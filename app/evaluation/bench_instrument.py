"""``hairdigi bench instrument``: how the instrument tables were chosen, and what a reading costs.

- **The tables' noise.** A member's reflectance ladder in d/8 SCI at 64 and 256 spp (one layout), and at
  256 spp in another layout of its fibres, each against a 1024-spp reference: the hard cases' readings
  through each, ΔE2000 from the reference's.
- **The aperture.** The same ladder over an 8 mm and a 25 mm spot: a homogeneous swatch's mean is the
  spot's, so the tables serve every aperture if these agree.
- **A reading's cost.** ``inference.instrument_reading.read_instrument`` for each hard case, three geometries,
  with the family's curves at the rig's swatch crop (each member reading the colour the capture showed)
  and without.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from colour_cxf import cxf3, write_cxf

from hairdigi.app.evaluation.results import Result
from hairdigi.app.evaluation.rig import HARD_CASES
from hairdigi.app.library.lab_readings import import_readings
from hairdigi.app.library.store import Library, SwatchRow
from hairdigi.inference.instrument_reading import BuildSettings, load_curves, member_ladder, read_instrument
from hairdigi.inference.refine import SIGMA_LEVELS, ResponseCurve
from hairdigi.inference.structure import family_curves
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.render.instrument_geometry import lab_of_reflectance, reflectance_ladder
from hairdigi.render.metrics import delta_e2000_lab
from hairdigi.render.spectra import hair_sigma_a_spectrum
from hairdigi.render.swatch_family import structure_strands

MEMBERS = ("layered", "deposited")


def _lab(ladder: np.ndarray, hair) -> np.ndarray:
    return lab_of_reflectance(ResponseCurve(np.asarray(SIGMA_LEVELS, float), np.asarray(ladder, float))(
        hair_sigma_a_spectrum(hair)))


def bench_instrument(args: argparse.Namespace) -> Result:
    """The ladders' noise and aperture against a 1024-spp reference, a reading's cost and an import's; writes
    ``instrument.csv``, ``.json`` and ``.png``."""
    quick = getattr(args, "quick", False)
    levels = np.asarray(SIGMA_LEVELS, float)
    rows = []
    for member in MEMBERS[:1] if quick else MEMBERS:
        strands = structure_strands(member, 8000, seed=0)
        timed = {}
        for label, spp, layout, aperture in (("64 spp", 64, 0, 8.0), ("256 spp", 256, 0, 8.0),
                                             ("256 spp, another layout", 256, 1, 8.0),
                                             ("256 spp, 25 mm spot", 256, 0, 25.0),
                                             ("reference: 1024 spp", 256 if quick else 1024, 0, 8.0)):
            start = time.perf_counter()
            if spp == 256 and aperture == 8.0:      # the build's own ladders (cached)
                ladder = member_ladder("d/8 SCI", member, layout, BuildSettings())
            else:
                ladder = reflectance_ladder(structure_strands(member, 8000, seed=layout) if layout else strands,
                                            "d/8 SCI", levels, aperture, 48, spp, seed=99)
            timed[label] = (ladder, time.perf_counter() - start)
        reference = timed.pop("reference: 1024 spp")[0]
        for label, (ladder, seconds) in timed.items():
            errors = [float(delta_e2000_lab(_lab(ladder, h), _lab(reference, h))) for h in HARD_CASES.values()]
            rows.append({"member": member, "ladder": label, "seconds": round(seconds, 2),
                         "median_de2000": round(float(np.median(errors)), 3), "worst_de2000": round(max(errors), 3)})
    rows += _reading_cost(HARD_CASES)
    rows += _import_cost()
    result = Result("instrument", rows, {"rows": len(rows)}, compact=True, plot=_plot).save(args.out)
    for r in rows:
        if "ladder" in r:
            result.text.append(f"{r['member']:10s} {r['ladder']:26s} against 1024 spp: median "
                               f"{r['median_de2000']:.2f}, worst {r['worst_de2000']:.2f} ΔE2000 "
                               f"({r['seconds']:.1f} s)")
        elif "reading" in r:
            result.text.append(f"a reading ({r['reading']}): {r['ms_median']:.1f} ms median, "
                               f"{r['ms_worst']:.1f} ms worst")
        else:
            result.text.append(f"import of {r['readings']} readings of {r['tresses']} tresses ({r['file']}): "
                               f"{r['seconds']:.3f} s")
    return result


def _reading_cost(hairs: dict) -> list[dict]:
    curves = load_curves()
    if curves is None:
        return []
    rig = family_curves(RIG_SWATCH_POSE)
    out = []
    for label, family in (("each member reads the capture's colour", rig), ("at the answer's absorption", None)):
        times = []
        for hair in hairs.values():
            start = time.perf_counter()
            read_instrument(hair, rig=family, curves=curves, intervals={})
            times.append(1000 * (time.perf_counter() - start))
        out.append({"reading": label, "ms_median": round(float(np.median(times)), 2), "ms_worst": round(max(times), 2)})
    return out


#: A lab's export: a few hundred readings (three a tress, SCI and SCE).
IMPORT_TRESSES = 100


def _import_cost() -> list[dict]:
    """``hairdigi library readings`` of a CSV and a CxF3 file of ``IMPORT_TRESSES`` tresses, 6 readings each,
    into a library of as many swatches (tagged with the tress ids)."""
    rng = np.random.default_rng(3)
    ids = [f"T-{i:04d}" for i in range(IMPORT_TRESSES)]
    out = []
    with tempfile.TemporaryDirectory(prefix="hairdigi-bench-readings-") as tmp:
        library = Library(str(Path(tmp) / "library.sqlite"))
        library.add([SwatchRow(id=f"c{i:015d}", kind="capture", capture_id=t) for i, t in enumerate(ids)])
        labs = [(t, mode, *rng.uniform((10, -5, 0), (80, 30, 40))) for t in ids for mode in ("SCI", "SCE") for _ in range(3)]
        csv_path = Path(tmp) / "export.csv"
        csv_path.write_text("Sample Name,Mode,L*,a*,b*\n" + "".join(f"{t},{m},{L:.2f},{a:.2f},{b:.2f}\n"
                                                                        for t, m, L, a, b in labs))
        spec = cxf3.ColorSpecification(id="sci", measurement_spec=cxf3.MeasurementSpec(
            geometry_choice=cxf3.GeometryChoice(choice=cxf3.EsphereType.SPECULAR_INCLUDED)))
        objects = [cxf3.Object(name=t, id=str(k), color_values=cxf3.ColorValues(choice=[
            cxf3.ColorCielab(l=L, a=a, b=b, color_specification="sci")])) for k, (t, _, L, a, b) in enumerate(labs)]
        cxf_path = Path(tmp) / "export.cxf"
        cxf_path.write_bytes(write_cxf(cxf3.CxF(resources=cxf3.Resources(
            object_collection=cxf3.ObjectCollection(object_value=objects),
            color_specification_collection=cxf3.ColorSpecificationCollection(color_specification=[spec])))))
        for path in (csv_path, cxf_path):
            start = time.perf_counter()
            readings = import_readings(library, path)
            out.append({"file": path.suffix[1:].upper(), "readings": len(readings), "tresses": len(ids),
                        "seconds": round(time.perf_counter() - start, 3)})
        library.close()
    return out


def _plot(rows: list[dict], path) -> None:
    matplotlib.use("Agg")

    ladders = [r for r in rows if "ladder" in r]
    fig, ax = plt.subplots(figsize=(8, 4))
    for member in dict.fromkeys(r["member"] for r in ladders):
        mine = [r for r in ladders if r["member"] == member]
        ax.scatter([r["seconds"] for r in mine], [r["median_de2000"] for r in mine], label=member)
        for r in mine:
            ax.annotate(r["ladder"], (r["seconds"], r["median_de2000"]), fontsize=7)
    ax.set_xlabel("seconds a ladder (12 levels, 2 cores)")
    ax.set_ylabel("median ΔE2000 from a 1024-spp ladder (hard cases, d/8 SCI)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
