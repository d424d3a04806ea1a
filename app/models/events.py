"""Typed events, free of Qt (napari's evented-model idea): ``events.twin.connect(callback)``.

Each event names the one type it carries, and :meth:`Event.emit` refuses anything else, so what a
subscriber receives is declared in code, not in a comment. A model declares its events as an
:class:`EventGroup` (``EVENTS``: name -> payload type) beside its payloads: the review's in
``app/review/payloads.py``, the Dye and Library panels' in their ``model.py``. :class:`Status`, the one
line a work can yield for the status bar, is every model's (``PanelModel.apply`` handles it).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

__all__ = ["Callback", "Event", "EventGroup", "Status"]

Callback = Callable[[object], None]


class Event:
    """Callbacks called with one value of the event's ``payload`` type, in the order they connected."""

    def __init__(self, name: str, payload: type | tuple[type, ...] = object) -> None:
        self.name, self.payload = name, payload
        self._callbacks: list[Callback] = []

    def connect(self, callback: Callback) -> Callback:
        self._callbacks.append(callback)
        return callback

    def disconnect(self, callback: Callback) -> None:
        if callback in self._callbacks:
            self._callbacks.remove(callback)

    def emit(self, value: object) -> None:
        if not isinstance(value, self.payload):
            raise TypeError(f"the {self.name} event carries {self.payload}, not {type(value).__name__}")
        for callback in list(self._callbacks):
            callback(value)


class EventGroup:
    """One :class:`Event` per name, as attributes; subclasses declare ``EVENTS``: name -> payload type."""

    EVENTS: dict[str, type | tuple[type, ...]] = {}

    def __init__(self) -> None:
        for name, payload in self.EVENTS.items():
            setattr(self, name, Event(name, payload))


@dataclass(frozen=True)
class Status:
    """One line for the status bar: what a work is doing, or why it could not (the user's to fix)."""

    text: str
