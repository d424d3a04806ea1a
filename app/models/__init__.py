"""The panel machinery, free of Qt: the one home of what every model behind a window or panel shares.

- ``work.py``: the worker protocol. :class:`~hairdigi.app.models.work.Work` (a model's slow work as a
  generator function: its yields are progress, its return the result), and the one loop that steps it
  (``drive``): :func:`~hairdigi.app.models.work.run_now` runs a work in the calling thread (tests, headless
  use), ``app/gui/workers.py``'s ``Task`` off the UI thread.
- ``events.py``: typed events (``Event``, ``EventGroup``) and the ``Status`` line every model can emit.
- ``panel.py``: :class:`~hairdigi.app.models.panel.PanelModel`, a model's state changed on one owner
  thread, its work's generations (a newer ask makes older work stale) and ``apply``, which hands a work's
  values to their handlers.

The review (``app/review/model.py``: ``ReviewModel``), Dye (``app/dye/model.py``: ``DyeModel``) and
Library (``app/library/model.py``: ``LibraryModel``) models are ``PanelModel``s. This package sits below
them and below the window: it imports neither Qt, nor ``app.gui``, nor ``app.cli`` (a contract in
``pyproject.toml``).
"""
