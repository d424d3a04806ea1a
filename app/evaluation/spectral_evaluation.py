"""``hairdigi evaluate --spectral``: hidden spectral hairs through a spectral rig, judged against the
CIE observer under daylight, tungsten and a shop LED, at the rig and away from it.

Each hidden hair (the rig evaluation's hard cases, a violet ash, and two dyes Table 1 cannot say:
one absorption band at 590 nm or 609 nm on blonde hair) is put under a spectral simulated rig
(``RigSession.simulated_rig(illuminant=..., sensitivities=...)``: white LEDs of a CIE LED SPD, the
ColorChecker's measured spectra, a real camera's sensitivities, the camera model's noise and 8-bit
encode) and captured as an operator does: calibrate on the chart, capture, estimate. Worlds: both of
colour-science's cameras under two phosphor LEDs, and the CIE observer itself (an ideal camera).

The truth is the hidden hair rendered spectrally (Mitsuba's spectral variant) under each light at the
rig's swatch pose and away from it (another camera, a key light and a grey sky), as an observer adapted
to that light sees it. Two answers are judged against it, rendered with the same strands and seed:

- ``rgb``: today's record, its RGB ``sigma_a`` rendered in RGB, times the light's RGB colour (what the
  RGB world predicts under that light);
- ``spectral``: the record's parameters refitted in the spectral world (``inference.spectral_reading``) and
  rendered spectrally under the light.
"""
from __future__ import annotations

import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from tqdm import tqdm

from hairdigi.app.evaluation.rig import HARD_CASES
from hairdigi.app.session.blockers import capture_as_told, messages
from hairdigi.app.session.rig_session import RigSession
from hairdigi.inference.encoder import Encoder
from hairdigi.inference.refine import RefineSettings, response_curve
from hairdigi.inference.spectral_reading import RigSpectra, spectral_answer, spectral_record
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.params import HairParams, sample_params
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, CameraPose
from hairdigi.render.io.figures import save_figure, save_table
from hairdigi.render.judge import judge_mean
from hairdigi.render.metrics import delta_e2000, error_stats
from hairdigi.render.spectra import band_dye, hair_sigma_a_spectrum, illuminant_whitepoint, light_rgb

#: The worlds: (camera sensitivities, the rig's LEDs: CIE LED series phosphor LEDs, LED-B4 5109 K and
#: LED-B5 6598 K); None is the CIE observer (an ideal camera).
WORLDS = (("nikon-5100", "LED-B4"), ("sigma-sdmerill", "LED-B5"), (None, "LED-B4"))
#: Where the customer sees the hair.
LIGHTS = ("D65", "A", "shop-led")
VIEWS = ("rig", "away")
JUDGE_SIZE, JUDGE_SPP, JUDGE_SEED = 48, 64, 424_242


@dataclass(frozen=True)
class SpectralSet:
    spp: int = 16                      # the spectral rig's light renders
    worlds: tuple = WORLDS
    judge_size: int = JUDGE_SIZE
    judge_spp: int = JUDGE_SPP
    seed: int | None = None            # held out: ``random`` hairs of this seed in place of the named ones
    random: int = 6


def hidden_hairs(config: SpectralSet = SpectralSet()) -> list[tuple[str, HairParams | np.ndarray]]:
    """The hidden hairs: Table 1 hard cases, and absorption spectra of banded dyes on blonde; held out
    (``config.seed``), ``config.random`` hairs drawn in turn: a Table 1 hair, a natural one (melanins
    alone), and a band dye (centre 430-660 nm) on a natural base."""
    if config.seed is not None:
        rng = np.random.default_rng(config.seed)
        hairs: list = []
        for i in range(config.random):
            natural = HairParams(melanin_concentration=float(rng.uniform(0.0, 0.97)),
                                 melanin_ratio=float(rng.uniform()), dye_concentration=0.0)
            if i % 3 == 0:
                hairs.append((f"table 1, {i}", sample_params(rng)))
            elif i % 3 == 1:
                hairs.append((f"natural, {i}", natural))
            else:
                centre, width, peak = rng.uniform(430.0, 660.0), rng.uniform(15.0, 40.0), rng.uniform(0.1, 0.4)
                hairs.append((f"band {centre:.0f} nm, {i}", hair_sigma_a_spectrum(natural) + band_dye(centre, width, peak)))
        return hairs
    blonde = hair_sigma_a_spectrum(HairParams(melanin_concentration=0.15, melanin_ratio=0.7, dye_concentration=0.0))
    return [*HARD_CASES.items(),
            ("violet ash", HairParams((150, 110, 220), 0.6, 0.15, 0.7)),
            ("band 590 nm on blonde", blonde + band_dye(590.0, 25.0, 0.25)),
            ("band 609 nm on blonde", blonde + band_dye(609.0, 20.0, 0.3))]


