"""The Library panel's model, free of Qt: the query (search, order, a colour to be near, the light), the
swatches it found, the chosen ones compared, their captured images, and the work behind them
(library queries, image reads, imports and exports).

The library is ``app/library/store.py``; what a row shows is ``app/library/view.py``. The model is a
``PanelModel`` (``app/models/``): widgets subscribe to its events and run its works in their workers;
nothing here queries the library or reads a file on the caller's thread. The works share the panel's
one connection, one at a time (a lock); imports open their own. A newer query supersedes an older one:
its result is dropped when it comes back (a stale result never overwrites a newer one).
"""
from __future__ import annotations

import threading
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Iterator

import numpy as np

from hairdigi.app.library import view
from hairdigi.app.library.importing import first_run, import_paths
from hairdigi.app.library.renderer_export import export_record
from hairdigi.app.library.store import Library, LibraryError, Swatch, redact
from hairdigi.app.library.swatch_colour import COLOURS, ILLUMINANTS, ColourError, hex_lab
from hairdigi.app.models.events import EventGroup, Status
from hairdigi.app.models.panel import PanelModel
from hairdigi.app.models.work import Work
from hairdigi.render.domain.errors import HairdigiError

__all__ = ["LibraryModel", "Query", "Rows", "Selection", "SwatchImage", "Imported", "Exported", "Events",
           "ORDERS", "MAX_ROWS", "NEAR_K"]

ORDERS = ("captured", "colour")   # newest first; by colour (lightness under daylight, light to dark)
MAX_ROWS = 500    # rows a query returns; search or find near a colour to reach the rest
NEAR_K = 200      # the nearest swatches a colour search returns


@dataclass(frozen=True)
class Query:
    """What the panel asks for: ``text`` in id, capture, session, tag or note; near ``near`` (#RRGGBB,
    or ""), under the light ``under``; in ``order`` when not near a colour."""

    text: str = ""
    near: str = ""
    order: str = "captured"
    under: str = ILLUMINANTS[0]


@dataclass(frozen=True)
class Rows:
    """A query's answer: the swatches, each one's ΔE2000 to the colour searched near, the library's size."""

    generation: int
    query: Query
    swatches: tuple[Swatch, ...] = ()
    distances: dict[str, float] = field(default_factory=dict)
    count: int = 0
    error: str | None = None          # the query could not run (a bad colour, the library gone): why

    @property
    def truncated(self) -> bool:
        return not self.query.near and len(self.swatches) >= MAX_ROWS


@dataclass(frozen=True)
class Selection:
    swatches: tuple[Swatch, ...]
    comparison: view.Comparison | None


@dataclass(frozen=True)
class SwatchImage:
    swatch_id: str
    rgb: np.ndarray | None          # None: the image is not on this machine


@dataclass(frozen=True)
class Imported:
    what: str
    count: int


@dataclass(frozen=True)
class Exported:
    paths: tuple[Path, ...]


class Events(EventGroup):
    """The model's events; each carries the new value of the state it names."""

    EVENTS = {"rows": Rows,               # what the last query found (a newer query's, never an older one's)
              "selection": Selection,     # the chosen swatches (up to two) and their comparison
              "image": SwatchImage,       # a swatch's captured image, read off the model's thread
              "changed": int,             # swatches were imported (how many): query again
              "exported": Exported,       # files written
              "status": str}              # one line (the library and what it shows, or what went wrong)


def near_lab(library: Library, near: str, under: str):
    """The colour ``near`` names: ``#RRGGBB``, or a reference tress (a swatch's id, capture id or tag) read under
    ``under`` (a light, or an instrument geometry); raises ColourError naming the fix."""
    try:
        return hex_lab(near)
    except ColourError:
        found = library.swatches_of(near.strip())
        if not found:
            raise ColourError(f"{near!r} is neither #RRGGBB nor a swatch's id, capture id or tag") from None
        lab = found[0].labs.get(under)
        if lab is None:
            raise ColourError(f"the reference {near!r} has no {under} colour; choose another light or reading") from None
        return lab


def run_query(library: Library, query: Query) -> tuple[list[Swatch], dict[str, float]]:
    """The swatches ``query`` asks for, and their ΔE2000 to its colour, a ``#RRGGBB`` or a reference tress
    (raises ColourError: a bad colour)."""
    if query.near:
        matches = library.find(near_lab(library, query.near, query.under), query.under, k=NEAR_K)
        text = query.text.lower()
        matches = [(s, d) for s, d in matches if not text or text in
                   " ".join([s.id, s.capture_id or "", s.session or "", s.note, *s.tags]).lower()]
        return [s for s, _ in matches], {s.id: d for s, d in matches}
    return library.all(query.text, query.order, limit=MAX_ROWS), {}


