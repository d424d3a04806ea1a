"""The typed records that cross layers on disk: a capture, a calibration profile, an estimate.

Each record is a frozen dataclass with ``to_json()`` (a plain dict for ``json.dump``) and
``from_json(data)`` (checks the fields, upgrades older layouts, raises :class:`RecordError` naming
the file's problem). ``SCHEMA_VERSION`` is written into every record; a file without it is a record
of the first layout (hairdigi 0.1.0, before these types) and is upgraded on read. :func:`read_record`
is the one reader of record files. An estimate's parts (its intervals, encoder reading, provenance
and refinement region) are typed in ``estimate_parts``; the field checks and :class:`RecordError` live
in ``record_fields``.

Where a capture keeps its calibration profile is decided here, once: in the capture record
(``CaptureRecord.calibration``), for live frames and RAW stills alike. Files of the first layout
kept a still's profile in its result record (``calibration_profile``); :func:`capture_profile` reads
both.

numpy and the standard library only: ``hardware``, ``inference`` and ``app`` all read these.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field, fields
from pathlib import Path

from hairdigi.render.domain.absorption import hair_sigma_a
from hairdigi.render.domain.appearance import AppearanceError, AppearanceEstimate
from hairdigi.render.domain.estimate_parts import EncoderReading, Provenance, Region, Uncertainty
from hairdigi.render.domain.files import MAX_JSON_BYTES, read_json, sha256_file, write_json_atomic
from hairdigi.render.domain.params import HairParams, HairParamsError
from hairdigi.render.domain.record_fields import RecordError, check_sigma_a, floats, need, real
from hairdigi.render.domain.session_folder import SessionFolder
from hairdigi.render.domain.text_enum import TextEnum

#: The layout written today. 1: hairdigi 0.1.0's dicts (no ``schema_version``); 2: the typed records.
SCHEMA_VERSION = 2


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


# --- warnings ----------------------------------------------------------------------------------
class WarningKind(TextEnum):
    """What a warning is about. Kinds in :data:`UNRELIABLE` make an estimate unreliable."""

    OUT_OF_DOMAIN = "out_of_domain"          # not a swatch the encoder knows
    UNREACHABLE = "unreachable"              # no Table 1 hair renders this colour
    RANGE_EDGE = "range_edge"                # the encoder pressed against its range
    CALIBRATION = "calibration"              # stale, mismatched or ill-fitting calibration
    NONFINITE = "nonfinite"                  # the path tracer returned NaN or Inf samples
    INTERVAL = "interval"                    # the colour is outside what the record's interval promises
    APPEARANCE = "appearance"                # shine or fibre variation not measured, or measured poorly
    STRUCTURE = "structure"                  # the single-light frames fit no swatch structure hairdigi draws
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
        return cls(kind, need(data, "message", str, "warning"))


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
    patches: tuple | None = None      # (24, 3) the chart's measured linear patch means, before correction

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
                "detection_cost": self.detection_cost,
                "patches": None if self.patches is None else [list(p) for p in self.patches]}

    @classmethod
    def from_json(cls, data) -> "CalibrationProfile":
        what = "calibration profile"
        _version(data, what)
        matrix = data.get("matrix")
        if not (isinstance(matrix, list) and len(matrix) == 3 and all(isinstance(r, list) for r in matrix)
                and len({len(r) for r in matrix}) == 1):
            raise RecordError(f"the {what}'s 'matrix' is not 3 rows of finite numbers")
        rows = tuple(floats(r, None, "matrix", what) for r in matrix)
        degree = need(data, "degree", int, what, 1, required=False)
        if not 1 <= degree <= 4:
            raise RecordError(f"the {what}'s 'degree' is {degree!r}, not a whole number from 1 to 4")
        time_ = need(data, "time", float, what)
        if time_ <= 0:
            raise RecordError(f"the {what}'s 'time' is {time_!r}, not a time in seconds since 1970")
        box = data.get("chart_box")
        cost = data.get("detection_cost")
        patches = data.get("patches")
        if patches is not None and not (isinstance(patches, list) and len(patches) == 24):
            raise RecordError(f"the {what}'s 'patches' is not the chart's 24 measured patches "
                              f"(calibrate again to record them)")
        return cls(id=need(data, "id", str, what, "", required=False) or _legacy_id(data),
                   method=need(data, "method", str, what), matrix=rows, time=time_, degree=degree,
                   delta_e2000=need(data, "delta_e2000", dict, what, {}, required=False),
                   targets=need(data, "targets", str, what, "", required=False),
                   settings=need(data, "settings", dict, what, {}, required=False),
                   chart_box=None if box is None else tuple(floats(c, 2, "chart_box", what) for c in box),
                   detection_cost=float(cost) if real(cost) else None,
                   time_iso=need(data, "time_iso", str, what, "", required=False),
                   patches=None if patches is None else tuple(floats(p, 3, "patches", what) for p in patches))


def _legacy_id(data: dict) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:12]


# --- capture -------------------------------------------------------------------------------------
class CaptureSource(TextEnum):
    """How a capture was taken: a frame of the bench camera's feed, or a RAW still imported."""

    LIVE = "live"
    RAW_STILL = "raw still"


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
    source: CaptureSource = CaptureSource.LIVE
    original: str | None = None                 # a still's original file name
    light_images: tuple[str, ...] = ()          # one frame per light alone, when the capture took them
    light_exposures: tuple[float, ...] = ()     # each light frame's exposure over the all-lights frame's
    schema_version: int = SCHEMA_VERSION

    KIND = "capture"

    def __post_init__(self) -> None:
        object.__setattr__(self, "source", CaptureSource(self.source))   # given as its text too

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
        return cls(id=need(data, "id", str, what, "", required=False),
                   image=need(data, "image", str, what, "", required=False),
                   image_sha256=need(data, "image_sha256", str, what, "", required=False),
                   captured=need(data, "captured", str, what, "", required=False),
                   lights=lights if lights is None or isinstance(lights, list) else _bad(what, "lights", lights),
                   frame_meta=need(data, "frame_meta", dict, what, {}, required=False),
                   calibration=None if profile is None else CalibrationProfile.from_json(profile),
                   simulated=bool(data.get("simulated", False)),
                   swatch_roi=None if roi is None else _roi(roi, what),
                   source=_source(need(data, "source", str, what, "live", required=False), what),
                   original=need(data, "original", str, what, None, required=False),
                   light_images=tuple(str(n) for n in need(data, "light_images", list, what, [], required=False)),
                   light_exposures=floats(data.get("light_exposures") or [], None, "light_exposures", what))


