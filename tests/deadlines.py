"""Time bounds in tests, made generous so that a loaded machine never fails a test.

A bound in a test says that something does not hang, or skips the work it must skip (a huge image is
refused from its header, a bad name before any render); it is not a speed figure: those are measured by
``hairdigi bench`` and ``hairdigi evaluate``. Each bound is the idle time it guards times ``LOAD_SLACK``:
the suite passes beside two busy processes at the same priority (a 2-core machine runs it at a third of
its idle speed), and a test that did the skipped work would still take far longer.
"""
import os

#: How much slower than idle a test may run before its bound fails (``HAIRDIGI_TEST_SLACK`` overrides).
LOAD_SLACK = float(os.environ.get("HAIRDIGI_TEST_SLACK", "5"))


def within(seconds: float) -> float:
    """The bound for work that takes at most ``seconds`` on an idle machine."""
    return seconds * LOAD_SLACK
