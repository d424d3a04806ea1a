"""The review's records as the window writes them: the calibration line, the parameters with their
intervals, the appearance, the spectral world and the lights' names. Pure text, no I/O."""
from __future__ import annotations

import time
from dataclasses import dataclass

import colour

from hairdigi.app.review.payloads import Shown
from hairdigi.app.review.previews import Stage
from hairdigi.render.domain.appearance import DEFAULT_APPEARANCE, AppearanceEstimate
from hairdigi.render.domain.estimate_parts import Uncertainty
from hairdigi.render.domain.params import VECTOR_FIELDS, HairParams
from hairdigi.render.domain.records import CalibrationProfile, EstimateRecord, EstimateWarning, WarningKind


@dataclass(frozen=True)
class ParameterView:
    """The shown parameters as the window writes them: one line per parameter (with its measured 68%
    interval), the dye chip, and the lines under them (provenance, refinement, warnings)."""

    lines: tuple[tuple[str, str], ...]       # (parameter, "dye_r: 120 ± 14")
    dye_rgb8: tuple[int, int, int] | None
    dye_tooltip: str
    info: str
    appearance: tuple[tuple[str, str], ...] = ()   # (field, "shine β_m: 0.27 (68%: 0.25–0.29)") or "not measured"


def as_profile(profile) -> CalibrationProfile | None:
    """A calibration profile, typed (from a profile or its JSON dict)."""
    if profile is None or isinstance(profile, CalibrationProfile):
        return profile
    return CalibrationProfile.from_json(profile)


def calibration_text(profile: CalibrationProfile | None, status: str, reasons: list[str],
                     now: float | None = None) -> str:
    """One line on the calibration: method, ΔE2000 before and after, age, and why it is stale."""
    if profile is None:
        return "calibration: none — press Calibrate with the chart in view"
    age_min = ((now or time.time()) - profile.time) / 60
    de = profile.delta_e2000
    text = (f"calibration: {profile.method}, ΔE2000 {de['before']['mean']:.2f} → {de['after']['mean']:.2f} "
            f"(max {de['after']['max']:.2f}), {age_min:.0f} min old")
    if reasons:
        text += " — STALE: " + "; ".join(reasons)
    return text


def parameter_lines(params: HairParams, uncertainty: Uncertainty | None) -> tuple[tuple[str, str], ...]:
    """Each Table 1 parameter with its measured 68% interval ("± w"), or "(undetermined)"."""
    intervals = {} if uncertainty is None else uncertainty.parameters
    values = dict(zip([f[0] for f in VECTOR_FIELDS], [*params.dye_rgb, params.dye_concentration,
                                                      params.melanin_concentration, params.melanin_ratio]))
    lines = []
    for name, _, _ in VECTOR_FIELDS:
        fmt = "{:.0f}" if name.startswith("dye_") and name[-1] in "rgb" else "{:.2f}"
        iv = intervals.get(name)
        if iv and not iv.determined:
            u = " (undetermined)"
        elif iv:
            u = f" ± {fmt.format(iv.half_width)}"
        else:
            u = ""
        lines.append((name, f"{name}: {fmt.format(values[name])}{u}"))
    return tuple(lines)


#: The appearance fields as the window names them, and how each value is written.
APPEARANCE_LABELS = {"longitudinal_roughness": ("shine β_m", "{:.2f}"), "fibre_spread": ("fibre spread", "{:.2f}"),
                     "grey_fraction": ("grey share", "{:.0%}")}


def appearance_lines(estimate: AppearanceEstimate | None, pending: bool = False) -> tuple[tuple[str, str], ...]:
    """Shine, fibre spread and grey share, each with its 68% interval when measured, or "not measured"
    (the default the previews render with); ``pending``: the encoder's first look, read at refinement."""
    value = estimate.value if estimate is not None else DEFAULT_APPEARANCE
    measured = estimate.measured if estimate is not None else ()
    lines = []
    for name, (label, fmt) in APPEARANCE_LABELS.items():
        v = fmt.format(getattr(value, name))
        if pending:
            text = f"{label}: – (read by refinement)"
        elif name not in measured:
            text = f"{label}: {v} — not measured (default)"
        else:
            text = f"{label}: {v}" + estimate.interval_text(name, fmt, "–")
        lines.append((name, text))
    return tuple(lines)


