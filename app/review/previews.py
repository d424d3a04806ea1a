"""The review's render plumbing, free of Qt: preview settings, the twin's and the hairstyle's passes as
generators, and the views they render.

A pass generator renders through ``Renderer.render_progressive`` and yields one pass at a time; it
stops at a yield when its consumer stops (or, before its next pass, when ``cancelled()``). A denoised
image is for the eye only: every number (ΔE, the chip's colour, exports' metrics) comes from the raw
path-traced image, and ``nonfinite`` counts the NaN or Inf values the path tracer returned in it.
"""
from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import Callable, Iterator

import cv2
import numpy as np

from hairdigi.app.models.work import Cancelled
from hairdigi.app.session import rig_session as rs
from hairdigi.render import denoise as dn
from hairdigi.render.domain.absorption import approximate_albedo, hair_sigma_a
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, Appearance
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.rig_geometry import N_LIGHTS
from hairdigi.render.domain.rig_geometry import CameraPose
from hairdigi.render.metrics import delta_e_map, mean_colour_delta_e
from hairdigi.render.renderer import Renderer, SceneSpec
from hairdigi.render.srgb import linear_to_srgb8, srgb8_to_linear
from hairdigi.render.domain.text_enum import TextEnum
from hairdigi.render.scenes import PORTRAIT_CAMERA, scalp_albedo
from hairdigi.render.spectra import balanced


class Stage(TextEnum):
    """Where the shown parameters come from."""

    ENCODER = "encoder"      # the encoder's first look, before refinement
    REFINED = "refined"      # the capture's record (refined by synthesis)
    BLOCKED = "blocked"      # no estimate: the record says why


@dataclass(frozen=True)
class PreviewSettings:
    """How previews render; the defaults are chosen by ``hairdigi bench previews`` (app/evaluation/bench_previews.py).

    Mean per-pixel ΔE2000 against 1024 spp, not denoised (clean: 3 or less), OIDN without guides: the
    twin (130 x 154) is 3.34 at 1 spp, 3.13 at 2, 3.06 at 4, 2.89 at 8 (clean), 2.75 at 16; raw it is
    6.1 even at 64 spp. At half resolution (65 x 77, a quarter of the samples per spp) it is clean
    at 4 spp: 3.1–3.6 at 1, 2.8–3.0 at 2, 2.69 at 4, in 0.19 s instead of 1.44 s for 8 spp at full
    resolution; the half-resolution twin is flat, the full-resolution one shows the fibres' streaks,
    so the twin goes from one to the other. The 512² hairstyle is clean from its first pass: 1.08 at
    1 spp, 0.89 at 2 (raw: 6.0 and 4.6). Albedo and normal guides never helped (twin 3.48 at 1 spp,
    3.13 at 8; hairstyle 1.08 at 1) and cost an AOV render.

    ``fibre_px``: the ΔE2000 map smooths real and twin over 6 px (at full resolution; 3 at half), about a clump of fibres in the rig
    view (0.04 swatch widths). Measured on a simulated capture whose mean colours differ by ΔE2000
    0.47: the map's mean is 2.38 at 2 px (noise and single fibres), 1.47 at 4, 1.17 at 6, 1.04 at 8.

    ``busy_feed_fps``: while a capture is estimated and its twin renders, the live feed slows down: on
    2 cores the simulated feed at 20 fps took a fifth of a core that the first passes need.
    """

    #: (scale, spp) of each twin pass: at half the capture's resolution first (running totals 1, 4),
    #: then at full resolution (8, 16, 32) for the streaks of the fibres.
    twin_passes: tuple[tuple[float, int], ...] = ((0.5, 1), (0.5, 3), (1.0, 8), (1.0, 8), (1.0, 16))
    twin_clean_spp: tuple[tuple[float, int], ...] = ((0.5, 4), (1.0, 8))   # (scale, spp) from which it is clean
    hairstyle_size: int = 512
    hairstyle_strands: int | None = None                   # None: the scene's default
    hairstyle_passes: tuple[int, ...] = (1, 1, 2, 4, 8)    # running totals 1, 2, 4, 8, 16
    hairstyle_clean_spp: int = 1
    first_look_passes: int = 1                             # passes rendered for the encoder's (unrefined) estimate
    denoise: bool = True
    fibre_px: float = 6.0                                  # smoothing of the ΔE2000 map (pixels), see above
    view_strands: int = 1500                               # strands drawn in the 3-D view
    warm: bool = True                                      # build the preview scenes before the first capture
    feed_fps: float = 20.0                                 # the live feed
    busy_feed_fps: float = 4.0                             # the live feed while a capture and its twin run


