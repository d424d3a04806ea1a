"""From a colour-corrected image to hair parameters and the one record written beside every estimate.

The steps: find the swatch crop, run the encoder (``inference.encoder``), refine by synthesis so the
swatch re-renders with the crop's mean colour (``inference.refine``), attach measured intervals
(``inference.uncertainty``), and collect warnings: out-of-domain inputs (``inference.domain_checks``), a
colour no Table 1 hair renders, parameters at the edge of the range, a stale calibration. ``hairdigi
estimate``, ``hairdigi rig`` and the app all go through :func:`estimate_image` and :func:`record`.
"""
from __future__ import annotations

import hashlib
import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from hairdigi.inference.appearance_reading import (AppearanceReading, check_light_frames, on_its_structure,
                                                   read_appearance, unmeasured_variation)
from hairdigi.inference.calibration import (CalibrationError, apply_profile, calibration_warnings, correction_warnings,
                                            detect_chart, load_profile)
from hairdigi.inference.domain_checks import domain_stats, domain_warnings
from hairdigi.inference.encoder import Encoder, Estimate
from hairdigi.inference.light_frames import read_light_frame
from hairdigi.inference.preprocess import (Roi, crop_of, find_swatch, find_swatch_core, read_image, swatch_crop,
                                           to_linear)
from hairdigi.inference.refine import (Refinement, RefineSettings, View, curve_reach, fitted_pixels, mean_linear, refine,
                                      response_curve)
from hairdigi.inference.structure import (DECISIVE, FAMILY_MOST_MISFIT, FAMILY_MOST_STREAKS, READ_MEMBERS,
                                          STRUCTURE_TABLE, UNMODELLED_MISFIT, UNMODELLED_STREAKS, TextureReading,
                                          decisive, read_texture, toward_family, unmodelled, with_structure)
from hairdigi.inference.uncertainty import intervals, load_table
from hairdigi.inference.view_check import view_warning, widened
from hairdigi.inference.views import swatch_view
from hairdigi.render.domain.bounds import DEFAULT_STRUCTURE, StructureMode
from hairdigi.render.domain.version import version
from hairdigi.render.domain.appearance import Appearance, AppearanceEstimate
from hairdigi.render.domain.estimate_parts import EncoderReading, Provenance, Uncertainty
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.record_fields import RecordError
from hairdigi.render.domain.records import (CalibrationProfile, CaptureRecord, EstimateRecord, EstimateWarning,
                                            RefinementRecord, UNRELIABLE, WarningKind, read_record)
from hairdigi.render.domain.rig_geometry import RIG_SWATCH_POSE, CameraPose, RigRegion
from hairdigi.resources import MODELS

UNCERTAINTY_TABLE = MODELS / "uncertainty.json"


#: A fibre variation read from the texture must let the refinement fit the capture's colour this well
#: (ΔE2000; the chain's 95% colour interval when it was chosen, ``hairdigi evaluate --rig``), or uniform
#: fibres are tried.
VARIATION_FIT_DE = 0.46

#: The colour's ΔE2000 through the whole simulated rig chain (``hairdigi evaluate --rig``).
CHAIN_TABLE = MODELS / "chain_uncertainty.json"
#: A refinement residual (ΔE2000) beyond which the assumed swatch is taken not to be the capture's: its
#: structure is then read from the single-light frames, and kept where it halves the residual. On
#: ``hairdigi evaluate --structures``' 91 swatches (the named 35 and ``--held-out 11``'s 56), 22 were
#: beyond it, one on the layered swatch (its reading did not halve the residual: kept); the 21 read
#: went from a fit of 1.17 median, 3.28 worst, to 0.49 and 1.64 (transfer 1.04 / 3.41 to 0.38 / 2.19).
UNREACHED_DE = 0.6


@dataclass
class EstimateResult:
    """Everything one estimate produced: the final parameters and how they were reached."""

    params: HairParams                   # refined when refinement ran, else the encoder's
    encoder: Estimate
    refinement: Refinement | None
    warnings: list[EstimateWarning] = field(default_factory=list)
    domain: dict = field(default_factory=dict)
    uncertainty: Uncertainty = field(default_factory=Uncertainty)
    seconds: float = 0.0
    appearance: AppearanceEstimate | None = None   # shine and fibre variation (None: refinement did not run)

    @property
    def reliable(self) -> bool:
        """False when a warning says the input is not a swatch the encoder knows."""
        return not any(w.kind in UNRELIABLE for w in self.warnings)


