"""The typed records that cross layers on disk: a capture, a calibration profile, an estimate.

Each record is a frozen dataclass with ``to_json()`` (a plain dict for ``json.dump``) and
``from_json(data)`` (checks the fields, upgrades older layouts, raises :class:`RecordError` naming
the file's problem). ``SCHEMA_VERSION`` is written into every record; a file without it is a record
of the first layout (hairdigi 0.1.0, before these types) and is upgraded on read. :func:`read_record`
is the one reader of record files.

Where a capture keeps its calibration profile is decided here, once: in the capture record
(``CaptureRecord.calibration``), for live frames and RAW stills alike. Files of the first layout
kept a still's profile in its result record (``calibration_profile``); :func:`capture_profile` reads
both.

numpy and the standard library only: ``hardware``, ``inference`` and ``app`` all read these.
"""
from __future__ import annotations

import enum
import hashlib
import json
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.appearance import AppearanceError, AppearanceEstimate
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import MAX_JSON_BYTES, read_json, sha256_file, write_json_atomic
from hairdigi.render.domain.params import HairParams, HairParamsError

#: The largest absorption (per fibre radius) a record may hold: Table 1's darkest hair is under 10; a fibre
#: at 100 passes e^-200 of the light, black to any renderer (MaterialX and Cycles refuse far larger values).
SIGMA_A_MAX = 100.0

#: The layout written today. 1: hairdigi 0.1.0's dicts (no ``schema_version``); 2: the typed records.
SCHEMA_VERSION = 2


class RecordError(HairdigiError, ValueError):
    """A record file or dict is not what it claims; the message names the field and the fix."""


