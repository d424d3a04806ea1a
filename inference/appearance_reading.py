"""Reading a swatch's appearance at estimate time: its shine from the single-light frames,
its fibre spread and grey share from the texture, and their intervals.

- **Shine.** The three single-light frames' swatch-area means (3 lights x 3 channels) against the
  per-light tables of the view (``inference.shine``): the shine, and the uniform swatch's response
  curve at that shine, which the refinement then inverts.
- **Greys.** The all-lights frame's texture at the fibre scale, through the fitted model of
  ``inference.texture`` (``resources/models/texture_model.json``); the colour then checks it (a grey
  share no hair renders at the capture's colour is dropped). The fibre spread is not read: the
  texture model has no skill for it (``FROM_TEXTURE``), so pigmented fibres are taken as uniform.
- **Intervals** come from ``resources/models/appearance_uncertainty.json`` (measured by ``hairdigi
  evaluate --appearance``); before it exists, the shine bench's figures.

A capture without single-light frames (an old session, a RAW still, an image on the command line
without ``--lights``) keeps the default shine, and its record says "shine not measured".
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from itertools import permutations

import numpy as np

from hairdigi.inference.refine import mean_linear, response_curve
from hairdigi.render.domain.appearance import (DEFAULT_APPEARANCE, SHINE_RANGE, SPREAD_RANGE, GREY_RANGE, Appearance,
                                               AppearanceEstimate)
from hairdigi.inference.shine import SHINE_FLOOR, estimate_shine, shine_tables
from hairdigi.inference.structure import read_structure
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import read_json
from hairdigi.render.domain.records import EstimateWarning, WarningKind
from hairdigi.render.domain.rig_geometry import N_LIGHTS
from hairdigi.render.domain.text_enum import text_of
from hairdigi.render.srgb import srgb8_to_linear
from hairdigi.resources import MODELS

UNCERTAINTY = MODELS / "appearance_uncertainty.json"
#: Half-widths used until ``hairdigi evaluate --appearance`` has measured them (``hairdigi bench shine``:
#: the shine was read within 0.010 median, 0.020 worst, on 12 held-out clean swatches).
FALLBACK = {"longitudinal_roughness": {"p68": 0.02, "p95": 0.05}}
_RANGES = {"longitudinal_roughness": SHINE_RANGE, "fibre_spread": SPREAD_RANGE, "grey_fraction": GREY_RANGE}


class LightFramesError(HairdigiError, ValueError):
    """The single-light frames do not fit the capture (count, size); the message says how to fix it."""


@dataclass
class AppearanceReading:
    """What was read: the estimate for the record, the curve to refine with, and warnings."""

    estimate: AppearanceEstimate
    curve: object | None = None                   # ResponseCurve at the read shine (None: the default's)
    warnings: list[EstimateWarning] = field(default_factory=list)
    seconds: float = 0.0
    swatch_model: str | None = None               # the structure read (None: the default, not read)
    misfits: dict[str, float] | None = None       # every member's misfit, when the structure was read

    @property
    def value(self) -> Appearance:
        return self.estimate.value


def half_widths() -> dict:
    """The measured interval half-widths per field, or the fallback before they were measured."""
    try:
        return read_json(UNCERTAINTY, ValueError, "missing", "unreadable ({exc})").get("half_widths", FALLBACK)
    except ValueError:
        return FALLBACK


def intervals_for(value: Appearance, fields: tuple[str, ...], widths: dict | None = None) -> dict:
    """``{field: {"p68": [lo, hi], "p95": [lo, hi]}}`` for the measured ``fields``, clipped to their ranges."""
    widths = half_widths() if widths is None else widths
    out = {}
    for name in fields:
        if name not in widths:
            continue
        v, (lo, hi) = getattr(value, name), _RANGES[name]
        out[name] = {p: [round(max(lo, v - w), 4), round(min(hi, v + w), 4)] for p, w in widths[name].items()}
    return out


def check_light_frames(frames: list[np.ndarray], image: np.ndarray, sums: bool = True) -> None:
    """One frame per light, each the size of the all-lights image, and (``sums``: the frames at the image's
    exposure) adding up to it as one capture's do; else one line naming the fix."""
    if len(frames) != N_LIGHTS:
        raise LightFramesError(f"the capture has {len(frames)} single-light frame(s), not {N_LIGHTS}: give one "
                               f"frame per light, in light order (light 0, 1, 2)")
    for i, frame in enumerate(frames):
        if frame.shape[:2] != image.shape[:2]:
            raise LightFramesError(f"light {i}'s frame is {frame.shape[1]}x{frame.shape[0]} but the image is "
                                   f"{image.shape[1]}x{image.shape[0]}: the frames must be of one view")
    if sums:   # at the image's exposure: one capture's frames add up to its all-lights frame
        problem = light_frames_problem(frames, image)
        if problem:
            raise LightFramesError(problem)