def _warn(kind: WarningKind, messages) -> list[EstimateWarning]:
    return [EstimateWarning(kind, m) for m in messages]


def interval_warnings(residual_de2000: float, uncertainty: Uncertainty) -> list[EstimateWarning]:
    """A warning when the twin misses the capture itself by more than the stated 68% colour interval:
    the truth cannot be expected inside it then."""
    stated = uncertainty.mean_colour_de2000_p68
    if stated is None or residual_de2000 <= stated:
        return []
    return _warn(WarningKind.INTERVAL, [
        f"interval: the twin misses this capture by ΔE2000 {residual_de2000:.2f}, more than the stated 68% "
        f"colour interval ({stated:.2f}); the stated intervals do not hold for it"])


def estimate_image(image: np.ndarray, encoder: Encoder, *, roi: Roi | None = None,
                   view: View = RIG_SWATCH_POSE, refine_colour: bool = True,
                   settings: RefineSettings = RefineSettings(), extra_warnings: list[EstimateWarning] = (),
                   on_encoder_estimate: Callable[[HairParams], None] | None = None,
                   renderer=None, light_images: list[np.ndarray] | None = None,
                   structure: StructureMode = DEFAULT_STRUCTURE,
                   sensor_clipped: np.ndarray | None = None,
                   borrowed: RigReading | None = None) -> EstimateResult:
    """Estimate a colour-corrected image: linear float RGB (a corrected capture) or 8-bit sRGB; a rig
    frame or a crop that is all hair.

    ``view`` says what the fitted pixels show: a ``RigRegion`` of a rig-view frame (the capture's
    swatch area, which the refinement fits and renders exactly), or the camera pose of an all-hair
    crop (the rig's swatch pose by default). ``on_encoder_estimate`` is told the encoder's parameters
    before refinement starts (the app shows them at once). ``light_images``: the same view lit by
    each light alone (light order), corrected as ``image`` and at its exposure: the shine is read
    from them; without them the record says "shine not measured". ``structure``: how the swatch's
    structure is treated (``render.domain.bounds.STRUCTURE_MODES``): "assumed", hairdigi's layered swatch;
    "family", the answer mapped to the mean of ``render.swatch_family``'s physical structures (or refined on
    the structure the single-light frames read decisively, ``inference.structure.decisive``); "read",
    read from the single-light frames among them and refined on it. ``sensor_clipped``: the image's
    saturated photosites per pixel (a RAW still's, ``Frame.clipped``): clipping is judged on them.
    ``borrowed``: in the family mode, an image without single-light frames of its own (a RAW still) takes the texture
    and the structure and shine that the rig's frames of the same swatch read (:func:`read_rig_structure`).
    """
    start = time.perf_counter()
    seen, structure = swatch_view(view), StructureMode(structure)
    crop, roi = swatch_crop(image, seen.roi(roi))
    est = encoder.estimate(image, roi)
    if on_encoder_estimate is not None:
        on_encoder_estimate(est.params)
    stats = domain_stats(crop, None if sensor_clipped is None else crop_of(sensor_clipped, roi))
    spread = max(est.view_spread.values()) if est.view_spread else None
    warnings = _warn(WarningKind.OUT_OF_DOMAIN, domain_warnings(stats, spread))
    refinement, appearance = None, None
    params = est.params
    if light_images is not None:
        check_light_frames(light_images, image)
    if refine_colour:
        fit = _Fit.of(est.params, image, light_images, view, roi, settings, renderer)
        refinement, appearance, structure, found = _refined(fit, structure, borrowed)
        warnings += found
        params = refinement.params
    if est.at_range_edge:
        warnings += _warn(WarningKind.RANGE_EDGE, [
            f"at the edge of the range: {', '.join(est.at_range_edge)} (the encoder pressed "
            "against the limit of what it was trained on)"])
    warnings += list(extra_warnings)
    chain = load_table(CHAIN_TABLE) if seen.rig else None
    uncertainty = intervals(params, load_table(UNCERTAINTY_TABLE), chain)
    if refinement is not None:   # a swatch's structure: read, or the default assumed (``inference.structure``)
        uncertainty = with_structure(uncertainty, load_table(STRUCTURE_TABLE), structure,
                                     refinement.region.swatch_model,
                                     frames=light_images is not None or borrowed is not None,
                                     modelled=not any(w.kind is WarningKind.STRUCTURE for w in warnings))
    if refinement is not None:
        warnings += interval_warnings(refinement.residual_de2000, uncertainty)
    return EstimateResult(params, est, refinement, warnings, stats.to_dict(), uncertainty,
                          time.perf_counter() - start, appearance)


