"""``hairdigi bench spectral``: the RGB fast path against the spectral render, under several lights.

Each hair is rendered once in RGB with white lights and once spectrally under each light
(``render.spectra``), on the same strands with the same sampler seed, in the rig at the bench
camera's pose. The RGB world's colour under a light is its white-light render times the light's
linear sRGB (``spectra.light_rgb``: exactly what an RGB renderer lit by that light gives). Both are
judged as an observer adapted to the light sees them: mean-colour ΔE2000 against the light's white.

Two RGB stand-ins for each hair:

- ``table1``: Table 1's RGB mapping (``render.domain.absorption``), for the hairs Table 1 can say: how far
  the fast path's colour is from the spectral model's, light by light;
- ``matched``: the RGB ``sigma_a`` whose RGB render matches the spectral render under D65, read per
  channel off a response curve of flat absorptions rendered at the same size and spp: what a perfect
  RGB estimate reads from a daylight capture. Under D65 it is right by construction; under another
  light it measures what an RGB world cannot carry from one light to another.

The hairs are the hard cases: platinum, black, a brown, a saturated red, a violet ash from Table 1,
and two dyes Table 1 cannot say, absorbing in one band (590 nm, a violet ash; 609 nm, a blue-green)
on blonde hair. A second spectral render at another seed gives the spectral render's own noise.
"""
from __future__ import annotations

import time
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from hairdigi.app.evaluation.results import Result
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE
from hairdigi.render.io.figures import save_figure
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.spectra import band_dye, hair_sigma_a_spectrum, illuminant_whitepoint, light_rgb

LIGHTS = ("D65", "A", "shop-led", "FL11")
BLONDE = HairParams(melanin_concentration=0.15, melanin_ratio=0.7, dye_concentration=0.0)


def hairs() -> dict[str, HairParams | np.ndarray]:
    """The bench's hairs: Table 1 parameters, or an absorption spectrum (a banded dye on blonde)."""
    blonde = hair_sigma_a_spectrum(BLONDE)
    return {
        "platinum": HairParams(melanin_concentration=0.0, dye_concentration=0.0),
        "black": HairParams(melanin_concentration=1.0, melanin_ratio=0.9, dye_concentration=0.0),
        "brown": HairParams(melanin_concentration=0.5, melanin_ratio=0.8, dye_concentration=0.0),
        "red": HairParams(dye_rgb=(255, 0, 0), dye_concentration=1.0, melanin_concentration=0.1),
        "violet-ash": HairParams(dye_rgb=(150, 110, 220), dye_concentration=0.6, melanin_concentration=0.15),
        "band-590": blonde + band_dye(590.0, 25.0, 0.25),
        "band-609": blonde + band_dye(609.0, 20.0, 0.3),
    }


#: The flat absorptions of the RGB response curve (per fibre radius): 0, then log-spaced.
CURVE_SIGMA = np.concatenate([[0.0], np.geomspace(0.005, 8.0, 24)])


def matched_sigma(colour: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """The RGB ``sigma_a`` whose render has this mean ``colour``: each channel read off ``curve``, the
    (len(CURVE_SIGMA), 3) mean colours of flat absorptions (falling with sigma_a), interpolated in
    log colour and clipped to its ends (a colour outside sRGB's gamut, a channel below 0, is clipped)."""
    logs = np.log(np.maximum(curve, 1e-6))
    target = np.log(np.maximum(np.asarray(colour, float), 1e-6))
    return np.array([np.interp(target[c], logs[::-1, c], CURVE_SIGMA[::-1]) for c in range(3)])


def run(out: Path, quick: bool = False) -> Result:
    """Render each hair in RGB and under each light; save ``spectral_bench.csv`` and ``.png``; return the result."""
    size, spp = (24, 32) if quick else (48, 128)
    lights = LIGHTS[:2] if quick else LIGHTS   # D65 first: the matched stand-in is read under it
    renderer = Renderer(max_cached=2)
    base = SceneSpec("swatch", camera=RIG_SWATCH_POSE)
    renderer.render(np.full(3, 0.3), base, size, 1)                              # build and compile first
    renderer.render(BLONDE, SceneSpec("swatch", camera=RIG_SWATCH_POSE, illuminant="D65"), size, 1)
    def mean(hair, spec, seed=5) -> np.ndarray:
        return renderer.render(hair, spec, size, spp, seed=seed).linear.reshape(-1, 3).mean(0)

    curve = np.array([mean(np.full(3, s), base) for s in CURVE_SIGMA])
    rows = []
    for name, hair in hairs().items():
        start = time.perf_counter()
        table1 = mean(hair_sigma_a(hair), base) if isinstance(hair, HairParams) else None
        rgb_seconds = time.perf_counter() - start
        truths = {}
        for light in lights:
            spec = SceneSpec("swatch", camera=RIG_SWATCH_POSE, illuminant=light)
            start = time.perf_counter()
            truths[light] = mean(hair, spec)
            seconds = time.perf_counter() - start
            again = mean(hair, spec, seed=6)
            if light == "D65":
                sigma = matched_sigma(truths["D65"], curve)
                matched = mean(sigma, base)
            white_xy, tint = illuminant_whitepoint(light), light_rgb(light)
            rows.append({"hair": name, "light": light, "size": size, "spp": spp,
                         "table1_de2000": None if table1 is None else
                         round(float(delta_e2000(table1 * tint, truths[light], white_xy)), 3),
                         "matched_de2000": round(float(delta_e2000(matched * tint, truths[light], white_xy)), 3),
                         "spectral_noise_de2000": round(float(delta_e2000(again, truths[light], white_xy)), 3),
                         "matched_sigma_a": " ".join(f"{v:.4g}" for v in sigma),
                         "spectral_seconds": round(seconds, 3), "rgb_seconds": round(rgb_seconds, 3)})
    return Result("spectral_bench", rows, plot=_plot).save(out)


def _plot(rows: list[dict], path: Path) -> None:
    names = list(dict.fromkeys(r["hair"] for r in rows))
    lights = list(dict.fromkeys(r["light"] for r in rows))
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), sharey=True)
    width = 0.8 / len(lights)
    noise = max(r["spectral_noise_de2000"] for r in rows)
    for ax, field, title in zip(axes, ("table1_de2000", "matched_de2000"),
                                ("Table 1's RGB mapping", "RGB matched under D65 (a perfect RGB estimate)")):
        for k, light in enumerate(lights):
            values = [next(r[field] for r in rows if r["hair"] == n and r["light"] == light) for n in names]
            ax.bar(np.arange(len(names)) + k * width, [np.nan if v is None else v for v in values], width,
                   label=light)
        ax.axhline(noise, color="k", lw=0.8, ls=":", label=f"spectral noise (worst {noise:.2f})")
        ax.set_xticks(np.arange(len(names)) + 0.4 - width / 2, names, fontsize=7, rotation=20)
        ax.set_title(title, fontsize=9)
    axes[0].set_ylabel("mean-colour ΔE2000 against spectral")
    axes[1].legend(fontsize=7, ncol=2)
    r0 = rows[0]
    fig.suptitle(f"the RGB world under other lights: rig swatch, {r0['size']}², {r0['spp']} spp, "
                 f"observer adapted to each light", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)