def _bad(what: str, key: str, value):
    raise RecordError(f"the {what}'s {key!r} is {value!r}, not a list")


def _source(value: str, what: str) -> CaptureSource:
    if not CaptureSource.knows(value):
        raise RecordError(f"the {what}'s 'source' is {value!r}, not one of {', '.join(CaptureSource.names())}")
    return CaptureSource(value)


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
    region: Region | None = None          # what was fitted and rendered (the same region)
    #: the sigma_a that renders the capture on the region's structure where ``sigma_a`` was mapped from it to
    #: another structure's (the family's mean, ``inference.structure.toward_family``): what the twin renders
    fitted_sigma_a: tuple[float, float, float] | None = None

    def to_json(self) -> dict:
        if not self.ran:
            return {"ran": False}
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        for key in ("sigma_a", "target_linear_rgb", "rendered_linear_rgb", "residual_history", "fitted_sigma_a"):
            if out[key] is not None:
                out[key] = list(out[key])
        if out["fitted_sigma_a"] is None:
            del out["fitted_sigma_a"]
        out["region"] = None if self.region is None else self.region.to_json()
        return out

    @classmethod
    def from_json(cls, data) -> "RefinementRecord":
        what = "refinement record"
        if not isinstance(data, dict):
            raise RecordError(f"a {what} is an object, not {type(data).__name__}")
        if not data.get("ran"):
            return cls()
        vec = {k: (None if data.get(k) is None else floats(data[k], 3, k, what))
               for k in ("sigma_a", "target_linear_rgb", "rendered_linear_rgb", "fitted_sigma_a")}
        check_sigma_a(vec["sigma_a"], f"the {what}'s 'sigma_a'")
        check_sigma_a(vec["fitted_sigma_a"], f"the {what}'s 'fitted_sigma_a'")
        return cls(ran=True, **vec,
                   residual_de2000=need(data, "residual_de2000", float, what, None, required=False),
                   iterations=need(data, "iterations", int, what, 0, required=False),
                   reachable=bool(data.get("reachable", True)),
                   seconds=need(data, "seconds", float, what, 0.0, required=False),
                   curve_seconds=need(data, "curve_seconds", float, what, 0.0, required=False),
                   curve_cached=bool(data.get("curve_cached", False)),
                   residual_history=floats(data.get("residual_history") or [], None, "residual_history", what),
                   nonfinite=need(data, "nonfinite", int, what, 0, required=False),
                   region=None if data.get("region") is None else _part(Region, data["region"], what, "region"))