@dataclass(frozen=True)
class _Fit:
    """What one estimate's refinement works from: the encoder's parameters, the fitted pixels' mean colour,
    the view, and (with single-light frames) their colours, the fitted texture and the frames' levels."""

    start: HairParams
    colour: np.ndarray
    view: View
    settings: RefineSettings
    renderer: object
    singles: np.ndarray | None
    texture: np.ndarray | None
    levels: np.ndarray | None

    @classmethod
    def of(cls, start: HairParams | None, image: np.ndarray, light_images: list[np.ndarray] | None, view: View,
           roi: Roi | None, settings: RefineSettings, renderer) -> "_Fit":
        """What ``image`` (and its single-light frames, if any) gives the refinement at ``view``."""
        seen = swatch_view(view)
        fitted = seen.pixels(image, roi)
        singles = None if light_images is None else np.array([mean_linear(seen.pixels(im, roi)) for im in light_images])
        return cls(start, mean_linear(fitted), view, settings, renderer, singles, seen.texture(fitted),
                   None if light_images is None else seen.frame_levels(light_images))

    def read(self, structures: tuple[str, ...] | None = None) -> AppearanceReading:
        """The appearance read from the frames (``inference.appearance_reading.read_appearance``)."""
        return read_appearance(self.singles, self.view, self.settings, self.renderer, texture_pixels=self.texture,
                               frame_levels=self.levels, structures=structures)

    def reach(self, reading: AppearanceReading) -> float:
        """How near (ΔE2000) hair of ``reading``'s appearance comes to the colour on its curve (``curve_reach``)."""
        curve = reading.curve or response_curve(self.view, self.settings, self.renderer,
                                                swatch_model=reading.swatch_model)
        return curve_reach(curve, reading.value, self.colour)

    def refine(self, reading: AppearanceReading, value: Appearance | None = None) -> Refinement:
        """The refinement on ``reading``'s swatch and curve, with its appearance or ``value``."""
        return refine(self.start, self.colour, self.view, self.settings, self.renderer,
                      reading.value if value is None else value, reading.curve, swatch_model=reading.swatch_model)


def _members(fit: _Fit) -> tuple[TextureReading | None, AppearanceReading | None, str | None]:
    """The family mode's reading of the structure: the texture's (``read_texture``), the single-light frames'
    among the members it leaves (None without frames), and the member they read decisively (None: none).

    The texture leaves the members that show no streaks where it reads none; the mean over those left stands
    for a structure the frames cannot tell; one they tell decisively among them is refined on."""
    texture = read_texture(fit.texture, fit.view)
    left = texture.weights if texture is not None else None
    if fit.singles is None:
        return texture, None, None
    members = fit.read(READ_MEMBERS if left is None else tuple(m for m in READ_MEMBERS if m in left))
    return texture, members, decisive(members.misfits or {})


@dataclass(frozen=True)
class RigReading:
    """What the rig's own frames of a swatch read of its structure (``read_rig_structure``, as ``_members``), for an
    image of the same swatch without single-light frames (a RAW still)."""

    texture: TextureReading | None       # read on the rig camera's frame
    frames: AppearanceReading | None     # the single-light frames' reading among the members the texture leaves
    decided: str | None                  # the member they read decisively (None: none)


