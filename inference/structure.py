"""What the swatch's physical structure does to an estimate, and the estimate made robust over it.

The refinement (``inference.refine``) finds the ``sigma_a`` whose swatch, drawn as hairdigi draws it
(``render.strands.layered_swatch_strands``, one layout), renders the capture's colour. A lab's swatch
lies another way (``render.swatch_family``): at equal ``sigma_a`` the physical structures of the family
render 0.4-2 ΔE2000 apart at the rig (``hairdigi evaluate --structures``), so the ``sigma_a`` read
through one structure inherits it. Each channel's mean colour is one monotone response curve of its
``sigma_a`` (``refine.ResponseCurve``), for every structure, so the structure acts per channel:

- ``family_curves`` renders (once per view; cached with the curves) every family member's response
  curve, each averaged over ``layouts`` strand layouts;
- ``to_family`` maps the refinement's ``sigma_a`` (the default structure's) to the ``sigma_a`` whose
  family-mean colour is the colour the default structure gives: ``F_family^-1(F_default(sigma))``;
- ``nuisance`` is how far each member's colour of that answer lies from the family mean (ΔE2000):
  what the record's colour interval carries for the structure it does not know.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from hairdigi.inference.refine import RefineSettings, ResponseCurve, View, params_for_sigma, response_curve
from hairdigi.inference.shine import estimate_shine, shine_tables
from hairdigi.inference.uncertainty import widen_colour
from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.bounds import StructureMode
from hairdigi.render.domain.estimate_parts import StructureInterval, Uncertainty
from hairdigi.render.domain.rig_geometry import RigRegion
from hairdigi.render.metrics import delta_e2000
from hairdigi.render.swatch_family import FAMILY
from hairdigi.resources import MODELS

#: Strand layouts each member's curve is averaged over (its seeds 0..LAYOUTS-1).
LAYOUTS = 2


@dataclass
class FamilyCurves:
    """Every family member's layout-averaged response curve at one view, and the default's own."""

    default: ResponseCurve                 # the refinement's: default structure, layout settings.strand_seed
    members: dict[str, ResponseCurve]      # member -> its curve, averaged over layouts
    seconds: float = 0.0

    @property
    def mean(self) -> ResponseCurve:
        """The family's response: the geometric mean of its members' curves."""
        return self.mean_of(None)

    def mean_of(self, weights: dict[str, float] | None) -> ResponseCurve:
        """The geometric mean of the members' curves, weighted by ``weights`` (member -> weight; None, or
        no known member weighted: the whole family's, evenly)."""
        chosen = {m: w for m, w in (weights or {}).items() if m in self.members and w > 0}
        if not chosen:
            return _averaged(list(self.members.values()))
        return _averaged([self.members[m] for m in chosen], list(chosen.values()))


def _averaged(curves: list[ResponseCurve], weights: list[float] | None = None) -> ResponseCurve:
    """The (weighted) geometric mean of curves on one sigma ladder (a member's layouts, or the family's members)."""
    logs = np.average([np.log(np.clip(c.mean, 1e-12, None)) for c in curves], axis=0, weights=weights)
    return ResponseCurve(curves[0].sigma.copy(), np.exp(logs), sum(c.seconds for c in curves),
                         all(c.cached for c in curves), sum(c.nonfinite for c in curves))


#: The family's curves are rendered on a canonical copy of a rig region: its frame scaled to ``FAMILY_FRAME[0]``
#: pixels wide and its region's edges snapped to ``FAMILY_FRAME[1]`` of those pixels. A RAW still (twice the
#: feed's resolution, its swatch found a few pixels off) and the live frames then share one set of curves,
#: rendered once (``len(FAMILY) * LAYOUTS`` curves, 1-3 minutes), where each still's own region rendered them
#: anew. The map is a ratio of two curves at one view, both on the canonical region.
FAMILY_FRAME = (400, 8)


def family_view(view: View, frame: tuple[int, int] = FAMILY_FRAME) -> View:
    """The canonical view the family's curves of ``view`` are rendered at (``FAMILY_FRAME``; a pose as it is)."""
    if not isinstance(view, RigRegion):
        return view
    width, grid = frame
    scale = width / view.frame_size[0]
    size = (width, max(grid, int(round(view.frame_size[1] * scale))))
    x, y, w, h = view.roi

    def snap(v: float, top: int) -> int:
        return int(min(top, max(0, round(v * scale / grid) * grid)))

    x0, y0 = min(snap(x, size[0]), size[0] - grid), min(snap(y, size[1]), size[1] - grid)
    x1, y1 = max(snap(x + w, size[0]), x0 + grid), max(snap(y + h, size[1]), y0 + grid)
    return replace(view, frame_size=size, roi=(x0, y0, min(x1, size[0]) - x0, min(y1, size[1]) - y0))


