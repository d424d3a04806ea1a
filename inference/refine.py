"""Refinement by synthesis: correct the encoder's estimate until the swatch it renders has the capture's
mean colour.

The fact this rests on (measured, ``shared/reference/inverse-notes.md``): in RGB rendering each
channel's expected swatch radiance depends on that channel's ``sigma_a`` alone, through one monotone
curve ``F(sigma; camera pose)`` shared by the three channels (the rig lights are white). So:

1. **Response curve.** Render a ladder of ``sigma`` levels as the capture saw the swatch, three
   levels per render (one per channel), with one sampler seed (common random numbers). 12 levels
   cost 4 small renders; the curve is cached on disk per view and settings, so the rig's fixed
   camera pays once (the bench camera's regions come from the shipped atlas, ``inference.atlas``, with
   no render at all). The view is the capture's own: for a rig frame, exactly the swatch area whose
   mean is fitted (``RigRegion``: the bench camera, its film cropped to that area, so the lights'
   fall-off across the swatch is in the render too); for an all-hair crop, a camera pose over the
   crop framing's centre.
2. **Invert** the curve per channel (monotone PCHIP in log space) at the capture's mean linear colour.
3. **Check and polish** (``iterations`` steps): render the swatch with the found ``sigma_a`` (same
   seed) and measure the residual; while it is above tolerance, shift each channel's goal by the
   residual and invert again. The curve supplies the slope, so a step cannot leave the monotone
   curve's range or overshoot as a bare secant does. The last step's ``sigma_a`` is not rendered
   (``RefineSettings.check_last``): its colour is the check before it moved along the curve. Rendering
   it measured the residual and changed no answer (the same ``sigma_a`` either way), at half the
   estimate's time.
4. **Back to Table 1.** Six parameters reach the image only through the 3-vector ``sigma_a``, so a
   3-D family of parameter vectors fits. The rule: the member **nearest the encoder's estimate**
   (Euclidean distance of the normalised Table 1 vectors) whose fibre colour matches, found by
   bounded least squares. The encoder's reading of texture and hue stays; only what the colour
   contradicts moves.
"""
from __future__ import annotations

import functools
import hashlib
import json
import threading
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import least_squares

from hairdigi.inference.atlas import curve_means
from hairdigi.render.domain.absorption import albedo_from_sigma_a, hair_sigma_a
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, GREY_SIGMA_A, Appearance
from hairdigi.render.domain.bounds import SwatchModel
from hairdigi.render.domain.text_enum import text_of
from hairdigi.render.domain.files import cache_dir, write_json_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.estimate_parts import Region
from hairdigi.render.domain.records import RefinementRecord
from hairdigi.render.domain.rig_geometry import CameraPose, Framing, RigRegion
from hairdigi.render.fibres import FIBRE_GROUPS, group_z
from hairdigi.render.swatch_family import REVISIONS
from hairdigi.render.srgb import srgb8_to_linear
from hairdigi.resources import ROOT

#: Where the refinement looks: a camera pose over the crop framing's centre (an all-hair image), or
#: a region of a rig-view frame (``RigRegion``: the capture's swatch area, rendered exactly).
View = CameraPose | RigRegion

#: Ladder of ``sigma_a`` levels (per fibre radius): white fibres to past the blackest Table 1 hair
#: (melanin 1 gives about 8.2 in blue). 12 levels = 4 renders of three channels each.
SIGMA_LEVELS = (0.0, 0.03, 0.08, 0.16, 0.3, 0.5, 0.8, 1.3, 2.0, 3.2, 5.5, 12.0)
_LOG_OFFSET = 0.02
#: A final residual above this (ΔE2000) means no swatch of Table 1 hair renders the capture's colour.
REACHABLE_DE = 1.0   # log(sigma + offset): the curve is smooth there down to sigma = 0
#: More check-and-correct renders for a swatch of varied fibres (greys, spread).
VARIED_EXTRA_ITERATIONS = 2


