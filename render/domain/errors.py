"""The one base of hairdigi's expected errors: a failure the user can fix, not a bug.

Every error class hairdigi defines derives from :class:`HairdigiError` and, for code that already
catches it by its builtin kind, keeps that builtin base too (``class RecordError(HairdigiError,
ValueError)``). The command line prints a ``HairdigiError`` as one line and exits 2; a plain
``ValueError``, ``TypeError``, ``KeyError`` or ``RuntimeError`` is a bug and keeps its traceback
(``hairdigi.app.cli.validation.is_expected``).

Raise a ``HairdigiError`` subclass where a user's input or environment (a file, an argument, a
device, a missing program) can cause the failure; keep a builtin error where only a programming
mistake can reach the line. Convert at the boundary: where numpy, ``json`` or ``int()`` refuse a
user's data, catch that error and raise the module's ``HairdigiError`` with a message naming the
file or field and the fix.

The standard library only: every layer imports this module.
"""
from __future__ import annotations


class HairdigiError(Exception):
    """A failure the user can fix; its message names the problem and the fix."""


class EvaluationError(HairdigiError, ValueError):
    """An evaluation that cannot run with the settings asked (sizes that cannot be compared), or that ran and
    judged nothing; the message says which settings to change. One class for every evaluation and bench."""