@dataclass(frozen=True)
class PassTag:
    """What a pass previews: the model's generation when its work began, the capture under review, the stage."""

    generation: int
    key: int
    stage: Stage
    light: int | None = None        # the twin: the light it is lit by alone (None: all lights)


@dataclass(frozen=True)
class TwinPreview:
    """One pass of the synthetic twin beside the real swatch."""

    generation: int
    raw: np.ndarray                 # linear float32, path-traced running mean: what every number uses
    clean: np.ndarray | None        # denoised copy, for the eye only (None without a denoiser)
    spp: int
    final: bool                     # the last pass
    clean_enough: bool              # spp >= PreviewSettings.twin_clean_spp
    delta_e: float                  # mean-colour ΔE2000, real vs raw twin
    delta_e_map: np.ndarray         # (h, w) ΔE2000 of real vs raw twin, both smoothed at the fibre scale
    hair_linear: np.ndarray         # the raw twin's mean linear colour: the estimated hair colour (the chip)
    stage: Stage
    seconds: float                  # since the work began
    key: int = 0                    # the Shown.key it previews
    scale: float = 1.0              # of the capture's resolution
    nonfinite: int = 0              # NaN or Inf values in ``raw`` (so in the map and the chip), replaced by 0
    light: int | None = None        # lit by this light alone, beside that light's captured frame (None: all)


@dataclass(frozen=True)
class HairstylePass:
    """One pass of the hairstyle render."""

    generation: int
    raw: np.ndarray
    clean: np.ndarray | None
    spp: int
    index: int
    passes: int
    clean_enough: bool
    label: str                      # "straight, studio" or the hair file's name
    stage: Stage
    seconds: float
    key: int = 0
    nonfinite: int = 0

    @property
    def final(self) -> bool:
        return self.index == self.passes


#: The grey share previews render, in steps of this: which strands are grey is the scene's structure
#: (a new share builds a new scene, seconds for a 512² hairstyle), and the estimate's 68% interval on
#: the share is about ±0.1 wide, so captures of like hair share a cached scene within their uncertainty.
PREVIEW_GREY_STEP = 0.05


def scene_appearance(appearance: Appearance | None) -> Appearance | None:
    """What a preview scene takes for ``appearance``: its shine and spread, its grey share in steps of
    ``PREVIEW_GREY_STEP``; None for the default (uniform) hair, which renders in the warm scenes."""
    if appearance is None:
        return None
    grey = round(appearance.grey_fraction / PREVIEW_GREY_STEP) * PREVIEW_GREY_STEP
    look = dataclasses.replace(appearance, grey_fraction=round(min(max(grey, 0.0), 1.0), 4))
    return None if look == DEFAULT_APPEARANCE else look


def lights_alone(light: int | None) -> tuple[float, ...]:
    """The rig lights' scales: all on (``light`` None), or light ``light`` alone at full power."""
    if light is None:
        return (1.0,) * N_LIGHTS
    if not 0 <= int(light) < N_LIGHTS:
        raise ValueError(f"light {light}: the rig has lights 0 to {N_LIGHTS - 1} (or None for all)")
    return tuple(1.0 if i == int(light) else 0.0 for i in range(N_LIGHTS))


def twin_view(roi: tuple[int, int, int, int], frame_size: tuple[int, int], simulated: bool,
              scale: float = 1.0, appearance: Appearance | None = None,
              light: int | None = None, swatch_model: str | None = None) -> tuple[SceneSpec, tuple[int, int]]:
    """The twin's scene and size: the rig camera over exactly the ROI (simulated geometry), or a crop;
    ``scale`` < 1 renders the same view with fewer pixels. The hair has the estimate's ``appearance``
    (shine, fibre spread, greys; None: the default), lit by ``light`` alone (None: all lights), on the swatch
    structure the estimate was read on (``swatch_model``; None: the default)."""
    if simulated:
        spec, size = rs.twin_spec(roi, frame_size, scale)
    else:
        spec, size = SceneSpec("swatch", framing="crop"), (max(8, round(roi[2] * scale)), max(8, round(roi[3] * scale)))
    return dataclasses.replace(spec, appearance=scene_appearance(appearance), lights=lights_alone(light),
                               swatch_model=swatch_model or spec.swatch_model), size