def _real(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _need(data: dict, key: str, kind, what: str, default=None, required: bool = True):
    if key not in data or data[key] is None:
        if required:
            raise RecordError(f"the {what}'s {key!r} is missing")
        return default
    value = data[key]
    if kind is float:
        if not _real(value):
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


def _version(data: dict, what: str) -> int:
    if not isinstance(data, dict):
        raise RecordError(f"a {what} is a JSON object, not {type(data).__name__}")
    version = data.get("schema_version", 1)
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise RecordError(f"the {what}'s 'schema_version' is {version!r}, not a whole number >= 1")
    if version > SCHEMA_VERSION:
        raise RecordError(f"the {what} has schema_version {version}, newer than this hairdigi reads "
                          f"({SCHEMA_VERSION}); update hairdigi")
    return version


def _floats(value, n: int | None, key: str, what: str) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or (n is not None and len(value) != n) or not all(map(_real, value)):
        size = f"{n} " if n is not None else ""
        raise RecordError(f"the {what}'s {key!r} is {value!r}, not a list of {size}finite numbers")
    return tuple(float(v) for v in value)


# --- warnings ----------------------------------------------------------------------------------
class WarningKind(str, enum.Enum):
    """What a warning is about. Kinds in :data:`UNRELIABLE` make an estimate unreliable."""

    OUT_OF_DOMAIN = "out_of_domain"          # not a swatch the encoder knows
    UNREACHABLE = "unreachable"              # no Table 1 hair renders this colour
    RANGE_EDGE = "range_edge"                # the encoder pressed against its range
    CALIBRATION = "calibration"              # stale, mismatched or ill-fitting calibration
    NONFINITE = "nonfinite"                  # the path tracer returned NaN or Inf samples
    INTERVAL = "interval"                    # the colour is outside what the record's interval promises
    APPEARANCE = "appearance"                # shine or fibre variation not measured, or measured poorly
    OTHER = "other"


UNRELIABLE = frozenset({WarningKind.OUT_OF_DOMAIN, WarningKind.UNREACHABLE})

#: How a first-layout warning string is recognised (its text began with these words).
_LEGACY_PREFIXES = ((WarningKind.OUT_OF_DOMAIN, "out of domain"), (WarningKind.UNREACHABLE, "unreachable"),
                    (WarningKind.RANGE_EDGE, "at the edge of the range"), (WarningKind.CALIBRATION, "calibration"),
                    (WarningKind.NONFINITE, "render:"))


@dataclass(frozen=True)
class EstimateWarning:
    kind: WarningKind
    message: str

    def __str__(self) -> str:
        return self.message

    def to_json(self) -> dict:
        return {"kind": self.kind.value, "message": self.message}

    @classmethod
    def from_json(cls, data) -> "EstimateWarning":
        if isinstance(data, str):      # the first layout: a bare sentence
            kind = next((k for k, prefix in _LEGACY_PREFIXES if data.startswith(prefix)), WarningKind.OTHER)
            return cls(kind, data)
        if not isinstance(data, dict):
            raise RecordError(f"a warning is a sentence or an object, not {type(data).__name__}")
        try:
            kind = WarningKind(data.get("kind"))
        except ValueError:
            raise RecordError(f"a warning's 'kind' is {data.get('kind')!r}, not one of "
                              f"{', '.join(k.value for k in WarningKind)}") from None
        return cls(kind, _need(data, "message", str, "warning"))


def warnings_from_json(items, what: str) -> tuple[EstimateWarning, ...]:
    if items is None:
        return ()
    if not isinstance(items, list):
        raise RecordError(f"the {what}'s 'warnings' is {type(items).__name__}, not a list")
    return tuple(EstimateWarning.from_json(w) for w in items)


# --- calibration -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class CalibrationProfile:
    """A colour correction fitted on the chart: the CCM, how well it fits, and what it depends on."""

    id: str
    method: str
    matrix: tuple[tuple[float, ...], ...]
    time: float
    degree: int = 1
    delta_e2000: dict = field(default_factory=dict)     # {"before"|"after": {"mean", "max", "median"}}
    targets: str = ""
    settings: dict = field(default_factory=dict)        # camera and light settings it holds for
    chart_box: tuple | None = None
    detection_cost: float | None = None
    time_iso: str = ""
    schema_version: int = SCHEMA_VERSION

    KIND = "calibration"

    @property
    def after_mean(self) -> float | None:
        """The chart's mean ΔE2000 after correction (None if not recorded)."""
        return (self.delta_e2000.get("after") or {}).get("mean")

    def to_json(self) -> dict:
        return {"kind": self.KIND, "schema_version": SCHEMA_VERSION, "id": self.id, "method": self.method,
                "degree": self.degree, "matrix": [list(r) for r in self.matrix], "time": self.time,
                "time_iso": self.time_iso, "delta_e2000": self.delta_e2000, "targets": self.targets,
                "settings": self.settings, "chart_box": None if self.chart_box is None else [list(c) for c in self.chart_box],
                "detection_cost": self.detection_cost}

    @classmethod
    def from_json(cls, data) -> "CalibrationProfile":
        what = "calibration profile"
        _version(data, what)
        matrix = data.get("matrix")
        if not (isinstance(matrix, list) and len(matrix) == 3 and all(isinstance(r, list) for r in matrix)
                and len({len(r) for r in matrix}) == 1):
            raise RecordError(f"the {what}'s 'matrix' is not 3 rows of finite numbers")
        rows = tuple(_floats(r, None, "matrix", what) for r in matrix)
        degree = _need(data, "degree", int, what, 1, required=False)
        if not 1 <= degree <= 4:
            raise RecordError(f"the {what}'s 'degree' is {degree!r}, not a whole number from 1 to 4")
        time_ = _need(data, "time", float, what)
        if time_ <= 0:
            raise RecordError(f"the {what}'s 'time' is {time_!r}, not a time in seconds since 1970")
        box = data.get("chart_box")
        cost = data.get("detection_cost")
        return cls(id=_need(data, "id", str, what, "", required=False) or _legacy_id(data),
                   method=_need(data, "method", str, what), matrix=rows, time=time_, degree=degree,
                   delta_e2000=_need(data, "delta_e2000", dict, what, {}, required=False),
                   targets=_need(data, "targets", str, what, "", required=False),
                   settings=_need(data, "settings", dict, what, {}, required=False),
                   chart_box=None if box is None else tuple(_floats(c, 2, "chart_box", what) for c in box),
                   detection_cost=float(cost) if _real(cost) else None,
                   time_iso=_need(data, "time_iso", str, what, "", required=False))


def _legacy_id(data: dict) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:12]