def _scene(view: str, light: str | None):
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec

    if view == "rig":
        return SceneSpec("swatch", camera=RIG_SWATCH_POSE, framing="crop", illuminant=light)
    return SceneSpec("swatch", camera=CameraPose(35.0, 200.0), framing="crop", env="key-sky", lights=(0.0, 0.0, 0.0),
                     illuminant=light)


def _mean(hair, scene, config: SpectralSet) -> np.ndarray:
    return judge_mean(hair, scene, config.judge_size, config.judge_spp, JUDGE_SEED)[0]


def _judge(hidden, found: dict, config: SpectralSet) -> dict:
    """ΔE2000 of each answer against the truth, by view and light (an observer adapted to the light): the
    ``rgb`` answer rendered in RGB times the light's RGB colour, the others rendered spectrally."""
    out = {}
    for view in VIEWS:
        rgb_white = _mean(found["rgb"], _scene(view, None), config)
        for light in LIGHTS:
            truth = np.clip(_mean(hidden, _scene(view, light), config), 1e-9, None)
            white = illuminant_whitepoint(light)
            out[f"truth_{view}_{light}"] = " ".join(f"{v:.5g}" for v in truth)   # to judge other answers later
            for answer in ANSWERS:
                if answer not in found:
                    continue
                colour = rgb_white * light_rgb(light) if answer == "rgb" else \
                    _mean(found[answer], _scene(view, light), config)
                out[f"{answer}_{view}_{light}"] = round(float(delta_e2000(np.clip(colour, 1e-9, None), truth, white)), 3)
    return out


ANSWERS = ("rgb", "spectral", "camera")


def answers(record, profile=None, led: str | None = None, sensitivities: str | None = None,
            curve=None) -> dict[str, np.ndarray | HairParams | float]:
    """A record's answers: ``rgb``, its RGB ``sigma_a``; ``spectral``, its parameters refitted in the
    spectral world (``inference.spectral_reading.spectral_answer``); with the calibration ``profile`` and the
    rig's ``led`` and camera ``sensitivities`` known, ``camera``, read in the camera's own RGB
    (``inference.spectral_reading.spectral_record``, as a capture of a declared rig is). ``*_residual``: each refit's colour residual."""
    curve = curve or response_curve(RIG_SWATCH_POSE, RefineSettings())
    rgb_sigma = np.asarray(record.refinement.sigma_a if record.refinement.sigma_a else hair_sigma_a(record.hair))
    out: dict = {"rgb": rgb_sigma}
    out["spectral"], out["spectral_residual"] = spectral_answer(record.hair, curve(rgb_sigma), curve)
    if record.spectral is not None:      # read as the capture was made (``inference.spectral_reading.spectral_record``)
        out["camera"], out["camera_residual"] = record.spectral.hair, record.spectral.residual
    elif profile is not None and led is not None:   # a record made before the rig declared its spectra
        reading = spectral_record(record, RigSpectra(led, sensitivities), profile).spectral
        if reading is not None:
            out["camera"], out["camera_residual"] = reading.hair, reading.residual
    return out


def judge_record(hidden, record, profile=None, led=None, sensitivities=None,
                 config: SpectralSet = SpectralSet()) -> dict:
    """ΔE2000 of a record's answers against a hidden hair, by answer, view and light."""
    return _judge(hidden, answers(record, profile, led, sensitivities), config)