def read_rig_structure(image: np.ndarray, light_images: list[np.ndarray], view: View,
                       settings: RefineSettings = RefineSettings(), renderer=None) -> RigReading:
    """The texture of ``image`` and the structure and shine that ``light_images`` (each light alone, corrected as
    ``image`` and at its exposure) read decisively at ``view``, as the family mode reads a capture (``_members``):
    what a RAW still of the same swatch, which has no such frames, borrows (``estimate_image``). The texture's
    classes were chosen on the rig camera's frames."""
    check_light_frames(light_images, image)
    texture, members, decided = _members(_Fit.of(None, image, light_images, view, None, settings, renderer))
    return RigReading(None if texture is None else replace(texture, source="the rig camera's frame"), members, decided)


def _refined(fit: _Fit, structure: StructureMode, borrowed: RigReading | None = None
             ) -> tuple[Refinement, AppearanceEstimate, StructureMode, list[EstimateWarning]]:
    """The refinement of ``fit`` with the appearance read on the way, the structure it was made on (a
    capture no hair on the assumed swatch reaches is read anew) and their warnings; ``borrowed``, the rig's
    reading of the same swatch (``read_rig_structure``), stands in for the frames ``fit`` lacks."""
    decided, members, texture = None, None, None
    if structure is StructureMode.FAMILY:
        texture, members, decided = _members(fit)
        if fit.singles is None and borrowed is not None:
            texture, members, decided = borrowed.texture or texture, borrowed.frames, borrowed.decided
    reading = members if decided else fit.read(READ_MEMBERS if structure is StructureMode.READ else None)
    if structure is not StructureMode.ASSUMED:     # greys are read on the swatch the texture model was fitted on
        reading = on_its_structure(reading, decided or (reading.swatch_model if structure is StructureMode.READ
                                                        else None))
    warnings = list(reading.warnings)
    read_misfits = (members if members is not None else reading).misfits if structure is not StructureMode.ASSUMED \
        else None
    worst = unmodelled(read_misfits)
    if worst is not None:
        warnings += _warn(WarningKind.STRUCTURE, [
            f"structure: no swatch structure hairdigi draws fits the single-light frames (the best misfit {worst:.3f}, "
            f"over {UNMODELLED_MISFIT:g}; the family's own swatches read at most {FAMILY_MOST_MISFIT:g}): the swatch "
            f"is built another way, and its colour interval is what such a structure measured"])
    elif texture is not None and texture.unmodelled:
        warnings += _warn(WarningKind.STRUCTURE, [
            f"structure: the swatch's texture shows streaks along the fibres ({texture.along:.3f}, over "
            f"{UNMODELLED_STREAKS:g}; the family's own swatches read at most {FAMILY_MOST_STREAKS:g}) that no swatch "
            f"structure hairdigi draws shows, as fibres gathered in clumps with gaps between them: the swatch is built "
            f"another way, and its colour interval is what such a structure measured"])
    appearance = reading.estimate
    # the colour checks the texture's reading: if hair of the read variation renders the capture's colour
    # worse than the chain's precision, and uniform fibres render it better, the reading is wrong for this
    # swatch (black hair's glints, a deposited swatch's shadows read as greys), and is not reported as
    # measured. Where the variation's own curve falls short of the colour by twice that, its refinement (check
    # renders) is run only if uniform fibres do not render the colour within it
    reach = fit.reach(reading) if reading.value.varied else 0.0
    refinement = None if reach > 2 * VARIATION_FIT_DE else fit.refine(reading)
    if reading.value.varied and (refinement is None or refinement.residual_de2000 > VARIATION_FIT_DE):
        uniform = fit.refine(reading, replace(reading.value, fibre_spread=0.0, grey_fraction=0.0))
        if refinement is None and uniform.residual_de2000 > min(reach, VARIATION_FIT_DE):
            refinement = fit.refine(reading)
        missed = reach if refinement is None else refinement.residual_de2000
        if refinement is None or uniform.residual_de2000 < refinement.residual_de2000:
            warnings += _warn(WarningKind.APPEARANCE, [
                f"appearance: with the grey share {reading.value.grey_fraction:.2f} read from the texture, no "
                f"hair renders this swatch's colour within ΔE2000 {VARIATION_FIT_DE} (residual {missed:.2f}"
                f"{' on its curve' if refinement is None else ''}; uniform fibres {uniform.residual_de2000:.2f}): "
                f"it is not reported as measured"])
            refinement, appearance = uniform, unmeasured_variation(reading.estimate)
    if (structure is not StructureMode.READ and not decided and fit.singles is not None
            and refinement.residual_de2000 > UNREACHED_DE):
        # no hair on the assumed swatch renders the capture's colour: the swatch is built another way.
        # Its structure is read from the single-light frames and kept where it reaches the colour
        reread = members or fit.read(READ_MEMBERS)
        reread = on_its_structure(reread, reread.swatch_model)
        other = fit.refine(reread)
        if other.residual_de2000 < refinement.residual_de2000 / 2:
            warnings += _warn(WarningKind.OTHER, [
                f"structure: no hair on hairdigi's layered swatch renders this swatch's colour (residual "
                f"ΔE2000 {refinement.residual_de2000:.2f}); its structure was read from the single-light "
                f"frames as {reread.swatch_model} (residual {other.residual_de2000:.2f}) and the estimate "
                f"made on it"])
            warnings = [w for w in warnings if w.kind != WarningKind.APPEARANCE] + list(reread.warnings)
            refinement, appearance, structure = other, reread.estimate, StructureMode.READ
    if decided:
        frames = ("the single-light frames" if fit.singles is not None else
                  "the rig's single-light frames of the same swatch (this image has none)")
        refinement = replace(refinement, region=replace(refinement.region, structure=(
            f"read decisively from {frames} as {decided} (its misfit under 1/{DECISIVE:g} of "
            f"every other member's: " + ", ".join(f"{m} {v:.3f}" for m, v in members.misfits.items()) + ")"
            + ("" if texture is None else f"; {texture.describe()}"))))
    elif structure is StructureMode.FAMILY:
        refinement = toward_family(refinement, fit.start, fit.view, fit.settings, fit.renderer,
                                   members.misfits if members is not None else None, texture)
    if not refinement.reachable:
        warnings += _warn(WarningKind.UNREACHABLE, [
            f"unreachable: no Table 1 hair renders this swatch's colour (residual ΔE2000 "
            f"{refinement.residual_de2000:.2f}); the parameters are the nearest colour"])
    if refinement.nonfinite:
        warnings += _warn(WarningKind.NONFINITE, [
            f"render: the refinement's renders returned {refinement.nonfinite} NaN or Inf values (counted "
            f"as 0); run again, and report it if it repeats"])
    return refinement, appearance, structure, warnings


