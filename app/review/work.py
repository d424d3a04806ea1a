"""The worker protocol, free of Qt: a model's slow work as a generator function, and its runner.

A :class:`Work` is napari's ``thread_worker`` idea: its yields are progress, its return the result. A
worker (``app/gui/workers.Jobs`` or ``Task`` in the window) runs it off the UI thread and hands each
value to the model's ``apply`` on the model's thread; :func:`run_now` does the same in the calling
thread (tests, headless use).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Generator

__all__ = ["Cancelled", "Work", "run_now", "returns"]

Cancelled = Callable[[], bool]


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


def run_now(work: Work | None, apply: Callable[[object], None], cancelled: Cancelled = lambda: False) -> object:
    """Run ``work`` in this thread, handing what it yields and returns to ``apply``; returns the result."""
    if work is None:
        return None
    result = None
    try:
        generator = work.run()
        while True:
            try:
                value = next(generator)
            except StopIteration as stop:
                result = stop.value
                break
            if cancelled():           # stop at a yield
                generator.close()
                return None
            apply(value)
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