def orbit_pose(azimuth_deg: float, elevation_deg: float, distance: float | None = None) -> CameraPose:
    """The portrait camera turned ``azimuth_deg`` around the head and raised ``elevation_deg``.

    Portrait poses are polar from the face direction, so the orbit stays in front of the face
    (polar < 90°): ``|azimuth|`` and ``|elevation|`` are clipped to 80° and 60°.
    """
    yaw, pitch = np.radians(np.clip(azimuth_deg, -80, 80)), np.radians(np.clip(elevation_deg, -60, 60))
    d = np.array([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)])
    polar = float(np.degrees(np.arccos(np.clip(d[2], -1.0, 1.0))))
    azimuth = float(np.degrees(np.arctan2(d[1], d[0]))) if polar > 1e-6 else PORTRAIT_CAMERA.azimuth_deg
    return CameraPose(min(polar, 89.0), azimuth, distance or PORTRAIT_CAMERA.distance)


def denoised(raw: np.ndarray, on: bool, quality: str = "high") -> np.ndarray | None:
    """The display copy of a pass (None when denoising is off or there is no denoiser)."""
    if not on or not dn.available():
        return None
    return dn.denoise(raw, quality=quality)


def hair_colour_rgb8(linear: np.ndarray) -> tuple[int, int, int]:
    """An sRGB 8-bit chip colour from a mean linear colour."""
    return tuple(int(v) for v in linear_to_srgb8(np.asarray(linear, dtype=np.float32)))


def strand_colour(params: HairParams) -> tuple[int, int, int]:
    """The strands' colour in the 3-D view: the fibre albedo, a little darkened (as lit hair looks)."""
    return hair_colour_rgb8(approximate_albedo(params) * 0.8)


def scalp_linear(params: HairParams) -> tuple[float, float, float]:
    """The scalp under the hair, linear, as the renderer colours it (``scenes.scalp_albedo``)."""
    return tuple(float(v) for v in scalp_albedo(hair_sigma_a(params)))


def twin_passes(renderer: Renderer, params: HairParams, real_srgb8: np.ndarray,
                view: Callable[[float], tuple[SceneSpec, tuple[int, int]]], schedule: tuple[tuple[float, int], ...],
                settings: PreviewSettings, denoise_on: bool, tag: PassTag,
                cancelled: Cancelled = lambda: False,
                after_clean: Callable[[], None] | None = None) -> Iterator[TwinPreview]:
    """The twin's passes over (scale, spp) steps; each run of one scale accumulates on its own. ``after_clean()``
    runs before each pass once a pass was clean, and may wait (the hairstyle's first pass goes first)."""
    clean_at = dict(settings.twin_clean_spp)
    real_full = srgb8_to_linear(real_srgb8)
    done, clean = 0, False

    def gate() -> None:
        if clean and after_clean is not None:
            after_clean()

    for scale, run in itertools.groupby(schedule, key=lambda p: p[0]):
        spec, size = view(scale)
        spps = [n for _, n in run]
        real = None
        for i, result in enumerate(renderer.render_progressive(params, spec, size, spps, cancelled=cancelled,
                                                               gate=gate), done + 1):
            raw = result.linear
            if real is None:
                real = real_full if raw.shape == real_full.shape else \
                    cv2.resize(real_full, (raw.shape[1], raw.shape[0]), interpolation=cv2.INTER_AREA)
            is_clean = result.spp >= clean_at.get(scale, result.spp + 1)
            clean = clean or is_clean
            yield TwinPreview(tag.generation, raw, denoised(raw, denoise_on), result.spp, i == len(schedule),
                              is_clean, mean_colour_delta_e(real, raw),
                              delta_e_map(real, raw, settings.fibre_px * scale), raw.reshape(-1, 3).mean(0),
                              tag.stage, result.seconds, tag.key, scale, result.nonfinite, tag.light)
        done += len(spps)


def hairstyle_passes(renderer: Renderer, params: HairParams, spec: SceneSpec, label: str,
                     schedule: tuple[int, ...], settings: PreviewSettings, denoise_on: bool, tag: PassTag,
                     cancelled: Cancelled = lambda: False,
                     gate: Callable[[], None] | None = None) -> Iterator[HairstylePass]:
    """The hairstyle's passes; ``gate()`` runs before each (the hairstyle lets the twin go first)."""
    passes = renderer.render_progressive(params, spec, settings.hairstyle_size, list(schedule),
                                         cancelled=cancelled, gate=gate)
    for i, result in enumerate(passes, 1):
        linear = result.linear
        if spec.illuminant is not None:   # rendered under another light: shown as an eye adapted to it sees it
            linear = balanced(linear, spec.illuminant)
        # OIDN's "fast" on the first pass: 0.22 s instead of 0.47 s at 512², per-pixel ΔE 1.50 for 1.48
        yield HairstylePass(tag.generation, linear,
                            denoised(linear, denoise_on, "fast" if i == 1 else "high"), result.spp, i,
                            len(schedule), result.spp >= settings.hairstyle_clean_spp, label, tag.stage,
                            result.seconds, tag.key, result.nonfinite)
