"""Ctrl-C around native rendering: the signal waits for the native call, then reaches Python.

Mitsuba's Python ``render`` installs its own SIGINT handler for the length of the call
(``src/render/python/integrator_v.cpp``, ``ScopedSignalHandler``). That handler writes a log line
from inside the signal handler, which is not async-signal-safe: a Ctrl-C that lands while the
interrupted thread holds the allocator's or the logger's lock hangs the process for good (CI,
2026-11: ``hairdigi dataset`` still rendering 60 s after Ctrl-C, nothing printed).

:func:`sigint_held` blocks SIGINT in the calling thread; the kernel keeps the signal pending, and
when the block ends it reaches Python's own handler (a ``KeyboardInterrupt`` in the main thread, or
the program's start-up handler). Mitsuba's handler never runs. ``render_in_passes`` bounds the wait
to one pass. Native pools are started with SIGINT held (``render.variant``), so their threads
inherit the block and only a thread outside native code takes the signal.

The standard library only.
"""
from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def sigint_held() -> Iterator[None]:
    """SIGINT blocked in this thread for the block; a Ctrl-C meanwhile is delivered as it ends."""
    if not hasattr(signal, "pthread_sigmask"):   # Windows: no signal masks (and no deadlock to avoid)
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def stop_among(exc: BaseException | None, kinds: tuple = (SystemExit, KeyboardInterrupt)) -> BaseException | None:
    """The first exception of ``kinds`` among ``exc`` and its causes, or None: native code (Mitsuba, Dr.Jit)
    and the import machinery wrap a Ctrl-C or a SIGTERM's SystemExit in errors of their own."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, kinds):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None