#: The single-light frames of one capture add up to its all-lights frame (light is additive; measured on the
#: simulated rig: level 0.996, residual 3.6% after 8x8 block means, frames of two lights 48-53% apart).
#: Outside these bounds the frames are not of this capture, or not at the exposure assumed.
SUM_LEVEL_RANGE = (1 / 1.5, 1.5)
SUM_RESIDUAL_MAX = 0.25
SAME_FRAME_MAX = 0.03


def _coarse(img: np.ndarray, block: int = 8) -> np.ndarray:
    """Linear block means of an image (about 400k pixels read at most): noise averaged, structure kept."""
    img = np.asarray(img)
    step = max(1, int(np.sqrt(img.shape[0] * img.shape[1] / 4e5)))
    img = img[::step, ::step]
    img = srgb8_to_linear(img) if img.dtype == np.uint8 else img.astype(np.float32)
    h, w = img.shape[0] // block * block, img.shape[1] // block * block
    if h == 0 or w == 0:
        return img.reshape(-1, img.shape[-1])
    return img[:h, :w].reshape(h // block, block, w // block, block, -1).mean((1, 3))


def light_frames_problem(frames: list[np.ndarray], image: np.ndarray) -> str | None:
    """Why linear single-light frames (each at the image's exposure) are not one capture with ``image``: their
    sum's level or its pixel-by-pixel difference from the all-lights frame, or two frames alike; None if none."""
    whole = _coarse(image)
    singles = [_coarse(f) for f in frames]
    total = sum(singles)
    level_image, level_sum = float(whole.mean()), float(total.mean())
    if level_image <= SHINE_FLOOR or level_sum <= SHINE_FLOOR:
        return None              # a dark frame: the dead-light checks name it
    ratio = level_sum / level_image
    if not SUM_LEVEL_RANGE[0] <= ratio <= SUM_LEVEL_RANGE[1]:
        ev = float(np.log2(ratio))
        return (f"the {len(frames)} single-light frames add up to {ratio:.2f}x the all-lights frame, not about 1: "
                f"they are not of this capture, or were taken {abs(ev):.1f} EV {'longer' if ev > 0 else 'shorter'} "
                f"(then pass --lights-ev {ev:.1f}, or keep the capture record beside the image)")
    residual = float(np.linalg.norm(total / ratio - whole) / max(np.linalg.norm(whole), 1e-12))
    if residual > SUM_RESIDUAL_MAX:
        return (f"the single-light frames do not add up to the all-lights frame pixel by pixel ({residual:.0%} apart): "
                f"they are not of this view or this capture; give the frames taken with it")
    for i in range(len(singles)):
        for j in range(i + 1, len(singles)):
            norm = float(np.linalg.norm(singles[i] + singles[j]))
            if norm > 0 and float(np.linalg.norm(singles[i] - singles[j])) / norm < SAME_FRAME_MAX:
                return (f"light {i}'s and light {j}'s frames are the same picture: lights from different sides "
                        f"cannot light the swatch alike; give each light's own frame")
    return None


def dark_lights(light_means: np.ndarray, frame_levels: np.ndarray | None = None) -> tuple[list[int], list[int]]:
    """Which lights cannot be read, and which merely leave the swatch dark.

    A light whose whole frame is dark (``frame_levels``, each frame's mean linear colour) is dead: the
    shine is not read. A light that lights the frame but leaves the swatch at the noise floor is a
    reading, not a fault: light 0 lies along the fibres and reaches the camera only through the
    longitudinal lobe's tail, so glossy hair sends almost none of it back (0.7% of the light at beta_m
    0.15): ``estimate_shine`` compares it above the floor and finds the hair glossy. Without whole
    frames (an all-hair crop) only a set of frames all at the floor is unreadable."""
    means = np.asarray(light_means, float).sum(1)
    at_floor = [i for i, m in enumerate(means) if m < 3 * SHINE_FLOOR]
    if frame_levels is not None:
        dead = [i for i, m in enumerate(np.asarray(frame_levels, float).reshape(len(means), -1).sum(1))
                if m < 3 * SHINE_FLOOR]
    else:
        dead = at_floor if len(at_floor) == len(means) else []
    return dead, [i for i in at_floor if i not in dead]


#: The single-light frames' misfit (rms log) held-out captures stay under: the best member's at most 0.036 over 266
#: captures of drawn structures (``packaging/evaluation/rig-drawn-*``), 0.020 a typical one. Above it, another
#: order of the frames fitting ``ORDER_GAIN`` times better names frames in the wrong order.
MAX_FRAMES_MISFIT = 0.05
ORDER_GAIN = 3.0
#: Beyond these the frames fit no shine at all (the reading's tables: the members read, or the assumed layered
#: swatch, whose misfit reached 0.339 on held-out swatches of other structures): a light off or weak, or frames of
#: another capture. (On the layered tables a light at 5% of its power reads 0.31-0.41, at 1% 0.34-0.44.)
MAX_MEMBERS_MISFIT, MAX_ASSUMED_MISFIT = 0.1, 0.36


def frames_misfit_warnings(light_means: np.ndarray, tables, misfit: float, members: bool) -> list[EstimateWarning]:
    """Unreliable-making warnings where the single-light frames fit the shine far worse than held-out captures do:
    another order of them fitting ``ORDER_GAIN`` times better (frames in the wrong order), or a misfit beyond
    ``MAX_MEMBERS_MISFIT`` (``members``: read over the family's members) or ``MAX_ASSUMED_MISFIT``."""

    if misfit <= MAX_FRAMES_MISFIT:
        return []
    orders = {order: estimate_shine(light_means[list(order)], tables).residual
              for order in permutations(range(len(light_means))) if list(order) != list(range(len(light_means)))}
    best = min(orders, key=orders.get)
    if orders[best] * ORDER_GAIN <= misfit:
        given = ",".join(f"L{i}" for i in range(len(light_means)))
        fits = ",".join(f"L{i}" for i in best)
        return [EstimateWarning(WarningKind.OUT_OF_DOMAIN, (
            f"light frames: given in the wrong order? as {given} they fit the shine with misfit {misfit:.3f} rms log "
            f"(held-out captures under {MAX_FRAMES_MISFIT:g}); taken as {fits} they fit {orders[best]:.3f}; give "
            f"--lights in light order (light 0 along the fibres, then 1 and 2), or capture again on the rig"))]
    limit = MAX_MEMBERS_MISFIT if members else MAX_ASSUMED_MISFIT
    if misfit <= limit:
        return []
    return [EstimateWarning(WarningKind.OUT_OF_DOMAIN, (
        f"light frames: they fit no shine (misfit {misfit:.3f} rms log, held-out captures under {limit:g}): a light "
        "off or weak in its frame, or frames of another capture" + ("" if members else ", or a swatch built unlike "
        "hairdigi's layered one (try --structure family)") + "; check the lights (Lights > Check) and capture "
        "again"))]


def read_appearance(light_means: np.ndarray | None, view, settings, renderer=None,
                    texture_pixels: np.ndarray | None = None, sigma_guess: np.ndarray | None = None,
                    frame_levels: np.ndarray | None = None, structures: tuple[str, ...] | None = None
                    ) -> AppearanceReading:
    """The appearance from the single-light means ``light_means`` (L, 3) at ``view`` (None: not
    captured) and the all-lights swatch area ``texture_pixels`` (linear) for spread and greys;
    ``frame_levels`` (L, 3), each single-light frame's whole mean, tells a dead light from glossy hair.
    ``structures``: swatch structures (``render.swatch_family``) to read from the single-light frames
    with the shine (``inference.structure.read_structure``); None: the default structure alone."""
    start = time.perf_counter()
    value, measured, method, warnings, curve = DEFAULT_APPEARANCE, [], {}, [], None
    swatch_model, misfits = None, None
    dead, dim = ([], []) if light_means is None else dark_lights(light_means, frame_levels)
    if light_means is None:
        warnings.append(EstimateWarning(WarningKind.APPEARANCE, (
            "shine not measured: this capture has no single-light frames (an earlier session, a RAW still, or an "
            "image without --lights), so the default shine 0.3 was assumed; capture again on the rig, or pass "
            "--lights, to measure it")))
    elif dead:
        warnings.append(EstimateWarning(WarningKind.APPEARANCE, (
            f"shine not measured: light {', '.join(map(str, dead))} left its own frame dark; check that every "
            f"light works (Lights > Check), then capture again. The default shine 0.3 was assumed")))
    else:
        if dim and frame_levels is None:
            warnings.append(EstimateWarning(WarningKind.APPEARANCE, (
                f"appearance: light {', '.join(map(str, dim))} barely lights the swatch in its own frame, which "
                f"glossy hair does (read as such); if a light may be dead, check it (Lights > Check)")))
        if structures:
            structure = read_structure(np.asarray(light_means, float), view, settings, renderer, structures)
            tables, shine, swatch_model = structure.tables, structure.shine, structure.swatch_model
            misfits = structure.misfits
            method["structure"] = (f"{swatch_model}: read from the {N_LIGHTS} single-light frames, whose per-light "
                                   f"tables fit best (rms log misfit " + ", ".join(
                                       f"{m} {v:.3f}" for m, v in structure.misfits.items()) + ")")
        else:
            tables = shine_tables(view, settings, renderer=renderer)
            shine = estimate_shine(np.asarray(light_means, float), tables)
        value = Appearance(longitudinal_roughness=round(shine.longitudinal_roughness, 4))
        warnings += frames_misfit_warnings(np.asarray(light_means, float), tables, shine.residual, bool(structures))
        curve = tables.all_lights_curve(shine.longitudinal_roughness)
        measured.append("longitudinal_roughness")
        method["longitudinal_roughness"] = (f"read from the {N_LIGHTS} single-light frames against the view's "
                                            f"per-light tables (misfit {shine.residual:.3f} rms log)")
        if shine.longitudinal_roughness in (float(tables.betas[0]), float(tables.betas[-1])):
            warnings.append(EstimateWarning(WarningKind.APPEARANCE, (
                f"appearance: the shine read is at the edge of what the tables hold ({tables.betas[0]:g}-"
                f"{tables.betas[-1]:g}); the hair may be glossier or rougher than that")))
    intervals = intervals_for(value, tuple(measured))
    if texture_pixels is not None and not texture_scale_fits(texture_pixels):
        method["grey_fraction"] = (f"not read: the swatch area is {texture_pixels.shape[1]} px wide, and the texture "
                                   f"model reads fibres at {TEXTURE_SWATCH_WIDTH} px (the bench camera's frame)")
    elif texture_pixels is not None:
        if sigma_guess is None:   # the uniform swatch's sigma_a of this colour: what the texture is read against
            uniform = curve if curve is not None else response_curve(view, settings, renderer)
            sigma_guess = uniform.inverse(mean_linear(texture_pixels))[0]
        variation = _read_variation(texture_pixels, sigma_guess, value.longitudinal_roughness)
        if variation is not None:
            # a share whose 95% interval reaches 0 is not told from none: it is reported (and rendered) as 0,
            # with its interval, so uniform hair is not drawn with a few greys it does not have (at the 68%
            # level, 25 of 61 captures of uniform swatches read 0.07-0.12 and were judged 0.46 against 0.38:
            # hairdigi evaluate --rig on the layered swatch)
            value = replace(value, **{k: 0.0 if _reaches_zero(variation.intervals.get(k))
                                      else float(getattr(variation, k)) for k in FROM_TEXTURE})
            measured += list(FROM_TEXTURE)
            method.update({k: "read from the texture (inference.texture's model)" for k in FROM_TEXTURE})
            intervals.update({k: v for k, v in variation.intervals.items() if k in FROM_TEXTURE})
    estimate = AppearanceEstimate(value, intervals, tuple(measured), method)
    return AppearanceReading(estimate, curve, warnings, time.perf_counter() - start, swatch_model, misfits)


#: What the texture gives the estimate. The grey share: held-out MAE 0.057 against 0.080 for always
#: answering the mean (``resources/models/texture_evaluation.json``). Not the fibre spread: its held-out
#: MAE (0.117) is the no-skill answer's (0.115), so it stays at uniform fibres and "not measured".
FROM_TEXTURE = ("grey_fraction",)

#: Whether estimates read fibre spread and greys from the texture (``hairdigi evaluate --appearance
#: --no-variation`` turns it off for the whole process, to measure what the reading adds).
READ_VARIATION = True


#: The swatch area's width in the frames the texture model was fitted on (the bench camera's 400x300
#: frame, ``rig_geometry.swatch_roi``): its features are read at that many pixels per fibre.
TEXTURE_SWATCH_WIDTH = 130


def texture_scale_fits(pixels: np.ndarray, tolerance: float = 0.25) -> bool:
    """Whether a swatch area shows its fibres at the texture model's scale (a RAW still at twice the
    feed's resolution, or a frame of another camera, does not)."""
    return abs(pixels.shape[1] / TEXTURE_SWATCH_WIDTH - 1.0) <= tolerance


#: The interval that must exclude 0 for a grey share to be reported (a 5% false-alarm rate on uniform hair).
GREY_DETECTION_LEVEL = "p95"


def _reaches_zero(interval: dict | None) -> bool:
    return interval is not None and GREY_DETECTION_LEVEL in interval and interval[GREY_DETECTION_LEVEL][0] <= 1e-3


def _read_variation(pixels: np.ndarray, sigma: np.ndarray | None, shine: float):
    """The texture model's reading, or None when the model is not installed (or reading is off)."""
    if not READ_VARIATION:
        return None
    from hairdigi.inference import texture   # deferred: loads OpenCV (~0.3 s); only this step needs it

    try:
        return texture.read_variation(pixels, sigma, shine)
    except FileNotFoundError:
        return None


def unmeasured_variation(estimate: AppearanceEstimate, why: str | None = None) -> AppearanceEstimate:
    """``estimate`` with its fibre spread and grey share back at uniform fibres and not measured (``why``: the
    method the record then states for them)."""
    names = ("fibre_spread", "grey_fraction")
    method = {k: v for k, v in estimate.method.items() if k not in names}
    if why:
        method.update({k: why for k in FROM_TEXTURE})
    return AppearanceEstimate(replace(estimate.value, fibre_spread=0.0, grey_fraction=0.0),
                              {k: v for k, v in estimate.intervals.items() if k not in names},
                              tuple(m for m in estimate.measured if m not in names), method)


#: The swatch structure the texture model was fitted on, the only one whose greys it reads. Refitted on renders
#: of all seven family members (150 samples, ``fit_texture`` data 5), its grey share had no skill (held-out MAE
#: 0.077 against the training mean's 0.074); the layered model's MAE was 0.044 on the layered samples, 0.063-0.068
#: on the deposited, spread, tilted and loose ones, 0.090 on wavy (bias +0.044) and 0.132 on deposited-coarse
#: (bias +0.109) (``packaging/bench/texture-structures``); through the rig it read a clumped platinum swatch
#: 0.31-0.36 grey (4.61 ΔE2000 median; 3.83 with greys not read) and a wavy saturated blue 0.16.
TEXTURE_STRUCTURE = "layered"


def on_its_structure(reading: AppearanceReading, structure) -> AppearanceReading:
    """``reading`` as the estimate keeps it when made on ``structure`` (a member's name, or None: mapped to the
    family's mean, the structure unknown): its grey share only on ``TEXTURE_STRUCTURE``."""
    if text_of(structure) == TEXTURE_STRUCTURE or not any(k in reading.estimate.measured for k in FROM_TEXTURE):
        return reading
    on = "the family's mean (the structure unknown)" if structure is None else f"the {text_of(structure)} swatch"
    why = (f"not read: the texture tells greys only on the {TEXTURE_STRUCTURE} swatch it was fitted on, and this "
           f"estimate is made on {on}")
    return replace(reading, estimate=unmeasured_variation(reading.estimate, why))
