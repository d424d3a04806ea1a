"""Where a rig session's files lie: the one place that knows a session folder's layout.

::

    <session>/calibration.json               the calibration profile (records.CalibrationProfile)
    <session>/captures/<id>.png|.dng|.<raw>  the capture's image (its capture record names it; its thumbnail)
    <session>/captures/<id>-light<i>.png     each light alone, when the capture took them
    <session>/captures/<id>.json             the capture record (records.CaptureRecord)
    <session>/captures/<id>.result.json      its result record (records.EstimateRecord)
    <session>/dyes/<name>.json               the dyes measured in the session (dye_record.DyeRecord)
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

#: How a capture's result record is named beside its capture record ``<id>.json``.
RESULT_SUFFIX = ".result.json"


@dataclass(frozen=True)
class SessionFolder:
    """A rig session's folder and the path of each of its files."""

    root: Path

    def __post_init__(self) -> None:
        object.__setattr__(self, "root", Path(self.root))

    @property
    def captures(self) -> Path:
        return self.root / "captures"

    @property
    def calibration(self) -> Path:
        return self.root / "calibration.json"

    @property
    def dyes(self) -> Path:
        return self.root / "dyes"

    def capture_record(self, capture_id: str) -> Path:
        return self.captures / f"{capture_id}.json"

    def result_record(self, capture_id: str) -> Path:
        return self.captures / f"{capture_id}{RESULT_SUFFIX}"

    def image(self, name: str) -> Path:
        """A capture's image (or light frame) by the file name its record gives."""
        return self.captures / name

    def result_records(self) -> list[Path]:
        """Every capture's result record, in capture order (ids are capture times)."""
        return sorted(self.captures.glob(f"*{RESULT_SUFFIX}"))

    def capture_records(self) -> list[Path]:
        """Every capture record (not result records, not hidden files), in capture order."""
        return sorted(p for p in self.captures.glob("*.json")
                      if not p.name.endswith(RESULT_SUFFIX) and not p.name.startswith("."))

    def is_session(self) -> bool:
        """Whether the folder holds a ``captures`` folder (a session's, perhaps with no capture yet)."""
        return self.captures.is_dir()

    def holds_records(self) -> bool:
        """Whether a session was written here: its calibration, or captures with their records."""
        return self.calibration.is_file() or (self.captures.is_dir() and any(self.captures.glob("*.json")))

    @classmethod
    def of_captures(cls, folder: str | os.PathLike) -> "SessionFolder | None":
        """The written session whose captures folder ``folder`` is, else None."""
        folder = Path(folder)
        session = cls(folder.parent)
        return session if folder == session.captures and session.holds_records() else None


def capture_id_of(path: str | os.PathLike) -> str:
    """The capture's id from its capture record's or result record's file name."""
    return Path(path).name.removesuffix(RESULT_SUFFIX).removesuffix(".json")


def is_result_record(path: str | os.PathLike) -> bool:
    return Path(path).name.endswith(RESULT_SUFFIX)


def capture_record_beside(result_path: str | os.PathLike) -> Path:
    """The capture record ``<id>.json`` beside a result record ``<id>.result.json``."""
    path = Path(result_path)
    return path.with_name(f"{capture_id_of(path)}.json")