def evaluate_spectral(out_dir: str | os.PathLike, config: SpectralSet = SpectralSet(), progress: bool = True) -> dict:
    """Capture every hidden hair in every world, estimate, refit, judge; write the table and plot."""
    encoder = Encoder()
    curve = response_curve(RIG_SWATCH_POSE, RefineSettings())
    hidden = hidden_hairs(config)
    rows: list[dict] = []
    bar = tqdm(total=len(hidden) * len(config.worlds), desc="spectral rig captures", unit="capture",
               disable=not progress)
    with tempfile.TemporaryDirectory(prefix="hairdigi-eval-spectral-") as tmp:
        for k, (name, hair) in enumerate(hidden):
            for camera, led in config.worlds:
                row = {"hidden": name, "camera": camera or "CIE observer", "led": led}
                start = time.perf_counter()
                session = RigSession.simulated_rig(Path(tmp) / f"s{k}", hidden=hair, spp=config.spp, encoder=encoder,
                                                   illuminant=led, sensitivities=camera)
                try:
                    row["rig_seconds"] = round(time.perf_counter() - start, 2)
                    start = time.perf_counter()
                    profile = session.calibrate()
                    result, recalibrated = capture_as_told(session)   # an over-exposed swatch: as the operator is told
                    profile = recalibrated or profile
                    row["exposure_ev"] = session.camera.camera.exposure_ev
                    row["chain_seconds"] = round(time.perf_counter() - start, 2)
                    row["calibration_de2000"] = round(float(profile.delta_e2000["after"]["mean"]), 3)
                except Exception as exc:   # noqa: BLE001 - a failure found by the evaluation is reported, not lost
                    row["error"] = f"{type(exc).__name__}: {exc}"
                finally:
                    session.close()
                rec = None if "error" in row else result.record
                if rec is None:
                    row.setdefault("blocked", "; ".join(messages(getattr(result, "blocked", []) or [])))
                    rows.append(row)
                    bar.update()
                    continue
                start = time.perf_counter()
                found = answers(rec, profile, led, camera, curve)
                row.update(refit_seconds=round(time.perf_counter() - start, 3),
                           reading_seconds=round(rec.spectral.seconds, 3) if rec.spectral else None,
                           stated_p95=rec.uncertainty.mean_colour_de2000_p95,
                           warnings=" | ".join(w.kind.value for w in rec.warnings),
                           rgb_answer=" ".join(f"{v:.4g}" for v in rec.hair.to_vector()),
                           rgb_sigma=" ".join(f"{v:.5g}" for v in found["rgb"]),
                           **{f"{a}_answer": " ".join(f"{v:.4g}" for v in found[a].to_vector())
                              for a in ANSWERS[1:] if a in found},
                           **{f"{a}_residual": round(found[f"{a}_residual"], 3) for a in ANSWERS[1:] if a in found})
                row.update(_judge(hair, found, config))
                rows.append(row)
                bar.update()
    bar.close()
    summary = summarise(rows)
    save_table(out_dir, "spectral_evaluation", rows, _plot, summary)
    return summary


