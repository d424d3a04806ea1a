"""Work off the UI thread: a cancellable task runner, and the live feed relayed from the frame source.

The Qt side of the worker protocol only: how a model's ``Work`` is stepped (what a cancel stops, what
``must_start`` starts) is ``app/models/work.py``'s ``drive``, which ``run_now`` shares; here it runs in a
thread pool and reports through signals.
"""
from __future__ import annotations

import inspect
import threading
import traceback
from typing import Callable

from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from hairdigi.app.models.work import Work, drive
from hairdigi.render.domain.errors import HairdigiError


class TaskSignals(QObject):
    progress = Signal(object)   # whatever the task reports (a partial result, a fraction)
    done = Signal(object)
    failed = Signal(str)
    finished = Signal()         # after done or failed, or after a cancel


class Task(QRunnable):
    """Runs ``fn()`` in a thread pool (:data:`POOL` for the window), napari ``thread_worker`` style.

    When ``fn()`` returns a generator, it is stepped by ``app/models/work.py``'s ``drive``: each value it
    yields is emitted as ``progress``, and :meth:`cancel` stops it at its next yield (the generator is
    closed there); its return value is emitted as ``done`` unless cancelled. A plain function's return
    value is ``done``. With ``must_start`` the generator takes its first step even when cancelled before a
    worker picked it up (a capture the operator asked for is taken, and its generator then runs it to its end).
    """

    def __init__(self, fn: Callable[[], object], name: str = "task", must_start: bool = False) -> None:
        super().__init__()
        self.fn = fn
        self.name = name
        self.must_start = must_start
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
                result = drive(result, self.signals.progress.emit, self._cancel.is_set, self.must_start)
            if not self._cancel.is_set():
                self.signals.done.emit(result)
        except HairdigiError as exc:        # an expected failure: its message names the problem and the fix
            self.signals.failed.emit(f"{self.name}: {exc}")
        except Exception as exc:            # a bug: shown as a banner, never swallowed; its traceback kept in the log
            traceback.print_exc()
            self.signals.failed.emit(f"{self.name} failed: {type(exc).__name__}: {exc} (a bug in hairdigi; the "
                                     f"traceback is in the log)")
        finally:
            self.signals.finished.emit()


#: The window's workers. More threads than cores: most tasks wait (on Mitsuba's own thread pool, the
#: camera, the serial port), and a capture, a twin and a hairstyle render must run side by side; Qt's
#: global pool has as many threads as cores (2 on the bench PCs).
POOL = QThreadPool()
POOL.setMaxThreadCount(8)


def start(task: Task, pool: QThreadPool | None = None) -> Task:
    (pool or QThreadPool.globalInstance()).start(task)
    return task


class Jobs:
    """A view's running model works (``Work``), at most one per name: a new one cancels the one it
    replaces. What a work yields and returns goes to ``apply`` (the model's) on the UI thread, a failure's
    one line to ``failed``, and its ``ended`` runs there when it is over. Each task is kept until it
    finishes (a :class:`Task` does not delete itself); once ``owner`` is destroyed, every task is
    cancelled and what is still in flight is dropped."""

    def __init__(self, apply: Callable[[object], None], failed: Callable[[str], None], owner: QObject | None = None,
                 pool: QThreadPool | None = None) -> None:
        self.apply, self.failed, self.pool = apply, failed, pool or POOL
        self.named: dict[str, Task] = {}
        self.running: set[Task] = set()
        self.alive = True
        if owner is not None:
            owner.destroyed.connect(lambda *_: self.close())

    def run(self, name: str | None, work: Work | None) -> Task | None:
        """Run ``work`` as the job ``name``, or as one no other replaces (``name`` None); ``work`` None:
        only cancel the job ``name``."""
        old = self.named.pop(name, None) if name is not None else None
        if old is not None:
            old.cancel()
        if work is None or not self.alive:
            return None
        task = Task(work.run, work.name, work.must_start)
        task.signals.progress.connect(self._apply)
        task.signals.done.connect(self._apply)
        task.signals.failed.connect(lambda text: self.alive and self.failed(text))
        if work.ended is not None:
            task.signals.finished.connect(lambda: self.alive and work.ended())
        task.signals.finished.connect(lambda: self._finished(name, task))
        if name is not None:
            self.named[name] = task
        self.running.add(task)
        return start(task, self.pool)

    def _apply(self, value) -> None:
        if self.alive:
            self.apply(value)

    def _finished(self, name: str, task: Task) -> None:
        self.running.discard(task)
        if self.named.get(name) is task:
            del self.named[name]

    def busy(self, name: str | None = None) -> bool:
        return bool(self.running) if name is None else name in self.named

    def cancel(self) -> None:
        for task in list(self.running):
            task.cancel()

    def close(self) -> None:
        self.alive = False
        self.cancel()


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
