"""How a record's fields are read: the error a bad field raises, naming the field and the fix, and
the checks every record type shares (``records``, ``estimate_parts``, ``dye_record``)."""
from __future__ import annotations

import math
from typing import Any

from hairdigi.render.domain.errors import HairdigiError

#: The largest absorption (per fibre radius) a record may hold: Table 1's darkest hair is under 10; a fibre
#: at 100 passes e^-200 of the light, black to any renderer (MaterialX and Cycles refuse far larger values).
SIGMA_A_MAX = 100.0


class RecordError(HairdigiError, ValueError):
    """A record file or dict is not what it claims; the message names the field and the fix."""


def real(value: Any) -> bool:
    """A finite number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def need(data: dict, key: str, kind, what: str, default=None, required: bool = True):
    """``data[key]`` checked to be ``kind`` (float: finite; int: whole), or ``default`` when absent
    and not ``required``; RecordError naming ``what``'s ``key`` otherwise."""
    if key not in data or data[key] is None:
        if required:
            raise RecordError(f"the {what}'s {key!r} is missing")
        return default
    value = data[key]
    if kind is float:
        if not real(value):
            raise RecordError(f"the {what}'s {key!r} is {value!r}, not a finite number")
        return float(value)
    if kind is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise RecordError(f"the {what}'s {key!r} is {value!r}, not a whole number")
        return value
    if not isinstance(value, kind):
        names = kind.__name__ if isinstance(kind, type) else "/".join(k.__name__ for k in kind)
        shown = repr(value) if len(repr(value)) <= 40 else f"a {type(value).__name__}"
        raise RecordError(f"the {what}'s {key!r} is {shown}, not {names}")
    return value


def floats(value, n: int | None, key: str, what: str) -> tuple[float, ...]:
    """A list of ``n`` (any number when None) finite numbers, as a tuple of floats."""
    if not isinstance(value, (list, tuple)) or (n is not None and len(value) != n) or not all(map(real, value)):
        size = f"{n} " if n is not None else ""
        raise RecordError(f"the {what}'s {key!r} is {value!r}, not a list of {size}finite numbers")
    return tuple(float(v) for v in value)


def check_sigma_a(sigma, what: str) -> None:
    """An absorption is three numbers from 0 to ``SIGMA_A_MAX``; else RecordError naming ``what``."""
    if sigma is not None and not all(0.0 <= float(s) <= SIGMA_A_MAX for s in sigma):
        raise RecordError(f"{what} {[float(s) for s in sigma]} is outside 0 to {SIGMA_A_MAX:g} per fibre radius "
                          f"(no hair absorbs a negative or such an amount); the record is damaged: estimate again")


def check_interval(low, high, what: str) -> None:
    """An interval's low end must not lie above its high end."""
    if real(low) and real(high) and low > high:
        raise RecordError(f"{what}'s interval is inverted (low {low} above high {high}); the record is damaged: "
                          f"estimate again")