@dataclass(frozen=True)
class SpectralReading:
    """The estimate in the spectral world, where the rig's LEDs and camera are known
    (``inference.spectral_reading.read_spectral``): the Table 1 hair whose spectral colour, seen by the rig's
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
            hair = HairParams.from_dict(need(data, "hair", dict, what))
        except (HairParamsError, TypeError, AttributeError) as exc:
            raise RecordError(f"the {what}'s 'hair' is not Table 1 parameters: {exc}") from None
        under = need(data, "under", dict, what, {}, required=False)
        return cls(hair=hair, led=need(data, "led", str, what), camera=need(data, "camera", str, what),
                   residual=need(data, "residual", float, what),
                   under={str(k): floats(v, 3, f"under {k}", what) for k, v in under.items()},
                   seconds=need(data, "seconds", float, what, 0.0, required=False))


@dataclass(frozen=True)
class InstrumentReading:
    """The swatch's CIELAB as a lab's colour instrument reads it (``inference.instrument_reading``): a named
    geometry (``render.instrument_geometry.GEOMETRIES``), observer and illuminant, over an aperture on the
    swatch's centre, with its interval (ΔE2000, 68% and 95%) and how it was obtained."""

    geometry: str                   # "d/8 SCI", "d/8 SCE", "45/0"
    lab: tuple[float, float, float]
    observer: str = "10"            # "10" (CIE 1964) or "2" (CIE 1931)
    illuminant: str = "D65"
    aperture_mm: float = 8.0
    p68: float | None = None        # ΔE2000 interval, where measured
    p95: float | None = None
    spread: float = 0.0             # ΔE2000: how far the family members' readings lie from their mean, at most
    method: str = ""

    def to_json(self) -> dict:
        return {"geometry": self.geometry, "observer": self.observer, "illuminant": self.illuminant,
                "aperture_mm": self.aperture_mm, "lab": [round(float(v), 3) for v in self.lab],
                "de2000_p68": self.p68, "de2000_p95": self.p95, "spread": round(self.spread, 3),
                "method": self.method}

    @classmethod
    def from_json(cls, data) -> "InstrumentReading":
        what = "instrument reading"
        if not isinstance(data, dict):
            raise RecordError(f"an {what} is an object, not {type(data).__name__}")
        return cls(geometry=need(data, "geometry", str, what), lab=floats(need(data, "lab", list, what), 3, "lab", what),
                   observer=need(data, "observer", str, what, "10", required=False),
                   illuminant=need(data, "illuminant", str, what, "D65", required=False),
                   aperture_mm=need(data, "aperture_mm", float, what, 8.0, required=False),
                   p68=need(data, "de2000_p68", float, what, None, required=False),
                   p95=need(data, "de2000_p95", float, what, None, required=False),
                   spread=need(data, "spread", float, what, 0.0, required=False),
                   method=need(data, "method", str, what, "", required=False))


@dataclass(frozen=True)
class EstimateRecord:
    """An estimate and where it came from: parameters, warnings, intervals, refinement, provenance.

    A capture's result record is an estimate record with ``capture`` set (the image's file name) and,
    when no estimate could be made, ``blocked`` (the reasons) and ``hair`` None.
    """

    hair: HairParams | None
    warnings: tuple[EstimateWarning, ...] = ()
    uncertainty: Uncertainty = field(default_factory=Uncertainty)
    encoder: EncoderReading | None = None          # None: no encoder ran (a dye prediction)
    refinement: RefinementRecord = field(default_factory=RefinementRecord)
    provenance: Provenance = field(default_factory=Provenance)
    capture: str | None = None
    blocked: tuple[str, ...] = ()
    swatch_roi: tuple[int, int, int, int] | None = None
    appearance: AppearanceEstimate | None = None   # shine and fibre variation; None: not read
    spectral: SpectralReading | None = None        # read in the camera's RGB; None: the rig's spectra unknown
    instrument: tuple[InstrumentReading, ...] = ()  # what a lab's colour instrument reads of the swatch
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
                        "warnings": [w.to_json() for w in self.warnings], "uncertainty": self.uncertainty.to_json(),
                        "encoder": {} if self.encoder is None else self.encoder.to_json(),
                        "refinement": self.refinement.to_json(), "provenance": self.provenance.to_json()})
            if self.appearance is not None:
                out["appearance"] = self.appearance.to_json()
            if self.spectral is not None:
                out["spectral"] = self.spectral.to_json()
            if self.instrument:
                out["instrument"] = [r.to_json() for r in self.instrument]
        return out

    def instrument_reading(self, geometry: str) -> InstrumentReading | None:
        """The record's reading in ``geometry`` (its name), or None."""
        return next((r for r in self.instrument if r.geometry == geometry), None)

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
        blocked = need(data, "blocked", list, what, [], required=False)
        roi = data.get("swatch_roi")
        return cls(hair=hair, warnings=warnings_from_json(data.get("warnings"), what),
                   uncertainty=_part(Uncertainty, data.get("uncertainty") or {}, what, "uncertainty"),
                   encoder=_part(EncoderReading, data["encoder"], what, "encoder") if data.get("encoder") else None,
                   refinement=RefinementRecord.from_json(data.get("refinement") or {"ran": False}),
                   provenance=_part(Provenance, data.get("provenance") or {}, what, "provenance"),
                   capture=need(data, "capture", str, what, None, required=False),
                   blocked=tuple(str(b) for b in blocked),
                   swatch_roi=None if roi is None else _roi(roi, what),
                   appearance=_appearance(data.get("appearance"), what),
                   spectral=None if data.get("spectral") is None else _spectral(data["spectral"], what),
                   instrument=_instrument(data.get("instrument"), what))


