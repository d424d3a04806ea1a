"""``hairdigi bench library``: ``find`` timed on a library of synthetic swatches, SQLite and PostgreSQL."""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from hairdigi.app.evaluation.registry import BENCH_OUT
from hairdigi.app.evaluation.results import Result
from hairdigi.app.library.importing import _with_colours
from hairdigi.app.library.store import Library, SwatchRecord, SwatchRow
from hairdigi.app.library.swatch_colour import ILLUMINANTS, hex_lab
from hairdigi.render.domain.files import write_csv_atomic, write_json_atomic
from hairdigi.render.domain.params import HairParams
from hairdigi.render.domain.records import EstimateRecord


def synthetic_rows(n: int, seed: int = 0) -> list:
    """``n`` swatches of uniformly drawn Table 1 parameters, coloured as an import colours them."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        record = EstimateRecord(hair=HairParams(tuple(rng.uniform(0, 255, 3)), rng.uniform(), rng.uniform(),
                                                rng.uniform()))
        rows.append(SwatchRow(id=f"b{seed:03d}{i:012d}", kind="estimate", captured=f"bench {i}", reliable=True,
                              hair=record.hair, sigma_a=record.sigma_a, record=SwatchRecord(estimate=record)))
    return _with_colours(rows)


def bench_library(args: argparse.Namespace) -> Result:
    """Time ``find`` (k = 10) on a library of ``--n`` swatches (10,000), SQLite and (``HAIRDIGI_BENCH_POSTGRES``)
    PostgreSQL; write ``library_bench.csv`` and ``.json``."""
    n = args.n or 10_000
    out = Path("packaging/bench/library") if args.out == BENCH_OUT else Path(args.out)
    start = time.perf_counter()
    rows = synthetic_rows(n)
    colour_s = time.perf_counter() - start
    backends = [("sqlite", None)]
    if os.environ.get("HAIRDIGI_BENCH_POSTGRES"):
        backends.append(("postgresql", os.environ["HAIRDIGI_BENCH_POSTGRES"]))
    results, text = [], []
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
                    text.append(f"{backend}: find near {kind} among {r['swatches']} swatches under {under}: median "
                                f"{r['find_ms_median']} ms, p95 {r['find_ms_p95']} ms (load {r['load_1min']})")
            if url:
                with library.db.transaction():
                    library.db.execute("DELETE FROM swatches WHERE id LIKE ?", ("b%",))
            library.close()
    files = [write_csv_atomic(out / "library_bench.csv", results),
             write_json_atomic(out / "library_bench.json", {"results": results, "command": "hairdigi bench library",
                                                            "cpu_count": os.cpu_count(),
                                                            "time": time.strftime("%Y-%m-%dT%H:%M:%S%z")})]
    return Result("library_bench", results, text=text, files=files)

