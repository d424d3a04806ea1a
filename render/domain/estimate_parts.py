"""The typed parts of an estimate record (``records.EstimateRecord``): its stated intervals
(:class:`Uncertainty`), the encoder's own answer (:class:`EncoderReading`), where it came from
(:class:`Provenance`) and what its refinement fitted (:class:`Region`).

Each is a frozen dataclass with ``to_json()`` and ``from_json(data)`` whose JSON is the dict these
parts were written as before they were typed: a field that is None is left out (``Provenance``
keeps the keys its writers always wrote, null or not), so old records load and new ones read alike.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

from hairdigi.render.domain.params import HairParams, HairParamsError
from hairdigi.render.domain.record_fields import RecordError, check_interval, floats, need, real
from hairdigi.render.domain.rig_geometry import CameraPose, GeometryError, RigRegion
from hairdigi.render.domain.bounds import StructureMode, SwatchModel
from hairdigi.render.domain.text_enum import TextEnum, text_of


def _parsed(enum: type[TextEnum], value):
    """``value`` as a member of ``enum`` where it names one; None, or a name this hairdigi does not know (a
    newer record's), as it is."""
    return enum(value) if value is not None and enum.knows(value) else value


def _object(data, what: str) -> dict:
    if not isinstance(data, dict):
        raise RecordError(f"the {what} is an object, not {type(data).__name__}")
    return data


def _hair(data, what: str) -> HairParams:
    try:
        return HairParams.from_dict(need(data, "hair", dict, what))
    except (HairParamsError, TypeError, AttributeError) as exc:
        raise RecordError(f"the {what}'s 'hair' is not Table 1 parameters: {exc}") from None


def _pose(value, key: str, what: str) -> CameraPose:
    """A camera pose from its dict (``polar_deg``, ``azimuth_deg``, ``distance``) or 3-list."""
    try:
        if isinstance(value, dict):
            return CameraPose(*(need(value, k, float, f"{what}'s {key!r}") for k in ("polar_deg", "azimuth_deg",
                                                                                      "distance")))
        return CameraPose(*floats(value, 3, key, what))
    except GeometryError as exc:
        raise RecordError(f"the {what}'s {key!r} is not a camera pose: {exc}") from None


def _rig_region(data: dict, what: str) -> RigRegion:
    """A rig frame's region from ``RigRegion``'s keys (``frame_size``, ``roi``, ``pose``, ``target``,
    ``half_width``)."""
    size, roi = floats(data.get("frame_size"), 2, "frame_size", what), floats(data.get("roi"), 4, "roi", what)
    if not all(v == int(v) for v in size + roi):
        raise RecordError(f"the {what}'s 'frame_size' and 'roi' are {size} and {roi}, not whole pixels")
    try:
        return RigRegion(tuple(int(v) for v in size), tuple(int(v) for v in roi),
                         _pose(need(data, "pose", list, what), "pose", what),
                         floats(need(data, "target", list, what), 3, "target", what),
                         need(data, "half_width", float, what))
    except GeometryError as exc:
        raise RecordError(f"the {what}'s 'roi' is not a rig frame's region: {exc}") from None


def _compact(out: dict) -> dict:
    return {k: v for k, v in out.items() if v is not None}


# --- intervals -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ParameterInterval:
    """One Table 1 parameter's measured 68% interval (``inference.uncertainty.intervals``)."""

    value: float
    low: float
    high: float
    half_width: float
    determined: bool = True      # False: the interval spans most of the parameter's range

    def to_json(self) -> dict:
        return {"value": self.value, "low": self.low, "high": self.high, "half_width": self.half_width,
                "determined": self.determined}

    @classmethod
    def from_json(cls, data, name: str) -> "ParameterInterval":
        what = f"interval of {name!r}"
        _object(data, what)
        low, high = need(data, "low", float, what), need(data, "high", float, what)
        check_interval(low, high, f"the {name!r}")
        return cls(value=need(data, "value", float, what), low=low, high=high,
                   half_width=need(data, "half_width", float, what), determined=bool(data.get("determined", True)))


@dataclass(frozen=True)
class StructureInterval:
    """The colour interval swatches of other structures measured for how the structure was treated
    (``inference.structure.with_structure``)."""

    mode: str                    # "assumed", "family" or "read"
    rendered: str | None         # the swatch structure the refinement rendered
    mean_colour_de2000_p68: float
    mean_colour_de2000_p95: float
    source: str = ""

    def __post_init__(self) -> None:   # parsed once: a member given in the process and its text read back are one
        object.__setattr__(self, "mode", _parsed(StructureMode, self.mode))
        object.__setattr__(self, "rendered", _parsed(SwatchModel, self.rendered))

    def to_json(self) -> dict:
        return {"mode": text_of(self.mode), "rendered": text_of(self.rendered), "mean_colour_de2000_p68": self.mean_colour_de2000_p68,
                "mean_colour_de2000_p95": self.mean_colour_de2000_p95, "source": self.source}

    @classmethod
    def from_json(cls, data) -> "StructureInterval":
        what = "uncertainty's 'structure'"
        _object(data, what)
        return cls(mode=need(data, "mode", str, what), rendered=need(data, "rendered", str, what, None, required=False),
                   mean_colour_de2000_p68=need(data, "mean_colour_de2000_p68", float, what),
                   mean_colour_de2000_p95=need(data, "mean_colour_de2000_p95", float, what),
                   source=need(data, "source", str, what, "", required=False))


@dataclass(frozen=True)
class SpectralInterval:
    """The spectral world's colour interval for the rig's camera (``inference.spectral_reading.with_spectral``)."""

    camera: str                  # the camera's name, or "unknown" where the rig declares none
    answer: str                  # "camera": the spectral reading's; "rgb": the record's own colour
    holds_for: str               # what the interval was measured on
    mean_colour_de2000_p68: float
    mean_colour_de2000_p95: float
    source: str = ""

    def to_json(self) -> dict:
        return {"camera": self.camera, "answer": self.answer, "holds_for": self.holds_for,
                "mean_colour_de2000_p68": self.mean_colour_de2000_p68,
                "mean_colour_de2000_p95": self.mean_colour_de2000_p95, "source": self.source}

    @classmethod
    def from_json(cls, data) -> "SpectralInterval":
        what = "uncertainty's 'spectral'"
        _object(data, what)
        return cls(camera=need(data, "camera", str, what), answer=need(data, "answer", str, what),
                   holds_for=need(data, "holds_for", str, what),
                   mean_colour_de2000_p68=need(data, "mean_colour_de2000_p68", float, what),
                   mean_colour_de2000_p95=need(data, "mean_colour_de2000_p95", float, what),
                   source=need(data, "source", str, what, "", required=False))


@dataclass(frozen=True)
class Uncertainty:
    """An estimate's stated intervals: each parameter's, and the mean colour's ΔE2000 at 68% and 95%
    with where that figure was measured; a dye prediction's ``sigma_a`` interval; or, with no interval
    table shipped, a ``note`` saying so beside the parameters' ``values``."""

    coverage: float | None = None
    method: str | None = None
    parameters: dict[str, ParameterInterval] = field(default_factory=dict)
    mean_colour_de2000_p68: float | None = None
    mean_colour_de2000_p95: float | None = None
    mean_colour_source: str | None = None
    structure: StructureInterval | None = None
    spectral: SpectralInterval | None = None
    sigma_a_low: tuple[float, float, float] | None = None     # a dye prediction's 68% sigma_a interval
    sigma_a_high: tuple[float, float, float] | None = None
    note: str | None = None
    values: HairParams | None = None

    def to_json(self) -> dict:
        return _compact({
            "note": self.note, "values": None if self.values is None else self.values.to_dict(),
            "coverage": self.coverage, "method": self.method,
            "parameters": {k: v.to_json() for k, v in self.parameters.items()} if self.parameters else None,
            "sigma_a_low": None if self.sigma_a_low is None else list(self.sigma_a_low),
            "sigma_a_high": None if self.sigma_a_high is None else list(self.sigma_a_high),
            "mean_colour_de2000_p68": self.mean_colour_de2000_p68, "mean_colour_de2000_p95": self.mean_colour_de2000_p95,
            "mean_colour_source": self.mean_colour_source,
            "structure": None if self.structure is None else self.structure.to_json(),
            "spectral": None if self.spectral is None else self.spectral.to_json()})

    @classmethod
    def from_json(cls, data) -> "Uncertainty":
        what = "uncertainty"
        _object(data, what)
        params = need(data, "parameters", dict, what, {}, required=False)
        sigma = {k: None if data.get(k) is None else floats(data[k], 3, k, what) for k in ("sigma_a_low", "sigma_a_high")}
        return cls(coverage=need(data, "coverage", float, what, None, required=False),
                   method=need(data, "method", str, what, None, required=False),
                   parameters={str(k): ParameterInterval.from_json(v, k) for k, v in params.items()},
                   mean_colour_de2000_p68=need(data, "mean_colour_de2000_p68", float, what, None, required=False),
                   mean_colour_de2000_p95=need(data, "mean_colour_de2000_p95", float, what, None, required=False),
                   mean_colour_source=need(data, "mean_colour_source", str, what, None, required=False),
                   structure=None if data.get("structure") is None else StructureInterval.from_json(data["structure"]),
                   spectral=None if data.get("spectral") is None else SpectralInterval.from_json(data["spectral"]),
                   **sigma, note=need(data, "note", str, what, None, required=False),
                   values=None if data.get("values") is None else _hair({"hair": data["values"]}, "uncertainty's values"))


# --- the encoder's answer ----------------------------------------------------------------------------
@dataclass(frozen=True)
class EncoderReading:
    """The encoder's answer before refinement: its parameters, those that pressed against its range's
    edge, and each parameter's spread over the input's 8 flips and turns (normalised 0-1)."""

    hair: HairParams
    at_range_edge: tuple[str, ...] = ()
    view_spread: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"hair": self.hair.to_dict(), "at_range_edge": list(self.at_range_edge),
                "view_spread": dict(self.view_spread)}

    @classmethod
    def from_json(cls, data) -> "EncoderReading":
        what = "encoder reading"
        _object(data, what)
        spread = need(data, "view_spread", dict, what, {}, required=False)
        return cls(hair=_hair(data, what),
                   at_range_edge=tuple(str(n) for n in need(data, "at_range_edge", list, what, [], required=False)),
                   view_spread={str(k): need(spread, k, float, f"{what}'s 'view_spread'") for k in spread})