def record(result: EstimateResult, encoder: Encoder, image_bytes: bytes | None = None,
           image_path: str | os.PathLike | None = None, calibration: dict | None = None,
           view: View = RIG_SWATCH_POSE) -> EstimateRecord:
    """The record of an estimate: parameters, warnings, intervals and provenance."""
    est, seen = result.encoder, swatch_view(view)
    provenance = Provenance(
        hairdigi_version=version(), time=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        model={"path": str(encoder.path), "sha256": encoder.sha256, "input_size": encoder.input_size},
        roi=None if est.roi is None else (est.roi.x, est.roi.y, est.roi.w, est.roi.h),
        camera=seen.pose, view=seen.recorded(),
        encoder_ms=round(est.seconds * 1000.0, 3), seconds=round(result.seconds, 3),
        calibration=calibration, domain=result.domain,
        image=None if image_path is None else str(image_path),
        image_sha256=None if image_bytes is None else hashlib.sha256(image_bytes).hexdigest())
    return EstimateRecord(
        hair=result.params, warnings=tuple(result.warnings), uncertainty=result.uncertainty,
        encoder=EncoderReading(est.params, tuple(est.at_range_edge), dict(est.view_spread)),
        refinement=result.refinement.to_record() if result.refinement else RefinementRecord(),
        provenance=provenance, appearance=result.appearance)


def calibration_summary(profile: CalibrationProfile, path: str | os.PathLike | None = None) -> dict:
    """What an estimate records of the calibration profile it was corrected with."""
    summary = {"id": profile.id, "method": profile.method, "delta_e2000_after": profile.delta_e2000.get("after")}
    if path is not None:
        summary["path"] = str(path)
    return summary