# --- capture -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CaptureRecord:
    """What the rig wrote beside a capture's image, before anything processed it."""

    id: str
    image: str                                  # the image's file name, beside this record
    image_sha256: str
    captured: str                               # local time, %Y-%m-%dT%H:%M:%S%z
    lights: list | None = None                  # [[on, intensity], ...] per light, as the board reports
    frame_meta: dict = field(default_factory=dict)
    calibration: CalibrationProfile | None = None   # the profile it is corrected with (live or still)
    simulated: bool = False
    swatch_roi: tuple[int, int, int, int] | None = None
    source: str = "live"                        # "live" or "raw still"
    original: str | None = None                 # a still's original file name
    light_images: tuple[str, ...] = ()          # one frame per light alone, when the capture took them
    light_exposures: tuple[float, ...] = ()     # each light frame's exposure over the all-lights frame's
    schema_version: int = SCHEMA_VERSION

    KIND = "capture"

    @property
    def calibration_id(self) -> str | None:
        return None if self.calibration is None else self.calibration.id

    def to_json(self) -> dict:
        return {"kind": self.KIND, "schema_version": SCHEMA_VERSION, "id": self.id, "image": self.image,
                "image_sha256": self.image_sha256, "captured": self.captured,
                "lights": self.lights,
                "frame_meta": self.frame_meta, "calibration_id": self.calibration_id,
                "calibration": None if self.calibration is None else self.calibration.to_json(),
                "simulated": self.simulated, "swatch_roi": None if self.swatch_roi is None else list(self.swatch_roi),
                "source": self.source, "original": self.original, "light_images": list(self.light_images),
                "light_exposures": list(self.light_exposures)}

    @classmethod
    def from_json(cls, data, legacy_profile: dict | None = None) -> "CaptureRecord":
        """``legacy_profile``: a first-layout still's profile, found in its result record."""
        what = "capture record"
        _version(data, what)
        profile = data.get("calibration") or legacy_profile
        roi = data.get("swatch_roi")
        lights = data.get("lights")
        return cls(id=_need(data, "id", str, what, "", required=False),
                   image=_need(data, "image", str, what, "", required=False),
                   image_sha256=_need(data, "image_sha256", str, what, "", required=False),
                   captured=_need(data, "captured", str, what, "", required=False),
                   lights=lights if lights is None or isinstance(lights, list) else _bad(what, "lights", lights),
                   frame_meta=_need(data, "frame_meta", dict, what, {}, required=False),
                   calibration=None if profile is None else CalibrationProfile.from_json(profile),
                   simulated=bool(data.get("simulated", False)),
                   swatch_roi=None if roi is None else _roi(roi, what),
                   source=_need(data, "source", str, what, "live", required=False),
                   original=_need(data, "original", str, what, None, required=False),
                   light_images=tuple(str(n) for n in _need(data, "light_images", list, what, [], required=False)),
                   light_exposures=_floats(data.get("light_exposures") or [], None, "light_exposures", what))


def _bad(what: str, key: str, value):
    raise RecordError(f"the {what}'s {key!r} is {value!r}, not a list")


def _roi(value, what: str) -> tuple[int, int, int, int]:
    if (not isinstance(value, (list, tuple)) or len(value) != 4
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value) or value[2] <= 0 or value[3] <= 0):
        raise RecordError(f"the {what}'s 'swatch_roi' is {value!r}, not x, y, w, h whole pixels")
    return tuple(value)


# --- estimate --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RefinementRecord:
    """What refinement by synthesis did (``ran`` False: the encoder's answer stands)."""

    ran: bool = False
    sigma_a: tuple[float, float, float] | None = None     # the median pigmented fibre's sigma_a
    residual_de2000: float | None = None
    iterations: int = 0
    reachable: bool = True
    seconds: float = 0.0
    curve_seconds: float = 0.0
    curve_cached: bool = False
    target_linear_rgb: tuple[float, ...] | None = None
    rendered_linear_rgb: tuple[float, ...] | None = None
    residual_history: tuple[float, ...] = ()
    nonfinite: int = 0
    region: dict | None = None            # what was fitted and rendered (the same region)

    def to_json(self) -> dict:
        if not self.ran:
            return {"ran": False}
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        for key in ("sigma_a", "target_linear_rgb", "rendered_linear_rgb", "residual_history"):
            if out[key] is not None:
                out[key] = list(out[key])
        return out

    @classmethod
    def from_json(cls, data) -> "RefinementRecord":
        what = "refinement record"
        if not isinstance(data, dict):
            raise RecordError(f"a {what} is an object, not {type(data).__name__}")
        if not data.get("ran"):
            return cls()
        vec = {k: (None if data.get(k) is None else _floats(data[k], 3, k, what))
               for k in ("sigma_a", "target_linear_rgb", "rendered_linear_rgb")}
        check_sigma_a(vec["sigma_a"], f"the {what}'s 'sigma_a'")
        return cls(ran=True, **vec,
                   residual_de2000=_need(data, "residual_de2000", float, what, None, required=False),
                   iterations=_need(data, "iterations", int, what, 0, required=False),
                   reachable=bool(data.get("reachable", True)),
                   seconds=_need(data, "seconds", float, what, 0.0, required=False),
                   curve_seconds=_need(data, "curve_seconds", float, what, 0.0, required=False),
                   curve_cached=bool(data.get("curve_cached", False)),
                   residual_history=_floats(data.get("residual_history") or [], None, "residual_history", what),
                   nonfinite=_need(data, "nonfinite", int, what, 0, required=False),
                   region=_need(data, "region", dict, what, None, required=False))


