"""The worker protocol, free of Qt: a model's slow work as a generator function, and the loop that runs it.

A :class:`Work` is napari's ``thread_worker`` idea: its yields are progress, its return the result. A
worker (``app/gui/workers.py``: ``Jobs`` and ``Task``) runs it off the UI thread and hands each value to
the model's ``apply`` on the model's thread; :func:`run_now` does the same in the calling thread (tests,
headless use). Both step the generator with :func:`drive`, the one place that says how a work stops
when cancelled.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Generator

__all__ = ["Cancelled", "Work", "drive", "run_now", "returns", "never"]

Cancelled = Callable[[], bool]


def never() -> bool:
    """A :data:`Cancelled` that never is."""
    return False


@dataclass
class Work:
    """A generator function run by a worker: its yields are progress, its return value the result.

    ``ended`` (when given) runs on the model's thread once the work is over: done, failed or cancelled.
    ``must_start``: the work begins even when cancelled before a worker picked it up (a capture asked for is taken).
    """

    name: str
    run: Callable[[], Generator[object, None, object]]
    ended: Callable[[], None] | None = None
    must_start: bool = False


def drive(generator: Generator[object, None, object], progress: Callable[[object], None],
          cancelled: Cancelled = never, must_start: bool = False) -> object:
    """Step ``generator`` to its end in this thread, handing each value it yields to ``progress``; returns
    its return value.

    Cancelled, it stops at a yield: the generator is closed there (its ``finally`` runs), a value it
    yielded after the cancel is dropped, and None is returned. It is not started at all when cancelled
    before its first step, unless ``must_start``: then it takes that step (and a generator that must run
    to its end, as a capture does, runs it in its ``finally``).
    """
    first = True
    while True:
        if cancelled() and not (first and must_start):      # stop at a yield
            generator.close()
            return None
        first = False
        try:
            value = next(generator)
        except StopIteration as stop:
            return stop.value
        if not cancelled():
            progress(value)


def run_now(work: Work | None, apply: Callable[[object], None], cancelled: Cancelled = never) -> object:
    """Run ``work`` in this thread, handing what it yields and returns to ``apply``; returns the result
    (None when cancelled: its result is dropped, as a worker drops it). ``work.ended`` runs at the end."""
    if work is None:
        return None
    try:
        result = drive(work.run(), apply, cancelled, work.must_start)
        if cancelled():
            return None
        if result is not None:
            apply(result)
        return result
    finally:
        if work.ended is not None:
            work.ended()


def returns(fn: Callable[[], object]) -> Callable[[], Generator[object, None, object]]:
    """A plain function as a work generator that yields nothing."""
    def run():
        return fn()
        yield  # noqa: unreachable: makes this a generator
    return run
