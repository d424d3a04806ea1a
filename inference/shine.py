"""Shine from the rig's three lights, one at a time: the measurement.

The bench camera looks almost perpendicular to the fibres. Light 0 lies along them and reaches the
camera only through the tail of the longitudinal lobe, so its share of the swatch's light measures
the shine (Mitsuba's longitudinal roughness beta_m); lights 1 and 2, across the fibres, change
little (``shared/reference/inverse-notes.md``: at equal absorption, light 0's share goes 0.7% ->
38% from beta_m 0.15 to 0.5, and the all-lights colour moves by up to 8.4 ΔE2000).

So, per light and per beta_m on a grid, the swatch area's mean colour is a monotone curve of each
channel's sigma_a, as for the refinement (``inference.refine``): ``ShineTables`` renders them (the
sigma ladder, 4 renders per light and beta_m, cached on disk per view). ``estimate_shine`` reads
beta_m and sigma_a from the three single-light means: for each beta_m, the all-lights sum fixes
sigma_a per channel; the beta_m whose single-light predictions fit the frames best (least squares in
log) is the shine.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace

import numpy as np

from hairdigi.inference.atlas import shine_means
from hairdigi.render.domain.appearance import Appearance
from hairdigi.inference.refine import (ResponseCurve, RefineSettings, View, cache_key, curve_settings, scene_for,
                                       view_key)
from hairdigi.render.domain.files import atomic_path, cache_dir
from hairdigi.render.domain.rig_geometry import N_LIGHTS

#: The beta_m grid of the tables: glossy virgin hair to rough, bleached hair (0.1-0.6).
BETA_GRID = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6)


@dataclass
class ShineTables:
    """Mean linear colour of the swatch area per light, beta_m and sigma level (one channel each)."""

    betas: np.ndarray           # (B,)
    sigma: np.ndarray           # (K,)
    means: np.ndarray           # (L, B, K)
    seconds: float = 0.0
    nonfinite: int = 0          # NaN or Inf values its renders returned (replaced by 0), kept in the cache with it
    _curves: dict = field(default_factory=dict, repr=False, compare=False)

    def curve(self, light: int, b: int) -> ResponseCurve:
        """Light ``light``'s response curve at ``betas[b]`` (built once per tables)."""
        key = (int(light), int(b))
        if key not in self._curves:
            self._curves[key] = ResponseCurve(self.sigma, self.means[light, b])
        return self._curves[key]

    def _weights(self, beta: float) -> tuple[int, float]:
        j = int(np.clip(np.searchsorted(self.betas, beta) - 1, 0, len(self.betas) - 2))
        t = float(np.clip((beta - self.betas[j]) / (self.betas[j + 1] - self.betas[j]), 0.0, 1.0))
        return j, t

    def all_lights_curve(self, beta: float) -> ResponseCurve:
        """The all-lights response curve at ``beta``: the lights' tables summed (log-linear in beta)."""
        j, t = self._weights(beta)
        total = np.exp((1 - t) * np.log(self.means[:, j].sum(0)) + t * np.log(self.means[:, j + 1].sum(0)))
        return ResponseCurve(self.sigma.copy(), total, self.seconds, True, self.nonfinite)

    def predict(self, sigma: np.ndarray, beta: float) -> np.ndarray:
        """(L, 3) single-light means of ``sigma`` (3,) at ``beta`` (linear in beta between grid points)."""
        j, t = self._weights(beta)
        out = np.empty((self.means.shape[0], 3))
        for light in range(self.means.shape[0]):
            a, b = self.curve(light, j)(sigma), self.curve(light, j + 1)(sigma)
            out[light] = np.exp((1 - t) * np.log(a) + t * np.log(b))
        return out


_TABLES_LOCK = threading.Lock()   # one build at a time: the app's warm-up and a first capture wait for each other