# --- provenance ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Provenance:
    """Where an estimate came from: hairdigi and its encoder, the image, the camera and view, the
    calibration it was corrected with, the crop's texture statistics and the time taken; for a dye
    prediction, the dye and base it was made of (``prediction``)."""

    hairdigi_version: str = ""
    time: str = ""                          # local time, %Y-%m-%dT%H:%M:%S%z
    model: dict | None = None               # the encoder file: {"path", "sha256", "input_size"}
    roi: tuple[int, int, int, int] | None = None   # the encoder's crop, x, y, w, h pixels
    camera: CameraPose | None = None        # the view's camera pose
    view: RigRegion | str | None = None     # the rig frame's region fitted, or "crop" (an all-hair crop)
    encoder_ms: float | None = None
    seconds: float | None = None
    calibration: dict | None = None         # {"id", "method", "delta_e2000_after", "path"?}; None: not corrected
    domain: dict | None = None              # the crop's texture statistics (inference.domain_checks.DomainStats)
    image: str | None = None
    image_sha256: str | None = None
    prediction: dict | None = None          # a dye prediction's dye, base, dose and lift (inference.dye.apply)
    extra: dict = field(default_factory=dict)   # what a caller of inference.estimate.record added by name

    @property
    def calibration_id(self) -> str | None:
        return (self.calibration or {}).get("id")

    @property
    def model_sha256(self) -> str:
        return str((self.model or {}).get("sha256", ""))

    def to_json(self) -> dict:
        out = _compact({
            "hairdigi_version": self.hairdigi_version or None, "model": self.model, "time": self.time or None,
            "roi": None if self.roi is None else list(self.roi),
            "camera": None if self.camera is None else asdict(self.camera),
            "view": self.view.to_dict() if isinstance(self.view, RigRegion) else self.view,
            "encoder_ms": self.encoder_ms, "seconds": self.seconds, "calibration": self.calibration,
            "domain": self.domain, "image": self.image, "image_sha256": self.image_sha256,
            "prediction": self.prediction})
        # the keys each writer always wrote, null or not: an estimate's crop and calibration, a prediction's camera
        always = (("roi", "calibration") if self.model is not None else ()) + (
            ("calibration", "camera") if self.prediction is not None else ())
        out.update({k: None for k in always if k not in out})
        return {**out, **self.extra}

    @classmethod
    def from_json(cls, data) -> "Provenance":
        what = "provenance"
        _object(data, what)
        roi, camera, view = data.get("roi"), data.get("camera"), data.get("view")
        if roi is not None and not (isinstance(roi, list) and len(roi) == 4
                                    and all(isinstance(v, int) and not isinstance(v, bool) for v in roi)):
            raise RecordError(f"the {what}'s 'roi' is {roi!r}, not x, y, w, h whole pixels")
        known = {f for f in cls.__dataclass_fields__ if f != "extra"}
        return cls(hairdigi_version=need(data, "hairdigi_version", str, what, "", required=False),
                   time=need(data, "time", str, what, "", required=False),
                   model=need(data, "model", dict, what, None, required=False),
                   roi=None if roi is None else tuple(roi),
                   camera=None if camera is None else _pose(camera, "camera", what),
                   view=view if view is None or isinstance(view, str) else _rig_region(_object(view, "provenance's "
                                                                                                     "'view'"), what),
                   encoder_ms=need(data, "encoder_ms", float, what, None, required=False),
                   seconds=need(data, "seconds", float, what, None, required=False),
                   calibration=need(data, "calibration", dict, what, None, required=False),
                   domain=need(data, "domain", dict, what, None, required=False),
                   image=need(data, "image", str, what, None, required=False),
                   image_sha256=need(data, "image_sha256", str, what, None, required=False),
                   prediction=need(data, "prediction", dict, what, None, required=False),
                   extra={k: v for k, v in data.items() if k not in known})


