"""The dye record: what ``hairdigi dye characterise`` measured of one dye, as a typed, versioned record.

A dye acts on a fibre by **deposit** (an added absorption ``sigma_a``, per fibre radius) and **lift**
(the developer removes a share of the melanin): ``sigma_dyed = (1 - lift) * sigma_melanin + deposit``
(the model and its references: ``inference/dye.py``). The record holds the fitted deposit and lift
with their 68% intervals, the (base, dyed) pairs it came from, each cited by its record's sha256 and
with its fit residual, the warnings (one pair: lift not measured), and provenance.

Layout as in ``render/domain/records.py``: a frozen dataclass with ``to_json()`` / ``from_json(data)``,
``schema_version`` written into every file, :class:`RecordError` naming the field at fault. numpy-free
and standard library only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hairdigi.render.domain.record_fields import RecordError, check_interval, check_sigma_a

#: The layout written today (1: the first dye record, hairdigi 0.2).
DYE_SCHEMA_VERSION = 1
KIND = "dye"
#: The longest name a dye record may hold (``hairdigi dye characterise --name`` takes 200).
MAX_NAME = 1000


def _real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _vec(data: dict, key: str, what: str, n: int = 3, optional: bool = False) -> tuple[float, ...] | None:
    value = data.get(key)
    if value is None and optional:
        return None
    if not isinstance(value, (list, tuple)) or len(value) != n or not all(map(_real, value)):
        raise RecordError(f"the {what}'s {key!r} is {value!r}, not a list of {n} finite numbers")
    return tuple(float(v) for v in value)


def _num(data: dict, key: str, what: str, optional: bool = False) -> float | None:
    value = data.get(key)
    if value is None and optional:
        return None
    if not _real(value):
        raise RecordError(f"the {what}'s {key!r} is {value!r}, not a finite number")
    return float(value)


def _text(data: dict, key: str, what: str, optional: bool = False) -> str | None:
    value = data.get(key)
    if value is None and optional:
        return None
    if not isinstance(value, str):
        raise RecordError(f"the {what}'s {key!r} is {value!r}, not text")
    return value


def _rounded(values, digits: int = 6) -> list[float]:
    return [round(float(v), digits) for v in values]


@dataclass(frozen=True)
class DyePairRecord:
    """One (natural base, dyed) pair the dye was measured on, cited by its files' checksums."""

    base: str                                   # the base's record file, as given
    base_sha256: str
    dyed: str
    dyed_sha256: str
    base_sigma_a: tuple[float, float, float]    # read as melanin alone (a natural base)
    dyed_sigma_a: tuple[float, float, float]
    base_calibration: str | None = None         # the calibration profile id each was corrected with
    dyed_calibration: str | None = None
    residual_sigma_a: tuple[float, float, float] = (0.0, 0.0, 0.0)   # measured - fitted dyed sigma_a
    residual_de2000: float = 0.0                # the same, as the swatch's mean-colour ΔE2000

    def to_json(self) -> dict:
        return {"base": self.base, "base_sha256": self.base_sha256, "dyed": self.dyed,
                "dyed_sha256": self.dyed_sha256, "base_sigma_a": _rounded(self.base_sigma_a),
                "dyed_sigma_a": _rounded(self.dyed_sigma_a), "base_calibration": self.base_calibration,
                "dyed_calibration": self.dyed_calibration, "residual_sigma_a": _rounded(self.residual_sigma_a),
                "residual_de2000": round(self.residual_de2000, 4)}

    @classmethod
    def from_json(cls, data) -> "DyePairRecord":
        what = "dye record's pair"
        if not isinstance(data, dict):
            raise RecordError(f"a {what} is an object, not {type(data).__name__}")
        return cls(base=_text(data, "base", what), base_sha256=_text(data, "base_sha256", what),
                   dyed=_text(data, "dyed", what), dyed_sha256=_text(data, "dyed_sha256", what),
                   base_sigma_a=_vec(data, "base_sigma_a", what), dyed_sigma_a=_vec(data, "dyed_sigma_a", what),
                   base_calibration=_text(data, "base_calibration", what, optional=True),
                   dyed_calibration=_text(data, "dyed_calibration", what, optional=True),
                   residual_sigma_a=_vec(data, "residual_sigma_a", what, optional=True) or (0.0, 0.0, 0.0),
                   residual_de2000=_num(data, "residual_de2000", what, optional=True) or 0.0)


