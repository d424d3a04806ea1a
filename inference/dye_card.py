"""The shade card of a dye: its prediction on the ten natural levels, each rendered and measured.

Each level (``inference.levels``) and the dye's prediction on it are rendered as small all-hair
swatches (Mitsuba, one sampler seed for both: their difference is the dye's, not the sampler's).
The labels come from the renders: the result's mean colour as sRGB and CIE L*a*b* (D65), and the
ΔE2000 from base to result. Each result is also shown under ``CARD_LIGHTS`` (daylight, tungsten, a
shop LED), as an eye adapted to each light sees it, with the ΔE2000 between daylight and each: the
predicted absorption as a spectrum (``render.spectra.rgb_sigma_spectrum``) and the rig's response
curve read per wavelength (``inference.spectral_reading.colour_under``), so no render is added. Written as
PNG and PDF (matplotlib; the PDF prints) and a JSON table.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from hairdigi.inference.dye import apply, describe_colour, rig_curve, sample_of
from hairdigi.inference.instrument_reading import load_curves, read_instrument
from hairdigi.inference.levels import LEVEL_NAMES, LEVELS, natural_base
from hairdigi.inference.spectral_reading import colour_under
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.dye_record import DyeRecord
from hairdigi.render.domain.files import atomic_paths, refuse_protected
from hairdigi.render.domain.records import EstimateRecord
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.spectra import balanced, rgb_sigma_spectrum

CARD_SIZE, CARD_SPP, CARD_SEED = 64, 16, 3
#: The lights each result is shown under (``render.domain.bounds.ILLUMINANTS``), daylight first.
CARD_LIGHTS = ("D65", "A", "shop-led")


def under_lights(sigma_rgb, curve) -> dict[str, dict]:
    """A predicted hair under each of ``CARD_LIGHTS``, adapted: its description, and ΔE2000 from daylight."""
    spectrum = rgb_sigma_spectrum(np.asarray(sigma_rgb, float))
    seen = {light: balanced(colour_under(curve, spectrum, light), light) for light in CARD_LIGHTS}
    day = seen[CARD_LIGHTS[0]]
    return {light: {**describe_colour(colour), "de2000_from_daylight": round(float(delta_e2000(day, colour)), 2)}
            for light, colour in seen.items()}


def instrument_labs(hair) -> dict[str, list[float]]:
    """A predicted hair as a lab's instrument would read its swatch (D65, 10°; ``inference.instrument_reading``: the
    family's structures at its absorption, their median), by geometry; {} where no tables are shipped."""
    curves = load_curves()
    if curves is None:
        return {}
    return {r.geometry: [round(v, 2) for v in r.lab] for r in read_instrument(hair, curves=curves, intervals={})}