@dataclass(frozen=True)
class RefineSettings:
    """Render settings of the refinement; defaults chosen by ``hairdigi bench refine``.

    Measured on 8 clean held-out swatches (resources/models/refine_bench.csv): 48² at 32 spp with 2
    iterations (one correction, each checked by a render: ``check_last`` on) gave median / p95 ΔE2000 0.16 / 0.30; the
    next cheaper settings 0.22 / 0.86 (64² at 8 spp) and 0.26 / 0.65 (32² at 32 spp), and one
    iteration (a check, no correction) 0.20 / 0.62 at the same 48² / 32 spp.
    """

    size: int = 48
    spp: int = 32                   # the response curve's and the shine tables' renders (cached per view)
    iterations: int = 2
    #: The check renders' samples. The result is the sigma_a whose fixed-seed check render matches the
    #: capture, so it inherits that render's noise offset: 4 hairs at the bench camera's swatch area against a
    #: 384-spp judge, on the layered swatch / the spread member, 32 spp left median 0.32 / 0.23 ΔE2000, 64 spp
    #: 0.16 / 0.15, 128 spp 0.17 / 0.12 at twice the time (``hairdigi bench check-spp``; ``resources/models/encoder.md``).
    check_spp: int = 64
    #: Strand layouts the check renders average over, ``check_spp / check_layouts`` samples each (the same
    #: samples). One: ``hairdigi bench layouts`` (5 hairs, each hidden in 4 layouts at the rig's swatch
    #: area) found two layouts' answers 0.25-0.55 ΔE2000 apart with one layout and 0.34-0.81 with four:
    #: the spread is the captures' own (each answer fits its capture within 0.09-0.39), not the check's.
    check_layouts: int = 1
    #: Whether the last ``sigma_a`` of the ``iterations`` is rendered. It is the answer either way; rendering it only
    #: measures its residual (the record's ``residual_de2000``; without, that is the check before it moved along the
    #: curve). Off: through the simulated rig (``hairdigi evaluate --rig``, the family's six structures and the
    #: clumped swatch, 68 captures) every answer was the same to the digit and each estimate took half the time
    #: (the family's 2.20 / 4.97 s median / p95 to 1.16 / 2.21 s).
    check_last: bool = False
    tolerance_de: float = 0.05      # stop polishing once the residual ΔE2000 is below this
    framing: Framing = Framing.CROP
    strand_seed: int = 0
    seed: int = 7
    levels: tuple[float, ...] = SIGMA_LEVELS


@dataclass
class ResponseCurve:
    """Mean linear value of one channel of the swatch against that channel's ``sigma_a``, at one pose."""

    sigma: np.ndarray    # (K,) increasing
    mean: np.ndarray     # (K,) decreasing
    seconds: float = 0.0     # what rendering it cost
    cached: bool = False     # read from the disk cache (so it cost nothing now)
    nonfinite: int = 0       # NaN or Inf values its renders returned (replaced by 0), kept in the cache with it

    def __post_init__(self) -> None:
        # enforce monotonicity against residual render noise (a flat step would make the inverse ambiguous)
        self.mean = np.minimum.accumulate(np.asarray(self.mean, float))
        for i in range(1, len(self.mean)):
            self.mean[i] = min(self.mean[i], self.mean[i - 1] * (1 - 1e-6))

    @functools.cached_property
    def _forward(self):
        return PchipInterpolator(np.log(self.sigma + _LOG_OFFSET), np.log(self.mean), extrapolate=True)

    @functools.cached_property
    def _backward(self):
        return PchipInterpolator(-np.log(self.mean), np.log(self.sigma + _LOG_OFFSET), extrapolate=False)

    def __call__(self, sigma: np.ndarray) -> np.ndarray:
        """F(sigma), interpolated monotonically (the interpolant is built once: a refinement and a
        structure reading call a curve hundreds of times, and building it was 1 s of a 5 s estimate)."""
        return np.exp(self._forward(np.log(np.clip(sigma, 0, None) + _LOG_OFFSET)))

    def inverse(self, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``sigma`` with F(sigma) = value, clipped to the ladder; and a mask of values outside it."""
        value = np.asarray(value, float)
        x = -np.log(self.mean)                     # increasing
        g = self._backward
        v = -np.log(np.clip(value, 1e-9, None))
        outside = (v < x[0] - 1e-9) | (v > x[-1] + 1e-9)
        sigma = np.exp(g(np.clip(v, x[0], x[-1]))) - _LOG_OFFSET
        return np.clip(sigma, 0.0, None), outside

    def to_dict(self) -> dict:
        return {"sigma": self.sigma.tolist(), "mean": self.mean.tolist(), "seconds": self.seconds,
                "nonfinite": self.nonfinite}


def scene_for(view: View, settings: RefineSettings, appearance: Appearance | None = None,
              swatch_model: str | None = None):
    """The scene and render size that show what the capture's fitted pixels show (with the hair's
    ``appearance``; None: the default uniform hair), on the swatch structure ``swatch_model`` (None:
    the default; ``render.swatch_family``)."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import SceneSpec

    look = None if appearance is None or appearance == DEFAULT_APPEARANCE else appearance
    if isinstance(view, RigRegion):
        film, crop, _ = view.render_plan(settings.size * settings.size)
        return SceneSpec("swatch", camera=view.pose, framing=Framing.RIG, target=view.target,
                         half_width=view.half_width, crop=crop, strand_seed=settings.strand_seed,
                         appearance=look, swatch_model=swatch_model), film
    return SceneSpec("swatch", camera=view, framing=settings.framing, strand_seed=settings.strand_seed,
                     appearance=look, swatch_model=swatch_model), settings.size


