"""What every panel's model shares, free of Qt: events, one owner thread, generations, and ``apply``.

A panel's model (the review's, the Dye panel's, the Library panel's) holds its state and hands out its
slow work as :class:`hairdigi.app.models.work.Work` (a generator function: its yields are progress, its
return the result). A worker runs the work and hands each value to :meth:`PanelModel.apply` on the
model's thread, the only thread that changes the model's state; :func:`hairdigi.app.models.work.run_now`
does the same in the calling thread (tests, headless use). Each kind of work has a generation: asking
again bumps it, so the older work stops at its next pass and whatever it still hands back is dropped (a
stale result never overwrites a newer one).
"""
from __future__ import annotations

import threading
from collections import defaultdict
from typing import Callable

from hairdigi.app.models.events import EventGroup, Status
from hairdigi.app.models.work import Cancelled

__all__ = ["PanelModel"]


class PanelModel:
    """A panel's state, changed on one thread only; subclasses name their ``Events`` and ``_HANDLERS``."""

    Events: type[EventGroup] = EventGroup
    #: payload type -> handler (an unbound method); :class:`Status` is handled here
    _HANDLERS: dict[type, Callable] = {}

    def __init__(self) -> None:
        self.events = self.Events()
        self.status = ""
        self._thread = threading.get_ident()       # the one thread that changes this state
        self._generation: dict[str, int] = defaultdict(int)

    def _owner(self) -> None:
        if threading.get_ident() != self._thread:
            raise RuntimeError(f"the {type(self).__name__}'s state changes on its own thread only: hand work "
                               "results to apply() there")

    # -- generations: what makes running work stale ------------------------------------------
    def _bump(self, *kinds: str) -> int:
        """A new generation of each kind of work in ``kinds`` (their running work goes stale); the last one's."""
        for kind in kinds:
            self._generation[kind] += 1
        return self._generation[kinds[-1]]

    def _current(self, kind: str, generation: int) -> bool:
        return self._generation[kind] == generation

    def _stale(self, kind: str, generation: int) -> Cancelled:
        """For the work: has it been superseded (read from the worker's thread: one int compare)."""
        return lambda: self._generation[kind] != generation

    def stop(self) -> None:
        """Make all running work stale (the panel is closing)."""
        for kind in list(self._generation):
            self._bump(kind)

    # -- results back from work (the model's thread) --------------------------------------------
    def apply(self, payload: object) -> None:
        """Store what a work yielded or returned, and emit its event; stale results are dropped."""
        self._owner()
        if payload is None:
            return
        if isinstance(payload, Status):
            self.show_status(payload.text)
            return
        handler = self._HANDLERS.get(type(payload))
        if handler is None:
            raise TypeError(f"the {type(self).__name__} has no use for {type(payload).__name__}")
        handler(self, payload)

    def show_status(self, text: str) -> None:
        """The status line: kept as ``status`` and emitted as the ``status`` event (a str; a model whose
        event carries a :class:`Status` says so by overriding this)."""
        self.status = text
        self.events.status.emit(text)
