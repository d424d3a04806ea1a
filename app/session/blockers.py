"""Why a capture was not estimated: each reason a :class:`Blocker`, its kind and the operator's message.

A capture's result record keeps the messages (``EstimateRecord.blocked``); the kinds are for what
acts on a reason (the appearance evaluation lowers the exposure on an over-exposed swatch)."""
from __future__ import annotations

from dataclasses import dataclass

from hairdigi.render.domain.text_enum import TextEnum


class BlockerKind(TextEnum):
    """What stopped an estimate."""

    UNCALIBRATED = "uncalibrated"      # the rig has no calibration profile
    NO_CHART = "no chart"              # the chart is not found in the frame
    OVER_EXPOSED = "over-exposed"      # the swatch clips: its colour is hidden
    NO_MODEL = "no model"              # the encoder cannot be loaded
    STILL_UNCALIBRATED = "still uncalibrated"   # a RAW still's chart cannot calibrate it


@dataclass(frozen=True)
class Blocker:
    """One reason a capture was not estimated: its kind, and the message the operator reads."""

    kind: BlockerKind
    message: str


def messages(blockers: list[Blocker] | tuple[Blocker, ...]) -> tuple[str, ...]:
    """The blockers' messages, in order: what a capture's record keeps and a report prints."""
    return tuple(b.message for b in blockers)
