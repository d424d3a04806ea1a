"""The hair-colour parameters of Kips et al. 2022, Table 1, with validation and a JSON form."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import read_json, write_json_atomic

# (name, low, high) for the six normalised components, in vector order.
VECTOR_FIELDS: tuple[tuple[str, float, float], ...] = (
    ("dye_r", 0.0, 255.0),
    ("dye_g", 0.0, 255.0),
    ("dye_b", 0.0, 255.0),
    ("dye_concentration", 0.0, 1.0),
    ("melanin_concentration", 0.0, 1.0),
    ("melanin_ratio", 0.0, 1.0),
)
_LOW = np.array([f[1] for f in VECTOR_FIELDS])
_SPAN = np.array([f[2] - f[1] for f in VECTOR_FIELDS])


class HairParamsError(HairdigiError, ValueError):
    """A hair-parameter value or file is invalid; the message names the field and its range."""


@dataclass(frozen=True)
class HairParams:
    """Table 1: dye colour (0–255 each), dye concentration, melanin concentration and ratio (0–1).

    ``melanin_ratio`` is the eumelanin share of the melanin: 1 is all eumelanin (brown–black),
    0 all pheomelanin (red–blond).
    """

    dye_rgb: tuple[float, float, float] = (255.0, 255.0, 255.0)
    dye_concentration: float = 0.0
    melanin_concentration: float = 0.5
    melanin_ratio: float = 0.8

    def __post_init__(self) -> None:
        rgb = self.dye_rgb
        if isinstance(rgb, np.ndarray):
            rgb = rgb.tolist() if rgb.ndim == 1 else [rgb.tolist()]
        if not isinstance(rgb, (tuple, list)) or len(rgb) != 3:
            count = f"a list of {len(rgb)}" if isinstance(rgb, (tuple, list)) else _describe(rgb)
            raise HairParamsError(f"dye_rgb must hold 3 values, numbers [r, g, b], got {count}")
        rgb = tuple(_real(name, v) for name, v in zip(("dye_r", "dye_g", "dye_b"), rgb))
        object.__setattr__(self, "dye_rgb", rgb)
        for name, value in zip(("dye_r", "dye_g", "dye_b"), rgb):
            _check(name, value, 0.0, 255.0)
        for name in ("dye_concentration", "melanin_concentration", "melanin_ratio"):
            value = _real(name, getattr(self, name))
            object.__setattr__(self, name, value)
            _check(name, value, 0.0, 1.0)

    # --- vector form for the encoder -------------------------------------------------------
    def to_vector(self) -> np.ndarray:
        """The six parameters normalised to [0, 1], in ``VECTOR_FIELDS`` order."""
        raw = np.array([*self.dye_rgb, self.dye_concentration, self.melanin_concentration,
                        self.melanin_ratio])
        return ((raw - _LOW) / _SPAN).astype(np.float32)

    @classmethod
    def from_vector(cls, vector: np.ndarray, clamp: bool = True) -> "HairParams":
        """Inverse of :meth:`to_vector`; with ``clamp`` values outside [0, 1] are clipped first."""
        v = np.asarray(vector, dtype=float).ravel()
        if v.shape != (6,):
            raise HairParamsError(f"a hair-parameter vector has 6 values, got {v.size}")
        if not np.all(np.isfinite(v)):
            raise HairParamsError("a hair-parameter vector contains NaN or Inf")
        if clamp:
            v = np.clip(v, 0.0, 1.0)
        raw = _LOW + v * _SPAN
        return cls(tuple(raw[:3]), raw[3], raw[4], raw[5])

    # --- dict / JSON ------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        return {
            "dye_rgb": [round(v, 4) for v in self.dye_rgb],
            "dye_concentration": round(self.dye_concentration, 6),
            "melanin_concentration": round(self.melanin_concentration, 6),
            "melanin_ratio": round(self.melanin_ratio, 6),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> "HairParams":
        """Read the parameters from a dict, at its top level or under a ``"hair"`` key."""
        if not isinstance(data, dict):
            raise HairParamsError(f"hair parameters must be a JSON object, got {type(data).__name__}")
        if "hair" in data and isinstance(data["hair"], dict):
            data = data["hair"]
        required = ("dye_rgb", "dye_concentration", "melanin_concentration", "melanin_ratio")
        missing = [k for k in required if k not in data]
        if missing:
            raise HairParamsError(
                f"hair parameters are missing {', '.join(missing)}; expected keys: {', '.join(required)}")
        return cls(data["dye_rgb"], data["dye_concentration"], data["melanin_concentration"],
                   data["melanin_ratio"])


def _describe(value: Any) -> str:
    """A value's kind and text, for messages: ``the string '0.5'``, ``true``, ``a list``."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"the string {value!r}"
    if value is None:
        return "null"
    return f"{'a list' if isinstance(value, (list, tuple)) else type(value).__name__} {value!r}"[:80]


def _real(name: str, value: Any) -> float:
    """``value`` as a float when it is a real number (not a bool, a string or a list); else an error."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise HairParamsError(f"{name} must be a number, got {_describe(value)}")
    return float(value)


def _check(name: str, value: float, low: float, high: float) -> None:
    if not math.isfinite(value) or not low <= value <= high:
        raise HairParamsError(f"{name} = {value} is outside its range [{low:g}, {high:g}]")


def load_params(path: str | os.PathLike) -> HairParams:
    """Load ``HairParams`` from a JSON file; errors name the file and the problem."""
    path = Path(path)
    data = read_json(path, HairParamsError, "no such parameter file", "not valid JSON ({exc})")
    try:
        return HairParams.from_dict(data)
    except HairParamsError as exc:
        raise HairParamsError(f"{path}: {exc}") from None


def save_params(path: str | os.PathLike, params: HairParams, **provenance: Any) -> Path:
    """Save ``{"hair": {...}, **provenance}`` atomically."""
    return write_json_atomic(path, {"hair": params.to_dict(), **provenance})


def sample_params(rng: np.random.Generator) -> HairParams:
    """Draw every parameter uniformly over its Table 1 range, as the paper does."""
    return HairParams.from_vector(rng.uniform(0.0, 1.0, size=6))