def shine_tables(view: View, settings: RefineSettings = RefineSettings(), betas=BETA_GRID, renderer=None,
                 cache: bool = True, swatch_model: str | None = None) -> ShineTables:
    """Render (or load) the per-light tables at ``view``: ``len(betas) x N_LIGHTS x 4`` small renders,
    on the swatch structure ``swatch_model`` (None: the default; ``render.swatch_family``). A second
    caller while they render waits, then loads them from the cache."""
    with _TABLES_LOCK:
        return _shine_tables(view, settings, betas, renderer, cache, swatch_model)


def _shine_tables(view: View, settings: RefineSettings, betas, renderer, cache: bool,
                  swatch_model: str | None = None) -> ShineTables:
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import default_renderer

    renderer = renderer or default_renderer()
    spec, size = scene_for(view, settings, swatch_model=swatch_model)
    key = cache_key([1, curve_settings(settings), view_key(view), list(betas)], spec, renderer.variant)
    path = cache_dir() / "response" / f"shine-{key}.npz"
    if cache and path.exists():
        data = np.load(path)
        return ShineTables(data["betas"], data["sigma"], data["means"], float(data["seconds"]),
                           int(data["nonfinite"]) if "nonfinite" in data.files else 0)
    levels = np.asarray(settings.levels, float)
    shipped = shine_means(view, levels, betas, settings.strand_seed, spec.swatch_model, renderer.variant) \
        if cache else None
    if shipped is not None:     # the bench camera's region: the shipped atlas's cells, no render
        return ShineTables(np.asarray(betas, float), levels.copy(), shipped, 0.0)
    start = time.perf_counter()
    order = levels.reshape(3, -1).T          # three levels per render, one per channel (as refine does)
    means = np.empty((N_LIGHTS, len(betas), len(levels)))
    nonfinite = 0
    for light in range(N_LIGHTS):
        lights = tuple(1.0 if i == light else 0.0 for i in range(N_LIGHTS))
        for b, beta in enumerate(betas):
            one = replace(spec, lights=lights, appearance=Appearance(float(beta)))
            for t, triple in enumerate(order):
                result = renderer.render(triple, one, size, settings.spp, settings.seed)
                means[light, b, [t, t + len(order), t + 2 * len(order)]] = result.linear.reshape(-1, 3).mean(0)
                nonfinite += result.nonfinite
    tables = ShineTables(np.asarray(betas, float), levels, means, time.perf_counter() - start, nonfinite)
    if cache:
        with atomic_path(path, ".npz") as tmp:
            np.savez(tmp, betas=tables.betas, sigma=tables.sigma, means=tables.means, seconds=tables.seconds,
                     nonfinite=tables.nonfinite)
    return tables


@dataclass(frozen=True)
class ShineEstimate:
    longitudinal_roughness: float
    sigma_a: tuple[float, float, float]
    residual: float                        # RMS of the log single-light misfit at the answer
    profile: tuple[tuple[float, float], ...]   # (beta, misfit) along the search, to judge its sharpness


#: Below this mean linear value (the renders' units) a single-light frame is at the camera's noise
#: floor: read noise clipped at black lifts a near-black mean by about this much, so misfits compare
#: log(value + floor). Light 0 on glossy hair (0.7% of the light at beta 0.15) sits there.
SHINE_FLOOR = 1e-3


def estimate_shine(single: np.ndarray, tables: ShineTables, steps: int = 51,
                   floor: float = SHINE_FLOOR) -> ShineEstimate:
    """beta_m and sigma_a from the (L, 3) mean linear colours of the swatch area, one light at a time."""
    single = np.clip(np.asarray(single, float), 1e-9, None)
    total = single.sum(0)
    best = None
    profile = []
    for beta in np.linspace(tables.betas[0], tables.betas[-1], steps):
        sigma, _ = tables.all_lights_curve(beta).inverse(total)
        misfit = float(np.sqrt(np.mean((np.log(tables.predict(sigma, beta) + floor) - np.log(single + floor)) ** 2)))
        profile.append((round(float(beta), 4), round(misfit, 5)))
        if best is None or misfit < best[0]:
            best = (misfit, float(beta), sigma)
    misfit, beta, sigma = best
    return ShineEstimate(beta, tuple(float(v) for v in sigma), misfit, tuple(profile))