def family_curves(view: View, settings: RefineSettings = RefineSettings(), renderer=None,
                  members: tuple[str, ...] = FAMILY, layouts: int = LAYOUTS, cache: bool = True) -> FamilyCurves:
    """The family's response curves at ``view`` (``len(members) * layouts`` curves, cached on disk or read from the
    shipped atlas; ``cache`` False: every one rendered now)."""
    default = response_curve(view, settings, renderer, cache)
    curves = {m: _averaged([response_curve(view, replace(settings, strand_seed=s), renderer, cache, swatch_model=m)
                            for s in range(layouts)]) for m in members}
    seconds = sum(c.seconds for c in curves.values() if not c.cached)
    return FamilyCurves(default, curves, seconds)


#: How far the family map applies to a hair, by its least ``sigma_a`` (per fibre radius): fully at or below
#: ``DARK_SIGMA[0]``, not at all at or above ``DARK_SIGMA[1]``, log-linearly between. Dark hair's colour is
#: mostly the fibres' surface reflection: the curves are flat there, and the structures' offsets are not
#: absorption (mapped anyway, black went to a fifth of its sigma_a, 1.1-1.5 ΔE2000 off). Measured with
#: ``hairdigi evaluate --structures`` (fit, median on other structures / on dark hair): the former rule
#: (kept only when every channel >= 3.2) 0.67 / 0.66 on the held-out set (``--held-out 11``, 56 swatches),
#: this one 0.55 / 0.29, chosen there; on the 35 named swatches, where the former rule was chosen, see
#: the model card.
DARK_SIGMA = (0.15, 0.6)


def family_weight(sigma: np.ndarray, dark: tuple[float, float] = DARK_SIGMA) -> float:
    """How far (0-1) the family map applies to a hair of ``sigma`` (see ``DARK_SIGMA``)."""
    least = max(float(np.min(sigma)), 1e-9)
    lo, hi = dark
    return float(np.clip(np.log(hi / least) / np.log(hi / lo), 0.0, 1.0))


def to_family(sigma: np.ndarray, family: FamilyCurves, dark: tuple[float, float] = DARK_SIGMA,
              weights: dict[str, float] | None = None) -> np.ndarray:
    """The ``sigma_a`` whose family-mean colour (``FamilyCurves.mean_of(weights)``; None: every member) is the default
    structure's colour of ``sigma``, applied as far as ``family_weight`` says (a dark hair keeps its answer)."""
    sigma = np.asarray(sigma, float)
    weight = family_weight(sigma, dark)
    if weight == 0.0:
        return sigma.copy()
    mapped = family.mean_of(weights).inverse(family.default(sigma))[0]
    return sigma * (np.clip(mapped, 1e-9, None) / np.clip(sigma, 1e-9, None)) ** weight


def member_spreads(sigma: np.ndarray, family: FamilyCurves, members: dict[str, float]) -> dict[str, float]:
    """ΔE2000 of each of ``members``' colour of ``sigma`` from their weighted mean's: were the swatch that member,
    the error of the answer ``sigma`` that the mean maps the capture to (the mean's colour of it is the capture's)."""
    sigma = np.asarray(sigma, float)
    centre = np.clip(family.mean_of(members)(sigma), 1e-9, None)
    return {m: round(float(delta_e2000(np.clip(family.members[m](sigma), 1e-9, None), centre)), 3) for m in members}


def nuisance(sigma: np.ndarray, family: FamilyCurves) -> dict[str, float]:
    """ΔE2000 of each member's colour of ``sigma`` from the family mean's (the structure left unknown)."""
    return member_spreads(sigma, family, dict.fromkeys(family.members, 1.0))


