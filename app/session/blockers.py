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


#: How far the evaluations lower a simulated camera's exposure each time a swatch is over-exposed.
EXPOSURE_STEP_EV = 0.5


def capture_as_told(session, tries: int = 2, **capture_options):
    """``session.capture(...)``, then, as the operator is told of an over-exposed swatch, up to ``tries``
    times: lower the simulated camera's exposure by ``EXPOSURE_STEP_EV``, calibrate again, capture again.
    Returns the last result and the calibration profile in force (None where it was not recalibrated)."""
    result, profile = session.capture(**capture_options), None
    for _ in range(tries):
        if not any(b.kind is BlockerKind.OVER_EXPOSED for b in result.blocked):
            break
        session.camera.camera.exposure_ev -= EXPOSURE_STEP_EV
        profile = session.calibrate()
        result = session.capture(**capture_options)
    return result, profile