@dataclass(frozen=True)
class DyeRecord:
    """A characterised dye: deposit ``sigma_a`` and lift, with 68% intervals, the pairs, and warnings.

    ``lift_measured`` is False when one base was all there was: lift is then assumed (0, or the
    least lift that explains a dyed hair lighter than its base) and its interval is None.
    ``shine_change`` stays None until the records carry a measured shine (``appearance``).
    """

    name: str
    deposit_sigma_a: tuple[float, float, float]
    lift: float
    lift_measured: bool
    pairs: tuple[DyePairRecord, ...]
    deposit_low: tuple[float, float, float] | None = None
    deposit_high: tuple[float, float, float] | None = None
    lift_low: float | None = None
    lift_high: float | None = None
    residual_de2000_max: float = 0.0
    residual_de2000_mean: float = 0.0
    shine_change: float | None = None
    warnings: tuple[str, ...] = ()
    intervals: dict = field(default_factory=dict)     # how the intervals were propagated
    provenance: dict = field(default_factory=dict)
    schema_version: int = DYE_SCHEMA_VERSION

    KIND = KIND

    def to_json(self) -> dict:
        return {"kind": KIND, "schema_version": DYE_SCHEMA_VERSION, "name": self.name,
                "model": "sigma_dyed = (1 - lift) * sigma_melanin(base) + deposit_sigma_a",
                "deposit_sigma_a": _rounded(self.deposit_sigma_a), "lift": round(self.lift, 6),
                "lift_measured": self.lift_measured,
                "deposit_low": None if self.deposit_low is None else _rounded(self.deposit_low),
                "deposit_high": None if self.deposit_high is None else _rounded(self.deposit_high),
                "lift_low": None if self.lift_low is None else round(self.lift_low, 6),
                "lift_high": None if self.lift_high is None else round(self.lift_high, 6),
                "shine_change": self.shine_change,
                "residual_de2000_max": round(self.residual_de2000_max, 4),
                "residual_de2000_mean": round(self.residual_de2000_mean, 4),
                "pairs": [p.to_json() for p in self.pairs], "warnings": list(self.warnings),
                "intervals": self.intervals, "provenance": self.provenance}

    @classmethod
    def from_json(cls, data) -> "DyeRecord":
        what = "dye record"
        if not isinstance(data, dict):
            raise RecordError(f"a {what} is a JSON object, not {type(data).__name__}")
        if data.get("kind", KIND) != KIND:
            raise RecordError(f"this is a {data.get('kind')!r} record, not a dye record; give the JSON that "
                              f"hairdigi dye characterise wrote")
        version = data.get("schema_version", DYE_SCHEMA_VERSION)
        if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= DYE_SCHEMA_VERSION:
            raise RecordError(f"the {what}'s 'schema_version' is {version!r}; this hairdigi reads 1 to "
                              f"{DYE_SCHEMA_VERSION} (update hairdigi for newer records)")
        deposit = _vec(data, "deposit_sigma_a", what)
        check_sigma_a(deposit, f"the {what}'s 'deposit_sigma_a'")
        lift = _num(data, "lift", what)
        if not 0.0 <= lift < 1.0:
            raise RecordError(f"the {what}'s 'lift' is {lift}, not in [0, 1)")
        low, high = _vec(data, "deposit_low", what, optional=True), _vec(data, "deposit_high", what, optional=True)
        for i, (lo, hi) in enumerate(zip(low or (), high or ())):
            check_interval(lo, hi, f"the {what}'s deposit channel {i}")
        check_interval(_num(data, "lift_low", what, optional=True), _num(data, "lift_high", what, optional=True),
                       f"the {what}'s lift")
        pairs = data.get("pairs")
        if not isinstance(pairs, list) or not pairs:
            raise RecordError(f"the {what}'s 'pairs' is {pairs!r}, not a list of the pairs it was measured on")
        warnings = data.get("warnings") or []
        if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
            raise RecordError(f"the {what}'s 'warnings' is not a list of sentences")
        name = _text(data, "name", what)
        if not name.strip():
            raise RecordError(f"the {what}'s 'name' is empty")
        if len(name) > MAX_NAME:
            raise RecordError(f"the {what}'s 'name' is {len(name)} characters, more than a dye's name holds "
                              f"({MAX_NAME}); the record is damaged or not a dye record")
        return cls(name=name, deposit_sigma_a=deposit, lift=lift, lift_measured=bool(data.get("lift_measured")),
                   pairs=tuple(DyePairRecord.from_json(p) for p in pairs),
                   deposit_low=_vec(data, "deposit_low", what, optional=True),
                   deposit_high=_vec(data, "deposit_high", what, optional=True),
                   lift_low=_num(data, "lift_low", what, optional=True),
                   lift_high=_num(data, "lift_high", what, optional=True),
                   residual_de2000_max=_num(data, "residual_de2000_max", what, optional=True) or 0.0,
                   residual_de2000_mean=_num(data, "residual_de2000_mean", what, optional=True) or 0.0,
                   shine_change=_num(data, "shine_change", what, optional=True),
                   warnings=tuple(warnings),
                   intervals=data.get("intervals") if isinstance(data.get("intervals"), dict) else {},
                   provenance=data.get("provenance") if isinstance(data.get("provenance"), dict) else {})
