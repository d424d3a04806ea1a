"""``hairdigi library import|find|tag|note|export|info`` and ``hairdigi bench library``."""
from __future__ import annotations

import argparse
import csv
import re
import sys
import time
from pathlib import Path

import numpy as np

from hairdigi.app.cli import validation as v
from hairdigi.app.library.importing import first_run, import_paths, record_row
from hairdigi.app.library.store import Library, LibraryError, Swatch, is_url, location, open_library, redact
from hairdigi.app.library.swatch_colour import COLOURS, ILLUMINANTS, INSTRUMENT, hex_lab, lab_hex
from hairdigi.render.domain.files import atomic_paths

#: An instrument geometry's prefix in the export's columns.
INSTRUMENT_COLUMNS = {"d/8 SCI": "sci", "d/8 SCE": "sce", "45/0": "g45_0"}
EXPORT_COLUMNS = ("id", "kind", "session", "capture_id", "captured", "imported", "reliable", "tags", "note",
                  "sigma_r", "sigma_g", "sigma_b", "daylight_L", "daylight_a", "daylight_b", "daylight_hex",
                  "studio_L", "studio_a", "studio_b", "studio_hex", *(f"{INSTRUMENT_COLUMNS[g]}_{c}" for g in INSTRUMENT for c in "Lab"),
                  "dye_r", "dye_g", "dye_b", "dye_concentration",
                  "melanin_concentration", "melanin_ratio", "image_path", "record_path")


def _open(progress=None) -> Library:
    """The library, with sessions written before it imported on its first open."""
    library = open_library()
    first_run(library, progress or (lambda line: print(line, file=sys.stderr)))
    return library


MAX_K = 10_000
MAX_TAG, MAX_NOTE = 200, 10_000


def text_up_to(limit: int, what: str):
    """An argparse type: text of at most ``limit`` characters."""
    def parse(text: str) -> str:
        if len(text) > limit:
            raise argparse.ArgumentTypeError(f"{what} of {len(text)} characters is longer than {limit}; shorten it")
        return text
    return parse


def query_lab(near: str, under: str) -> np.ndarray:
    """CIELAB of ``near``: ``#RRGGBB``, or a record file's swatch under ``under``."""
    text = near.strip()
    if text.startswith("#") or (len(text) == 6 and all(c in "0123456789abcdefABCDEF" for c in text)
                                and not Path(text).exists()):
        return hex_lab(text)
    row = record_row(text)
    if not row.labs:
        raise LibraryError(f"{text}: the record has no estimate, so no colour to search near")
    if under not in row.labs:
        raise LibraryError(f"{text}: the record has no {under} reading (written before hairdigi read instruments); "
                           f"estimate it again, or search --under daylight")
    return np.asarray(row.labs[under])


def printable(text: str) -> str:
    """Text safe for a terminal: control characters (ANSI escapes, carriage returns) shown as ``?``."""
    return "".join("?" if (ord(c) < 32 or 127 <= ord(c) < 160) else c for c in str(text))


def swatch_line(s: Swatch, under: str = "daylight") -> str:
    lab = s.labs.get(under)
    colour = lab_hex(lab) if lab else "-------"
    where = f"{Path(s.session).name}/{s.capture_id}" if s.session else Path(s.record_path or "").name
    tags = f" [{', '.join(s.tags)}]" if s.tags else ""
    note = f" — {s.note}" if s.note else ""
    return printable(f"{s.id}  {s.kind:8s} {colour}  {s.captured or '':24s} {where}{tags}{note}")


def export_rows(library: Library) -> list[dict]:
    rows = []
    for s in library.all():
        hair = s.hair
        dye = (None,) * 3 if hair is None else hair.dye_rgb
        row = {"id": s.id, "kind": s.kind, "session": s.session, "capture_id": s.capture_id, "captured": s.captured,
               "imported": s.imported, "reliable": s.reliable, "tags": ";".join(s.tags), "note": s.note}
        row.update(dict(zip(("sigma_r", "sigma_g", "sigma_b"), s.sigma_a or (None,) * 3)))
        for ill in ILLUMINANTS:
            lab = s.labs.get(ill)
            row.update(dict(zip((f"{ill}_L", f"{ill}_a", f"{ill}_b"), lab or (None,) * 3)))
            row[f"{ill}_hex"] = lab_hex(lab) if lab else None
        for g in INSTRUMENT:
            row.update(dict(zip((f"{INSTRUMENT_COLUMNS[g]}_{c}" for c in "Lab"), s.labs.get(g) or (None,) * 3)))
        row.update({"dye_r": dye[0], "dye_g": dye[1], "dye_b": dye[2],
                    "dye_concentration": None if hair is None else hair.dye_concentration,
                    "melanin_concentration": None if hair is None else hair.melanin_concentration,
                    "melanin_ratio": None if hair is None else hair.melanin_ratio,
                    "image_path": s.image_path, "record_path": s.record_path})
        rows.append({k: row[k] for k in EXPORT_COLUMNS})
    return rows


