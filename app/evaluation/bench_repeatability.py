"""``hairdigi bench repeatability``: one swatch lifted and laid down again, read by hairdigi and by an instrument.

A lab's instrument reads an 8-25 mm spot: lift a tress and lay it under the port again and L* moves by
0.6-1.2 between readings. hairdigi sees the whole swatch. Each hair here is laid on the simulated rig's
holder ``PLACEMENTS`` times, each time a new layout of its fibres (another strand seed: the same swatch
combed down again) under a slightly other exposure, captured, estimated in the default mode, and read
(``EstimateRecord.instrument``). Beside it, the virtual instrument (``render.instrument_geometry``) reads each
placement's spot. The table gives, per hair and geometry, the spread of each: the mean and largest
ΔE2000 of a placement from the placements' mean.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from hairdigi.app.evaluation.results import Result
from hairdigi.app.evaluation.rig import HARD_CASES
from hairdigi.app.session.rig_session import RigSession
from hairdigi.inference.encoder import Encoder
from hairdigi.render.camera_model import CameraModel
from hairdigi.render.instrument_geometry import lab_of_tristimulus, spectral_tristimulus
from hairdigi.render.metrics import delta_e2000_lab
from hairdigi.render.spectra import hair_sigma_a_spectrum
from hairdigi.render.swatch_family import structure_strands

#: The hairs laid down again: the rig evaluation's hard cases that span the lightness range, and a dye.
HAIRS = ("copper (the demo)", "black", "platinum", "saturated blue")
PLACEMENTS = 5
#: Each placement's exposure error (EV), as an operator's lamp warms and the camera meters again.
EXPOSURE_JITTER_EV = 0.2


def spread(labs: list[np.ndarray]) -> dict:
    """Mean and largest ΔE2000 of each reading from the readings' mean; and the largest pair apart."""
    labs = [np.asarray(v, float) for v in labs]
    centre = np.mean(labs, axis=0)
    away = [float(delta_e2000_lab(v, centre)) for v in labs]
    pairs = [float(delta_e2000_lab(a, b)) for i, a in enumerate(labs) for b in labs[i + 1:]]
    return {"mean_from_mean": round(float(np.mean(away)), 3), "worst_from_mean": round(float(np.max(away)), 3),
            "worst_pair": round(max(pairs, default=0.0), 3), "L_sd": round(float(np.std([v[0] for v in labs], ddof=1)), 3)}


