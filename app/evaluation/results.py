"""What an evaluation or a benchmark measured, as one value that saves and prints itself.

A :class:`Result` holds the table (``rows``: one dict per case, the CSV's lines), the figures that sum
it up (``summary``: the JSON's ``"summary"``), the lines a reader sees (``text``) and the files the run
wrote (``files``). An evaluation's function returns one; the registry (``registry.Entry.run``) prints it
and exits 0, so no command formats its own "wrote ..." line::

    result = Result("fibres_bench", rows, plot=draw_fibres)
    result.save(out)                 # fibres_bench.csv and fibres_bench.png (and .json with a summary)
    result.text.append("platinum  4 groups: 0.12 s")
    return result                    # the registry prints the text, then "wrote out/fibres_bench.csv and ..."

Work that writes its own files (most of ``app/evaluation/*``) hands their paths to ``files`` instead of
calling :meth:`Result.save`.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, TextIO

from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic


def _and(words: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


@dataclass
class Result:
    """One evaluation's or benchmark's results.

    ``name`` is the files' stem (``render_bench``: ``render_bench.csv``, ``.json``, ``.png``). ``plot``,
    when given, draws ``rows`` into a PNG (``plot(rows, path)``), as the module that measured them draws
    it. ``note`` follows the list of files in brackets ("24 cases"). ``compact`` names the files as
    ``stem.csv, .json and .png in FOLDER`` (``hairdigi evaluate``'s way) instead of ``wrote PATH and PATH``
    (``hairdigi bench``'s).
    """

    name: str
    rows: list[dict] = field(default_factory=list)
    summary: dict = field(default_factory=dict)
    text: list[str] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    note: str = ""
    compact: bool = False
    plot: Callable[[list[dict], Path], object] | None = field(default=None, repr=False, compare=False)

    def save(self, out_dir: str | os.PathLike) -> Result:
        """Write ``name.csv`` (the rows), ``name.json`` (``{"summary", "rows"}``, only with a summary) and
        ``name.png`` (with a ``plot``) into ``out_dir``, each atomically; add them to ``files``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        self.files.append(write_csv_atomic(out / f"{self.name}.csv", self.rows))
        if self.summary:
            self.files.append(write_json_atomic(out / f"{self.name}.json", {"summary": self.summary, "rows": self.rows}))
        if self.plot is not None:
            path = out / f"{self.name}.png"
            self.plot(self.rows, path)
            self.files.append(path)
        return self

    def wrote(self) -> str:
        """The line naming the files written ("" when none were)."""
        if not self.files:
            return ""
        note = f" ({self.note})" if self.note else ""
        folders = {Path(f).parent for f in self.files}
        if self.compact and len(folders) == 1:
            stem = Path(self.files[0]).stem     # the first file's stem, said once: a.csv, .json and .png
            names = [Path(f).name for f in self.files[:1]] + [
                Path(f).suffix if Path(f).stem == stem else Path(f).name for f in self.files[1:]]
            return f"{_and(names)} in {folders.pop()}{note}"
        return f"wrote {_and([str(f) for f in self.files])}{note}"

    def lines(self) -> list[str]:
        """What the run prints: its text, then the files it wrote."""
        return [*self.text, *([self.wrote()] if self.files else [])]

    def print(self, file: TextIO | None = None) -> None:
        """Print :meth:`lines` (to stdout unless ``file``)."""
        for line in self.lines():
            print(line, file=file or sys.stdout)
