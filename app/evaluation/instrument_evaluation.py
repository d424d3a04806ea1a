"""``hairdigi evaluate --instrument``: hairdigi's instrument reading against a virtual instrument.

Each hidden swatch (the rig evaluation's hard cases and random Table 1 draws, each on a physical
structure of ``InstrumentSet.structures``, in a strand layout no table was rendered on) is captured
through the simulated rig and estimated in the default mode (``RigSession``: calibrate, capture); the
record's instrument readings (``inference.instrument_reading``) are then judged against the same swatch read
by a virtual instrument: a spectral render of the truth in the instrument's geometry
(``render.instrument_geometry.spectral_tristimulus``: the integrating sphere with and without its specular trap,
and the 45° ring), its hair's absorption the truth's spectrum, seen through the observer's bands under
the illuminant. ``--ship`` writes each geometry's 68% and 95% quantiles as the readings' interval.
"""
from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.app.evaluation.rig import CONDITIONS, hidden_set, RigSet
from hairdigi.app.session.rig_session import RigSession
from hairdigi.hardware.sim_still import write_raw_still
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.instrument_reading import INSTRUMENT_UNCERTAINTY
from hairdigi.render.camera_model import CameraModel
from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic
from hairdigi.render.instrument_geometry import lab_of_tristimulus, spectral_tristimulus
from hairdigi.render.io.figures import save_table
from hairdigi.render.metrics import delta_e2000_lab, quantiles
from hairdigi.render.spectra import hair_sigma_a_spectrum
from hairdigi.render.swatch_family import structure_strands

#: The virtual instrument reads each tress at this many places along its fibres and averages, as a lab does.
SPOTS = 3
#: The rig evaluation's casts and exposures, less the over-exposures an operator is told to undo (+0.5 EV
#: clips platinum and saturated red): the readings are judged, not the exposure check.
EXPOSED = tuple(c for c in CONDITIONS if c[1] <= 0.0)
#: The first hidden swatch's fibre layout (strand seed); the k-th swatch's is ``HIDDEN_LAYOUT + k``: layouts no
#: instrument table or family curve was rendered on (those are 0 and 1), one a swatch, so that one layout's
#: luck is not every swatch's (a deposited swatch's 8 mm spot reads L* 42.3-43.6 over layouts 0-7; layout 5,
#: the one every swatch first shared, 43.55).
HIDDEN_LAYOUT = 5


@dataclass(frozen=True)
class InstrumentSet:
    random: int = 3                                  # random Table 1 draws beside the hard cases
    structures: tuple[str, ...] = ("clumped", "deposited", "wavy")   # the hidden swatches' structures, in turn
    rig_spp: int = 32                                # the simulated rig's light renders
    truth_spp: int = 128                             # the virtual instrument's spectral renders (each of SPOTS)
    truth_size: int = 48
    geometries: tuple[str, ...] = ("d/8 SCI", "d/8 SCE", "45/0")
    #: None: hairdigi's RGB simulated rig; (camera sensitivities, LEDs): a spectral one, both declared, whose
    #: records read the hair in the camera's RGB (``EstimateRecord.spectral``), as a lab's declared rig does
    world: tuple[str | None, str] | None = None
    stills: bool = True                              # each swatch also as a RAW still imported into its session


def truth_readings(params, structure: str, geometries, spp: int, size: int,
                   layout: int = HIDDEN_LAYOUT) -> dict[str, np.ndarray]:
    """The virtual instrument's CIELAB of the hidden swatch (its fibres in ``layout``) in each geometry (D65, 10°)."""
    strands = structure_strands(structure, 8000, seed=layout)
    sigma = hair_sigma_a_spectrum(params)
    return {g: lab_of_tristimulus(spectral_tristimulus(strands, sigma, g, spp=spp, size=size, spots=SPOTS))
            for g in geometries}


#: A lab instrument's repeatability when a tress is lifted and laid under its port again (SD of one reading,
#: L*, a*, b*): readings 0.6-1.2 L* apart (the issue's figure, J. Cosmet. Sci. 51(5)); a* and b* about half.
PLACEMENT_SD = (0.45, 0.25, 0.25)
#: Readings a simulated lab takes of each tress in each geometry (lifting it between them).
LAB_READINGS = 3