def varied_curve(curve: ResponseCurve, appearance: Appearance) -> ResponseCurve:
    """A uniform swatch's response curve turned into a varied one's, as the fibres' mixture: each
    pigment group at sigma * exp(spread * z_k) and the greys at their own sigma, weighted by their
    shares. Light passing between unlike fibres makes the truth differ a little; the refinement's
    check renders (of the real varied swatch) correct that, with this curve's slope."""
    if not appearance.varied:
        return curve
    g = appearance.grey_fraction
    pigmented = np.mean([curve(curve.sigma * np.exp(appearance.fibre_spread * z)) for z in group_z(FIBRE_GROUPS)], 0)
    mean = (1 - g) * pigmented + g * curve(np.array([GREY_SIGMA_A]))[0]
    return ResponseCurve(curve.sigma.copy(), mean, curve.seconds, curve.cached, curve.nonfinite)


def curve_reach(curve: ResponseCurve, appearance: Appearance, target: np.ndarray) -> float:
    """ΔE2000 from ``target`` of the nearest colour the swatch of ``appearance`` makes on ``curve`` (its own
    prediction, no render): about 0 where its hair reaches the colour, the colour's distance where it does not."""
    varied = varied_curve(curve, appearance)
    sigma, _ = varied.inverse(np.asarray(target, float))
    return float(delta_e2000(np.clip(varied(sigma), 1e-9, None), np.clip(np.asarray(target, float), 1e-9, None)))


def fitted_pixels(image: np.ndarray, view: View) -> np.ndarray:
    """The pixels of ``image`` whose mean the refinement fits: a rig view's region exactly as it is
    rendered, or (an all-hair crop) the whole image."""
    if isinstance(view, RigRegion):
        x, y, w, h = view.render_plan()[2]
        return image[y:y + h, x:x + w]
    return image


#: Response curves shipped as they are cached, for the fixed views an estimate uses most away from the rig (the
#: rig's swatch pose over an all-hair crop; ``inference.atlas_build.ship_pose``): read where the cache has none.
SHIPPED_TABLES = ROOT / "tables" / "response"

_CURVE_LOCK = threading.Lock()   # one curve at a time: the app's warm-up and a capture must not both render it


def response_curve(view: View, settings: RefineSettings = RefineSettings(), renderer=None,
                   cache: bool = True, swatch_model: str | None = None) -> ResponseCurve:
    """The swatch's response curve seen from ``view``: ``len(levels) / 3`` renders, cached on disk;
    on the structure ``swatch_model`` (None: the default) in layout ``settings.strand_seed``."""
    with _CURVE_LOCK:
        return _response_curve(view, settings, renderer, cache, swatch_model)


