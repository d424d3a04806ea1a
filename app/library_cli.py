"""``hairdigi library import|find|tag|note|export|info`` and ``hairdigi bench library``."""
from __future__ import annotations

import argparse
import csv
import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hairdigi.app.library import Library, LibraryError, Swatch, open_library
from hairdigi.app.swatch_colour import ILLUMINANTS, hex_lab, lab_hex

EXPORT_COLUMNS = ("id", "kind", "session", "capture_id", "captured", "imported", "reliable", "tags", "note",
                  "sigma_r", "sigma_g", "sigma_b", "daylight_L", "daylight_a", "daylight_b", "daylight_hex",
                  "studio_L", "studio_a", "studio_b", "studio_hex", "dye_r", "dye_g", "dye_b", "dye_concentration",
                  "melanin_concentration", "melanin_ratio", "image_path", "record_path")


def _open(progress=None) -> Library:
    """The library, with sessions written before it imported on its first open."""
    from hairdigi.app.library_import import first_run

    library = open_library()
    first_run(library, progress or (lambda line: print(line, file=sys.stderr)))
    return library


def query_lab(near: str, under: str) -> np.ndarray:
    """CIELAB of ``near``: ``#RRGGBB``, or a record file's swatch under ``under``."""
    text = near.strip()
    if text.startswith("#") or (len(text) == 6 and all(c in "0123456789abcdefABCDEF" for c in text)
                                and not Path(text).exists()):
        return hex_lab(text)
    from hairdigi.app.library_import import record_row

    row = record_row(text)
    if not row.labs:
        raise LibraryError(f"{text}: the record has no estimate, so no colour to search near")
    return np.asarray(row.labs[under])


def swatch_line(s: Swatch, under: str = "daylight") -> str:
    lab = s.labs.get(under)
    colour = lab_hex(lab) if lab else "-------"
    where = f"{Path(s.session).name}/{s.capture_id}" if s.session else Path(s.record_path or "").name
    tags = f" [{', '.join(s.tags)}]" if s.tags else ""
    note = f" — {s.note}" if s.note else ""
    return f"{s.id}  {s.kind:8s} {colour}  {s.captured or '':24s} {where}{tags}{note}"


def export_rows(library: Library) -> list[dict]:
    rows = []
    for s in library.all():
        hair = s.hair or {}
        dye = hair.get("dye_rgb") or [None] * 3
        row = {"id": s.id, "kind": s.kind, "session": s.session, "capture_id": s.capture_id, "captured": s.captured,
               "imported": s.imported, "reliable": s.reliable, "tags": ";".join(s.tags), "note": s.note}
        row.update(dict(zip(("sigma_r", "sigma_g", "sigma_b"), s.sigma_a or (None,) * 3)))
        for ill in ILLUMINANTS:
            lab = s.labs.get(ill)
            row.update(dict(zip((f"{ill}_L", f"{ill}_a", f"{ill}_b"), lab or (None,) * 3)))
            row[f"{ill}_hex"] = lab_hex(lab) if lab else None
        row.update({"dye_r": dye[0], "dye_g": dye[1], "dye_b": dye[2],
                    "dye_concentration": hair.get("dye_concentration"),
                    "melanin_concentration": hair.get("melanin_concentration"),
                    "melanin_ratio": hair.get("melanin_ratio"), "image_path": s.image_path, "record_path": s.record_path})
        rows.append({k: row[k] for k in EXPORT_COLUMNS})
    return rows


def write_export(library: Library, csv_path: str | None = None, xlsx_path: str | None = None) -> list[Path]:
    from hairdigi.render.base.files import atomic_path, write_text_atomic

    rows = export_rows(library)
    written = []
    if csv_path:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=EXPORT_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
        written.append(write_text_atomic(csv_path, buffer.getvalue()))
    if xlsx_path:
        from openpyxl import Workbook

        book = Workbook()
        sheet = book.active
        sheet.title = "swatches"
        sheet.append(list(EXPORT_COLUMNS))
        for row in rows:
            sheet.append([row[k] for k in EXPORT_COLUMNS])
        with atomic_path(xlsx_path) as tmp:
            book.save(tmp)
        written.append(Path(xlsx_path))
    return written


# --- commands --------------------------------------------------------------------------------------
def cmd_library(args: argparse.Namespace) -> int:
    with _open() as library:
        return COMMANDS[args.library_command](library, args)


def _import(library: Library, args) -> int:
    from hairdigi.app.library_import import import_paths

    n = import_paths(library, args.paths, progress=lambda line: print(line, flush=True))
    print(f"imported {n} swatches; the library at {library.where} holds {library.count()}")
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
    print(f"{library.resolve(args.swatch)}: {', '.join(tags) or 'no tags'}")
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


def _info(library: Library, args) -> int:
    print(f"library: {library.where}\nschema version: {library.version}\nswatches: {library.count()}\n"
          f"sessions imported: {len(library.sessions())}")
    return 0


COMMANDS = {"import": _import, "find": _find, "tag": _tag, "note": _note, "export": _export, "info": _info}