def lab_csv_rows(capture_id: str, truth: dict[str, np.ndarray], rng: np.random.Generator) -> list[dict]:
    """A simulated lab's readings of one tress: the virtual instrument's, each placement off by ``PLACEMENT_SD``."""
    rows = []
    for geom, lab in truth.items():
        for _ in range(LAB_READINGS):
            L, a, b = np.asarray(lab) + rng.normal(0.0, PLACEMENT_SD)
            rows.append({"Sample Name": capture_id, "Mode": geom, "L*": round(float(L), 2), "a*": round(float(a), 2),
                         "b*": round(float(b), 2), "Observer": "10", "Illuminant": "D65"})
    return rows


def evaluate_instrument(out_dir: str | os.PathLike, config: InstrumentSet = InstrumentSet(),
                        progress: bool = True, ship: bool = False, lab_dir: str | os.PathLike | None = None) -> dict:
    """Capture, estimate and read every hidden swatch; judge each reading against the virtual instrument.
    ``lab_dir``: also keep the sessions there (``sessions/``) and write a simulated lab's instrument export
    of the same tresses (``readings.csv``, keyed by capture id) for ``hairdigi library readings``."""
    encoder = Encoder()
    hidden = hidden_set(RigSet(random=config.random))
    rows: list[dict] = []
    bar = tqdm(total=len(hidden), desc="instrument", unit="swatch", disable=not progress)
    lab_rows: list[dict] = []
    rng = np.random.default_rng(2026_1129)
    with tempfile.TemporaryDirectory(prefix="hairdigi-eval-instrument-") as tmp:
        root = Path(lab_dir) / "sessions" if lab_dir is not None else Path(tmp)
        for k, (name, params) in enumerate(hidden):
            structure = config.structures[k % len(config.structures)]
            cast, ev = EXPOSED[k % len(EXPOSED)]
            spectra = {} if config.world is None else {"sensitivities": config.world[0], "illuminant": config.world[1]}
            session = RigSession.simulated_rig(root / f"s{k}", hidden=params, spp=config.rig_spp,
                                               camera_model=CameraModel(exposure_ev=ev, cast=cast), encoder=encoder,
                                               swatch_model=structure, strand_seed=HIDDEN_LAYOUT + k, **spectra)
            start = time.perf_counter()
            takes = []                       # (source, capture result, seconds): the live frame, then a RAW still
            try:
                session.calibrate()
                takes.append(("live", session.capture(), time.perf_counter() - start))
                if config.stills:
                    start = time.perf_counter()
                    takes.append(("raw still", session.import_still(_still_of(session, Path(tmp) / f"IMG_{k:04d}.dng")),
                                  time.perf_counter() - start))
            finally:
                session.close()
            head = {"hidden": name, "structure": structure, "layout": HIDDEN_LAYOUT + k,
                    "cast": "/".join(f"{c:g}" for c in cast), "exposure_ev": ev}
            truth = None
            for source, result, seconds in takes:
                record = result.record
                if record is None or not record.instrument:
                    rows.append({**head, "source": source, "error": "; ".join(str(b) for b in result.blocked)
                                 or "no instrument reading"})
                    continue
                if truth is None:
                    start_truth = time.perf_counter()
                    truth = truth_readings(params, structure, config.geometries, config.truth_spp, config.truth_size,
                                           HIDDEN_LAYOUT + k)
                    truth_seconds = time.perf_counter() - start_truth
                if source == "live":
                    lab_rows += lab_csv_rows(result.capture_id, truth, rng)
                for geom in config.geometries:
                    rows.append({**head, "source": source, **_judged(record, geom, truth[geom]),
                                 "estimate_seconds": round(seconds, 2), "truth_seconds": round(truth_seconds, 2)})
            bar.update()
    bar.close()
    if lab_dir is not None:
        write_csv_atomic(Path(lab_dir) / "readings.csv", lab_rows)
    summary = summarise(rows, config)
    save_table(out_dir, "instrument_evaluation", rows, _plot, summary)
    if ship:
        ship_intervals(summary)
    return summary


def _still_of(session, path: Path) -> Path:
    """A still camera's RAW of the session's bench: twice the feed's resolution, its exposure 0.8 of the feed's
    (as ``hairdigi evaluate --rig`` takes its stills)."""
    radiance = session.camera.radiance().repeat(2, axis=0).repeat(2, axis=1)
    return write_raw_still(path, radiance * 0.8)