def curve_settings(settings: RefineSettings) -> dict:
    """What of ``settings`` a response curve or a shine table depends on (its cache key): all but the
    check renders' samples."""
    data = asdict(settings)
    for check in ("check_spp", "check_layouts", "check_last"):
        data.pop(check)
    return data


def grid_settings(settings: RefineSettings) -> dict:
    """``curve_settings`` without the layout: what a shipped table of every layout was rendered with."""
    return {k: v for k, v in curve_settings(settings).items() if k != "strand_seed"}


def view_key(view: View) -> dict:
    """What identifies a view in a cache key."""
    return view.to_dict() if isinstance(view, RigRegion) else asdict(view)


def cache_key(head: list, spec, variant: str) -> str:
    """The disk-cache key of renders of ``spec``'s swatch: ``head`` (what the caller renders) with the
    swatch's strands, depth, the variant and its model (left out for the first swatch, "today", so
    its cached files keep their keys) and the model's geometry revision where it has one."""
    model = spec.swatch_model
    name = text_of(model)                  # REVISIONS is keyed by the structures' text
    data = [*head, spec.n_strands, spec.depth, variant] + ([name] if model is not SwatchModel.TODAY else []) \
        + ([REVISIONS[name]] if name in REVISIONS else [])
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()[:16]


def _response_curve(view: View, settings: RefineSettings, renderer, cache: bool,
                    swatch_model: str | None = None) -> ResponseCurve:
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import default_renderer

    renderer = renderer or default_renderer()
    spec, size = scene_for(view, settings, swatch_model=swatch_model)
    key = cache_key([2, curve_settings(settings), view_key(view)], spec, renderer.variant)
    path = cache_dir() / "response" / f"curve-{key}.json"
    found = next((p for p in (path, SHIPPED_TABLES / path.name) if p.exists()), None) if cache else None
    if found is not None:
        try:
            data = json.loads(found.read_text())
            return ResponseCurve(np.array(data["sigma"]), np.array(data["mean"]), data.get("seconds", 0.0), True,
                                 int(data.get("nonfinite", 0)))
        except (ValueError, KeyError, OSError):
            pass   # a damaged cache entry is rebuilt
    levels = np.asarray(settings.levels, float)
    shipped = curve_means(view, levels, settings.strand_seed, spec.swatch_model, renderer.variant,
                          grid_settings(settings)) if cache else None
    if shipped is not None:     # the bench camera's region (the atlas's cells) or a crop's pose (the pose tables): no render
        return ResponseCurve(levels.copy(), shipped, 0.0, True)
    if len(levels) % 3:
        raise ValueError(f"the sigma ladder needs a multiple of 3 levels (one per channel), got {len(levels)}")
    start = time.perf_counter()
    means = np.empty_like(levels)
    nonfinite = 0
    # interleave low and high levels in one render, so each render's noise spreads over the curve
    order = levels.reshape(3, -1).T
    for triple_idx, triple in enumerate(order):
        result = renderer.render(triple, spec, size, settings.spp, settings.seed)
        means[[triple_idx, triple_idx + len(order), triple_idx + 2 * len(order)]] = \
            result.linear.reshape(-1, 3).mean(0)
        nonfinite += result.nonfinite
    curve = ResponseCurve(levels, means, time.perf_counter() - start, nonfinite=nonfinite)
    if cache:
        write_json_atomic(path, {"view": view_key(view), "settings": curve_settings(settings), **curve.to_dict()})
    return curve