def add_parser(sub) -> None:
    p = sub.add_parser("library", help="the swatch library: import sessions, find by colour, tag, note, export "
                                       "(HAIRDIGI_LIBRARY: a file or postgresql:// URL)")
    lib = p.add_subparsers(dest="library_command", required=True)
    q = lib.add_parser("import", help="import session folders (one transaction each) or record files")
    q.add_argument("paths", nargs="+", metavar="SESSION")
    q = lib.add_parser("find", help="the swatches nearest a colour, by mean-colour ΔE2000, one a line")
    q.add_argument("--near", required=True, help="an estimate record (JSON) or #RRGGBB")
    q.add_argument("--under", choices=ILLUMINANTS, default="daylight",
                   help="the light the colours are compared under (approximations; see app/swatch_colour.py)")
    q.add_argument("--k", type=int, default=10, help="how many matches (default 10)")
    q = lib.add_parser("tag", help="tag a swatch (its id or a unique start of it, or its capture id)")
    q.add_argument("swatch")
    q.add_argument("tags", nargs="+")
    q.add_argument("--remove", action="store_true", help="remove these tags instead")
    q = lib.add_parser("note", help="set a swatch's note")
    q.add_argument("swatch")
    q.add_argument("text")
    q = lib.add_parser("export", help="every swatch as a table")
    q.add_argument("--csv", help="CSV file to write")
    q.add_argument("--xlsx", help="Excel file to write (openpyxl)")
    lib.add_parser("info", help="where the library is, its schema version and size")
    p.set_defaults(func=cmd_library)


# --- benchmark -------------------------------------------------------------------------------------
def synthetic_rows(n: int, seed: int = 0) -> list:
    """``n`` swatches of uniformly drawn Table 1 parameters, coloured as an import colours them."""
    from hairdigi.app.library import SwatchRow
    from hairdigi.app.library_import import _with_colours
    from hairdigi.render.absorption import hair_sigma_a
    from hairdigi.render.base.params import HairParams

    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        hair = HairParams(tuple(rng.uniform(0, 255, 3)), rng.uniform(), rng.uniform(), rng.uniform())
        rows.append(SwatchRow(id=f"b{seed:03d}{i:012d}", kind="estimate", captured=f"bench {i}", reliable=True,
                              hair=hair.to_dict(), sigma_a=tuple(float(v) for v in hair_sigma_a(hair)),
                              record={"kind": "estimate", "hair": hair.to_dict(), "bench": True}))
    return _with_colours(rows)


def bench_library(args: argparse.Namespace) -> int:
    """Time ``find`` (k = 10) on a library of ``--n`` swatches (10,000), SQLite and (``HAIRDIGI_BENCH_POSTGRES``) PostgreSQL."""
    from hairdigi.render.base.files import write_csv_atomic, write_json_atomic

    n = args.n or 10_000
    out = Path("packaging/bench/library") if args.out == "out/bench" else Path(args.out)
    start = time.perf_counter()
    rows = synthetic_rows(n)
    colour_s = time.perf_counter() - start
    backends = [("sqlite", None)]
    if os.environ.get("HAIRDIGI_BENCH_POSTGRES"):
        backends.append(("postgresql", os.environ["HAIRDIGI_BENCH_POSTGRES"]))
    results = []
    rng = np.random.default_rng(1)
    queries = [f"#{int(v):06x}" for v in rng.integers(0, 0xFFFFFF, 50)]
    with tempfile.TemporaryDirectory(prefix="hairdigi-bench-") as tmp:
        for backend, url in backends:
            library = Library(url or str(Path(tmp) / "library.sqlite"))
            if url:   # a fresh table set: the bench's rows only
                with library.db.transaction():
                    library.db.execute("DELETE FROM swatches WHERE id LIKE ?", ("b%",))
            t0 = time.perf_counter()
            library.add(rows)
            import_s = time.perf_counter() - t0
            for under in ILLUMINANTS:
                near_swatch = [np.asarray(rows[i].labs[under]) + rng.normal(0, 0.5, 3)
                               for i in rng.integers(0, n, len(queries))]
                for kind, labs in (("#RRGGBB at random", [hex_lab(q) for q in queries]),
                                   ("a swatch's colour (--near RECORD)", near_swatch)):
                    times = []
                    for lab in labs:
                        t0 = time.perf_counter()
                        library.find(lab, under, 10)
                        times.append(1000 * (time.perf_counter() - t0))
                    results.append({"backend": backend, "swatches": library.count(), "under": under, "near": kind,
                                    "k": 10, "queries": len(labs), "find_ms_median": round(float(np.median(times)), 2),
                                    "find_ms_p95": round(float(np.percentile(times, 95)), 2),
                                    "find_ms_max": round(float(np.max(times)), 2),
                                    "write_s": round(import_s, 3), "colour_s": round(colour_s, 3),
                                    "load_1min": round(os.getloadavg()[0], 2)})
                    r = results[-1]
                    print(f"{backend}: find near {kind} among {r['swatches']} swatches under {under}: median "
                          f"{r['find_ms_median']} ms, p95 {r['find_ms_p95']} ms (load {r['load_1min']})")
            if url:
                with library.db.transaction():
                    library.db.execute("DELETE FROM swatches WHERE id LIKE ?", ("b%",))
            library.close()
    write_csv_atomic(out / "library_bench.csv", results)
    write_json_atomic(out / "library_bench.json", {"results": results, "command": "hairdigi bench library",
                                                   "cpu_count": os.cpu_count(), "time": time.strftime("%Y-%m-%dT%H:%M:%S%z")})
    print(f"wrote {out / 'library_bench.csv'} and {out / 'library_bench.json'}")
    return 0