class LibraryModel(PanelModel):
    """The Library panel's state on ``library`` (an open connection the model closes), and its work."""

    Events = Events

    def __init__(self, library: Library) -> None:
        super().__init__()
        self.library = library
        self.where = library.where
        self.query = Query()
        self.rows = Rows(0, self.query)
        self.selection = Selection((), None)
        self.images: dict[str, np.ndarray | None] = {}
        self._lock = threading.Lock()        # one work at a time on the connection
        self._closed = False

    @property
    def swatches(self) -> tuple[Swatch, ...]:
        return self.rows.swatches

    @contextmanager
    def _connection(self) -> Iterator[Library]:
        """The library, for one work at a time; after :meth:`close`, the last work closes it."""
        with self._lock:
            if self._closed:
                raise LibraryError("the library is closed (its window was closed); open the Library panel again")
            try:
                yield self.library
            finally:
                if self._closed:
                    self.library.close()

    def close(self) -> None:
        """Close the connection now, or when the work using it ends (the UI thread never waits for it)."""
        self._closed = True
        self.stop()
        if self._lock.acquire(blocking=False):
            try:
                self.library.close()
            finally:
                self._lock.release()

    # -- the query ----------------------------------------------------------------------------
    def set_query(self, **changes) -> Query:
        """Change what is asked (``text``, ``near``, ``order``, ``under``); :meth:`query_work` runs it."""
        self._owner()
        if "order" in changes and changes["order"] not in ORDERS:
            raise ValueError(f"order {changes['order']!r}: one of {', '.join(ORDERS)}")
        if "under" in changes and changes["under"] not in COLOURS:
            raise ValueError(f"light {changes['under']!r}: one of {', '.join(COLOURS)}")
        before = self.query
        self.query = replace(before, **{k: v.strip() if isinstance(v, str) else v for k, v in changes.items()})
        if self.query.under != before.under:     # the chips and the comparison are under the light chosen
            self.select(self.selection.swatches)
        return self.query

    def query_work(self) -> Work:
        """Run the query as it is now; whatever an older query still returns is dropped."""
        self._owner()
        generation = self._bump("query")
        stale = self._stale("query", generation)
        query = self.query

        def run():
            if stale():
                return None
            try:
                with self._connection() as library:
                    if stale():                # superseded while it waited for the connection
                        return None
                    swatches, distances = run_query(library, query)
                    count = library.count()
            except HairdigiError as exc:       # a bad colour, a closed or unavailable library; a bug keeps its traceback
                return Rows(generation, query, error=" ".join(str(exc).split()))
            return Rows(generation, query, tuple(swatches), distances, count)
            yield  # noqa: unreachable: makes this a generator
        return Work("library query", run)

    def _apply_rows(self, rows: Rows) -> None:
        if not self._current("query", rows.generation):
            return
        if rows.error is not None:
            self.show_status(rows.error)
            return
        self.rows = rows
        self.events.rows.emit(rows)
        self.show_status(f"library {redact(self.where)}: {rows.count} swatches; {len(rows.swatches)} shown"
                         + (" (the first ones: search to narrow)" if rows.truncated else ""))

    # -- the chosen swatches ---------------------------------------------------------------------
    def select(self, swatches) -> Selection:
        """Choose up to two swatches: the comparison is computed here (their colours are in the rows);
        their images come from :meth:`image_work`."""
        self._owner()
        chosen = tuple(swatches)[:2]
        self.selection = Selection(chosen, view.compare(*chosen) if len(chosen) == 2 else None)
        self.events.selection.emit(self.selection)
        return self.selection

    def image(self, swatch: Swatch) -> tuple[bool, np.ndarray | None]:
        """(read yet, the image) of ``swatch``'s capture."""
        return swatch.id in self.images, self.images.get(swatch.id)

    def image_work(self, swatches=None) -> Work | None:
        """Read the captured images of ``swatches`` (default: the chosen ones) not read yet; None if none."""
        todo = [s for s in (self.selection.swatches if swatches is None else swatches) if s.id not in self.images]
        if not todo:
            return None

        def run():
            for swatch in todo:
                yield SwatchImage(swatch.id, view.capture_image(swatch))
        return Work("swatch images", run)

    def _apply_image(self, image: SwatchImage) -> None:
        self.images[image.swatch_id] = image.rgb
        self.events.image.emit(image)

    # -- imports and exports ----------------------------------------------------------------------
    def import_work(self, folders: list[str]) -> Work:
        """Import session folders, on a connection of the work's own; then the panel queries again."""
        where, folders = self.where, [str(f) for f in folders]

        def run():
            with Library(where) as lib:
                return Imported(f"imported {', '.join(folders)}", import_paths(lib, folders, progress=lambda line: None))
            yield  # noqa: unreachable: makes this a generator
        return Work("library import", run)

    def first_run_work(self) -> Work:
        """Import the sessions written before the library was (once), on a connection of its own."""
        where = self.where

        def run():
            with Library(where) as lib:
                return Imported("sessions written before the library imported", first_run(lib, progress=lambda line: None))
            yield  # noqa: unreachable: makes this a generator
        return Work("library first run", run)

    def _apply_imported(self, imported: Imported) -> None:
        self.show_status(f"{imported.what}: {imported.count} swatches")
        self.events.changed.emit(imported.count)

    def export_work(self, swatch: Swatch, path: str | Path, fmt: str) -> Work | None:
        """Export ``swatch``'s estimate as MaterialX (``materialx``) or a Blender script (``blender``)."""
        self._owner()
        if not swatch.record_path:
            self.show_status("select a swatch with an estimate to export")
            return None
        record, name, path = swatch.record_path, swatch.capture_id or swatch.id, str(path)

        def run():
            try:
                return Exported(tuple(Path(p) for p in export_record(record, fmt, path, name=name)))
            except (ValueError, OSError) as exc:
                return Status(f"export: {exc}")
            yield  # noqa: unreachable: makes this a generator
        return Work("export", run)

    def _apply_exported(self, exported: Exported) -> None:
        self.show_status(f"wrote {exported.paths[0]}")
        self.events.exported.emit(exported)

    _HANDLERS = {Rows: _apply_rows, SwatchImage: _apply_image, Imported: _apply_imported, Exported: _apply_exported}