#: OWASP's CSV injection advice: a cell starting with one of these is read as a formula by a spreadsheet.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: Where a spreadsheet may split a cell's text into cells (a locale's list separator, text to columns, a
#: pasted line): every piece after one of these is a cell start too.
CELL_SEPARATORS = ",;|\t\r\n\v\f"
#: A piece after a separator that starts a formula, past spaces and double quotes (a quoted ``"=1+2"``).
_FORMULA_AFTER_SEPARATOR = re.compile(rf"([{re.escape(CELL_SEPARATORS)}][ \"]*)(?=[=+\-@])")
#: The most characters an XLSX cell holds (Excel's limit; openpyxl writes more, and Excel cuts them).
XLSX_CELL_MAX = 32_767


def neutral_cell(value):
    """A table cell no spreadsheet runs, however it splits it: text starting (past spaces and quotes) with
    ``= + - @``, TAB or CR gets a leading ``'``, and so does every piece after a separator a spreadsheet may
    split on (``, ; |`` TAB, CR, LF) that starts with ``= + - @``. Idempotent; numbers are kept."""
    if not isinstance(value, str):
        return value
    value = _FORMULA_AFTER_SEPARATOR.sub(r"\1'", value)
    if value.startswith(FORMULA_STARTS) or value.lstrip(' "').startswith(FORMULA_STARTS[:4]):
        return "'" + value
    return value


def _xlsx_cell(value, row: dict, column: str):
    """A cell for openpyxl: neutralised, stored as text (never a formula), and within Excel's size."""
    value = neutral_cell(value)
    if isinstance(value, str) and len(value) > XLSX_CELL_MAX:
        raise LibraryError(f"swatch {row['id']}: its {column} is {len(value)} characters, more than an Excel cell "
                           f"holds ({XLSX_CELL_MAX}); shorten it (hairdigi library note) or export --csv")
    return value


def check_export_paths(csv_path: str | None, xlsx_path: str | None, library_where: str | None = None) -> None:
    """Both outputs have their extension, differ, and are none of the library's, a session's or the package's files."""
    inputs = {"library": library_where} if library_where and not is_url(library_where) else {}
    v.check_distinct({"--csv": csv_path, "--xlsx": xlsx_path})
    if csv_path:
        v.check_output_file(csv_path, "--csv", (".csv",), "CSV", inputs)
    if xlsx_path:
        v.check_output_file(xlsx_path, "--xlsx", (".xlsx",), "an Excel workbook", inputs)


def write_export(library: Library, csv_path: str | None = None, xlsx_path: str | None = None) -> list[Path]:
    """The library as CSV and/or XLSX, both published together; cells that a spreadsheet would run as a
    formula are neutralised (a leading ``'``)."""
    rows = [{k: neutral_cell(v) for k, v in row.items()} for row in export_rows(library)]
    book = None
    if xlsx_path:
        from openpyxl import Workbook  # deferred: openpyxl takes 0.1 s to load; only --xlsx needs it

        book = Workbook()
        sheet = book.active
        sheet.title = "swatches"
        sheet.append(list(EXPORT_COLUMNS))
        for row in rows:
            sheet.append([_xlsx_cell(row[k], row, k) for k in EXPORT_COLUMNS])
            for cell in sheet[sheet.max_row]:
                if cell.data_type == "f":     # openpyxl reads any text starting with "=" as a formula
                    cell.data_type = "s"
    with atomic_paths(csv_path, xlsx_path) as (csv_tmp, xlsx_tmp):
        if csv_tmp is not None:
            with open(csv_tmp, "w", newline="", encoding="utf-8") as f:   # text quoted: one cell in any locale
                writer = csv.DictWriter(f, fieldnames=EXPORT_COLUMNS, quoting=csv.QUOTE_NONNUMERIC)
                writer.writeheader()
                writer.writerows(rows)
        if xlsx_tmp is not None:
            book.save(xlsx_tmp)
    return [Path(p) for p in (csv_path, xlsx_path) if p]


# --- commands --------------------------------------------------------------------------------------
def run(args: argparse.Namespace) -> int:
    if args.library_command == "export":   # the outputs are checked before the library is opened
        if not args.csv and not args.xlsx:
            raise LibraryError("give --csv FILE, --xlsx FILE or both")
        check_export_paths(args.csv, args.xlsx, location())
    with _open() as library:
        return COMMANDS[args.library_command](library, args)


def _import(library: Library, args) -> int:
    n = import_paths(library, args.paths, progress=lambda line: print(line, flush=True))
    print(f"imported {n} swatches; the library at {redact(library.where)} holds {library.count()}")
    return 0