# --- the refinement's region ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Region:
    """What a refinement fitted and rendered (the same region): a rig frame's region, or the camera
    pose of an all-hair crop; the swatch structure rendered, and how a structure was mapped."""

    rig: RigRegion | None = None            # a rig frame's region, fitted and rendered exactly
    crop_pose: CameraPose | None = None     # or an all-hair crop's camera
    swatch_model: str | None = None         # the swatch structure rendered (render.renderer.SWATCH_MODELS)
    structure: str | None = None            # the structure mapping applied after (inference.structure)
    source: str | None = None               # what stands in for a fit and render (a dye prediction's)
    members: dict | None = None             # the family members the structure map averaged: member -> weight
    #: member -> ΔE2000 of its colour of the mapped answer from the members' mean (the capture's colour): the
    #: error the answer has were the swatch that member (``inference.structure.toward_family``)
    spreads: dict | None = None

    def __post_init__(self) -> None:   # parsed once: a member given in the process and its text read back are one
        object.__setattr__(self, "swatch_model", _parsed(SwatchModel, self.swatch_model))

    @property
    def spread(self) -> float | None:
        """The largest of ``spreads``: how far the answer may be off were the swatch any member (None: no map)."""
        return max(self.spreads.values()) if self.spreads else None

    def to_json(self) -> dict:
        out = self.rig.to_dict() if self.rig is not None else {}
        if self.crop_pose is not None:
            out["crop_pose"] = asdict(self.crop_pose)
        return {**out, **_compact({"swatch_model": text_of(self.swatch_model), "structure": self.structure,
                                   "source": self.source, "members": self.members, "spreads": self.spreads})}

    @classmethod
    def from_json(cls, data) -> "Region":
        what = "refinement's region"
        _object(data, what)
        pose = data.get("crop_pose")
        return cls(rig=_rig_region(data, what) if data.get("roi") is not None else None,
                   crop_pose=None if pose is None else _pose(pose, "crop_pose", what),
                   swatch_model=need(data, "swatch_model", str, what, None, required=False),
                   structure=need(data, "structure", str, what, None, required=False),
                   source=need(data, "source", str, what, None, required=False),
                   members=_members(data.get("members"), what),
                   spreads=_members(data.get("spreads"), what, "spreads", "ΔE2000 values >= 0", 0.0))


def _members(data, what: str, key: str = "members", values: str = "weights > 0", floor: float | None = None
             ) -> dict | None:
    """A region's ``members`` (family member -> weight, a number > 0) or ``spreads`` (member -> ΔE2000 >= 0), or None."""
    if data is None:
        return None
    ok = (lambda v: v > 0) if floor is None else (lambda v: v >= floor)   # noqa: E731
    if not isinstance(data, dict) or not all(isinstance(k, str) and real(v) and ok(v) for k, v in data.items()):
        raise RecordError(f"the {what}'s '{key}' must map member names to {values}, got {data!r}")
    return {k: float(v) for k, v in data.items()}