@dataclass
class Refinement:
    """What refinement did: the parameters, the fitted ``sigma_a``, and how well the colour matches."""

    params: HairParams
    sigma_a: np.ndarray
    target: np.ndarray                 # the capture's mean linear colour
    rendered: np.ndarray               # mean linear colour the result renders (last render, or the curve)
    residual_de2000: float             # ΔE2000 between the two
    iterations: int
    reachable: bool                    # False: no Table 1 hair renders this colour (residual > REACHABLE_DE)
    seconds: float                     # all of it, the response curve included when it was rendered now
    curve_seconds: float               # what the response curve cost to render (now or when cached)
    curve_cached: bool = False
    history: list[float] = field(default_factory=list)   # residual ΔE2000 after each step
    nonfinite: int = 0                 # NaN or Inf samples in its renders, the curve's too (counted, replaced by 0)
    region: Region = field(default_factory=Region)        # what it fitted and rendered
    curve: "ResponseCurve | None" = None   # the curve it inverted (the region's, at the swatch's appearance)
    #: where ``sigma_a`` was mapped to another structure's (``inference.structure.toward_family``): the sigma_a
    #: fitted on the region's own structure, which renders the capture there (the twin renders it)
    fitted_sigma_a: "np.ndarray | None" = None

    @property
    def polish_seconds(self) -> float:
        """The cost once the pose's response curve is cached: inversion, checks and the Table 1 fit."""
        return self.seconds - (0.0 if self.curve_cached else self.curve_seconds)

    def to_record(self) -> RefinementRecord:
        return RefinementRecord(
            ran=True, sigma_a=tuple(round(float(v), 6) for v in self.sigma_a),
            residual_de2000=round(self.residual_de2000, 4), iterations=self.iterations, reachable=self.reachable,
            seconds=round(self.seconds, 3), curve_seconds=round(self.curve_seconds, 3), curve_cached=self.curve_cached,
            target_linear_rgb=tuple(round(float(v), 6) for v in self.target),
            rendered_linear_rgb=tuple(round(float(v), 6) for v in self.rendered),
            residual_history=tuple(round(v, 4) for v in self.history), nonfinite=self.nonfinite, region=self.region,
            fitted_sigma_a=None if self.fitted_sigma_a is None else
            tuple(round(float(v), 6) for v in self.fitted_sigma_a))


def fibre_appearance(sigma: np.ndarray) -> np.ndarray:
    """Cube-rooted Chiang 2016 albedo of ``sigma_a`` (as the training loss uses it): a perceptually
    even scale of fibre colour."""
    return albedo_from_sigma_a(np.clip(sigma, 0, None) + 1e-8) ** (1.0 / 3.0)


def params_for_sigma(sigma: np.ndarray, prior: HairParams, weight: float = 300.0) -> tuple[HairParams, bool]:
    """The Table 1 parameters nearest ``prior`` whose ``sigma_a`` matches ``sigma``; and whether one does.

    Bounded least squares on the normalised vector: ``weight`` x the fibre-appearance mismatch (3
    residuals), and the distance to the prior (6). A ``sigma`` outside what Table 1 can make gives
    the nearest colour it can, and ``False``.
    """
    goal = fibre_appearance(np.asarray(sigma, float))
    v0 = prior.to_vector().astype(float)

    def residuals(v: np.ndarray) -> np.ndarray:
        s = hair_sigma_a(HairParams.from_vector(v))
        return np.concatenate([weight * (fibre_appearance(s) - goal), v - v0])

    fit = least_squares(residuals, v0, bounds=(0.0, 1.0), x_scale=1.0, xtol=1e-10, ftol=1e-10, max_nfev=400)
    params = HairParams.from_vector(fit.x)
    mismatch = np.abs(fibre_appearance(hair_sigma_a(params)) - goal).max()
    return params, bool(mismatch < 2e-3)