def _find(library: Library, args) -> int:
    lab = query_lab(args.near, args.under)
    start = time.perf_counter()
    matches = library.find(lab, args.under, args.k)
    seconds = time.perf_counter() - start
    if not matches:
        print("the library holds no swatch with a colour yet; hairdigi library import SESSION", file=sys.stderr)
        return 0
    for rank, (s, de) in enumerate(matches, 1):
        print(f"{rank:3d}  ΔE2000 {de:6.2f}  {swatch_line(s, args.under)}")
    print(f"{len(matches)} of {library.count()} swatches, under {args.under}, in {seconds * 1000:.1f} ms",
          file=sys.stderr)
    return 0


def _tag(library: Library, args) -> int:
    tags = library.tag(args.swatch, args.tags, remove=args.remove)
    print(printable(f"{library.resolve(args.swatch)}: {', '.join(tags) or 'no tags'}"))
    return 0


def _note(library: Library, args) -> int:
    print(f"{library.note(args.swatch, args.text)}: note saved")
    return 0


def _export(library: Library, args) -> int:
    if not args.csv and not args.xlsx:
        raise LibraryError("give --csv FILE, --xlsx FILE or both")
    for path in write_export(library, args.csv, args.xlsx):
        print(f"wrote {path}")
    return 0


def _readings(library: Library, args) -> int:
    # deferred: 3 ms to import, for library readings only; the parser must not pay it (hairdigi --help in 0.2 s)
    from hairdigi.app.library.lab_readings import import_readings, parse_columns

    start = time.perf_counter()
    readings = import_readings(library, args.file, allow_unknown=args.allow_unknown, columns=parse_columns(args.columns),
                               default_geometry=args.geometry, observer=args.observer, illuminant=args.illuminant)
    tresses = len({r.tress for r in readings})
    print(f"imported {len(readings)} readings of {tresses} tresses from {Path(args.file).name} in "
          f"{time.perf_counter() - start:.2f} s; compare them with hairdigi evaluate --readings --out DIR")
    return 0


def _info(library: Library, args) -> int:
    print(f"library: {redact(library.where)}\nschema version: {library.version}\nswatches: {library.count()}\n"
          f"sessions imported: {len(library.sessions())}")
    return 0


COMMANDS = {"import": _import, "find": _find, "tag": _tag, "note": _note, "export": _export, "info": _info,
            "readings": _readings}


def add_parser(sub) -> None:
    p = sub.add_parser("library", help="the swatch library: import sessions, find by colour, tag, note, export "
                                       "(HAIRDIGI_LIBRARY: a file or postgresql:// URL)")
    lib = p.add_subparsers(dest="library_command", required=True)
    q = lib.add_parser("import", help="import session folders (one transaction each) or record files")
    q.add_argument("paths", nargs="+", metavar="SESSION")
    q = lib.add_parser("find", help="the swatches nearest a colour, by mean-colour ΔE2000, one a line")
    q.add_argument("--near", required=True, help="an estimate record (JSON) or #RRGGBB")
    q.add_argument("--under", choices=COLOURS, default="daylight",
                   help="the light the colours are compared under (approximations; see app/library/swatch_colour.py), "
                        "or an instrument geometry's reading (D65, 10°)")
    q.add_argument("--k", type=v.int_in(1, MAX_K), default=10, help=f"how many matches (1 to {MAX_K}; default 10)")
    q = lib.add_parser("tag", help="tag a swatch (its id or a unique start of it, or its capture id)")
    q.add_argument("swatch")
    q.add_argument("tags", nargs="+", type=text_up_to(MAX_TAG, "a tag"))
    q.add_argument("--remove", action="store_true", help="remove these tags instead")
    q = lib.add_parser("note", help="set a swatch's note")
    q.add_argument("swatch")
    q.add_argument("text", type=text_up_to(MAX_NOTE, "a note"))
    q = lib.add_parser("export", help="every swatch as a table")
    q.add_argument("--csv", help="CSV file to write")
    q.add_argument("--xlsx", help="Excel file to write (openpyxl)")
    lib.add_parser("info", help="where the library is, its schema version and size")
    q = lib.add_parser("readings", help="import the lab's instrument readings of its tresses (CSV or CxF3), keyed by "
                                        "tress id: a swatch's id, capture id or tag")
    q.add_argument("file", help="the instrument's export: .csv (columns found by name; see --columns) or .cxf")
    q.add_argument("--columns", help="FIELD=HEADER,... where the headers are not recognised (fields: id, L, a, b, "
                                     "geometry, observer, illuminant)")
    q.add_argument("--geometry", default="d/8 SCI", help="the geometry of readings that do not name one "
                                                          "(d/8 SCI, d/8 SCE, 45/0; default d/8 SCI)")
    q.add_argument("--observer", default="10", choices=("10", "2"), help="the observer of readings that do not name one")
    q.add_argument("--illuminant", default="D65", help="the illuminant of readings that do not name one (default D65)")
    q.add_argument("--allow-unknown", action="store_true", help="keep readings of tresses no swatch is tagged with yet")
    p.set_defaults(func=run)