@dataclass(frozen=True)
class SpectralReading:
    """The estimate in the spectral world, where the rig's LEDs and camera are known
    (``inference.spectral.read_spectral``): the Table 1 hair whose spectral colour, seen by the rig's
    camera under its LEDs, is the capture's, and that hair's colour under other lights.

    ``EstimateRecord.hair`` stays the RGB world's answer (what the RGB renders, the library and the
    exports use); this is the answer for colour under any light."""

    hair: HairParams
    led: str                       # the rig's LEDs: a light's name, or an SPD CSV's file name
    camera: str                    # the camera's sensitivities: a name, a CSV's file name, or "cie"
    residual: float                # the read's colour residual (CIELAB ΔE76, in the corrected space)
    under: dict = field(default_factory=dict)   # light -> CIELAB of the swatch, an observer adapted to it
    seconds: float = 0.0

    def to_json(self) -> dict:
        return {"hair": self.hair.to_dict(), "led": self.led, "camera": self.camera,
                "residual": round(self.residual, 4), "under": {k: [round(v, 3) for v in lab] for k, lab in
                                                              self.under.items()},
                "seconds": round(self.seconds, 3)}

    @classmethod
    def from_json(cls, data) -> "SpectralReading":
        what = "spectral reading"
        if not isinstance(data, dict):
            raise RecordError(f"a {what} is an object, not {type(data).__name__}")
        try:
            hair = HairParams.from_dict(_need(data, "hair", dict, what))
        except (HairParamsError, TypeError, AttributeError) as exc:
            raise RecordError(f"the {what}'s 'hair' is not Table 1 parameters: {exc}") from None
        under = _need(data, "under", dict, what, {}, required=False)
        return cls(hair=hair, led=_need(data, "led", str, what), camera=_need(data, "camera", str, what),
                   residual=_need(data, "residual", float, what),
                   under={str(k): _floats(v, 3, f"under {k}", what) for k, v in under.items()},
                   seconds=_need(data, "seconds", float, what, 0.0, required=False))


@dataclass(frozen=True)
class EstimateRecord:
    """An estimate and where it came from: parameters, warnings, intervals, refinement, provenance.

    A capture's result record is an estimate record with ``capture`` set (the image's file name) and,
    when no estimate could be made, ``blocked`` (the reasons) and ``hair`` None.
    """

    hair: HairParams | None
    warnings: tuple[EstimateWarning, ...] = ()
    uncertainty: dict = field(default_factory=dict)
    encoder: dict = field(default_factory=dict)
    refinement: RefinementRecord = field(default_factory=RefinementRecord)
    provenance: dict = field(default_factory=dict)
    capture: str | None = None
    blocked: tuple[str, ...] = ()
    swatch_roi: tuple[int, int, int, int] | None = None
    appearance: AppearanceEstimate | None = None   # shine and fibre variation; None: not read
    spectral: SpectralReading | None = None        # read in the camera's RGB; None: the rig's spectra unknown
    schema_version: int = SCHEMA_VERSION

    KIND = "estimate"

    @property
    def reliable(self) -> bool:
        """False when no estimate was made, or a warning says the input is not a swatch the encoder knows."""
        return self.hair is not None and not any(w.kind in UNRELIABLE for w in self.warnings)

    @property
    def sigma_a(self) -> tuple[float, float, float] | None:
        """The absorption that reaches the image: the refinement's, or Table 1's mapping of ``hair``."""
        if self.refinement.sigma_a is not None:
            return self.refinement.sigma_a
        if self.hair is None:
            return None
        return tuple(float(s) for s in hair_sigma_a(self.hair))

    def warning_messages(self) -> list[str]:
        return [w.message for w in self.warnings]

    def to_json(self) -> dict:
        out = {"kind": self.KIND, "schema_version": SCHEMA_VERSION}
        if self.capture is not None:
            out.update({"capture": self.capture, "blocked": list(self.blocked),
                        "swatch_roi": None if self.swatch_roi is None else list(self.swatch_roi)})
        if self.hair is not None:
            out.update({"hair": self.hair.to_dict(), "reliable": self.reliable,
                        "warnings": [w.to_json() for w in self.warnings], "uncertainty": self.uncertainty,
                        "encoder": self.encoder, "refinement": self.refinement.to_json(),
                        "provenance": self.provenance})
            if self.appearance is not None:
                out["appearance"] = self.appearance.to_json()
            if self.spectral is not None:
                out["spectral"] = self.spectral.to_json()
        return out

    @classmethod
    def from_json(cls, data) -> "EstimateRecord":
        what = "estimate record"
        _version(data, what)
        _check_kind(data, cls.KIND, what)
        hair = data.get("hair")
        if hair is not None:
            try:
                hair = HairParams.from_dict(hair)
            except (HairParamsError, TypeError, AttributeError) as exc:
                raise RecordError(f"the {what}'s 'hair' is not Table 1 parameters: {exc}") from None
        blocked = _need(data, "blocked", list, what, [], required=False)
        roi = data.get("swatch_roi")
        return cls(hair=hair, warnings=warnings_from_json(data.get("warnings"), what),
                   uncertainty=_check_uncertainty(_need(data, "uncertainty", dict, what, {}, required=False), what),
                   encoder=_need(data, "encoder", dict, what, {}, required=False),
                   refinement=RefinementRecord.from_json(data.get("refinement") or {"ran": False}),
                   provenance=_need(data, "provenance", dict, what, {}, required=False),
                   capture=_need(data, "capture", str, what, None, required=False),
                   blocked=tuple(str(b) for b in blocked),
                   swatch_roi=None if roi is None else _roi(roi, what),
                   appearance=_appearance(data.get("appearance"), what),
                   spectral=None if data.get("spectral") is None else _spectral(data["spectral"], what))