def mean_linear(image: np.ndarray, band_pixels: int = 1 << 18) -> np.ndarray:
    """Mean linear RGB of an image, 8-bit sRGB or linear float (what the swatch's colour is judged by),
    summed in bands of rows: at most ``band_pixels`` pixels are converted to float at once."""
    image = np.asarray(image)
    if image.ndim != 3:   # a list of pixels
        image = image.reshape(-1, 1, 3)
    lut = srgb8_to_linear(np.arange(256)) if image.dtype == np.uint8 else None
    h, w = image.shape[:2]
    rows = max(1, band_pixels // max(1, w))
    total = np.zeros(3)
    for y in range(0, h, rows):
        band = image[y:y + rows].reshape(-1, 3)
        total += np.sum(lut[band] if lut is not None else band, axis=0, dtype=np.float64)
    return total / max(1, h * w)


def check_render(sigma: np.ndarray, spec, size, settings: RefineSettings, renderer) -> tuple[np.ndarray, int]:
    """The check render's mean linear colour of ``sigma`` and its NaN/Inf count: ``settings.check_layouts``
    strand layouts (from ``spec.strand_seed`` on; one for varied fibres), ``check_spp`` samples in all."""
    # varied fibres (greys, a spread) split the strands into groups: a new layout is a new scene there, so one
    layouts = 1 if spec.groups else max(1, int(settings.check_layouts))
    spp = max(1, settings.check_spp // layouts)
    means, nonfinite = [], 0
    for k in range(layouts):
        result = renderer.render(sigma, replace(spec, strand_seed=spec.strand_seed + k), size, spp, settings.seed)
        means.append(result.linear.reshape(-1, 3).mean(0))
        nonfinite += result.nonfinite
    return np.mean(means, axis=0), nonfinite


def refine(prior: HairParams, target: np.ndarray, view: View = CameraPose(),
           settings: RefineSettings = RefineSettings(), renderer=None,
           appearance: Appearance = DEFAULT_APPEARANCE, curve: ResponseCurve | None = None,
           swatch_model: str | None = None) -> Refinement:
    """Refine ``prior`` so that the swatch seen from ``view`` renders with mean linear colour ``target``
    (the mean of ``fitted_pixels``). The swatch has ``appearance`` and the structure ``swatch_model``
    (None: the default; ``inference.structure.read_structure`` reads it); ``curve`` is the uniform
    swatch's response at its shine (from that structure's shine tables), else the default shine's is
    rendered or loaded. The result's ``sigma_a`` is the median pigmented fibre's."""
    # deferred: loads Mitsuba; the entry point chooses the variant, not an import (render.variant)
    from hairdigi.render.renderer import default_renderer

    renderer = renderer or default_renderer()
    start = time.perf_counter()
    target = np.asarray(target, float)
    if curve is None:
        if appearance.longitudinal_roughness != DEFAULT_APPEARANCE.longitudinal_roughness:
            raise ValueError("refining at another shine needs that shine's curve (inference.shine's tables)")
        curve = response_curve(view, settings, renderer, swatch_model=swatch_model)
    curve = varied_curve(curve, appearance)
    goal = target.copy()
    sigma, _ = curve.inverse(goal)
    rendered = curve(sigma)          # with no iterations, the curve's own prediction
    history: list[float] = []
    spec, size = scene_for(view, settings, appearance, swatch_model)
    nonfinite = curve.nonfinite   # the curve's renders are this refinement's too (rendered now or when cached)
    # varied fibres: the mixture curve only approximates light passing between unlike fibres, so
    # the check renders may need two more corrections
    iterations = settings.iterations + (VARIED_EXTRA_ITERATIONS if appearance.varied else 0)
    for k in range(iterations):
        rendered, bad = check_render(sigma, spec, size, settings, renderer)
        nonfinite += bad
        history.append(float(delta_e2000(rendered, target)))
        if history[-1] < settings.tolerance_de or k == iterations - 1:
            break   # the returned sigma is the last one rendered, with its measured residual
        # shift the goal by the residual and invert again: the curve supplies the slope
        goal = np.clip(goal + (target - rendered), 1e-6, None)
        step, _ = curve.inverse(goal)
        if k == iterations - 2 and not settings.check_last:
            # the last sigma is not rendered: its colour is the check's moved along the curve
            rendered, sigma = rendered + curve(step) - curve(sigma), step
            break
        sigma = step
    params, _ = params_for_sigma(sigma, prior)
    # the colour the returned parameters render: the last render, moved along the curve by what the
    # mapping to Table 1 changed (nothing, unless the colour is outside what Table 1 can make)
    final = rendered + curve(hair_sigma_a(params)) - curve(sigma)
    residual = float(delta_e2000(np.clip(final, 1e-9, None), target))
    return Refinement(params, hair_sigma_a(params), target, np.asarray(final, float), residual, len(history),
                      residual < REACHABLE_DE, time.perf_counter() - start, curve.seconds, curve.cached, history,
                      nonfinite, Region(rig=view if isinstance(view, RigRegion) else None,
                                        crop_pose=None if isinstance(view, RigRegion) else view,
                                        swatch_model=spec.swatch_model), curve)