def _judged(record, geom: str, true: np.ndarray) -> dict:
    """One reading of a record against the virtual instrument's: ΔE2000, the differences and both readings."""
    reading = record.instrument_reading(geom)
    lab = np.asarray(reading.lab)
    return {"geometry": geom, "de2000": round(float(delta_e2000_lab(lab, true)), 3),
            "dL": round(float(lab[0] - true[0]), 3), "da": round(float(lab[1] - true[1]), 3),
            "db": round(float(lab[2] - true[2]), 3), "L": round(float(lab[0]), 2), "a": round(float(lab[1]), 2),
            "b": round(float(lab[2]), 2), "true_L": round(float(true[0]), 2), "true_a": round(float(true[1]), 2),
            "true_b": round(float(true[2]), 2), "spread": round(reading.spread, 3),
            "warnings": " | ".join(w.kind.value for w in record.warnings)}


def summarise(rows: list[dict], config: InstrumentSet) -> dict:
    ok = [r for r in rows if "de2000" in r]
    by_geometry = {g: quantiles([r["de2000"] for r in ok if r["geometry"] == g]) for g in config.geometries}
    by_structure = {s: quantiles([r["de2000"] for r in ok if r["structure"] == s]) for s in config.structures}
    by_source = {src: {g: quantiles([r["de2000"] for r in ok if r["source"] == src and r["geometry"] == g])
                       for g in config.geometries} for src in dict.fromkeys(r["source"] for r in ok)}
    by_case = {}
    for r in ok:
        by_case.setdefault(r["hidden"], []).append(r["de2000"])
    bias = {g: {c: round(float(np.mean([r[c] for r in ok if r["geometry"] == g])), 3) for c in ("dL", "da", "db")}
            for g in config.geometries if any(r["geometry"] == g for r in ok)}
    return {"swatches": len({(r["hidden"], r["structure"]) for r in rows}), "errors": [r for r in rows if "error" in r],
            "by_geometry": by_geometry, "by_structure": by_structure, "by_source": by_source,
            "by_case": {k: quantiles(v) for k, v in by_case.items()}, "bias": bias,
            "settings": {"random": config.random, "structures": list(config.structures), "rig_spp": config.rig_spp,
                         "truth_spp": config.truth_spp, "truth_size": config.truth_size,
                         "layouts": f"{HIDDEN_LAYOUT} + k",
                         "rig": "RGB" if config.world is None else f"spectral: {config.world[0] or 'CIE observer'} "
                                                                    f"under {config.world[1]}"}}


def ship_intervals(summary: dict, path: str | os.PathLike | None = None) -> Path:
    """Write each geometry's measured 68% and 95% quantiles as the readings' interval."""
    structures = ", ".join(summary["settings"]["structures"])
    out = {g: {"p68": round(float(s["p68"]), 3), "p95": round(float(s["p95"]), 3), "n": s["n"],
               "source": f"hairdigi evaluate --instrument ({s['n']} hidden swatches of {structures} against a virtual "
                         f"instrument)"}
           for g, s in summary["by_geometry"].items() if s["n"]}
    return write_json_atomic(Path(path or INSTRUMENT_UNCERTAINTY), out)


def _plot(rows: list[dict], path: Path) -> None:
    matplotlib.use("Agg")
    ok = [r for r in rows if "de2000" in r]
    geometries = list(dict.fromkeys(r["geometry"] for r in ok))
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for i, g in enumerate(geometries):
        values = [r["de2000"] for r in ok if r["geometry"] == g]
        axes[0].scatter(np.full(len(values), i) + np.linspace(-0.15, 0.15, len(values)), values, s=14)
    axes[0].set_xticks(range(len(geometries)), geometries)
    axes[0].axhline(1.0, color="grey", lw=0.8, ls="--")
    axes[0].set_ylabel("ΔE2000, hairdigi against the virtual instrument")
    sci = [r for r in ok if r["geometry"] == geometries[0]] if geometries else []
    axes[1].scatter([r["true_L"] for r in sci], [r["dL"] for r in sci], s=14, label="ΔL*")
    axes[1].scatter([r["true_L"] for r in sci], [r["da"] for r in sci], s=14, label="Δa*")
    axes[1].scatter([r["true_L"] for r in sci], [r["db"] for r in sci], s=14, label="Δb*")
    axes[1].axhline(0.0, color="grey", lw=0.8)
    axes[1].set_xlabel(f"the instrument's L* ({geometries[0] if geometries else ''})")
    axes[1].set_ylabel("hairdigi − instrument")
    axes[1].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