#: The structures the single-light frames choose among. Deposited and wavy swatches render alike at the
#: rig (0.1-0.9 ΔE2000 apart at equal sigma_a, ``hairdigi bench family``), so "deposited" stands for both;
#: a spread swatch, whose crossing fibres keep out of one another, stands high and loose and renders
#: 1.5-4 darker than the deposited one, so it is read on its own.
READ_MEMBERS = ("layered", "tilted", "deposited", "deposited-coarse", "spread", "loose")


#: A structure reading is decisive when the next-best member's misfit is at least this many times the best's:
#: the "family" mode then refines on the structure read, and maps to the family's mean otherwise. Chosen on
#: ``hairdigi evaluate --structures`` (fit on other structures, median / p95 with the rule): held out 13 in
#: Mitsuba 0.48 / 1.48 (mapped alone 0.51 / 2.14: the spread swatch, read at ratios 2.2-9.2), Blender Cycles
#: 0.90 / 1.71 (read alone 0.71 / 2.10: tilted swatches misread as deposited at ratios 1.03-1.60); any ratio
#: from 1.8 to 2.2 gave the same figures. Checked on draws it was not chosen on: see the model card.
DECISIVE = 2.0


#: The single-light frames' best misfit (``StructureReading.misfits``, rms log) over which no structure of the family
#: fits the swatch: a swatch built in a way hairdigi does not draw. On the simulated rig's live captures, the
#: family's own swatches read at most 0.036 (``packaging/evaluation/rig-drawn-texture``, 58 captures of six members;
#: the layered swatch from tilted cameras 0.032); a structure drawn outside the family, before its figures were
#: seen (``clumped``), read 0.074-0.147 in every capture and was 2.68 / 4.73 ΔE2000 off the truth
#: (``packaging/evaluation/rig-default-clumped``). Such an estimate is flagged, and states that measured error.
UNMODELLED_MISFIT = 0.05
#: The largest best-member misfit the family's own swatches read through the rig (the figure above).
FAMILY_MOST_MISFIT = 0.036


def unmodelled(misfits: dict[str, float] | None, limit: float = UNMODELLED_MISFIT) -> float | None:
    """The best member's misfit where even it is over ``limit`` (no structure of the family fits), else None."""
    if not misfits:
        return None
    best = min(misfits.values())
    return best if best > limit else None


def decisive(misfits: dict[str, float], ratio: float = DECISIVE) -> str | None:
    """The member whose misfit is under ``1 / ratio`` of every other's (``StructureReading.misfits``), or None."""
    if len(misfits) < 2:
        return None
    best, second = sorted(misfits.items(), key=lambda kv: kv[1])[:2]
    return best[0] if second[1] >= ratio * max(best[1], 1e-9) else None


@dataclass(frozen=True)
class StructureReading:
    """The structure whose per-light tables fit the single-light frames best, and its shine."""

    swatch_model: str
    shine: object                          # inference.shine.ShineEstimate on that structure's tables
    misfits: dict[str, float]              # rms log misfit of every member's best shine
    tables: object                         # its ShineTables

    @property
    def curve(self) -> ResponseCurve:
        """The all-lights response curve of the structure read, at the shine read."""
        return self.tables.all_lights_curve(self.shine.longitudinal_roughness)


def read_structure(light_means: np.ndarray, view: View, settings: RefineSettings = RefineSettings(),
                   renderer=None, members: tuple[str, ...] = READ_MEMBERS) -> StructureReading:
    """Shine and structure from the (L, 3) single-light means: each member's tables give a best shine
    and a misfit (``inference.shine.estimate_shine``); the member that fits best is read. A fibre off the
    swatch's axis sends the light along the fibres more of its light and the lights across them less."""
    fits = {}
    for member in members:
        tables = shine_tables(view, settings, renderer=renderer, swatch_model=member)
        fits[member] = (estimate_shine(np.asarray(light_means, float), tables), tables)
    best = min(fits, key=lambda m: fits[m][0].residual)
    return StructureReading(best, fits[best][0], {m: round(f[0].residual, 5) for m, f in fits.items()},
                            fits[best][1])