def card_rows(dye: DyeRecord, size: int = CARD_SIZE, spp: int = CARD_SPP, seed: int = CARD_SEED,
              dose: float = 1.0, curve=None) -> list[dict]:
    """Render each natural level and the dye on it; the measured colours and ΔE2000 per level."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec, default_renderer

    renderer = default_renderer()
    spec = SceneSpec("swatch", framing="crop")
    curve = curve or rig_curve()
    rows = []
    for level in LEVELS:
        hair = natural_base(level)
        base = sample_of(EstimateRecord(hair=hair), path=f"level {level}")
        pred = apply(dye, base, dose, curve)
        start = time.perf_counter()
        before = renderer.render(hair_sigma_a(hair), spec, size, spp, seed)
        after = renderer.render(pred.sigma_a, spec, size, spp, seed)
        mean_before = before.linear.reshape(-1, 3).mean(0)
        mean_after = after.linear.reshape(-1, 3).mean(0)
        rows.append({"level": level, "name": LEVEL_NAMES[level], "base": describe_colour(mean_before),
                     "result": describe_colour(mean_after), "hair": pred.params.to_dict(),
                     "sigma_a": [round(float(v), 6) for v in pred.sigma_a],
                     "de2000": round(float(delta_e2000(mean_before, mean_after)), 2),
                     "under": under_lights(pred.sigma_a, curve),
                     "instrument": instrument_labs(pred.params),
                     "render_s": round(time.perf_counter() - start, 3),
                     "nonfinite": before.nonfinite + after.nonfinite,   # NaN/Inf values rendered as 0
                     "_images": (before.srgb, after.srgb)})
    return rows


def _chips(*colours_hex: str):
    """Flat chips of colours side by side (base | result; or one hair under several lights), 8-bit."""
    rgb = [[int(h[i:i + 2], 16) for i in (1, 3, 5)] for h in colours_hex]
    chip = np.zeros((20, 20 * len(rgb), 3), np.uint8)
    for k, value in enumerate(rgb):
        chip[:, 20 * k:20 * (k + 1)] = value
    return chip


def draw_card(dye: DyeRecord, rows: list[dict], dose: float = 1.0):
    """The card as a matplotlib figure: the natural levels above, the dye's result below, labelled. A plain
    ``Figure``, not pyplot's: no GUI canvas, so a worker thread may draw it while a Qt window runs."""
    # 11 x 4.8 in: the PDF prints on A4 or Letter, landscape, without scaling
    fig = Figure(figsize=(11.0, 6.6))
    axes = fig.subplots(4, len(rows), gridspec_kw={"height_ratios": [1, 1, 0.45, 0.45]})
    lift = (f"lift {dye.lift:.2f}" + ("" if dye.lift_measured else " (assumed: one base)"))
    dep = ", ".join(f"{v:.3f}" for v in dye.deposit_sigma_a)
    fig.suptitle(f"{dye.name}{'' if dose == 1 else f' at dose {dose:g}'}: deposit sigma_a ({dep}), {lift}",
                 fontsize=10)
    for col, row in enumerate(rows):
        top, bottom, chips, lights = axes[0, col], axes[1, col], axes[2, col], axes[3, col]
        top.imshow(row["_images"][0], interpolation="nearest")
        bottom.imshow(row["_images"][1], interpolation="nearest")
        chips.imshow(_chips(row["base"]["srgb"], row["result"]["srgb"]), interpolation="nearest")
        under = row["under"]
        lights.imshow(_chips(*[under[light]["srgb"] for light in CARD_LIGHTS]), interpolation="nearest")
        lights.set_xlabel(" ".join(f"{under[light]['de2000_from_daylight']:.1f}" for light in CARD_LIGHTS[1:]),
                          fontsize=7)
        for ax in (top, bottom, chips, lights):
            ax.set_xticks([])
            ax.set_yticks([])
        top.set_title(f"level {row['level']}\n{row['base']['srgb']}", fontsize=7)
        lab = row["result"]["lab"]
        sci = row.get("instrument", {}).get("d/8 SCI")
        bottom.set_xlabel(f"{row['result']['srgb']}\nL*a*b* {lab[0]:.0f} {lab[1]:.0f} {lab[2]:.0f}\n"
                          + (f"SCI {sci[0]:.0f} {sci[1]:.0f} {sci[2]:.0f}\n" if sci else "")
                          + f"ΔE00 {row['de2000']:.1f}", fontsize=7)
    axes[0, 0].set_ylabel("natural", fontsize=8)
    axes[1, 0].set_ylabel("dyed", fontsize=8)
    axes[2, 0].set_ylabel("mean:\nbase | dyed", fontsize=7)
    axes[3, 0].set_ylabel("dyed under\nD65 | A | LED", fontsize=7)
    fig.text(0.01, 0.01, "predicted by hairdigi (Kips et al. 2022 Table 1 absorption; deposit + lift); "
                         "colours are the rendered swatches' means, sRGB D65;\nbottom row: the dyed hair under "
                         "daylight, tungsten (A) and a shop LED (LED-B3) as an eye adapted to each sees it, "
                         "ΔE00 from daylight below (tungsten, LED); SCI: as a d/8 spectrophotometer reads the dyed "
                         "swatch (D65, 10°, specular included)", fontsize=6)
    fig.tight_layout(rect=(0, 0.04, 1, 0.95))
    return fig


def shade_card(dye: DyeRecord, out_png: str | os.PathLike, dose: float = 1.0, size: int = CARD_SIZE,
               spp: int = CARD_SPP, curve=None) -> tuple[Path, Path, Path, list[dict]]:
    """Write the card as PNG, PDF (beside it) and JSON, all three published together (a failure leaves none
    of them half made, and the old card whole); returns the three paths and the rows. None of the three may
    be a record, a dye, a capture or a library (``ProtectedFileError``, before anything is rendered)."""
    out_png = Path(out_png)
    pdf, table = out_png.with_suffix(".pdf"), out_png.with_suffix(".json")
    refuse_protected((out_png, pdf, table))   # every file checked before any render or write
    rows = card_rows(dye, size, spp, dose=dose, curve=curve)
    fig = draw_card(dye, rows, dose)
    clean = [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows]
    with atomic_paths(out_png, pdf, table, suffixes=(".png", ".pdf", ".json")) as (png_tmp, pdf_tmp, json_tmp):
        fig.savefig(pdf_tmp, format="pdf")
        fig.savefig(png_tmp, dpi=150, format="png")
        json_tmp.write_text(json.dumps({"dye": dye.name, "dose": dose, "render": {
            "size": size, "spp": spp, "seed": CARD_SEED, "framing": "crop"}, "levels": clean}, indent=2) + "\n",
            encoding="utf-8")
    return out_png, pdf, table, clean
