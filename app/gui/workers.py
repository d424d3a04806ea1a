"""Work off the UI thread: a cancellable task runner and the live-feed thread."""
from __future__ import annotations

import threading
import time
import traceback
from typing import Callable

from PySide6.QtCore import QObject, QRunnable, QThread, QThreadPool, Signal


class TaskSignals(QObject):
    progress = Signal(object)   # whatever the task reports (a partial result, a fraction)
    done = Signal(object)
    failed = Signal(str)
    finished = Signal()         # after done or failed, or after a cancel


class Task(QRunnable):
    """Runs ``fn(report, cancelled)`` in the global thread pool.

    ``report(x)`` emits ``progress``; ``cancelled()`` is true once :meth:`cancel` was called, and the
    function should return early then. Its return value is emitted as ``done`` unless cancelled.
    """

    def __init__(self, fn: Callable, name: str = "task") -> None:
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
            result = self.fn(self.signals.progress.emit, self._cancel.is_set)
            if not self._cancel.is_set():
                self.signals.done.emit(result)
        except Exception as exc:  # shown to the operator as a banner, never swallowed
            traceback.print_exc()
            self.signals.failed.emit(f"{self.name}: {exc}")
        finally:
            self.signals.finished.emit()


def start(task: Task, pool: QThreadPool | None = None) -> Task:
    (pool or QThreadPool.globalInstance()).start(task)
    return task


class FeedThread(QThread):
    """Reads frames from a camera as fast as ``fps`` allows and emits them; errors stop the feed."""

    frame = Signal(object)
    failed = Signal(str)

    def __init__(self, read: Callable, fps: float = 20.0) -> None:
        super().__init__()
        self.read = read
        self.period = 1.0 / fps
        self._stop = threading.Event()
        self.frames = 0

    def run(self) -> None:
        while not self._stop.is_set():
            start = time.perf_counter()
            try:
                self.frame.emit(self.read())
                self.frames += 1
            except Exception as exc:
                self.failed.emit(f"camera: {exc}")
                return
            self._stop.wait(max(0.0, self.period - (time.perf_counter() - start)))

    def stop(self) -> None:
        self._stop.set()
        self.wait(2000)