def parameter_view(shown: Shown, extra: tuple[EstimateWarning, ...] = ()) -> ParameterView:
    """What the window writes for ``shown``: parameters, the dye chip and the lines under them."""
    rec = shown.record
    if shown.params is None:
        reasons = list(rec.blocked) if rec is not None and rec.blocked else ["none saved"]
        return ParameterView((), None, "", "no estimate: " + "; ".join(reasons))
    p = shown.params
    lines = parameter_lines(p, rec.uncertainty if rec is not None else None)
    tooltip = f"dye colour alone, at concentration {p.dye_concentration:.2f}"
    if shown.stage == Stage.ENCODER or rec is None:
        return ParameterView(lines, tuple(int(v) for v in p.dye_rgb), tooltip,
                             "encoder's estimate; refining by synthesis…", appearance_lines(None, pending=True))
    info = [f"model {rec.provenance.model_sha256[:12]}, calibration {rec.provenance.calibration_id}"]
    if rec.refinement.ran:
        residual = rec.refinement.residual_de2000   # None in a record written without it
        info.append(f"refined in {rec.refinement.seconds:.1f} s: residual ΔE2000 "
                    + ("not recorded" if residual is None else f"{residual:.2f}"))
    colour = rec.uncertainty.mean_colour_de2000_p68
    if colour is not None:
        info.append(f"colour within ΔE2000 {colour:.2f} of the truth in 68% of held-out captures "
                    f"({rec.uncertainty.mean_colour_source or 'held-out clean crop renders'})")
    info += spectral_lines(rec)
    info += instrument_lines(rec)
    info += [f"⚠ {w.message}" for w in (*rec.warnings, *extra)]
    return ParameterView(lines, tuple(int(v) for v in p.dye_rgb), tooltip, "\n".join(info),
                         appearance_lines(rec.appearance))


#: How the window names the lights a spectral reading gives the colour under.
UNDER_NAMES = {"D65": "daylight", "A": "tungsten", "shop-led": "shop LED"}


def spectral_lines(rec: EstimateRecord) -> list[str]:
    """A record's spectral world, for the window: the colour under each light (read in the declared
    camera's RGB) and how far it moves from daylight, or the metamerism an undeclared camera leaves."""
    stated = rec.uncertainty.spectral
    lines = []
    if rec.spectral is not None:
        under = rec.spectral.under
        day = under.get("D65")
        cells = [f"{UNDER_NAMES.get(light, light)} L* {lab[0]:.0f}" + (
                 f" (ΔE2000 {float(colour.delta_E(day, lab, method='CIE 2000')):.1f} from daylight)" if day is not None and light != "D65" else "")
                 for light, lab in under.items()]
        lines.append(f"read in the camera's RGB ({rec.spectral.camera} under {rec.spectral.led}): " + "; ".join(cells))
    if stated is not None:
        lines.append(f"spectral world ({stated.camera} camera): within ΔE2000 {stated.mean_colour_de2000_p68:.2f} "
                     f"in 68% for {stated.holds_for}")
    return lines


def instrument_lines(rec: EstimateRecord) -> list[str]:
    """A record's instrument readings, as the lab's instrument would give them, with their interval."""
    lines = []
    for r in rec.instrument:
        interval = f" (within ΔE2000 {r.p68:.2f} in 68%)" if r.p68 is not None else ""
        lines.append(f"instrument {r.geometry} {r.illuminant}/{r.observer}°, {r.aperture_mm:g} mm: L* {r.lab[0]:.1f} "
                     f"a* {r.lab[1]:.1f} b* {r.lab[2]:.1f}{interval}")
    return lines


def light_name(light: int | None) -> str:
    """"all lights" or "light i alone"."""
    return "all lights" if light is None else f"light {light} alone"


def nonfinite_warning(what: str, count: int) -> EstimateWarning:
    return EstimateWarning(WarningKind.NONFINITE, f"render: the {what} preview had {count} NaN or Inf values "
                                                  f"(shown as black); its colours are not to be trusted")