def check_sigma_a(sigma, what: str) -> None:
    """An absorption is three numbers from 0 to ``SIGMA_A_MAX``; else RecordError naming ``what``."""
    if sigma is not None and not all(0.0 <= float(s) <= SIGMA_A_MAX for s in sigma):
        raise RecordError(f"{what} {[float(s) for s in sigma]} is outside 0 to {SIGMA_A_MAX:g} per fibre radius "
                          f"(no hair absorbs a negative or such an amount); the record is damaged: estimate again")


def check_interval(low, high, what: str) -> None:
    """An interval's low end must not lie above its high end."""
    if _real(low) and _real(high) and low > high:
        raise RecordError(f"{what}'s interval is inverted (low {low} above high {high}); the record is damaged: "
                          f"estimate again")


def _check_uncertainty(uncertainty: dict, what: str) -> dict:
    """Per-parameter intervals hold low <= high."""
    params = uncertainty.get("parameters")
    for name, entry in (params.items() if isinstance(params, dict) else ()):
        if isinstance(entry, dict):
            check_interval(entry.get("low"), entry.get("high"), f"the {what}'s {name!r}")
    return uncertainty


def _check_kind(data: dict, kind: str, what: str) -> None:
    """A record of another kind (a dye record, a calibration profile) is named, not read as this one."""
    other = data.get("kind")
    if other is None and "matrix" in data and "method" in data:
        other = "calibration"
    if other is not None and other != kind:
        raise RecordError(f"this is a {str(other)[:40]!r} record, not an {what}; give the record that hairdigi "
                          f"estimate (or a capture) wrote")
    if other is None and not any(k in data for k in ("hair", "capture", "blocked")):
        raise RecordError(f"this JSON holds no 'hair', 'capture' or 'blocked': not an {what}; give the record "
                          f"that hairdigi estimate (or a capture) wrote")


def _spectral(data, what: str) -> SpectralReading:
    try:
        return SpectralReading.from_json(data)
    except RecordError as exc:
        raise RecordError(f"the {what}'s 'spectral': {exc}") from None


def _appearance(data, what: str) -> AppearanceEstimate | None:
    if data is None:
        return None
    try:
        return AppearanceEstimate.from_json(data)
    except AppearanceError as exc:
        raise RecordError(f"the {what}'s 'appearance': {exc}") from None


# --- files ---------------------------------------------------------------------------------------
def read_record(path: str | os.PathLike, cls, **kwargs):
    """Read and upgrade one record file; ``RecordError`` names the file and its problem."""
    path = Path(path)
    data = read_json(path, RecordError, f"no such {cls.KIND} record",
                     f"not a {cls.KIND} record ({{exc}})")
    try:
        return cls.from_json(data, **kwargs)
    except RecordError as exc:
        raise RecordError(f"{path}: {exc}") from None


def write_record(path: str | os.PathLike, record) -> Path:
    """Write a record atomically, in today's layout."""
    return write_json_atomic(path, record.to_json())


def record_sha256(path: str | os.PathLike) -> str:
    """The checksum a record is cited by (dye records cite the estimates they came from)."""
    return sha256_file(path, RecordError, MAX_JSON_BYTES)


def capture_profile(capture: dict | None, result: dict | None) -> dict | None:
    """The profile a capture was corrected with, from its files' dicts in either layout."""
    return (capture or {}).get("calibration") or (result or {}).get("calibration_profile")