def estimate_file(image_path: str | os.PathLike, encoder: Encoder, roi: Roi | None = None,
                  calibration_path: str | os.PathLike | None = None, camera: CameraPose | None = None,
                  refine_colour: bool = True, settings: RefineSettings = RefineSettings(),
                  rig_view: bool | None = None, light_paths: list | None = None,
                  light_exposures: list[float] | None = None, structure: StructureMode = DEFAULT_STRUCTURE
                  ) -> tuple[EstimateResult, EstimateRecord, np.ndarray]:
    """Read, colour-correct (when a calibration profile is given) and estimate; returns the result,
    its record and the corrected image (linear float when corrected, else as read).

    ``rig_view``: the image is a whole frame of the bench camera (the swatch's region is then fitted
    and rendered as the rig sees it); None decides by whether a ColorChecker is in view. ``camera``:
    the pose of an all-hair view (None: not known, the rig's assumed, and checked against the swatch's
    outline where one is in view: ``inference.view_check``).
    ``light_paths``: the same view lit by each light alone (light order), 8/16-bit sRGB or linear
    EXR, corrected as the image; ``light_exposures`` each one's exposure over the image's (default:
    the rig's capture record beside the image, if it names these frames, else 1). ``structure``:
    how the swatch's structure is treated (``estimate_image``; "read" needs the light frames).
    """
    image_path = Path(image_path)
    image = read_image(image_path)
    lights = None
    if light_paths is not None:
        lights = [read_light_frame(path) for path in light_paths]
        check_light_frames(lights, image, sums=False)   # their sum is checked at the image's exposure, below
        factors = light_exposures or _recorded_exposures(image_path, light_paths) or [1.0] * len(lights)
        lights = [to_linear(im) / np.float32(k) for im, k in zip(lights, factors)]
    if rig_view is None:
        try:
            detect_chart(image)
            rig_view = True
        except CalibrationError:
            rig_view = False
    view: View = camera or RIG_SWATCH_POSE
    outline = None
    if roi is None and (rig_view or camera is None):
        roi, outline = find_swatch_core(image) if rig_view else find_swatch(image)
    if rig_view:
        view = RigRegion((image.shape[1], image.shape[0]), (roi.x, roi.y, roi.w, roi.h))
    # without --camera, the swatch's outline (when one is in view) must agree with the assumed camera
    assumed = swatch_view(view).pose.polar_deg
    unknown_view = view_warning(outline, assumed, bool(rig_view)) if camera is None else None
    calibration, extra = None, []
    if calibration_path is not None:
        profile = load_profile(calibration_path)
        raw = image
        image = apply_profile(image, profile)
        lights = None if lights is None else [apply_profile(im, profile) for im in lights]
        calibration = calibration_summary(profile, calibration_path)
        # against the capture's own settings and time when the rig's record sits beside the image
        extra = _warn(WarningKind.CALIBRATION, calibration_warnings(calibration_path, image_path))
        if rig_view:
            extra += _warn(WarningKind.CALIBRATION, correction_warnings(
                profile, mean_linear(fitted_pixels(to_linear(raw), view)), mean_linear(fitted_pixels(image, view))))
    if unknown_view is not None:
        extra += _warn(WarningKind.OTHER, [unknown_view])
    result = estimate_image(image, encoder, roi=roi, view=view, refine_colour=refine_colour, settings=settings,
                            extra_warnings=extra, light_images=lights,
                            structure=structure if lights is not None or structure != StructureMode.READ
                            else StructureMode.ASSUMED)
    if unknown_view is not None:
        result.uncertainty = widened(result.uncertainty)
    return result, record(result, encoder, image_path.read_bytes(), image_path, calibration, view), image


def _recorded_exposures(image_path: Path, light_paths: list) -> list[float] | None:
    """The single-light frames' exposures from the rig's capture record beside the image, when it
    names exactly these frames (a capture re-estimated from its folder)."""
    meta = image_path.with_suffix(".json")
    try:
        capture = read_record(meta, CaptureRecord) if meta.is_file() else None
    except RecordError:
        return None
    if capture is None or [Path(p).name for p in light_paths] != list(capture.light_images):
        return None
    return list(capture.light_exposures) or None