#: The texture's reading of the structure (``inference.texture.streaks``, at the canonical frame width
#: ``FAMILY_FRAME[0]``): streak-free when the orientation order is under ``STREAK_FREE_ORDER``, streaked when
#: the correlation along the fibres and the order are both over ``STREAKED``, undecided between. Chosen on
#: ``hairdigi bench streaks`` (the simulated rig's live frames, RAW stills and tilted cameras of 16 hairs):
#: the order alone parts the classes (layered and tilted at most 0.40, the deposits, spread and wavy swatches
#: at least 0.46). The correlation confirms a streaked reading only: a RAW still, without a sensor's noise,
#: shows dark layered hair's own fibres (up to 0.11 along them in ``hairdigi evaluate --rig``'s stills).
STREAK_FREE_ORDER = 0.45
STREAKED = (0.01, 0.55)
#: The members a streak-free texture leaves, each weighted by the share of its bench captures that read so
#: (``hairdigi bench streaks``; the texture's likelihood of each member, as a posterior weight over an even
#: prior): fibres side by side in full layers show no streaks, and a loose swatch mostly shows none. A streaked
#: texture keeps the whole family: its own members (deposited 1, coarse 0.87, spread 1, wavy 1) lose the
#: lighter structures that balance the spread swatch's darkness, and through the rig the deposited swatches'
#: answers came out dark (1.03 median, 0.49 with the whole family;
#: ``packaging/evaluation/rig-drawn-texture-streaked``).
TEXTURE_MEMBERS = {"streak-free": {"layered": 1.0, "tilted": 1.0, "loose": 0.85}}
#: The streaks along the fibres (``TextureReading.along``) over which the texture is no structure of the family's:
#: swatches of fibres gathered into clumps with gaps between them. The family's own rig frames read at most 0.287
#: (``hairdigi bench streaks``: a coarse deposit, live; RAW stills at most 0.184, tilted cameras 0.089; in
#: ``hairdigi evaluate --rig``'s 303 captures of six members at most 0.135). The clumped swatch read 0.350-0.478
#: (``packaging/evaluation/rig-default-clumped``), platinum the least: the captures whose frames fit a member
#: (misfit 0.033-0.046, under ``UNMODELLED_MISFIT``), 3.0-4.3 off the truth with the family's interval (95%
#: 1.38). Set above the family's largest, knowing clumped's; an estimate over it is flagged as a structure none
#: of the family fits and states that interval.
UNMODELLED_STREAKS = 0.3
#: The strongest streaks the family's own rig frames read (the figure above).
FAMILY_MOST_STREAKS = 0.287


@dataclass(frozen=True)
class TextureReading:
    """What the swatch area's texture says of the structure: "streak-free", "streaked", or None (undecided)."""

    kind: str | None
    along: float
    order: float
    source: str = ""        # where it was read, when not the image estimated (a RAW still takes the rig camera's)

    @property
    def weights(self) -> dict[str, float] | None:
        """The members the texture leaves, weighted (None: every member: undecided, or streaked)."""
        return TEXTURE_MEMBERS.get(self.kind) if self.kind else None

    @property
    def unmodelled(self) -> bool:
        """Streaks stronger than any structure of the family shows (``UNMODELLED_STREAKS``)."""
        return self.along > UNMODELLED_STREAKS

    def describe(self) -> str:
        """One line for the record."""
        stats = f"streaks along the fibres {self.along:.3f}, orientation order {self.order:.2f}" + (
            f", on {self.source}" if self.source else "")
        if self.kind is None:
            return f"the texture is undecided ({stats})"
        if self.weights is None:
            return f"the texture reads {self.kind} ({stats}): every member kept"
        members = ", ".join(f"{m} {w:g}" for m, w in self.weights.items())
        return f"the texture reads {self.kind} ({stats}): {members}"


def read_texture(pixels_linear: np.ndarray, view: View) -> TextureReading | None:
    """The structure the swatch area's texture reads (``TextureReading``), its pixels scaled to the canonical
    frame width first (a RAW still's twice the feed's); None where there is no rig view's texture."""
    # deferred: OpenCV takes ~0.3 s; only this step needs it
    import cv2

    from hairdigi.inference.texture import streaks

    if pixels_linear is None or not isinstance(view, RigRegion):
        return None
    scale = FAMILY_FRAME[0] / view.frame_size[0]
    pixels = np.asarray(pixels_linear, np.float32)
    if abs(scale - 1.0) > 0.05:
        size = (max(1, round(pixels.shape[1] * scale)), max(1, round(pixels.shape[0] * scale)))
        pixels = cv2.resize(pixels, size, interpolation=cv2.INTER_AREA)
    try:
        found = streaks(pixels)
    except ValueError:          # an area too small to read
        return None
    if found.order < STREAK_FREE_ORDER:
        kind = "streak-free"
    elif found.along > STREAKED[0] and found.order > STREAKED[1]:
        kind = "streaked"
    else:
        kind = None
    return TextureReading(kind, found.along, found.order)