def bench_repeatability(args: argparse.Namespace) -> Result:
    """Each hair laid down ``PLACEMENTS`` times (``--quick``: two hairs, three): the spread of hairdigi's
    readings beside an 8 mm instrument spot's; writes ``repeatability.csv``, ``.json`` and ``.png``."""
    quick = getattr(args, "quick", False)
    hairs = HAIRS[:2] if quick else HAIRS
    placements = 3 if quick else PLACEMENTS
    geometries = ("d/8 SCI", "d/8 SCE")
    encoder = Encoder()
    rng = np.random.default_rng(7)
    readings: dict[tuple[str, str], dict[str, list]] = {}
    rows = []
    with tempfile.TemporaryDirectory(prefix="hairdigi-bench-repeat-") as tmp:
        for name in hairs:
            params = HARD_CASES[name]
            for k in range(placements):
                seed, ev = 20 + k, float(rng.uniform(-EXPOSURE_JITTER_EV, EXPOSURE_JITTER_EV))
                session = RigSession.simulated_rig(Path(tmp) / f"{name[:6]}-{k}", hidden=params, spp=32, encoder=encoder,
                                                   camera_model=CameraModel(exposure_ev=ev, cast=(1.0, 1.0, 1.0)),
                                                   swatch_model="deposited", strand_seed=seed)
                start = time.perf_counter()
                try:
                    session.calibrate()
                    record = session.capture().record
                finally:
                    session.close()
                seconds = time.perf_counter() - start
                truth = _placed_truth(params, seed, geometries)
                print(f"{name}, placement {k + 1} of {placements}: estimated in {seconds:.1f} s", flush=True)
                for geom in geometries:
                    mine = record.instrument_reading(geom).lab if record is not None and record.instrument else None
                    slot = readings.setdefault((name, geom), {"hairdigi": [], "instrument": []})
                    if mine is not None:
                        slot["hairdigi"].append(np.asarray(mine))
                    slot["instrument"].append(truth[geom])
                    rows.append({"hair": name, "placement": k, "geometry": geom, "exposure_ev": round(ev, 3),
                                 "hairdigi_L": None if mine is None else round(mine[0], 2),
                                 "hairdigi_a": None if mine is None else round(mine[1], 2),
                                 "hairdigi_b": None if mine is None else round(mine[2], 2),
                                 "instrument_L": round(float(truth[geom][0]), 2),
                                 "instrument_a": round(float(truth[geom][1]), 2),
                                 "instrument_b": round(float(truth[geom][2]), 2), "seconds": round(seconds, 2)})
    summary = {"placements": placements, "structure": "deposited", "spreads": []}
    for (name, geom), slot in readings.items():
        summary["spreads"].append({"hair": name, "geometry": geom,
                                   "hairdigi": spread(slot["hairdigi"]) if len(slot["hairdigi"]) > 1 else None,
                                   "instrument_spot": spread(slot["instrument"])})
    result = Result("repeatability", rows, summary, compact=True, plot=_plot).save(args.out)
    result.text.append(f"{placements} placements of each hair (a new layout of its fibres and "
                       f"±{EXPOSURE_JITTER_EV} EV each), deposited swatches; ΔE2000 of a placement's reading from "
                       f"their mean (mean / worst):")
    for s in summary["spreads"]:
        h, i = s["hairdigi"], s["instrument_spot"]
        ours = f"{h['mean_from_mean']:.2f} / {h['worst_from_mean']:.2f} (L* SD {h['L_sd']:.2f})" if h else "not read"
        result.text.append(f"  {s['hair']:18s} {s['geometry']}: hairdigi {ours}; an 8 mm instrument spot "
                           f"{i['mean_from_mean']:.2f} / {i['worst_from_mean']:.2f} (L* SD {i['L_sd']:.2f})")
    return result


def _placed_truth(params, seed: int, geometries) -> dict[str, np.ndarray]:
    """The virtual instrument's reading of one placement's spot (its own fibre layout)."""
    strands = structure_strands("deposited", 8000, seed=seed)
    sigma = hair_sigma_a_spectrum(params)
    return {g: lab_of_tristimulus(spectral_tristimulus(strands, sigma, g, spp=128, size=48)) for g in geometries}


def _plot(rows: list[dict], path: Path) -> None:
    matplotlib.use("Agg")

    hairs = list(dict.fromkeys(r["hair"] for r in rows))
    sci = [r for r in rows if r["geometry"] == "d/8 SCI"]
    fig, ax = plt.subplots(figsize=(8, 4))
    for i, hair in enumerate(hairs):
        mine = [r for r in sci if r["hair"] == hair]
        ours = [r["hairdigi_L"] for r in mine if r["hairdigi_L"] is not None]
        theirs = [r["instrument_L"] for r in mine]
        ax.scatter(np.full(len(ours), i - 0.1), np.asarray(ours) - np.mean(ours) if ours else [], color="tab:blue",
                   label="hairdigi" if i == 0 else None)
        ax.scatter(np.full(len(theirs), i + 0.1), np.asarray(theirs) - np.mean(theirs), color="tab:orange",
                   label="an 8 mm instrument spot" if i == 0 else None)
    ax.set_xticks(range(len(hairs)), hairs)
    ax.set_ylabel("L* (d/8 SCI) − its mean over placements")
    ax.axhline(0, color="grey", lw=0.8)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