def summarise(rows: list[dict]) -> dict:
    """Median / p95 / worst for each answer, view and light; by case and by camera; the stated interval."""
    done = [r for r in rows if "rgb_rig_D65" in r]
    summary = {"captures": len(rows), "estimated": len(done),
               "errors": [f"{r['hidden']} {r['camera']} {r['led']}: {r.get('error') or r.get('blocked')}"
                          for r in rows if "rgb_rig_D65" not in r]}
    for answer in ANSWERS:
        if not any(f"{answer}_rig_D65" in r for r in done):
            continue
        summary[answer] = {f"{view} {light}": error_stats(r.get(f"{answer}_{view}_{light}") for r in done)
                           for view in VIEWS for light in LIGHTS}
        summary[f"{answer}_by_case"] = {
            case: {light: error_stats(r.get(f"{answer}_rig_{light}") for r in done if r["hidden"] == case)
                   for light in LIGHTS}
            for case in dict.fromkeys(r["hidden"] for r in done)}
        summary[f"{answer}_by_camera"] = {
            camera: {light: error_stats(r.get(f"{answer}_rig_{light}") for r in done if r["camera"] == camera)
                     for light in LIGHTS}
            for camera in dict.fromkeys(r["camera"] for r in done)}
    stated = [r for r in done if r.get("stated_p95") is not None]
    if stated:   # what each answer's record claims it holds for: the RGB answer daylight, the reading every light
        summary["stated_p95_held"] = {
            a: round(float(np.mean([r[f"{a}_{view}_{light}"] <= r["stated_p95"] for r in stated for view in VIEWS
                                    for light in (LIGHTS if a == "camera" else LIGHTS[:1])])), 3)
            for a in ANSWERS if all(f"{a}_rig_D65" in r for r in stated)}
    summary["seconds"] = {k: error_stats(r.get(k) for r in done) for k in ("rig_seconds", "chain_seconds",
                                                                           "refit_seconds", "reading_seconds")}
    summary["table"] = interval_table(done)
    summary["calibration_de2000"] = error_stats(r.get("calibration_de2000") for r in done)
    return summary


def camera_key(camera: str) -> str:
    """A row's camera as ``inference.spectral_reading.SPECTRAL_TABLE`` names it."""
    return "cie" if camera == "CIE observer" else camera


def interval_table(done: list[dict]) -> dict:
    """The spectral world's colour intervals (``inference.spectral_reading.SPECTRAL_TABLE``): each camera's
    reading over every view and light; ``unknown``, the RGB answer under daylight over every camera."""
    def quantiles(values: list[float], answer: str, holds_for: str) -> dict:
        return {"answer": answer, "holds_for": holds_for, "n": len(values),
                "p68": round(float(np.quantile(values, 0.68)), 3), "p95": round(float(np.quantile(values, 0.95)), 3)}

    cameras = {}
    for camera in dict.fromkeys(r["camera"] for r in done):
        values = [r[f"camera_{view}_{light}"] for r in done if r["camera"] == camera for view in VIEWS
                  for light in LIGHTS if f"camera_{view}_{light}" in r]
        if values:
            cameras[camera_key(camera)] = quantiles(values, "camera", "the spectral reading's colour at the rig "
                                                    "and away, under daylight, tungsten and a shop LED")
    rgb = [r[f"rgb_{view}_D65"] for r in done for view in VIEWS]
    if rgb:
        cameras["unknown"] = quantiles(rgb, "rgb", "the record's colour under daylight, at the rig and away, "
                                       "through a camera and LEDs the rig does not declare")
    return {"source": f"hairdigi evaluate --spectral: {len(done)} spectral-rig captures "
                      f"({', '.join(dict.fromkeys(r['camera'] for r in done))})", "cameras": cameras}


def _plot(rows: list[dict], path: Path) -> None:
    done = [r for r in rows if "rgb_rig_D65" in r]
    cases = list(dict.fromkeys(r["hidden"] for r in done))
    fig, axes = plt.subplots(1, len(LIGHTS), figsize=(13, 4), sharey=True)
    for ax, light in zip(axes, LIGHTS):
        for i, case in enumerate(cases):
            for answer, colour, dx in (("rgb", "C3", -0.2), ("spectral", "C0", 0.0), ("camera", "C2", 0.2)):
                v = [r[f"{answer}_rig_{light}"] for r in done if r["hidden"] == case and f"{answer}_rig_{light}" in r]
                ax.scatter([i + dx] * len(v), v, s=14, alpha=0.7, color=colour, label=answer if i == 0 else None)
        ax.axhline(1.0, ls="--", color="grey", lw=0.8)
        ax.set_xticks(range(len(cases)), cases, rotation=35, ha="right", fontsize=7)
        ax.set_title(f"at the rig, seen under {light}", fontsize=9)
    axes[0].set_ylabel("mean-colour ΔE2000 against the spectral truth")
    axes[0].legend(fontsize=8)
    fig.suptitle("spectral rig: real cameras' sensitivities under white LEDs, judged by the CIE observer", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)