def _part(cls, data, what: str, key: str):
    """``cls.from_json(data)``, its RecordError prefixed with where the part sits."""
    try:
        return cls.from_json(data)
    except RecordError as exc:
        raise RecordError(f"the {what}'s {key!r}: {exc}") from None


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


def _instrument(data, what: str) -> tuple[InstrumentReading, ...]:
    if data is None:
        return ()
    if not isinstance(data, list):
        raise RecordError(f"the {what}'s 'instrument' is a list of readings, not {type(data).__name__}")
    try:
        return tuple(InstrumentReading.from_json(item) for item in data)
    except RecordError as exc:
        raise RecordError(f"the {what}'s 'instrument': {exc}") from None


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


def read_swatch_record(path: str | os.PathLike) -> CaptureRecord | EstimateRecord:
    """The record a library swatch points at: a capture's result record, its capture record where no
    result was written, or a lone estimate record; told apart by its ``kind`` (or, in the first layout,
    by the capture record's ``image_sha256``)."""
    data = read_json(Path(path), RecordError, "no such record", "not a record ({exc})")
    capture = isinstance(data, dict) and (data.get("kind") == CaptureRecord.KIND
                                          or ("kind" not in data and "image_sha256" in data))
    try:
        return (CaptureRecord if capture else EstimateRecord).from_json(data)
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


@dataclass(frozen=True)
class SessionCapture:
    """A session capture's records as read back; a file that could not be read is None here and named
    in ``problems`` (one line each), so one bad file hides nothing else."""

    id: str
    capture: CaptureRecord | None                 # None: no capture record, or unreadable
    result: EstimateRecord | None                 # None: no result written, or unreadable
    profile: CalibrationProfile | None            # the profile it was corrected with (either layout)
    problems: tuple[str, ...] = ()
    result_written: bool = False                  # a result record file exists (readable or not)


def read_session_capture(folder: SessionFolder, capture_id: str) -> SessionCapture:
    """A capture's record and its result record from a session folder. A first-layout capture record
    without its own ``id`` or ``image`` takes the capture's id and ``<id>.png``; a first-layout still's
    profile, kept in its result record, is read into its capture record (or stands alone when the
    capture record cannot be read)."""
    problems = []
    result_path, meta_path = folder.result_record(capture_id), folder.capture_record(capture_id)
    data, result = None, None
    if result_path.exists():
        try:
            data = read_json(result_path, RecordError, "missing", "not a result record ({exc})")
            result = EstimateRecord.from_json(data)
        except RecordError as exc:
            problems.append(f"{result_path.name}: {exc}")
        data = data if isinstance(data, dict) else None
    legacy, capture = capture_profile(None, data), None
    if meta_path.exists():
        try:
            meta = read_json(meta_path, RecordError, "missing", "not a capture record ({exc})")
            meta = {"id": capture_id, "image": f"{capture_id}.png", **meta} if isinstance(meta, dict) else meta
            capture = CaptureRecord.from_json(meta, legacy_profile=legacy)
        except RecordError as exc:
            problems.append(f"{meta_path}: {exc}")
    profile = capture.calibration if capture is not None else None
    if capture is None and legacy is not None:
        try:
            profile = CalibrationProfile.from_json(legacy)
        except RecordError as exc:
            problems.append(f"{result_path.name}: {exc}")
    return SessionCapture(capture_id, capture, result, profile, tuple(problems), result_path.exists())
