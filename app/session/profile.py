"""A session's rig profile: what the rig declares once (its camera's sensitivities, its LEDs' SPD, how its
estimates treat the swatch's structure), kept as ``<session>/rig-profile.json`` and read by every command
that works on the session; a flag given on the command line overrides it for that command and says so.

::

    {"version": 1, "sensitivities": "/lab/camera-ssf.csv", "led": "/lab/leds-spd.csv", "structure": "family"}

Qt-free, and without the science: the standard library and ``render.domain`` only.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from hairdigi.render.domain.bounds import CAMERAS, DEFAULT_STRUCTURE, ILLUMINANTS, StructureMode
from hairdigi.render.domain.errors import HairdigiError
from hairdigi.render.domain.files import read_json, write_json_atomic

#: The profile's file name in a session folder.
PROFILE_NAME = "rig-profile.json"
#: The version this hairdigi writes and reads.
PROFILE_VERSION = 1
#: A spectrum given as a file: its path, stored absolute.
SPECTRUM_FILES = (".csv", ".txt")
#: Each field a flag can override: field -> (the flag, the words for it in a notice).
FLAGS = {"sensitivities": ("--sensor", "camera sensitivities"), "led": ("--led", "LEDs"),
         "structure": ("--structure", "structure mode")}


class ProfileError(HairdigiError, ValueError):
    """A rig profile that cannot be read: damaged, of an unknown version, or declaring an unknown spectrum."""


@dataclass(frozen=True)
class RigProfile:
    """What a rig declares once: its camera's sensitivities and its LEDs (each a name or a CSV's absolute path;
    None: undeclared), and the structure mode of its estimates."""

    sensitivities: str | None = None
    led: str | None = None
    structure: StructureMode = DEFAULT_STRUCTURE

    def __post_init__(self) -> None:
        object.__setattr__(self, "structure", StructureMode(self.structure))
        object.__setattr__(self, "sensitivities", _absolute(self.sensitivities))
        object.__setattr__(self, "led", _absolute(self.led))

    @property
    def spectral(self) -> bool:
        """Whether the rig declares its spectra (its LEDs and its camera)."""
        return self.led is not None and self.sensitivities is not None

    def to_json(self) -> dict:
        """The profile as its file holds it."""
        return {"version": PROFILE_VERSION, "sensitivities": self.sensitivities, "led": self.led,
                "structure": str(self.structure)}


def _absolute(value: str | None) -> str | None:
    """A spectrum's name as it is, a CSV's path made absolute (a profile is read from other folders)."""
    if value is None or not str(value).lower().endswith(SPECTRUM_FILES):
        return value
    return str(Path(value).expanduser().resolve())


def profile_path(session_folder: str | os.PathLike) -> Path:
    """Where a session keeps its rig profile."""
    return Path(session_folder) / PROFILE_NAME


def read_profile(session_folder: str | os.PathLike) -> RigProfile | None:
    """The session's rig profile, or None where it has none; ProfileError (one line) for a damaged file."""
    path = profile_path(session_folder)
    if not path.exists():
        return None
    fix = f"fix it, or remove it and declare the rig again with hairdigi rig --session {session_folder}"
    data = read_json(path, ProfileError, "no such rig profile", f"not valid JSON ({{exc}}); {fix}")
    if not isinstance(data, dict):
        raise ProfileError(f"{path}: a rig profile is a JSON object; {fix}")
    if data.get("version") != PROFILE_VERSION:
        raise ProfileError(f"{path}: rig profile version {data.get('version')!r}, where this hairdigi reads "
                           f"version {PROFILE_VERSION}; {fix}")
    unknown = sorted(set(data) - {"version", *FLAGS})
    if unknown:
        raise ProfileError(f"{path}: unknown field(s) {', '.join(unknown)} (a profile holds "
                           f"{', '.join(FLAGS)}); {fix}")
    problem = _field_problem(data)
    if problem is not None:
        raise ProfileError(f"{path}: {problem}; {fix}")
    return RigProfile(data.get("sensitivities"), data.get("led"), data.get("structure", str(DEFAULT_STRUCTURE)))


def _field_problem(data: dict) -> str | None:
    """What is wrong with a profile's fields, in a few words, or None."""
    sensor, led, structure = data.get("sensitivities"), data.get("led"), data.get("structure", str(DEFAULT_STRUCTURE))
    if not StructureMode.knows(structure):
        return f"structure {structure!r} is not one of {', '.join(StructureMode.names())}"
    for name, value, known in (("sensitivities", sensor, (*CAMERAS, "cie")), ("led", led, ILLUMINANTS)):
        if value is not None and (not isinstance(value, str)
                                  or not (value in known or value.lower().endswith(SPECTRUM_FILES))):
            return f"{name} {value!r} is neither one of {', '.join(known)} nor a CSV file"
    if (sensor is None) != (led is None):
        return "a rig declares its LEDs (led) and its camera (sensitivities) together: give both, or neither"
    return None


def write_profile(session_folder: str | os.PathLike, profile: RigProfile) -> Path:
    """Write the session's rig profile, atomically."""
    return write_json_atomic(profile_path(session_folder), profile.to_json())


def merged(profile: RigProfile | None, flags: dict) -> tuple[RigProfile, list[str]]:
    """The profile with the flags given on the command line (field -> value; None: not given) in its place
    for one command, and one notice line for each flag that changes what the session's profile declares."""
    base = profile or RigProfile()
    given = {field: value for field, value in flags.items() if value is not None}
    out = replace(base, **given)
    notices = []
    if profile is not None:
        for field in given:
            was, now = getattr(profile, field), getattr(out, field)
            if was != now:
                flag, words = FLAGS[field]
                notices.append(f"rig profile: {flag} {given[field]} overrides the session's {words} "
                               f"({'none declared' if was is None else was}) for this command")
    return out, notices
