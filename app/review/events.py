"""A tiny event primitive, free of Qt (napari's evented-model style): ``events.twin.connect(callback)``."""
from __future__ import annotations

from typing import Callable

Callback = Callable[[object], None]


class Event:
    """Callbacks called with one value, in the order they connected."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._callbacks: list[Callback] = []

    def connect(self, callback: Callback) -> Callback:
        self._callbacks.append(callback)
        return callback

    def disconnect(self, callback: Callback) -> None:
        if callback in self._callbacks:
            self._callbacks.remove(callback)

    def emit(self, value: object = None) -> None:
        for callback in list(self._callbacks):
            callback(value)


class EventGroup:
    """One :class:`Event` per name, as attributes; subclasses list their ``NAMES``."""

    NAMES: tuple[str, ...] = ()

    def __init__(self, names: tuple[str, ...] | None = None) -> None:
        for name in names or self.NAMES:
            setattr(self, name, Event(name))