#: The fit's ΔE2000 on swatches of other structures (``hairdigi evaluate --structures --ship``), by
#: whether the structure was read: what a record's colour interval carries for a structure it does not know.
STRUCTURE_TABLE = MODELS / "structure_uncertainty.json"


#: The evaluation's name of each mode's figures in ``STRUCTURE_TABLE``; "family_unread": the family mode
#: without single-light frames (a RAW still), every answer mapped to the whole family's mean.
_TABLE_KEYS = {StructureMode.ASSUMED: "shipped", StructureMode.FAMILY: "family", StructureMode.READ: "read"}


def with_structure(uncertainty: Uncertainty, table: dict | None, mode: StructureMode = StructureMode.ASSUMED,
                   swatch_model: str | None = None, frames: bool = True, modelled: bool = True) -> Uncertainty:
    """``uncertainty`` (``inference.uncertainty.intervals``) with its colour interval widened to what
    swatches of other structures measured for ``mode`` (the larger of the two, per level), and a
    ``structure`` entry naming the mode and the structure rendered. ``frames``: the capture had single-light
    frames to read the structure from (without, the family mode states its figures without a reading);
    ``modelled`` False: they fit no structure of the family (``unmodelled``), and the interval is what a structure
    outside it measured."""
    mode = StructureMode(mode)              # the text at an edge (a record, a flag), the enum inside
    key = _TABLE_KEYS[mode]
    if not frames and mode is StructureMode.FAMILY and table and "family_unread" in table:
        key = "family_unread"
    if not modelled and table and "unmodelled" in table:
        key = "unmodelled"
    if not table or key not in table:
        return uncertainty
    measured = table[key]
    unread = {"family_unread": " without single-light frames",
              "unmodelled": ", a structure none of the family fits"}.get(key, "")
    source = measured.get("source") or table.get("source", "hairdigi evaluate --structures")
    out = widen_colour(uncertainty, measured["p68"], measured["p95"], f"{source} (--structure {mode}{unread})")
    return replace(out, structure=StructureInterval(mode, swatch_model, round(measured["p68"], 3),
                                                    round(measured["p95"], 3), table.get("source", "")))


def toward_family(refinement, prior, view: View, settings: RefineSettings = RefineSettings(), renderer=None,
                  misfits: dict[str, float] | None = None, texture: TextureReading | None = None):
    """``refinement`` (``inference.refine.Refinement``) with its sigma_a mapped to the family's mean (``to_family``)
    and the Table 1 parameters nearest ``prior`` that make it; the residual stays the one measured on the default
    structure; ``misfits``, the single-light frames' undecided reading (None: none), is recorded with it;
    ``texture`` (``read_texture``), where it reads a class, weights the members the map averages.
    (Leaving out the members the frames rule out, misfit ten times the best's, helped the layered swatch and
    hurt the deposited ones through the rig: ``packaging/evaluation/structures-held-out-check/family_ruled_out_replay.*``
    and the manual's figures.) The family's curves render once per canonical view (``family_view``;
    cached)."""
    start = time.perf_counter()
    family = family_curves(family_view(view), settings, renderer)
    weights = texture.weights if texture is not None else None
    params, _ = params_for_sigma(to_family(refinement.sigma_a, family, weights=weights), prior)
    why = ("no single-light frames read the structure" if not misfits else
           "the single-light frames read none decisively: " + ", ".join(f"{m} {v:.3f}" for m, v in misfits.items()))
    if texture is not None:
        why = f"{texture.describe()}; {why}"
    mean = (f"the family's mean: {', '.join(family.members)}" if weights is None else
            "the weighted mean of the members the texture leaves")
    members = ({m: 1.0 for m in family.members} if weights is None else
               {m: float(w) for m, w in weights.items() if m in family.members and w > 0})
    sigma = hair_sigma_a(params)
    return replace(refinement, params=params, sigma_a=sigma, fitted_sigma_a=refinement.sigma_a,
                   seconds=refinement.seconds + time.perf_counter() - start,
                   region=replace(refinement.region, structure=f"mapped to {mean} ({why})", members=members,
                                  spreads=member_spreads(sigma, family, members)))
