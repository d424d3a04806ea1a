"""Work off the UI thread: a cancellable task runner, and the live feed relayed from the frame source."""
from __future__ import annotations

import inspect
import threading
import traceback
from typing import Callable

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal


class TaskSignals(QObject):
    progress = Signal(object)   # whatever the task reports (a partial result, a fraction)
    done = Signal(object)
    failed = Signal(str)
    finished = Signal()         # after done or failed, or after a cancel


class Task(QRunnable):
    """Runs ``fn()`` in a thread pool (:data:`POOL` for the window), napari ``thread_worker`` style.

    When ``fn()`` returns a generator, each value it yields is emitted as ``progress``, and
    :meth:`cancel` stops it at its next yield (the generator is closed there); its return value is
    emitted as ``done`` unless cancelled. A plain function's return value is ``done``.
    """

    def __init__(self, fn: Callable[[], object], name: str = "task") -> None:
        super().__init__()
        self.fn = fn
        self.name = name
        self.signals = TaskSignals()
        self._cancel = threading.Event()
        self.setAutoDelete(False)

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def is_cancelled(self) -> bool:
        return self._cancel.is_set()

    def run(self) -> None:
        try:
            result = self.fn()
            if inspect.isgenerator(result):
                result = self._iterate(result)
            if not self._cancel.is_set():
                self.signals.done.emit(result)
        except Exception as exc:  # shown to the operator as a banner, never swallowed
            traceback.print_exc()
            self.signals.failed.emit(f"{self.name}: {exc}")
        finally:
            self.signals.finished.emit()

    def _iterate(self, generator) -> object:
        while True:
            if self._cancel.is_set():      # stop at a yield
                generator.close()
                return None
            try:
                value = next(generator)
            except StopIteration as stop:
                return stop.value
            if not self._cancel.is_set():
                self.signals.progress.emit(value)


#: The window's workers. More threads than cores: most tasks wait (on Mitsuba's own thread pool, the
#: camera, the serial port), and a capture, a twin and a hairstyle render must run side by side; Qt's
#: global pool has as many threads as cores (2 on the bench PCs).
POOL = QThreadPool()
POOL.setMaxThreadCount(8)


def start(task: Task, pool: QThreadPool | None = None) -> Task:
    (pool or QThreadPool.globalInstance()).start(task)
    return task


class FrameFeed(QObject):
    """The live feed: relays the session's frame source (the camera's one owner) onto the UI thread."""

    frame = Signal(object)
    failed = Signal(str)

    def __init__(self, source) -> None:
        super().__init__()
        self.source = source
        self.frames = 0
        self._unsubscribe = None

    def _relay(self, frame) -> None:
        self.frames += 1
        self.frame.emit(frame)

    def start(self) -> None:
        if self._unsubscribe is None:
            self._unsubscribe = self.source.subscribe(self._relay, lambda message: self.failed.emit(f"camera: {message}"))

    def stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None
