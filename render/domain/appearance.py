"""The hair's appearance beyond Table 1: its shine and how its fibres differ.

Table 1 gives one absorption ``sigma_a`` for every fibre and the renderer gave them one shine. Real
swatches differ in both: virgin hair is glossy and bleached hair rough, fibres vary in pigment, and
greys sit among pigmented fibres. Three numbers say how:

- ``longitudinal_roughness``: the shine, Mitsuba's ``hair`` beta_m (0.3 is what the project rendered
  before; lower is glossier). The estimate reads it in ``SHINE_RANGE``.
- ``fibre_spread``: the standard deviation of ln sigma_a across the pigmented fibres; a fibre's
  sigma_a is sigma_a_median * exp(spread * z), z ~ N(0, 1).
- ``grey_fraction``: the share of unpigmented fibres (``GREY_SIGMA_A``).

``Appearance`` is what a renderer draws; ``AppearanceEstimate`` is what an estimate read from a
capture, with intervals and which of the three it measured (a capture without single-light frames
keeps the default shine, and says so).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from hairdigi.render.domain.errors import HairdigiError

#: The shine the project rendered before appearance was read, and every default scene still renders.
DEFAULT_SHINE = 0.3
#: Shine the renderer accepts: 0 renders black and below 0.05 gives fireflies (Mitsuba 3.9).
RENDER_SHINE_RANGE = (0.05, 1.0)
#: Shine the estimate reads (the per-light tables' grid): glossy virgin hair to rough, bleached hair.
SHINE_RANGE = (0.1, 0.6)
SPREAD_RANGE = (0.0, 1.0)
GREY_RANGE = (0.0, 1.0)
#: The absorption of an unpigmented fibre, per fibre radius (a faint keratin yellow is below what
#: the rig can tell: "sigma_a about 0.01").
GREY_SIGMA_A = 0.01

FIELDS = ("longitudinal_roughness", "fibre_spread", "grey_fraction")
_RANGES = {"longitudinal_roughness": RENDER_SHINE_RANGE, "fibre_spread": SPREAD_RANGE, "grey_fraction": GREY_RANGE}
_MEANING = {"longitudinal_roughness": "the shine, Mitsuba's beta_m", "fibre_spread": "the std of ln sigma_a across fibres",
            "grey_fraction": "the share of grey fibres"}


class AppearanceError(HairdigiError, ValueError):
    """An appearance value is out of its range or not a number; the message names the field."""


@dataclass(frozen=True)
class Appearance:
    """Shine, fibre-to-fibre spread and grey share of a swatch (the defaults: today's uniform hair)."""

    longitudinal_roughness: float = DEFAULT_SHINE
    fibre_spread: float = 0.0
    grey_fraction: float = 0.0

    def __post_init__(self) -> None:
        for name in FIELDS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise AppearanceError(f"{name} ({_MEANING[name]}) must be a finite number, got {value!r}")
            lo, hi = _RANGES[name]
            if not lo <= value <= hi:
                raise AppearanceError(f"{name} ({_MEANING[name]}) must be between {lo} and {hi}, got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def varied(self) -> bool:
        """True when the fibres differ (spread or greys): the renderer then draws fibre groups."""
        return self.fibre_spread > 0.0 or self.grey_fraction > 0.0

    def to_dict(self) -> dict:
        return {name: getattr(self, name) for name in FIELDS}

    @classmethod
    def from_dict(cls, data: dict, strict: bool = True) -> "Appearance":
        """From a dict holding any of the three fields (the others take their defaults); ``strict``: a key
        that is none of them (a misspelt field) is refused, naming the nearest field."""
        if not isinstance(data, dict):
            raise AppearanceError(f"an appearance is an object with {', '.join(FIELDS)}, not {type(data).__name__}")
        unknown = [k for k in data if k not in FIELDS]
        if strict and unknown:
            import difflib   # deferred: the CLI parser imports this module; difflib only for a misspelt field

            near = difflib.get_close_matches(str(unknown[0]), FIELDS, n=1)
            raise AppearanceError(f"{str(unknown[0])[:60]!r} is not an appearance field"
                                  f"{f' (did you mean {near[0]!r}?)' if near else ''}; the fields are "
                                  f"{', '.join(FIELDS)}")
        return cls(**{name: data[name] for name in FIELDS if data.get(name) is not None})


DEFAULT_APPEARANCE = Appearance()

#: The ranges synthetic swatches are drawn from (the appearance's held-out set; the training data of the
#: encoder and of the texture model): shine, fibre spread, grey share, each uniform.
APPEARANCE_DRAW = {"longitudinal_roughness": (0.12, 0.5), "fibre_spread": (0.0, 0.5), "grey_fraction": (0.0, 0.3)}


def sample_appearance(rng) -> Appearance:
    """One appearance drawn uniformly over ``APPEARANCE_DRAW`` by ``rng`` (a numpy Generator)."""
    return Appearance(**{name: float(rng.uniform(*APPEARANCE_DRAW[name])) for name in FIELDS})


@dataclass(frozen=True)
class AppearanceEstimate:
    """What an estimate read of the appearance: the values, their intervals, and what was measured.

    ``intervals`` maps a field to ``{"p68": [lo, hi], "p95": [lo, hi]}``; ``measured`` names the
    fields read from the capture (the others are defaults, e.g. the shine of a capture without
    single-light frames); ``method`` says how (a line each)."""

    value: Appearance = DEFAULT_APPEARANCE
    intervals: dict = field(default_factory=dict)
    measured: tuple[str, ...] = ()
    method: dict = field(default_factory=dict)

    @property
    def shine_measured(self) -> bool:
        return "longitudinal_roughness" in self.measured

    def interval_text(self, name: str, fmt: str = "{:.2f}", dash: str = "-") -> str:
        """`` (68%: lo-hi)`` for a measured field; for a share reported as none while its 68% interval
        excludes it (greys are kept only when their 95% interval excludes none), that it was not told
        from none, with the 95% interval; "" without intervals."""
        levels = self.intervals.get(name) or {}
        p68, p95 = levels.get("p68"), levels.get("p95")
        if p68 is None:
            return ""
        value = getattr(self.value, name)
        if p95 is not None and not p68[0] <= value <= p68[1]:
            return f" (not told from none; 95%: {fmt.format(p95[0])}{dash}{fmt.format(p95[1])})"
        return f" (68%: {fmt.format(p68[0])}{dash}{fmt.format(p68[1])})"

    def to_json(self) -> dict:
        return {**self.value.to_dict(), "intervals": self.intervals, "measured": list(self.measured),
                "method": self.method}

    @classmethod
    def from_json(cls, data) -> "AppearanceEstimate":
        """From a record's ``appearance``; a block holding only some fields (an earlier layout, or an
        edited record) counts those as measured and leaves the rest at their defaults."""
        value = Appearance.from_dict(data, strict=False)   # beside intervals, measured and method
        measured = data.get("measured")
        if measured is None:
            measured = [name for name in FIELDS if data.get(name) is not None]
        if not isinstance(measured, list) or not all(m in FIELDS for m in measured):
            raise AppearanceError(f"appearance 'measured' must list some of {', '.join(FIELDS)}, got {measured!r}")
        intervals = data.get("intervals") or {}
        method = data.get("method") or {}
        if not isinstance(intervals, dict) or not isinstance(method, dict):
            raise AppearanceError("appearance 'intervals' and 'method' must be objects")
        for name, levels in intervals.items():
            for level, bounds in (levels.items() if isinstance(levels, dict) else ()):
                if (isinstance(bounds, list) and len(bounds) == 2 and all(isinstance(b, (int, float)) for b in bounds)
                        and bounds[0] > bounds[1]):
                    raise AppearanceError(f"appearance {name!r} {level} interval {bounds} is inverted (low above "
                                          f"high); the record is damaged")
        return cls(value, intervals, tuple(measured), method)
